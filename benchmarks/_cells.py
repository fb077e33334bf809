"""Table cells of the independent matrix's report (benchmarks/bench_independent.py): a
row's named effects with their fits, a fit with its interval, a parameter set."""

from __future__ import annotations

from typing import Any


def fitted_cell(f: dict[str, Any]) -> str:
    if f.get("value") is None or f.get("lo") is None or f.get("hi") is None:
        return "—"
    if f.get("side") == "upper":
        return f"< {f['hi']:.3g}"
    return f"{f['value']:.3g} [{f['lo']:.3g}, {f['hi']:.3g}]"


def named_cell(r: dict[str, Any]) -> str:
    """The named effects, each with its fitted parameters where the row has them."""
    if not r["named"]:
        return "—"
    nf = r.get("named_fits") or {}

    def one(name: str) -> str:
        ps = nf.get(name)
        if not ps:
            return name
        return (
            name
            + " ("
            + "; ".join(f"{k} {v[0]:.3g} [{v[1]:.3g}, {v[2]:.3g}]" for k, v in ps.items())
            + ")"
        )

    return ", ".join(one(n) for n in r["named"])


def params_cell(p: dict[str, float]) -> str:
    return ", ".join(f"{k} {v:.4g}" for k, v in p.items())

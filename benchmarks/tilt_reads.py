"""Which signal group reads a ground tilt, size and heading together, on clean builds and on
slopes of the independent generator.

``group_reads.py`` reads one parameter with the others held at the truth; a clean build has
no truth to hold, and what a slope single must clear is the tilt a clean build is read at
(the clean-fit allowance: 0.27-2.37 deg over 100 clean cases). Here each case's training
windows (after ``diagnose``'s split, forms and floor) are replayed over a polar grid of
tilts (``--sizes`` x 12 headings, 30 deg apart) and each signal group's own best tilt is
kept beside all signals' (the mean log loss ratio, what ``diagnose``'s naming test judges
by). Why (stop
94): slopes of 2-3 deg were fitted at 1.6-1.7 deg, the joints pulling them low, and then
withdrawn because the allowance's interval reached "off"; whether a group reads slopes
right *and* clean builds flat is what a read from that group would need. A diagnostic that
knows the answer: ``diagnose`` reads nothing of it.

    python benchmarks/tilt_reads.py --cases 70833=3,heading_deg=70 --clean 70839 70840 \\
        --out out/tilt_reads

Writes ``OUT/tilt_reads.md``, ``.jsonl`` and ``.png``. Seeds 70000-70999 are this project's
exploratory seeds: no registered block draws them.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
from _report import write_report
from group_reads import parse_case, prepared_case, run_cases

from rover_env.calibration import residuals as rs
from rover_env.calibration.fit import SIGNAL_GROUPS, group_losses

HEADINGS = tuple(float(h) for h in range(-180, 180, 30))
KEYS = ("all", *SIGNAL_GROUPS)


def tilt_grid(sizes: list[float]) -> list[tuple[float, float]]:
    """(deg, heading_deg) pairs: "off" first, then every size at every heading."""
    return [(0.0, 0.0)] + [(s, h) for s in sizes if s > 0 for h in HEADINGS]


def best_tilts(
    grid: list[tuple[float, float]], ratios: list[float], groups: Any
) -> dict[str, list[float]]:
    """Each key's best (deg, heading): all signals by the mean log loss ratio, each group by
    its summed loss over the windows."""
    g = np.asarray(groups, dtype=float)
    out = {"all": list(grid[int(np.argmin(ratios))])}
    for i, k in enumerate(SIGNAL_GROUPS):
        out[k] = list(grid[int(np.argmin(g[:, i]))])
    return out


def heading_error(a: float, b: float) -> float:
    """The smaller angle between two headings (deg)."""
    return abs((a - b + 180.0) % 360.0 - 180.0)


def read_case(job: dict[str, Any]) -> dict[str, Any]:
    """One case: every group's loss over the polar grid on the training windows."""
    dg = prepared_case(job)
    grid = [tuple(p) for p in job["tilts"]]
    l0, ratios, groups = None, [], []
    for deg, head in grid:
        ext = {"slope": {"deg": deg, "heading_deg": head}} if deg else {}
        res = dg.ev.run(ext, "train")
        loss = rs.window_losses(res, dg.ev.scale)
        l0 = loss if l0 is None else l0
        ratios.append(float(np.mean(np.log(loss / l0))))
        groups.append([float(v) for v in group_losses(res, dg.ev.scale).sum(axis=0)])
    return {
        "seed": job["seed"],
        "truth": [job["size"], job.get("others", {}).get("heading_deg", 0.0)],
        "reads": best_tilts(grid, ratios, groups),
        "forms": {f.name: round(float(f.value), 4) for f in dg.forms if f.adopted},
    }


def read_text(read: list[float], truth: list[float]) -> str:
    """A read as size @ heading, with its heading error where both tilt."""
    if read[0] == 0:
        return "0"
    text = f"{read[0]:g} @ {read[1]:g}"
    return text + (f" ({heading_error(read[1], truth[1]):.0f})" if truth[0] else "")


def table(rows: list[dict[str, Any]]) -> str:
    """The markdown report: per case, each group's read and, for the clean cases, the
    spread of the sizes each group reads."""
    lines = [
        "# Which signal group reads a ground tilt (size @ heading, deg)",
        "",
        "Each cell: the tilt of the polar grid that minimises that group's summed loss (all:"
        " the mean log loss ratio, what `diagnose`'s naming test judges by) on the training"
        " windows; in"
        " brackets the heading's error against the truth (`benchmarks/tilt_reads.py`).",
        "",
        "| seed | truth | " + " | ".join(KEYS) + " |",
        "|" + "---|" * (2 + len(KEYS)),
    ]
    for r in sorted(rows, key=lambda r: (r["truth"][0], r["seed"])):
        t = r["truth"]
        cells = [str(r["seed"]), f"{t[0]:g} @ {t[1]:g}" if t[0] else "clean"]
        cells += [read_text(r["reads"][k], t) for k in KEYS]
        lines.append("| " + " | ".join(cells) + " |")
    clean = [r for r in rows if not r["truth"][0]]
    if clean:
        lines += [
            "",
            "| on clean builds | " + " | ".join(KEYS) + " |",
            "|" + "---|" * (1 + len(KEYS)),
        ]
        med = [float(np.median([r["reads"][k][0] for r in clean])) for k in KEYS]
        top = [max(r["reads"][k][0] for r in clean) for k in KEYS]
        lines.append("| median size read | " + " | ".join(f"{v:g}" for v in med) + " |")
        lines.append("| largest size read | " + " | ".join(f"{v:g}" for v in top) + " |")
    return "\n".join(lines) + "\n"


def plot(rows: list[dict[str, Any]], path: Path) -> None:
    """Each group's size read against the truth (clean builds at 0)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.0, 4.5))
    top = max([r["truth"][0] for r in rows] + [1.0])
    for i, k in enumerate(KEYS):
        x = np.array([r["truth"][0] for r in rows]) + (i - 2) * 0.03 * top
        y = np.array([r["reads"][k][0] for r in rows])
        ax.scatter(x, y, label=k, marker="os^vD"[i % 5], s=28)
    ax.plot([0, top], [0, top], color="grey", lw=0.8, ls="--", label="read = truth")
    ax.set_xlabel("true tilt (deg; clean builds at 0)")
    ax.set_ylabel("tilt read (deg, training windows)")
    ax.set_title("ground tilt: each signal group's own read")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def said(row: dict[str, Any]) -> str:
    """A case's progress line."""
    return f"seed {row['seed']} truth {row['truth']}: {row['reads']}"


def write(rows: list[dict[str, Any]], out: Path) -> int:
    """The table and the figure of ``rows`` into ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    write_report(out / "tilt_reads.md", table(rows))
    plot(rows, out / "tilt_reads.png")
    print(f"wrote {out / 'tilt_reads.md'}")
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--cases",
        nargs="*",
        default=[],
        help="SEED=DEG,heading_deg=H: slopes (70833=3,heading_deg=70)",
    )
    ap.add_argument("--clean", type=int, nargs="*", default=[], help="clean builds")
    ap.add_argument(
        "--sizes", default="0.5,1,1.5,2,3,4,6", help="tilt sizes (deg), comma-separated"
    )
    ap.add_argument("--drives", type=int, default=3)
    ap.add_argument("--duration", type=float, default=50.0)
    ap.add_argument("--work", type=Path, default=Path("out/group_reads/work"))
    ap.add_argument("--out", type=Path, default=Path("out/tilt_reads"))
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--from-jsonl", type=Path, default=None, help="tabulate saved rows again")
    a = ap.parse_args(argv)
    if a.from_jsonl is not None:
        return write([json.loads(x) for x in a.from_jsonl.read_text().splitlines() if x], a.out)
    cases = [parse_case(c, "slope") for c in a.cases]
    if not cases and not a.clean:
        raise SystemExit("--cases or --clean: at least one case")
    try:
        sizes = [float(v) for v in a.sizes.split(",")]
    except ValueError:
        raise SystemExit(f"--sizes: not comma-separated numbers: {a.sizes!r}") from None
    if not sizes or not all(math.isfinite(v) and v > 0 for v in sizes):
        raise SystemExit(f"--sizes: positive finite sizes, got {a.sizes!r}")
    base = {"effect": "slope", "param": "deg", "work": str(a.work), "drives": a.drives}
    base |= {"duration": a.duration, "tilts": tilt_grid(sizes)}
    rows = run_cases(read_case, base, cases, a.clean, a.workers, a.out / "tilt_reads.jsonl", said)
    return write(rows, a.out)


if __name__ == "__main__":
    raise SystemExit(main())

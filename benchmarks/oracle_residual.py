"""How far could the main residual fall? Replay each matrix case's held-out drive with the truth.

For every single-effect case of the matrix (``bench_diagnose.py``'s work folder), the held-out
drive is replayed three times, with the same settings as ``diagnose``: the nominal model, the
configuration ``diagnose`` wrote, and the *truth*, the exact configuration the logs were made
with (``truth.yaml``, which ``diagnose`` never reads). The truth's reduction of the main
residual's RMS is the most any diagnosis could achieve on that drive: what it leaves is the
replay's own floor (sensor noise seen through the window initialisation, chaotic pivot
turns). Writes ``OUT/oracle.md``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

import numpy as np
import yaml

from rover_env.calibration.replay import SIGNALS, ReplaySettings, replay_config
from rover_env.config import load_rover
from rover_env.logs import read_log


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--work", default="out/bench_diagnose")
    ap.add_argument("--out", default="docs/calibration")
    ap.add_argument("--kind", default="own_single", help="case folder prefix (GEN_KIND)")
    args = ap.parse_args()
    rows = []
    cases = sorted(p for p in Path(args.work).glob(f"{args.kind}_*") if (p / "out").is_dir())
    if not cases:
        raise SystemExit(f"no {args.kind}_* cases with an out/ folder in {args.work}")
    for i, d in enumerate(cases, 1):
        res = json.loads((d / "out" / "result.json").read_text())
        truth = yaml.safe_load((d / "logs" / "truth.yaml").read_text())["effects"]
        base = load_rover("proto_explorer")
        held = read_log(res["logs"][-1])
        j = SIGNALS.index(res["main_signal"])
        rms = {}
        for name, cfg in (
            ("nominal", base),
            ("truth", dataclasses.replace(base, extensions=truth)),
            ("diagnosed", load_rover(d / "out" / "rover.yaml")),
        ):
            col = replay_config(cfg, [held], ReplaySettings())["resid"][:, j]
            rms[name] = float(np.sqrt(np.mean(col[np.isfinite(col)] ** 2)))
        rows.append((d.name, res["main_signal"], rms))
        print(f"[{i}/{len(cases)}] {d.name}: {rms}", flush=True)
    L = [
        "# Main residual: the diagnosed model against the truth",
        "",
        "`python benchmarks/oracle_residual.py` (module docstring): held-out RMS of each case's",
        "main residual with the nominal model, with the truth (the configuration the logs were",
        "made with) and with the configuration `diagnose` wrote. The truth's reduction is the",
        "most any diagnosis can reach on that drive.",
        "",
        "| case | signal | nominal | truth | diagnosed | reduction, truth | reduction, diagnosed |",
        "|---|---|---|---|---|---|---|",
    ]
    for name, sig, r in rows:
        rt = 1 - r["truth"] / r["nominal"]
        rd = 1 - r["diagnosed"] / r["nominal"]
        L.append(
            f"| {name} | {sig} | {r['nominal']:.4g} | {r['truth']:.4g} | {r['diagnosed']:.4g}"
            f" | {100 * rt:.0f} % | {100 * rd:.0f} % |"
        )
    out = Path(args.out) / "oracle.md"
    out.write_text("\n".join(L) + "\n")
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

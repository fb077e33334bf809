"""Two effects on a grid: what a case's logs say about a pair, against what diagnose named.

Forward selection fits a second effect with the first held at its fit. When the two act
alike (a command lag and a delay both shift the wheels' response, by about tau + d), the
first absorbs the second's share and the second fits near "off" beside it. This replays the
case's windows (after the model forms diagnose fits first) at every pair of values on two
grids and prints the training windows' summed loss in floor units, and the training and
held-out gains against the nominal model: where the logs put the pair. A diagnostic of the
method on cases already looked at; nothing in ``diagnose`` reads it.

    python benchmarks/pair_grid.py LOGS_DIR command_lag:tau=0.28,0.38,0.49 \\
        command_delay:delay=0,0.05,0.1 --fit 0.49
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from rover_env.calibration import residuals as rs
from rover_env.calibration.candidates import catalogue
from rover_env.calibration.diagnosis import floor, form, split
from rover_env.calibration.diagnosis.judge import gain
from rover_env.calibration.diagnosis.state import Diagnosis, Options
from rover_env.calibration.fit import fit


def parse_axis(text: str) -> tuple[str, str, list[float]]:
    """``effect:param=v1,v2,...`` as (effect, param, values)."""
    try:
        head, values = text.split("=", 1)
        effect, param = head.split(":", 1)
        return effect, param, [float(v) for v in values.split(",")]
    except ValueError:
        raise SystemExit(f"axis {text!r}: expected effect:param=v1,v2,... (numbers)") from None


def grid(
    logs_dir: Path,
    a: tuple[str, str, list[float]],
    b: tuple[str, str, list[float]],
    total: float | None = None,
) -> None:
    """Print one row per grid point (``a`` outer, ``b`` inner); with ``total``, then the two
    effects fitted together on the training windows (``fit``, both free) from ``total``
    split between them at 1/4, 1/2 and 3/4."""
    logs = sorted(str(p) for p in logs_dir.glob("drive_*.csv"))
    if not logs:
        raise SystemExit(f"{logs_dir}: no drive_*.csv")
    with tempfile.TemporaryDirectory() as tmp:
        d = Diagnosis(logs, Path(tmp), Options(progress=False, workers=1))
        split.split(d)
        form.fit_model_form(d)
        floor.baseline(d)
        ev = d.ev
        t0 = rs.window_losses(ev.run({}, "train"), d.noise)
        h0 = rs.window_losses(ev.run({}, "held"), d.noise)
        print(f"{a[0]}.{a[1]} {b[0]}.{b[1]}  training loss (floor units)  gain: training held-out")
        for va in a[2]:
            for vb in b[2]:
                ext = {e: {p: v} for e, p, v in ((a[0], a[1], va), (b[0], b[1], vb)) if v != 0.0}
                t1 = rs.window_losses(ev.run(ext, "train"), d.noise)
                h1 = rs.window_losses(ev.run(ext, "held"), d.noise)
                print(
                    f"{va:8.4g} {vb:8.4g}  {t1.sum():14.1f}  {gain(t0, t1):7.3f} {gain(h0, h1):7.3f}",
                    flush=True,
                )
        if total is None:
            return
        cands = catalogue([a[0], b[0]])
        if [c.name for c in cands] != [a[0], b[0]] or any(c.k != 1 for c in cands):
            raise SystemExit("--fit: both axes must be one-parameter effects, in catalogue order")
        for share in (0.25, 0.5, 0.75):
            x0 = np.array([share * total, (1 - share) * total])
            f = fit(ev, cands, "train", x_start=x0, max_nfev=8, probe=False)
            h1 = rs.window_losses(ev.run(f.ext, "held"), d.noise)
            print(
                f"fitted together from {x0.round(4).tolist()}: {f.x.round(4).tolist()}"
                f" ({f.nfev} replays), held-out gain {gain(h0, h1):.3f}",
                flush=True,
            )


def main() -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("logs", type=Path, help="a case's logs folder (drive_*.csv)")
    ap.add_argument(
        "a", help="effect:param=v1,v2,... (outer axis; a value of 0 leaves the effect out)"
    )
    ap.add_argument("b", help="effect:param=v1,v2,... (inner axis)")
    ap.add_argument(
        "--fit",
        type=float,
        default=None,
        metavar="TOTAL",
        help="then fit both together from TOTAL split between them (the one value named)",
    )
    args = ap.parse_args()
    grid(args.logs, parse_axis(args.a), parse_axis(args.b), args.fit)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Two effects on a grid: what a case's logs say about a pair, against what diagnose named.

Forward selection fits a second effect with the first held at its fit. When the two act
alike (a command lag and a delay both shift the wheels' response, by about tau + d), the
first absorbs the second's share and the second fits near "off" beside it. This replays the
case's windows (after the model forms diagnose fits first) at every pair of values on two
grids and prints the training windows' summed loss in floor units, and the training and
held-out gains against the nominal model: where the logs put the pair. A diagnostic of the
method on cases already looked at; nothing in ``diagnose`` reads it.

    python benchmarks/pair_grid.py LOGS_DIR command_lag:tau=0.28,0.38,0.49 \\
        command_delay:delay=0,0.05,0.1
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from rover_env.calibration import residuals as rs
from rover_env.calibration.diagnosis import floor, form, split
from rover_env.calibration.diagnosis.judge import gain
from rover_env.calibration.diagnosis.state import Diagnosis, Options


def parse_axis(text: str) -> tuple[str, str, list[float]]:
    """``effect:param=v1,v2,...`` as (effect, param, values)."""
    try:
        head, values = text.split("=", 1)
        effect, param = head.split(":", 1)
        return effect, param, [float(v) for v in values.split(",")]
    except ValueError:
        raise SystemExit(f"axis {text!r}: expected effect:param=v1,v2,... (numbers)") from None


def grid(logs_dir: Path, a: tuple[str, str, list[float]], b: tuple[str, str, list[float]]) -> None:
    """Print one row per grid point (``a`` outer, ``b`` inner)."""
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


def main() -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("logs", type=Path, help="a case's logs folder (drive_*.csv)")
    ap.add_argument(
        "a", help="effect:param=v1,v2,... (outer axis; a value of 0 leaves the effect out)"
    )
    ap.add_argument("b", help="effect:param=v1,v2,... (inner axis)")
    args = ap.parse_args()
    grid(args.logs, parse_axis(args.a), parse_axis(args.b))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Speed of the calibration replay (issue 16, item 8), as ratios measured in this run.

Run: python benchmarks/bench_replay.py [--windows 12] [--rounds 5]

One seeded own-generator drive (50 s) is cut into the replay's windows; the same windows are
replayed in interleaved rounds (the machine is shared: medians of the rounds) by:

* ``contacts``: the replay with MuJoCo's own collisions on (the reference) and off (flat
  ground, the same numbers to the bit, checked here);
* ``sensors``: then MuJoCo's sensor stage off too (what ``diagnose`` runs: the replay reads
  the state only; the same numbers to the bit, checked here);
* ``command_lag``, ``command_delay``: a replay with a command effect over the plain plugin
  replay: what one command-effect candidate costs against the others. The effect's rows
  for all the rows of a drive call are computed in Python at once and queued in the
  plugin's state, which feeds them to the motors inside one ``mj_step`` call per
  ``SCHEDULE_ROWS`` substeps (until stop 45: one call per substep, 1.9 x a plain replay;
  until stop 97 rows computed and queued row by row: a lag 1.62 x, a delay 1.37 x).
* ``Python loops``: a replay with a command lag whose recursions (the substeps' targets, the
  window's primed state) run on Python floats (``ROVER_ENV_NATIVE=0``, the code before stop
  102) against the compiled ones (``rover_env/effects/recursions.c``); the same numbers to the
  bit, checked here.
* ``per read``: the replay's loop before stop 98, one ``drive`` per stretch between two
  read-outs (every log row), against :meth:`RoverSim.drive_read` (a window's rows in one
  call, the state read after each): plain and with a command lag; the same numbers to the
  bit, checked here. ``drive`` is today's (itself ``drive_read`` with nothing read): 0.94 of
  the time plain, 0.93 with a lag; against stop 97's ``drive``, measured before it went
  through ``drive_read``, 0.86 and 0.85.
* ``row by row``: the replay as it drove the log before stop 57, one
  ``set_speed_targets`` and one checked ``step`` per log row: plain, and with a hinge
  effect (rolling resistance); the same numbers to the bit, checked here.

Prints seconds per replay and the ratios; nothing is timed in the tests.
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from rover_env.calibration.replay import (
    Replayer,
    ReplaySettings,
    make_windows,
    prepare,
    replay_arrays,
)
from rover_env.config import RoverConfig
from rover_env.generators.make_logs import make_logs
from rover_env.logs import read_log
from rover_env.sim.simulator import RoverSim

DRIVE_READ = RoverSim.drive_read


def row_by_row(sim: RoverSim, targets: np.ndarray, steps: np.ndarray) -> None:
    """The replay's loop before stop 57: each row's targets set and stepped, checked."""
    for u, n in zip(np.asarray(targets).reshape(-1, 4), np.asarray(steps).reshape(-1), strict=True):
        sim.set_speed_targets(u)
        sim.step(int(n))


def per_read(step: Callable[[RoverSim, np.ndarray, np.ndarray], None]) -> Any:
    """A replay's read-outs as before stop 98: ``step`` (``RoverSim.drive``, or
    :func:`row_by_row`) once per stretch between two read-outs, the state read after it."""

    def drive_read(
        sim: RoverSim, targets: Any, steps: Any, after: Any, qpos: Any, body: int
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        d, qi = sim.data, np.asarray(qpos)
        out = [
            np.empty((len(after), len(qi))),
            np.empty((len(after), 3)),
            np.empty((len(after), 9)),
        ]
        k = 0
        for j, r in enumerate(after):
            step(sim, targets[k:r], steps[k:r])
            k = r
            out[0][j], out[1][j], out[2][j] = d.qpos[qi], d.xpos[body], d.xmat[body]
        return out[0], out[1], out[2]

    return drive_read


def drive(sim: RoverSim, targets: np.ndarray, steps: np.ndarray) -> None:
    """:meth:`RoverSim.drive` on the plugin without hinge effects (``drive_read`` with nothing
    read), through the unpatched ``drive_read``."""
    DRIVE_READ(sim, targets, steps, (), (), 0)


PATCH = {"per read": per_read(drive), "row by row": per_read(row_by_row)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--windows", type=int, default=12)
    ap.add_argument("--rounds", type=int, default=5)
    args = ap.parse_args()
    st = ReplaySettings()
    with tempfile.TemporaryDirectory() as tmp:
        paths = make_logs(Path(tmp), {}, drives=1, seed=11, progress=False)
        log = read_log(paths[0])
    base = RoverConfig()
    p = prepare(log, base, "drive", st)
    windows = make_windows([p], st)[: args.windows]
    lag = replace(base, extensions={"command_lag": {"tau": 0.15}})
    delay = replace(base, extensions={"command_delay": {"delay": 0.15}})
    rr = replace(base, extensions={"rolling_resistance": {"c_rr": 0.03}})
    variants = {
        "contacts on (reference)": (base, True, True),
        "contacts off": (base, False, True),
        "contacts, sensors off (diagnose)": (base, False, False),
        "command_lag, diagnose's": (lag, False, False),
        "command_delay, diagnose's": (delay, False, False),
        "command_lag, Python loops (before stop 102)": (lag, False, False),
        "command_lag, per read (before stop 98)": (lag, False, False),
        "per read (before stop 98)": (base, False, False),
        "row by row (before stop 57)": (base, False, False),
        "rolling_resistance, diagnose's": (rr, False, False),
        "rolling_resistance, row by row": (rr, False, False),
    }
    times: dict[str, list[float]] = {k: [] for k in variants}
    native_before = os.environ.get("ROVER_ENV_NATIVE")
    outputs: dict[str, dict[str, np.ndarray]] = {}
    for _ in range(args.rounds):
        for name, (cfg, contacts, sensors) in variants.items():
            patch = next((f for k, f in PATCH.items() if k in name), DRIVE_READ)
            RoverSim.drive_read = patch  # type: ignore[method-assign]
            os.environ["ROVER_ENV_NATIVE"] = "0" if "Python loops" in name else "1"
            t0 = time.perf_counter()
            res = Replayer(cfg, st, contacts=contacts, sensors=sensors).run([p], windows)
            times[name].append(time.perf_counter() - t0)
            outputs[name] = replay_arrays(res)
    RoverSim.drive_read = DRIVE_READ  # type: ignore[method-assign]
    if native_before is None:  # the caller's setting back, as found
        os.environ.pop("ROVER_ENV_NATIVE")
    else:
        os.environ["ROVER_ENV_NATIVE"] = native_before
    ref = outputs["contacts on (reference)"]

    def same(name: str, ref: dict[str, np.ndarray] = ref) -> bool:
        return all(np.array_equal(ref[k], outputs[name][k]) for k in ref)

    med = {k: statistics.median(v) for k, v in times.items()}
    sim_s = len(windows) * st.window
    print(
        f"{len(windows)} windows of {st.window:g} s ({sim_s:g} s simulated), {args.rounds} rounds"
    )
    for k, v in med.items():
        print(f"  {k:34s} {v:6.3f} s per replay  ({sim_s / v:5.0f} x real time)")
    on = med["contacts on (reference)"]
    off = med["contacts off"]
    dia = med["contacts, sensors off (diagnose)"]
    print(
        f"contacts off / on: {off / on:.2f} of the time, identical to the bit:"
        f" {same('contacts off')}"
    )
    print(
        f"sensors off / on (contacts off): {dia / off:.2f} of the time; diagnose's replay / the"
        f" reference: {dia / on:.2f}; identical to the bit: {same('contacts, sensors off (diagnose)')}"
    )
    lag_s = med["command_lag, diagnose's"]
    delay_s = med["command_delay, diagnose's"]
    print(f"command_lag / plain (diagnose's replay): {lag_s / dia:.2f}")
    print(f"command_delay / plain (diagnose's replay): {delay_s / dia:.2f}")
    loops = "command_lag, Python loops (before stop 102)"
    print(
        f"command_lag compiled / on Python loops: {lag_s / med[loops]:.2f} of the time;"
        f" identical to the bit: {same(loops, outputs['command_lag, diagnose' + chr(39) + 's'])}"
    )
    per = med["per read (before stop 98)"]
    print(
        f"diagnose's replay / a drive() per read-out: {dia / per:.2f} of the time (with a lag:"
        f" {lag_s / med['command_lag, per read (before stop 98)']:.2f}); identical to the bit:"
        f" {same('per read (before stop 98)', outputs['contacts, sensors off (diagnose)'])},"
        f" {same('command_lag, per read (before stop 98)', outputs['command_lag, diagnose' + chr(39) + 's'])}"
    )
    row = med["row by row (before stop 57)"]
    print(
        f"diagnose's replay / row by row: {dia / row:.2f} of the time; identical to the bit:"
        f" {same('row by row (before stop 57)', outputs['contacts, sensors off (diagnose)'])}"
    )
    rr_d, rr_r = med["rolling_resistance, diagnose's"], med["rolling_resistance, row by row"]
    print(
        f"with rolling resistance: {rr_d / rr_r:.2f} of the time; identical to the bit:"
        f" {same('rolling_resistance, row by row', outputs['rolling_resistance, diagnose' + chr(39) + 's'])}"
    )


if __name__ == "__main__":
    main()

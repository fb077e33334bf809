"""``diagnose()``: the stages in order over one :class:`~.state.Diagnosis`.

split (:mod:`.split`) → form (:mod:`.form`) → floor (:mod:`.floor`) → fit
(:mod:`.fit_stage`) → select (:mod:`.select`) → odometry (:mod:`.odometry`) → effort
(:mod:`.effort_stage`) → balance (:mod:`.balance_stage`) → one wheel (:mod:`.one_wheel`) → evidence (:mod:`.evidence_stage`) → write (:mod:`.write`). After selection the model form is judged again (:mod:`.again`) beside the
winner or, with none named, the leading candidate; when that changes the forms, the
diagnosis runs again from the start under the new options.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from rover_env.calibration.diagnosis import (
    again,
    balance_stage,
    effort_stage,
    evidence_stage,
    fit_stage,
    floor,
    form,
    odometry,
    one_wheel,
    select,
    split,
)
from rover_env.calibration.diagnosis import write as write_stage
from rover_env.calibration.diagnosis.state import Diagnosis, Options
from rover_env.calibration.replay import parallel_replays


def diagnose(
    paths: list[str | Path], out: str | Path, opts: Options | None = None
) -> dict[str, Any]:
    """Name the effects the logs show (:mod:`rover_env.calibration.diagnose`); writes
    ``out``, returns the result.

    With ``opts.workers`` > 1 on the local executor the candidate fits run side by side, and
    every other stage's replays split their windows over as many processes."""
    opts = opts or Options()
    with parallel_replays(opts.workers if opts.executor == "local" else 1):
        return run(paths, out, opts)


def run(
    paths: list[str | Path], out: str | Path, opts: Options, earlier: Diagnosis | None = None
) -> dict[str, Any]:
    """One pass of the stages; a second under the options the form's re-judgement sets
    (``earlier``: the first pass, whose clock and stage times the second carries on)."""
    Path(out).mkdir(parents=True, exist_ok=True)
    d = Diagnosis(list(paths), Path(out), opts)
    if earlier is not None:
        d.t_start = earlier.t_start
        d.earlier_passes = [*earlier.earlier_passes, earlier.stage_seconds]
        d.allowance_differs = earlier.allowance_differs
    for name, stage in FIRST:
        timed(d, name, stage)
    rerun = timed(d, "again", again.judge_again)
    if rerun is not None:
        return run(paths, out, rerun, d)
    for name, stage in LAST:
        timed(d, name, stage)
    write_stage.write(d)
    return d.result


Stage = Callable[[Diagnosis], Any]
FIRST: tuple[tuple[str, Stage], ...] = (
    ("split", split.split),
    ("form", form.fit_model_form),
    ("floor", floor.baseline),
    ("fit", fit_stage.fit_candidates),
    ("winner", select.name_winner),
)
"""The stages before the form's re-judgement, each with the name its time is kept under."""
LAST: tuple[tuple[str, Stage], ...] = (
    ("select", select.select),
    ("odometry", odometry.name_by_odometry),
    ("effort", effort_stage.name_by_effort),
    ("balance", balance_stage.name_by_balance),
    ("one_wheel", one_wheel.withdraw_one_wheel),
    ("evidence", evidence_stage.seek_evidence),
)
"""The stages after it, before the write."""


def timed(d: Diagnosis, name: str, stage: Stage) -> Any:
    """``stage(d)``, its wall seconds added to ``d.stage_seconds[name]``."""
    t0 = time.perf_counter()
    try:
        return stage(d)
    finally:
        d.stage_seconds[name] = d.stage_seconds.get(name, 0.0) + time.perf_counter() - t0

"""``diagnose()``: the stages in order over one :class:`~.state.Diagnosis`.

split (:mod:`.split`) → form (:mod:`.form`) → floor (:mod:`.floor`) → fit
(:mod:`.fit_stage`) → select (:mod:`.select`) → odometry (:mod:`.odometry`) → one wheel
(:mod:`.one_wheel`) → evidence (:mod:`.evidence_stage`) → write (:mod:`.write`). After selection the model form is judged again (:mod:`.again`) beside the
winner or, with none named, the leading candidate; when that changes the forms, the
diagnosis runs again from the start under the new options.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from rover_env.calibration.diagnosis import (
    again,
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


def run(paths: list[str | Path], out: str | Path, opts: Options) -> dict[str, Any]:
    """One pass of the stages; a second under the options the form's re-judgement sets."""
    Path(out).mkdir(parents=True, exist_ok=True)
    d = Diagnosis(list(paths), Path(out), opts)
    split.split(d)
    form.fit_model_form(d)
    floor.baseline(d)
    fit_stage.fit_candidates(d)
    select.name_winner(d)
    rerun = again.judge_again(d)
    if rerun is not None:
        return run(paths, out, rerun)
    select.select(d)
    odometry.name_by_odometry(d)
    one_wheel.withdraw_one_wheel(d)
    evidence_stage.seek_evidence(d)
    write_stage.write(d)
    return d.result

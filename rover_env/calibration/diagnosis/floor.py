"""Stage 3, floor: the replay floor and the baseline.

Owns what every later test is measured against: the replay floor (the residual the model
leaves on its own twin of each drive, read through the logs' sensor noise: what a perfect
model would leave), the baseline replay of every window, the per-signal scale of the fits
and the residual tables before any effect. Why twins: the replay's own inexactness
(window initialisation, sensor quantisation) is not a missing effect.
"""

from __future__ import annotations

import numpy as np

from rover_env.calibration import residuals as rs
from rover_env.calibration.diagnosis.state import Diagnosis
from rover_env.calibration.fit import Evaluator
from rover_env.calibration.replay import (
    PreparedLog,
    Replayer,
    ReplaySettings,
    Window,
    prepare,
)
from rover_env.config import RoverConfig


def baseline(d: Diagnosis) -> None:
    """Sets the evaluator, the replay floor, the baseline replays, scale and tables."""
    d.ev = Evaluator(
        d.base,
        d.st,
        d.prepared,
        d.sets,
        profile_zeros=d.opts.fit_joint_zero
        and (d.opts.model_form or d.opts.forms_reverted is not None),
        profile_free_gain=d.opts.fit_free_gain,
        free_common_max=d.opts.free_common,
        screen_middle=d.opts.screen_middle,
    )
    # Replay floor: what a perfect model leaves, from the model's own twin of each drive.
    d.noise = replay_floor(d.base, d.prepared, d.all_w, d.sensor_noise, d.st)
    d.say(
        "replay floor from the model's twin drives: "
        + ", ".join(f"{k} {v:.3g}" for k, v in d.noise.items())
    )
    d.base_train = d.ev.run({}, "train")
    d.base_held = d.ev.run({}, "held")
    d.say(f"baseline replay done ({d.ev.seconds:.1f}s, backend {base_backend(d.base)})")
    d.scale = rs.signal_scale(rs.stack(d.base_train, d.prepared), d.noise)
    d.ev.scale = d.scale
    all_results = d.base_train + d.base_held
    d.table_before = rs.table(rs.stack(all_results, d.prepared), d.noise)
    d.table_held_before = rs.table(rs.stack(d.base_held, d.prepared), d.noise)


def model_floor(d: Diagnosis, cfg: RoverConfig) -> dict[str, float]:
    """The held-out floor of ``cfg`` (a model with effects), never under the baseline's:
    a tilted or slower model replays its own twin less exactly than the nominal one."""
    ff = replay_floor(cfg, d.prepared, d.held_w, d.sensor_noise, d.st)
    return {k: max(v, d.noise[k]) for k, v in ff.items()}


def replay_floor(
    cfg: RoverConfig,
    prepared: list[PreparedLog],
    windows: list[Window],
    sensor_noise: dict[str, float],
    st: ReplaySettings,
) -> dict[str, float]:
    """Per-signal RMS residual a perfect model leaves: the model replays its own twins.

    Twins are made only for the logs ``windows`` use (the others keep their place).
    """
    rng = np.random.default_rng(0)
    res = rs.resolutions(prepared)
    used = {w.log_index for w in windows}
    states = rs.twins_of(prepared, cfg, used)
    twins = []
    for i, p in enumerate(prepared):
        if i not in used:
            twins.append(p)
            continue
        log = rs.twin_sensed(p, states[i], sensor_noise, res, rng)
        twins.append(prepare(log, cfg, p.name + " twin", st))
    return rs.signal_scale(rs.stack(Replayer(cfg, st).run(twins, windows), twins), sensor_noise)


def base_backend(cfg: RoverConfig) -> str:
    from rover_env.sim.build import resolve_auto_backend

    return resolve_auto_backend(cfg)

"""The joints' height judged against the loose soil before it is adopted (stop 134).

Why: on hard ground a wheel's lateral force acts at its contact point, a wheel radius below
the hub; on loose soil the stresses' resultant acts at the hub (both here and in the
independent generator). The roll joints between segments feel the lateral forces through
their lever above where the force acts, so on soil the model's roll swings in turns are
those of hard ground with the joints about a wheel radius lower. Fitted before any effect,
the joint height took that: the independent generator's very soft regolith 74106 (spent,
k_phi 3.0e5; its joints 5 cm above the axles) adopted -3.1 cm (training 12.5 % better), and
under it the soil at its true k_phi left theta_1 (segments 1-2 roll) 7 x worse than hard
ground, the soil fitted hard ground in every form and a rolling resistance at its range's end
was named. At the nominal height the same soil explains the windows better than the height
does (theta_1 in the soil's turns swings as in the logs), so the height is not adopted
before the effects; beside a named soil it is fitted again (:mod:`.again`).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from rover_env.calibration import residuals as rs
from rover_env.calibration.candidates import catalogue, merge
from rover_env.calibration.diagnosis.form_ladder import baseline, log_ratio
from rover_env.calibration.diagnosis.state import FormFit
from rover_env.calibration.replay import PreparedLog, Replayer, ReplaySettings, Window
from rover_env.config import RoverConfig
from rover_env.effects import build_effects


def soil_is_on(cfg: RoverConfig) -> bool:
    """Whether ``cfg`` already carries a loose soil (a refit beside a soil: nothing to judge
    the height against)."""
    return any(e.name == "loose_soil" and not e.is_off for e in build_effects(cfg.extensions))


def soil_screen(
    cfg: RoverConfig,
    prepared: list[PreparedLog],
    windows: list[Window],
    settings: ReplaySettings,
    sensor_noise: dict[str, float],
) -> tuple[float, str]:
    """The loose soil's best criterion on ``windows`` under ``cfg`` (mean log loss ratio
    against ``cfg`` itself, as :func:`.form_ladder.fit_ladder` judges a form) and where:
    every soil form at the ladder's middle rung, then the best form at the rungs either side
    of it (9 replays)."""
    scale, l0, eps = baseline(cfg, prepared, windows, settings, sensor_noise)
    soil = catalogue(["loose_soil"])[0]
    ladder = [float(p[0]) for p in (soil.ladder or ())]
    mid = len(ladder) // 2

    def crit(label: str, rung: int) -> float:
        ext = soil.with_form(label).to_ext(np.array([ladder[rung]]))
        c = replace(cfg, extensions=merge(cfg.extensions, ext))
        losses = rs.window_losses(Replayer(c, settings).run(prepared, windows), scale)
        return log_ratio(losses, l0, eps)

    tried = {(label, mid): crit(label, mid) for label, _ in soil.forms}
    form = min(tried, key=lambda k: tried[k])[0]
    for rung in (mid - 1, mid + 1):
        if 0 <= rung < len(ladder):
            tried[(form, rung)] = crit(form, rung)
    label, rung = min(tried, key=lambda k: tried[k])
    k_phi = 1e6 / ladder[rung]
    return tried[(label, rung)], f"loose_soil k_phi {k_phi:.3g} ({label})"


def height_beside_soil(
    form: FormFit,
    cfg: RoverConfig,
    prepared: list[PreparedLog],
    windows: list[Window],
    settings: ReplaySettings,
    sensor_noise: dict[str, float],
) -> FormFit:
    """``form`` (the joint height fitted under ``cfg``), not adopted where the loose soil at
    ``cfg``'s height explains the training windows better than the height does
    (:func:`soil_screen`; :attr:`FormFit.beaten_by` says by what). A height kept nominal, or
    fitted beside a soil, is returned as it is."""
    if not form.adopted or soil_is_on(cfg):
        return form
    own = form.ladder.get(form.value)
    if own is None:
        return form
    soil, where = soil_screen(cfg, prepared, windows, settings, sensor_noise)
    if soil >= own:
        return form
    said = f"the loose soil explains more, {where} at {soil:+.3g} against the height's {own:+.3g}"
    return replace(form, adopted=False, beaten_by=said)

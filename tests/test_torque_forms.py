"""``diagnose --torque-forms``: the torque limit searched under each anti-windup form of the
speed loop, each form's "off" the form alone (stop 110)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from rover_env.calibration.candidates import TORQUE_FORMS, catalogue, with_torque_forms
from rover_env.config import RoverConfig, load_rover
from rover_env.sim.build import physical_config


def _cfg(ext: dict[str, dict[str, float]]) -> RoverConfig:
    """The configuration the simulator builds from the rover with extensions ``ext``."""
    return physical_config(replace(load_rover("proto_explorer"), extensions=ext))


def test_the_conditional_form_sets_the_loop_and_the_cut_the_limit() -> None:
    nominal = load_rover("proto_explorer")
    assert nominal.motor.anti_windup == "clamp"
    both = _cfg({"torque_limit": {"fraction": -0.5, "conditional": 1.0}})
    assert both.motor.anti_windup == "conditional"
    assert both.motor.torque_limit == 0.5 * nominal.motor.torque_limit
    alone = _cfg({"torque_limit": {"fraction": 0.0, "conditional": 1.0}})
    assert alone.motor.anti_windup == "conditional"
    assert alone.motor.torque_limit == nominal.motor.torque_limit
    cut = _cfg({"torque_limit": {"fraction": -0.5}})
    assert cut.motor.anti_windup == "clamp"


def test_each_form_keeps_its_own_off_and_only_the_limit_takes_forms() -> None:
    cands = {c.name: c for c in catalogue()}
    tl = with_torque_forms(cands["torque_limit"])
    assert [lab for lab, _ in tl.forms] == [lab for lab, _ in TORQUE_FORMS]
    off = np.array(tl.off)
    cond = tl.with_form(TORQUE_FORMS[1][0])
    assert cond.to_ext(off) == {"torque_limit": {"fraction": 0.0, "conditional": 1.0}}
    conf = tl.with_form(TORQUE_FORMS[0][0])
    assert conf.to_ext(np.array([-0.3])) == {"torque_limit": {"fraction": -0.3, "conditional": 0.0}}
    # A worker's fit comes back as extensions: the form is read from them, not defaulted.
    assert tl.adopt_form(cond.to_ext(np.array([-0.3]))).form == TORQUE_FORMS[1][0]
    assert tl.k == cands["torque_limit"].k and cond.k == tl.k + 1
    assert with_torque_forms(cands["slope"]) is cands["slope"]

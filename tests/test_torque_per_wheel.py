"""benchmarks/torque_per_wheel.py's model: each driven wheel's motor gets its own limit, the
configuration's times that wheel's factor, and nothing else of the robot changes."""

from __future__ import annotations

import xml.etree.ElementTree as ET

from _bench import load_bench

from rover_env.config import RoverConfig
from rover_env.sim.model import robot_xml


def test_each_wheel_gets_its_own_limit_and_nothing_else_moves() -> None:
    tpw = load_bench("torque_per_wheel")
    cfg = RoverConfig()
    scale = {"1L": 0.85, "1R": 1.08, "2L": 0.92, "2R": 0.84}
    tpw.SCALE.update(scale)
    try:
        patched = tpw.per_wheel_xml(cfg)
    finally:
        tpw.SCALE.clear()
    motors = {m.get("name"): m for m in ET.fromstring(patched).iter("dcmotor") if m.get("name")}
    assert set(motors) == {f"motor_{w}" for w in scale}
    for w, s in scale.items():
        limit = float(motors[f"motor_{w}"].get("saturation", "nan").split()[0])
        assert limit == cfg.motor.torque_limit * s, w
    plain = robot_xml(cfg)
    assert tpw.per_wheel_xml(cfg) == plain  # no factors: the configuration's model
    changed = [a for a, b in zip(plain.splitlines(), patched.splitlines(), strict=True) if a != b]
    assert len(changed) == len(scale)

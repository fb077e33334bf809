"""The injected effects, each implemented here from its physical meaning (issue 47's list).

``effects`` maps an effect name to its parameters; the first parameter named in :data:`MAIN` is
the one ``--effect name=value`` sets. Each is applied where it physically lives:

- ``rolling_resistance`` (``c_rr`` in [0, 0.3]): the ground pressure under a rolling wheel shifts
  ahead of the axle; modelled as a moment ``c_rr F_z (d - delta)`` opposing the wheel's rotation
  (smoothed through tanh over 0.01 m/s of rim speed), so a steadily rolling wheel needs
  ``c_rr F_z`` of ground force (obtained through slip) to keep turning. On all six wheels.
- ``slope`` (``deg`` in [-20, 20], ``heading_deg`` default 0): the ground rises at ``deg`` toward
  ``heading_deg`` from the rover's initial heading (counter-clockwise); applied by tilting gravity.
  With SPEC's mu_x = 0.4 and only the four driven wheels held (segment 3's wheels roll freely)
  the rover stands on at most about atan(0.4 * 2/3) = 15 degrees along its heading: on steeper
  slopes it slides during the settling second and the drive (physics, kept on purpose). On a
  side slope the tire state's 2 mm/s floor lets a parked rover creep about 1 mm/s sideways.
- ``rolling_radius`` (``fraction`` in [-0.2, 0.1]): the effective rolling radius of every wheel
  (``d - delta/3`` at its load) times ``1 + fraction``; geometry and deflection unchanged.
- ``torque_limit`` (``fraction`` in [-0.8, 1]): the motor drivers' current limit times
  ``1 + fraction``.
- ``friction`` (``fraction`` in [-0.7, 1]): mu_x and mu_y times ``1 + fraction`` (on loose soil:
  tan(phi) and c).
- ``command_lag`` (``tau`` in [0, 2] s): each controller sees its target through a first-order
  lag (exact discretisation at the control rate).
- ``command_delay`` (``delay`` in [0, 1] s): each controller sees the target sent ``delay`` ago.
- ``load_dependent_friction`` (``fall`` in [0, 0.8], ``range`` N, default 60): friction falls with
  the wheel's load, ``mu(F_z) = mu (1 - fall tanh(F_z / range))`` (0 load: full friction;
  far above ``range``: ``(1 - fall) mu``).
- ``loose_soil`` (``k_phi`` factor in [0.3, 3], ``sand`` 0/1): the ground is SOIL.md's loose soil
  (:mod:`soil` presets: regolith, or dry sand when ``sand`` is 1) with k_phi times the factor.

Four more act on a real rover but have no counterpart in ``rover-env diagnose``'s catalogue (the
"outside the catalogue" cases of the acceptance matrix, ``benchmarks/bench_independent.py``):

- ``payload`` (``fraction`` in [0, 1]): a rigid load of ``fraction`` times the rover's total mass
  bolted on segment 2's deck (its centre 0.14 m above the axle, a 0.2 x 0.2 x 0.1 m box): more
  load on segment 2's wheels, and through the chain's springs on its neighbours.
- ``toe`` (``deg`` in [-10, 10]): the two front wheels (segment 1) yawed on their mounts, ``deg``
  toe-in (positive: the wheels' fronts point toward the centre line), as a misaligned bracket.
  Straight driving makes them roll at a slip angle: lateral forces that cancel left to right but
  scrub speed and take traction.
- ``brake_drag`` (``torque`` N m in [0, 2], ``wheel`` index 0-5 of 1L 1R 2L 2R 3L 3R, default 4:
  3L): a dragging brake or seized bearing on one wheel, a Coulomb moment ``torque`` (smoothed
  over 0.05 rad/s, as the gearbox drag) between that wheel and its segment. On a free wheel it
  slows that wheel and pulls the rover toward its side; a driven wheel's speed loop hides it
  except in the current it needs.
- ``battery_sag`` (``fraction`` in [0, 0.9]): the motors' supply voltage is ``1 - fraction`` of
  nominal (a tired battery, a long harness): the drivers clip at that voltage, which lowers each
  motor's top speed and the torque it has left near it (the current limit stays).
"""

from __future__ import annotations

from dataclasses import dataclass

MAIN: dict[str, str] = {
    "rolling_resistance": "c_rr",
    "slope": "deg",
    "rolling_radius": "fraction",
    "torque_limit": "fraction",
    "friction": "fraction",
    "command_lag": "tau",
    "command_delay": "delay",
    "load_dependent_friction": "fall",
    "loose_soil": "k_phi",
    "payload": "fraction",
    "toe": "deg",
    "brake_drag": "torque",
    "battery_sag": "fraction",
}
OUTSIDE: tuple[str, ...] = ("payload", "toe", "brake_drag", "battery_sag")
"""Effects with no counterpart in ``rover-env diagnose``'s catalogue."""
RANGES: dict[tuple[str, str], tuple[float, float]] = {
    ("rolling_resistance", "c_rr"): (0.0, 0.3),
    ("slope", "deg"): (-20.0, 20.0),
    ("slope", "heading_deg"): (-360.0, 360.0),
    ("rolling_radius", "fraction"): (-0.2, 0.1),
    ("torque_limit", "fraction"): (-0.8, 1.0),
    ("friction", "fraction"): (-0.7, 1.0),
    ("command_lag", "tau"): (0.0, 2.0),
    ("command_delay", "delay"): (0.0, 1.0),
    ("load_dependent_friction", "fall"): (0.0, 0.8),
    ("load_dependent_friction", "range"): (1.0, 1000.0),
    ("loose_soil", "k_phi"): (0.3, 3.0),
    ("loose_soil", "sand"): (0.0, 1.0),
    ("payload", "fraction"): (0.0, 1.0),
    ("toe", "deg"): (-10.0, 10.0),
    ("brake_drag", "torque"): (0.0, 2.0),
    ("brake_drag", "wheel"): (0.0, 5.0),
    ("battery_sag", "fraction"): (0.0, 0.9),
}


class EffectError(ValueError):
    """An unknown effect or parameter, or a value out of range."""


@dataclass(frozen=True)
class Effects:
    """The resolved effects, as the simulator reads them (neutral values when absent)."""

    c_rr: float = 0.0
    slope_deg: float = 0.0
    slope_heading_deg: float = 0.0
    radius_scale: float = 1.0
    current_limit_scale: float = 1.0
    friction_scale: float = 1.0
    lag_tau: float = 0.0
    delay: float = 0.0
    friction_fall: float = 0.0
    friction_range: float = 60.0
    soil: str | None = None
    k_phi_factor: float = 1.0
    payload_fraction: float = 0.0
    toe_deg: float = 0.0
    brake_torque: float = 0.0
    brake_wheel: int = 4
    supply_scale: float = 1.0


def resolve(effects: dict[str, dict[str, float]]) -> Effects:
    """Check ``effects`` and turn it into :class:`Effects`."""
    kw: dict[str, float | int | str | None] = {}
    for name, params in effects.items():
        if name not in MAIN:
            raise EffectError(f"unknown effect {name!r}; known: {', '.join(MAIN)}")
        for key, value in params.items():
            if (name, key) not in RANGES:
                raise EffectError(f"{name}: unknown parameter {key!r}")
            lo, hi = RANGES[(name, key)]
            if not lo <= float(value) <= hi:
                raise EffectError(f"{name}.{key} = {value} outside [{lo}, {hi}]")
        if MAIN[name] not in params:
            raise EffectError(f"{name}: needs {MAIN[name]!r}")
        v = float(params[MAIN[name]])
        if name == "rolling_resistance":
            kw["c_rr"] = v
        elif name == "slope":
            kw["slope_deg"] = v
            kw["slope_heading_deg"] = float(params.get("heading_deg", 0.0))
        elif name == "rolling_radius":
            kw["radius_scale"] = 1.0 + v
        elif name == "torque_limit":
            kw["current_limit_scale"] = 1.0 + v
        elif name == "friction":
            kw["friction_scale"] = 1.0 + v
        elif name == "command_lag":
            kw["lag_tau"] = v
        elif name == "command_delay":
            kw["delay"] = v
        elif name == "load_dependent_friction":
            kw["friction_fall"] = v
            kw["friction_range"] = float(params.get("range", 60.0))
        elif name == "loose_soil":
            kw["soil"] = "dry_sand" if float(params.get("sand", 0.0)) >= 0.5 else "regolith"
            kw["k_phi_factor"] = v
        elif name == "payload":
            kw["payload_fraction"] = v
        elif name == "toe":
            kw["toe_deg"] = v
        elif name == "brake_drag":
            kw["brake_torque"] = v
            wheel = float(params.get("wheel", 4.0))
            if wheel != int(wheel):
                raise EffectError(f"brake_drag.wheel = {wheel}: a wheel index 0-5")
            kw["brake_wheel"] = int(wheel)
        elif name == "battery_sag":
            kw["supply_scale"] = 1.0 - v
    return Effects(**kw)  # type: ignore[arg-type]


def parse_cli(spec: str) -> tuple[str, dict[str, float]]:
    """``name=value[,key=value...]`` -> (name, params); the first value is the main parameter."""
    head, *rest = spec.split(",")
    if "=" not in head:
        raise EffectError(f"--effect {spec!r}: expected name=value")
    name, value = head.split("=", 1)
    name = name.strip()
    if name not in MAIN:
        raise EffectError(f"unknown effect {name!r}; known: {', '.join(MAIN)}")
    params = {MAIN[name]: float(value)}
    for item in rest:
        k, _, v = item.partition("=")
        params[k.strip()] = float(v)
    return name, params

"""A replay steps where the tire keeps the free wheels stable (stop 104).

The transient tire holds a wheel's rim on a spring C_s / sigma_x and a damper D_x; a free
wheel (no rotor behind it) is stepped explicitly on them. With a steady-state tire's
relaxation length (0.32 mm, a model form ``diagnose`` fits) the 2 ms replay rang the free
wheels: their replay floor came out 20 x the 1 ms one, and every candidate fitted under that
form lost the free wheels' evidence.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from rover_env.calibration.diagnosis.floor import replay_floor
from rover_env.calibration.diagnosis.form import LADDER, carried_ladder, with_sigma
from rover_env.calibration.replay import ReplaySettings, make_windows, prepare, replay_step
from rover_env.calibration.residuals import noise_floor
from rover_env.config import RoverConfig, load_rover
from rover_env.generators.make_logs import make_logs
from rover_env.logs import read_log
from rover_env.sim.model import stable_config, stable_step, wheel_spin_inertia
from rover_env.sim.simulator import RoverSim
from rover_env.tire import TireParams, transient_forces, transient_step
from rover_env.tire import stable_step as tire_stable_step


def _slip_left(sigma: float, k: float) -> float:
    """A free wheel spinning 10 % fast on a hub at 0.1 m/s, stepped at ``k`` x the stable
    step for 0.5 s: the largest slip speed (m/s) over its second half."""
    p = replace(TireParams(), sigma_x=sigma, sigma_y=sigma)
    cfg = RoverConfig()
    r, j = cfg.geometry.wheel_radius, wheel_spin_inertia(cfg)
    dt = k * tire_stable_step(p, j, r)
    v, w, ux, uy = 0.1, 1.1 * 0.1 / r, 0.0, 0.0
    slips = []
    for _ in range(int(0.5 / dt)):
        ux2, uy2, dux, duy = transient_step(ux, uy, v, 0.0, r * w, 27.0, dt, p)
        fx, _ = transient_forces(ux2, uy2, dux, duy, 27.0, p)
        w -= dt * r * float(fx) / j
        ux, uy = float(ux2), float(uy2)
        slips.append(abs(r * w - v))
    return max(slips[len(slips) // 2 :])


@pytest.mark.parametrize("sigma", [0.02, 0.0025, 0.00032])
def test_the_stable_step_is_where_a_free_wheel_stops_ringing(sigma: float) -> None:
    assert _slip_left(sigma, 0.9) < 1e-6
    assert _slip_left(sigma, 1.1) > 1e-2


def test_the_replay_steps_at_2_ms_only_where_the_tire_allows() -> None:
    cfg = RoverConfig()
    assert stable_config(cfg) is cfg
    # the bound's inertia is the one the model's free wheels carry about their axles
    sim = RoverSim(cfg, backend="plugin")
    wheel = sim.model.body("wheel_3L")
    # (the MJCF writes 6 significant digits)
    assert wheel.inertia[1] == pytest.approx(wheel_spin_inertia(cfg), rel=1e-5)
    assert replay_step(with_sigma(cfg, 0.0025), 0.002).sim.timestep == pytest.approx(0.002)
    short = with_sigma(cfg, 0.00032)  # stable below 1.2 ms
    assert 0.001 < stable_step(short) < 0.002
    assert replay_step(short, 0.002).sim.timestep == pytest.approx(0.001)
    shortest = with_sigma(cfg, 0.00016)  # rings at the rover's own 1 ms too
    assert stable_step(shortest) < 0.001
    assert replay_step(shortest, 0.002).sim.timestep == pytest.approx(0.0005)
    assert stable_config(shortest).sim.timestep == pytest.approx(0.0005)


def test_a_short_relaxation_replays_its_own_twin_as_well_as_the_nominal(tmp_path: Path) -> None:
    paths = make_logs(tmp_path, {}, drives=1, seed=5, duration=21.0, progress=False)
    base = load_rover("proto_explorer")
    st = ReplaySettings()

    def free_floor(cfg: RoverConfig) -> float:
        prep = [prepare(read_log(p), cfg, p.name, st) for p in paths]
        floor = replay_floor(cfg, prep, make_windows(prep, st), noise_floor(prep), st)
        return max(floor["wheel_3L"], floor["wheel_3R"])

    nominal, short = free_floor(base), free_floor(with_sigma(base, 0.00032))
    # At 2 ms the short relaxation's free wheels read ~20 x the nominal's (stop 104).
    assert short < 1.5 * nominal, (short, nominal)
    assert np.isfinite(nominal) and nominal > 0


def test_the_relaxation_form_tries_only_what_the_rovers_own_step_carries() -> None:
    cfg = RoverConfig()
    rungs = carried_ladder(cfg)
    assert min(rungs) == pytest.approx(0.0003125) and max(rungs) == max(LADDER)
    assert set(LADDER) - set(rungs) == {0.00015625}
    assert all(stable_step(with_sigma(cfg, s)) > cfg.sim.timestep for s in rungs)


def test_a_simulation_past_the_stable_step_warns_naming_the_step_and_the_tire() -> None:
    import warnings

    from rover_env.config import SimSpec

    ringing = replace(with_sigma(RoverConfig(), 0.00032), sim=SimSpec(timestep=0.002))
    with pytest.warns(RuntimeWarning, match=r"sim\.timestep 0\.002 s .*\(tire\.sigma_x 0\.00032"):
        RoverSim(ringing, backend="plugin")
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        RoverSim(stable_config(ringing), backend="plugin")  # at its stable step: silent
        RoverSim(RoverConfig(), backend="plugin")

"""The Warp rover (rover_env.warp, float32, device "cpu") against the C plugin (float64).

One 10 s drive (3 rad/s straight, a 2 / 4 rad/s left turn from 4 to 7 s, 4 rad/s straight
to the end; after RoverSim.reset's 0.5 s settle) on hard ground (``flat``) and on loose soil
(``paper-sand``: mars-sand over the whole ground, with its rut map), both worlds in one
Warp simulation, sampled every 0.1 s. MuJoCo's own contacts are off on both sides (on flat
ground they never fire; RoverSim(contacts=False)). Everything compiles once per session.

Tolerances (docs/gpu.md): the drive is stable (the C plugin with its state rounded to float32
at the start returns to its own trajectory within 1e-6 m and 1e-4 N: test below), so what
Warp adds is float32 arithmetic along the way, not chaos. Its largest term is the wheels'
angle integration: ~30 rad held in float32 (ulp 1.9e-6 rad) advanced by ~3e-3 rad per substep,
a relative resolution of ~6e-4 of each wheel's travel, against slip speeds of ~1e-3 m/s
(0.4 % of the tread speed) on which the driven axles' longitudinal force balance rests: the
forces that balance (F_x up to 1.5 N after the turn) differ by ~1 %, and so the loads (F_z)
and, on soil, the sinkage (1e-3 of it) by less. The bounds (TOL) are about three times the
largest differences measured, and a 5 % change of the tire's relaxation length in the C
plugin (test below) breaks them; a 2 % change moves F_x by 0.05 N, so Warp's float32 runs
differ from the float64 plugin by about what a 1 % change of that constant does.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

pytest.importorskip("mujoco_warp", reason="the gpu extra (mujoco-warp) is not installed")

import torch

from rover_env import tire
from rover_env.config import load_rover
from rover_env.envs.episode import OBS_NAMES
from rover_env.estimation.batch import BatchSlipEstimator
from rover_env.sim.simulator import RoverSim
from rover_env.warp.sim import WarpRoverSim

CFG = load_rover("proto_explorer")

TERRAINS = ("flat", "paper-sand")
SAMPLE = 100  # substeps between samples (0.1 s)


def targets_at(t: float) -> np.ndarray:
    if t < 4.0:
        return np.full(4, 3.0)
    if t < 7.0:
        return np.array([2.0, 4.0, 2.0, 4.0])  # 1L 1R 2L 2R: a left turn
    return np.full(4, 4.0)


TOL = {  # about 3x the largest |Warp - C| measured over the drive (in brackets)
    "pos": 1e-3,  # m, segment 1's position over 2.3 m of travel [2.2e-4]
    "F_x": 0.08,  # N, 0.3 % of the static wheel load (26 N) [2.4e-2, after the turn]
    "F_y": 0.08,  # N [7.9e-3]
    "F_z": 0.2,  # N, 0.8 % of the load [6.1e-2, soil: 1e-3 of the sinkage, F_z ~ h^(n+1)]
    "slip": 5e-3,  # slip ratio [1.7e-3]
    "sinkage": 3e-5,  # m, of ~6.6 mm [7.6e-6]
    "rut": 2.5e-4,  # m, rut depth read along the track [7.6e-5]
}


def _record(step, read, n: int) -> dict[str, np.ndarray]:
    out: dict[str, list[np.ndarray]] = {}
    for k in range(n):
        step(k)
        for name, v in read().items():
            out.setdefault(name, []).append(v)
    return {k: np.array(v) for k, v in out.items()}


def _c_drive(terrain: str, rover: object = "proto_explorer", perturb: bool = False) -> dict:
    sim = RoverSim(rover, terrain, backend="plugin", contacts=False, sensors=False)  # type: ignore[arg-type]
    if perturb:  # the state rounded to float32 once
        d = sim.data
        d.qpos[:] = d.qpos.astype(np.float32)
        d.qvel[:] = d.qvel.astype(np.float32)
        d.plugin_state[:] = d.plugin_state.astype(np.float32)
    eps = sim.cfg.tire.v_eps

    def step(k: int) -> None:
        sim.set_speed_targets(targets_at(k * SAMPLE * sim.dt))
        sim.step(SAMPLE)

    def read() -> dict[str, np.ndarray]:
        t = sim.wheel_truth()
        return {
            "pos": sim.data.qpos[:3].copy(),
            "F_x": t.F_x,
            "F_y": t.F_y,
            "F_z": t.F_z,
            "slip": tire.slip_ratio(t.v_x, t.v_w, eps),
            "sinkage": t.sinkage,
        }

    rec = _record(step, read, 100)
    rec["rut_state"] = (
        sim._plugin.rut_state(sim.data.plugin_state).copy() if sim._plugin is not None else None
    )
    rec["grid"] = sim.terrain.rut_grid
    return rec


@pytest.fixture(scope="module")
def warp_drive() -> list[dict]:
    sim = WarpRoverSim(2, terrain=list(TERRAINS), device="cpu", contacts=False)
    eps = sim.cfg.tire.v_eps

    def step(k: int) -> None:
        sim.set_speed_targets(np.tile(targets_at(k * SAMPLE * sim.dt), (2, 1)))
        sim.step(SAMPLE)

    def read() -> dict[str, np.ndarray]:
        t = sim.wheel_truth()
        return {
            "pos": sim.d.qpos.numpy()[:, :3].astype(np.float64),
            "F_x": t["F_x"],
            "F_y": t["F_y"],
            "F_z": t["F_z"],
            "slip": tire.slip_ratio(t["v_x"], t["v_w"], eps),
            "sinkage": t["sinkage"],
        }

    rec = _record(step, read, 100)
    return [
        {**{k: v[:, w] for k, v in rec.items()}, "rut_state": sim.rut_state(w)} for w in range(2)
    ]


@pytest.fixture(scope="module")
def c_drive() -> list[dict]:
    return [_c_drive(t) for t in TERRAINS]


def _worst(a: dict, b: dict) -> dict[str, float]:
    return {
        k: float(np.abs(a[k] - b[k]).max()) for k in ("pos", "F_x", "F_y", "F_z", "slip", "sinkage")
    }


@pytest.mark.parametrize("world", [0, 1], ids=TERRAINS)
def test_warp_drive_equals_c_plugin(
    warp_drive: list[dict], c_drive: list[dict], world: int
) -> None:
    w, c = warp_drive[world], c_drive[world]
    assert np.ptp(c["pos"][:, 0]) > 2.0  # it drove
    assert np.abs(c["F_y"]).max() > 0.1  # the turn loaded the tires sideways
    worst = _worst(w, c)
    bad = {k: v for k, v in worst.items() if not v <= TOL[k]}
    assert not bad, f"{TERRAINS[world]}: Warp - C beyond tolerance: {bad} (all: {worst})"


def test_warp_soil_sinks_and_leaves_the_same_rut(
    warp_drive: list[dict], c_drive: list[dict]
) -> None:
    w, c = warp_drive[1], c_drive[1]
    assert c["sinkage"].min() > 1e-3 and (w["sinkage"] > 0).all()
    grid = c["grid"]
    # read both rut maps along the whole track: every 2 cm over the rover's path, +-0.3 m across
    xs = np.arange(-0.5, c["pos"][-1, 0] + 0.1, 0.02)
    ys = np.arange(-0.6, 0.61, 0.02)
    gx, gy = np.meshgrid(xs, ys)
    rc = grid.lookup(c["rut_state"], gx.ravel(), gy.ravel())
    rw = grid.lookup(w["rut_state"], gx.ravel(), gy.ravel())
    assert rc.max() > 1e-3  # ruts were written
    assert np.abs(rw - rc).max() <= TOL["rut"]


def test_tolerances_see_a_five_percent_model_change(c_drive: list[dict]) -> None:
    """The C plugin against itself: a float32 rounding of the state stays far inside the
    bounds (the drive is stable), a 5 % change of the relaxation length sigma_x leaves
    them on both grounds."""
    for world, terrain in enumerate(TERRAINS):
        worst = _worst(_c_drive(terrain, perturb=True), c_drive[world])
        assert worst["pos"] < 1e-6 and worst["F_x"] < 1e-4, worst
    cfg = load_rover("proto_explorer")
    changed = dataclasses.replace(cfg, tire=dataclasses.replace(cfg.tire, sigma_x=0.021))
    for world, terrain in enumerate(TERRAINS):
        worst = _worst(_c_drive(terrain, changed), c_drive[world])
        assert any(worst[k] > TOL[k] for k in worst), (terrain, worst)


def test_torch_env_and_ppo_stay_on_the_device() -> None:
    """The batched env's tensors live on its device, episodes end and restart inside step,
    and one PPO iteration runs on it (CPU here)."""
    torch = pytest.importorskip("torch")
    from rover_env.warp.env import ACT_DIM, OBS_DIM, WarpRoverEnv
    from rover_env.warp.ppo import PPOConfig, train

    env = WarpRoverEnv(3, device="cpu", episode_seconds=0.2, seed=1)
    obs = env.reset()
    assert obs.shape == (3, OBS_DIM) and obs.device == env.device
    cmd0 = env.command.clone()
    for _ in range(4):
        obs, rew, term, trunc = env.step(torch.full((3, ACT_DIM), 0.8))
    assert trunc.all() and not term.any() and torch.isfinite(rew).all()
    assert (env.steps == 0).all() and not torch.equal(env.command, cmd0)  # restarted
    v, _ = env.true_motion()  # after the reset: back at rest
    assert v.abs().max() < 0.02 and (obs[:, :6] == 0).all()  # one sample: no rates yet
    _, rows = train(env, 1, PPOConfig(steps_per_env=4, minibatches=2, epochs=1))
    assert np.isfinite(rows[0]["mean_reward"]) and rows[0]["steps_per_s"] > 0


# --- The Warp env's observation carries the device estimator's estimate (tests/test_warp_estimator.py
# checks the estimator itself). Here, beside the drives, so that one process compiles Warp's
# kernels for both.
@pytest.fixture(scope="module")
def env_run() -> dict:
    """A 2-world Warp env on CPU for 10 steps (0.8 s episodes: one restart), recording the
    estimator's inputs; world 0 drives straight, world 1 turns."""
    from rover_env.warp.env import WarpRoverEnv

    env = WarpRoverEnv(2, device="cpu", episode_seconds=0.8, seed=3)
    pushes: list[tuple] = []
    push = env.estimator.push

    def recording(ids, t, phi, theta):
        mask = torch.ones(2, dtype=torch.bool) if ids is None else ids.clone()
        pushes.append((mask.numpy(), t.numpy().copy(), phi.numpy().copy(), theta.numpy().copy()))
        push(ids, t, phi, theta)

    env.estimator.push = recording  # type: ignore[method-assign]
    obs = [env.reset()]
    truth = []
    action = torch.tensor([[0.75] * 4, [0.5, 1.0, 0.5, 1.0]])
    for _ in range(10):
        obs.append(env.step(action)[0])
        truth.append(env.true_motion()[0].clone())
    return {"env": env, "obs": torch.stack(obs).numpy(), "pushes": pushes, "truth": truth}


def test_env_observation_is_the_cpu_envs_layout(env_run: dict) -> None:
    from rover_env.envs.proto_explorer import ProtoExplorerEnv

    cpu = ProtoExplorerEnv()
    assert env_run["obs"].shape[2] == len(OBS_NAMES) == cpu.observation_space.shape[0]
    assert env_run["obs"].dtype == cpu.observation_space.dtype


def test_env_observation_carries_the_estimate(env_run: dict) -> None:
    """The observation's estimator entries are the numpy estimator's on the same inputs
    (to the float32 bounds above), restart included; the joint angles are the inputs."""
    ref = BatchSlipEstimator(CFG, 2)
    env, obs = env_run["env"], env_run["obs"]
    per_obs = [1] + [env.samples_per_step + 1] * 10  # each step ends with the restart push
    pushes = iter(env_run["pushes"])
    ix = {name: OBS_NAMES.index(name) for name in OBS_NAMES}
    restarted = 0
    last_theta = np.zeros((2, 5), dtype=np.float32)
    for k, count in enumerate(per_obs):
        for _ in range(count):
            mask, t, phi, theta = next(pushes)
            ids = np.flatnonzero(mask)
            if ids.size and (t[ids] == 0).all():  # a new episode's first sample
                ref.reset(ids)
                restarted += 1
            ref.push(ids, t[ids], phi[ids], theta[ids])
            last_theta[ids] = theta[ids]
        e = ref.estimate()
        o = obs[k]
        want = np.stack([q.slip_ratio for q in e])
        np.testing.assert_allclose(o[:, ix["slip_estimate_1L"] :][:, :4], want, atol=2e-4)
        rates = np.stack([q.phi_rate for q in e])
        np.testing.assert_allclose(o[:, :6], rates, atol=1e-5)
        speed = [q.seg_velocity[1, 0] for q in e]
        np.testing.assert_allclose(o[:, ix["speed_estimate"]], speed, atol=1e-5)
        np.testing.assert_allclose(o[:, ix["theta_1"] : ix["theta_5"] + 1], last_theta, atol=0)
    assert restarted == 2  # the reset and the end of the 0.8 s episodes


def test_env_estimate_tracks_the_true_speed_driving_straight(env_run: dict) -> None:
    """World 0 drives straight on hard ground: after the 0.5 s warm-up the estimated speed
    of the middle segment is the true one within 2 % and the slip is small."""
    obs, truth = env_run["obs"], env_run["truth"]
    k = 7  # 0.7 s into the episode, the last step before the restart
    v_true = float(truth[k - 1][0])
    v_est = float(obs[k, 0, OBS_NAMES.index("speed_estimate")])
    assert v_true > 0.15 and abs(v_est - v_true) < 0.02 * v_true, (v_est, v_true)
    assert np.abs(obs[k, 0, 34:38]).max() < 0.03


def test_warp_lateral_split_pivot_equals_c_plugin() -> None:
    """TireParams.lateral_split (eq. 11 for every sign, stop 63) in Warp as in the C
    plugin: 1 s straight, then a 2 s pivot, where the driven wheels turn against their hubs."""
    cfg = dataclasses.replace(CFG, tire=dataclasses.replace(CFG.tire, lateral_split=1.0))
    ws = WarpRoverSim(1, rover=cfg, terrain="flat", device="cpu", contacts=False)
    cs = RoverSim(cfg, "flat", backend="plugin", contacts=False, sensors=False)
    plain = RoverSim(CFG, "flat", backend="plugin", contacts=False, sensors=False)
    for targets, n in ((np.full(4, 2.45), 1000), (np.array([-1.5, 1.5, -1.5, 1.5]), 2000)):
        ws.set_speed_targets(targets[None, :])
        ws.step(n)
        for sim in (cs, plain):
            sim.set_speed_targets(targets)
            sim.step(n)
    pos_w = ws.d.qpos.numpy()[0, :3].astype(np.float64)
    assert np.abs(pos_w - cs.data.qpos[:3]).max() < TOL["pos"]
    assert np.abs(plain.data.qpos[:3] - cs.data.qpos[:3]).max() > 10 * TOL["pos"]  # it matters

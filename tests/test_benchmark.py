"""Benchmark (rover_env.benchmark): seed plan, scenarios, the scenario wrapper, statistics, one
short end-to-end run with its tables, and the torch-free code path."""

from __future__ import annotations

import csv
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rover_env import seeds as seed_plan
from rover_env.benchmark.metrics import METRICS
from rover_env.benchmark.report import paired, t_interval
from rover_env.benchmark.scenarios import load_scenario, scenario_names
from rover_env.config import ConfigError
from rover_env.tasks.scenario import ScenarioTask

EXPECTED = {"flat-turns", "ice-patch", "split-mu", "slope", "bumps", "stuck-wheel"}


def test_seed_plan_is_disjoint() -> None:
    seed_plan.assert_disjoint()
    sets = {k: set(v) for k, v in seed_plan.SPLITS.items() if k != "training"}
    train = seed_plan.SPLITS["training"]
    for a in sets:
        assert not any(s in train for s in sets[a])
        for b in sets:
            assert a == b or not sets[a] & sets[b]
    assert seed_plan.seeds("test", 3) == [4000, 4001, 4002]
    assert seed_plan.training_seed(2, 5) in train
    with pytest.raises(ValueError):
        seed_plan.seeds("test", 10_000)
    with pytest.raises(ValueError):
        seed_plan.seeds("nope")


def test_disjointness_check_catches_an_overlap(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(seed_plan.SPLITS, "validation", range(3050, 3150))
    with pytest.raises(AssertionError, match="overlap"):
        seed_plan.assert_disjoint()


def test_scenarios_load_and_jitter_per_seed() -> None:
    assert EXPECTED <= set(scenario_names())
    for name in EXPECTED:
        sc = load_scenario(name)
        a, b, a2 = sc.episode(3000), sc.episode(3001), sc.episode(3000)
        assert a == a2, "an episode is a pure function of (scenario, seed)"
        assert a.start != b.start
        assert a.schedule.path_length(a.duration) > 0
    ice = load_scenario("ice-patch")
    mus = {ice.episode(s).terrain.patches[0].mu_x for s in range(3000, 3005)}
    assert len(mus) == 5 and all(0.06 <= m <= 0.1 for m in mus)
    assert load_scenario("stuck-wheel").slip_wasted
    with pytest.raises(ConfigError, match="no shipped scenario"):
        load_scenario("no-such-scenario")


def test_scenario_wrapper_overrides_commands() -> None:
    from rover_env.benchmark.run import ScenarioWrapper
    from rover_env.envs.proto_explorer import OBS_NAMES, ProtoExplorerEnv

    ep = load_scenario("flat-turns").episode(3000, duration=4.5)
    w = ScenarioWrapper(ProtoExplorerEnv(terrain=ep.terrain))
    w.set_episode(ep)
    obs, info = w.reset()
    i = OBS_NAMES.index("command_speed")
    assert tuple(obs[i : i + 2]) == pytest.approx(ep.schedule.at(0.0))
    done, steps = False, 0
    while not done:
        obs, _, term, trunc, info = w.step(np.zeros(4, dtype=np.float32))
        steps += 1
        done = term or trunc
        t = w.base.sim.time
        assert tuple(obs[i : i + 2]) == pytest.approx(ep.schedule.at(t))
        assert tuple(info["command"]) == pytest.approx(ep.schedule.at(t))
    assert steps == 45 and trunc and not term  # the task's length ends the episode
    assert tuple(info["command"]) == pytest.approx((0.15, 0.2))  # from 4 s
    assert isinstance(w.base.task, ScenarioTask) and w.base.task.episode is ep


def test_scenario_wrapper_writes_no_private_env_state() -> None:
    """The wrapper hands the env a task; it never assigns to the env's private attributes."""
    import ast
    import inspect

    from rover_env.benchmark import run

    tree = ast.parse(inspect.getsource(run.ScenarioWrapper))
    writes = [
        ast.unparse(t)
        for node in ast.walk(tree)
        if isinstance(node, ast.Assign | ast.AugAssign | ast.AnnAssign)
        for t in (node.targets if isinstance(node, ast.Assign) else [node.target])
        if isinstance(t, ast.Attribute | ast.Subscript) and "._" in ast.unparse(t)
    ]
    assert not writes, writes


def test_t_interval_and_paired_differences() -> None:
    from scipy import stats

    x = [1.0, 2.0, 4.0, 7.0]
    m, lo, hi = t_interval(x)
    ci = stats.t.interval(0.95, 3, loc=np.mean(x), scale=stats.sem(x))
    assert (lo, hi) == pytest.approx(ci) and m == pytest.approx(3.5)
    assert t_interval([2.0]) == (2.0, 2.0, 2.0)
    rows = []
    for seed, (a, b) in enumerate([(1.0, 0.5), (2.0, 1.4), (3.0, 2.6)]):
        base = dict.fromkeys(METRICS, 0.0)
        rows.append({"controller": "A", "scenario": "s", "seed": seed, **base, "mean_abs_slip": a})
        rows.append({"controller": "B", "scenario": "s", "seed": seed, **base, "mean_abs_slip": b})
    p = {r["metric"]: r for r in paired(rows, "A")}["mean_abs_slip"]
    assert p["diff_mean"] == pytest.approx(-0.5) and p["ci_high"] < 0
    assert p["controller_mean"] == pytest.approx(1.5) and p["baseline_mean"] == pytest.approx(2.0)
    assert p["p"] == pytest.approx(stats.ttest_rel([0.5, 1.4, 2.6], [1.0, 2.0, 3.0]).pvalue)
    # The interval alone excludes 0, but not after Holm over the table's comparisons (one per metric).
    assert p["p"] < 0.05 < p["p_holm"] and p["comparisons"] == len(METRICS)
    assert p["verdict"] == "no difference"
    rows += [
        {
            "controller": c,
            "scenario": "s",
            "seed": 10 + k,
            **dict.fromkeys(METRICS, 0.0),
            "mean_abs_slip": v,
        }
        for k in range(5)
        for c, v in (("A", 2.0 + 0.1 * k), ("B", 1.5 + 0.1 * k + 0.05 * (k % 2)))
    ]
    p = {r["metric"]: r for r in paired(rows, "A")}["mean_abs_slip"]
    assert p["p_holm"] < 0.05 and p["verdict"] == "better"


def test_holm_correction() -> None:
    from rover_env.benchmark.report import holm

    assert holm([0.01, 0.04, 0.03, 0.005]) == pytest.approx([0.03, 0.06, 0.06, 0.02])
    out = holm([0.2, float("nan"), 0.6])
    assert out[0] == pytest.approx(0.4) and math.isnan(out[1]) and out[2] == pytest.approx(0.6)


def test_benchmark_one_short_episode_writes_well_formed_tables(tmp_path: Path) -> None:
    from rover_env.benchmark.cli import run_benchmark

    files = run_benchmark(
        ["open-loop", "slip-pi"], ["ice-patch"], 1, tmp_path, duration=2.0, progress=False
    )
    with files["summary"].open() as fh:
        summary = list(csv.DictReader(fh))
    assert {r["metric"] for r in summary} == set(METRICS)
    assert {r["controller"] for r in summary} == {"open-loop", "slip-pi"}
    for r in summary:
        for k in ("mean", "ci_low", "ci_high"):
            assert math.isfinite(float(r[k])), r
        assert float(r["ci_low"]) <= float(r["mean"]) <= float(r["ci_high"])
    with files["episodes"].open() as fh:
        episodes = list(csv.DictReader(fh))
    assert len(episodes) == 2 and all(set(METRICS) <= set(e) for e in episodes)
    with files["paired"].open() as fh:
        pairs = list(csv.DictReader(fh))
    assert {r["metric"] for r in pairs} == set(METRICS)
    assert all(
        math.isfinite(float(r[k])) for r in pairs for k in ("diff_mean", "ci_low", "ci_high")
    )
    text = files["markdown"].read_text()
    assert "## ice-patch" in text and "Paired differences" in text
    assert files["metrics"].stat().st_size > 1000


def test_benchmark_imports_no_torch_for_classical_controllers(tmp_path: Path) -> None:
    code = (
        "import sys\n"
        "from rover_env.benchmark.cli import run_benchmark\n"
        f"run_benchmark(['open-loop', 'slip-pi'], ['split-mu'], 1, {str(tmp_path)!r},"
        " duration=1.0, progress=False, plots=False)\n"
        "print('torch' in sys.modules, 'stable_baselines3' in sys.modules)\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=120
    )
    assert out.stdout.strip().splitlines()[-1] == "False False"


def test_ppo_controller_runs_through_the_env(tmp_path: Path) -> None:
    sb3 = pytest.importorskip("stable_baselines3")
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    from rover_env.benchmark.run import Job, run_jobs
    from rover_env.envs.proto_explorer import ProtoExplorerEnv
    from rover_env.policies.specs import make_controller

    venv = VecNormalize(DummyVecEnv([ProtoExplorerEnv]))
    model = sb3.PPO("MlpPolicy", venv, n_steps=8, batch_size=8, device="cpu")
    model.save(tmp_path / "best_model.zip")
    venv.save(str(tmp_path / "vecnormalize.pkl"))
    ctrl = make_controller(f"ppo:{tmp_path}")
    assert ctrl.action_layout == "wheels"
    assert ctrl.normalizer is not None  # type: ignore[attr-defined]
    (row,) = run_jobs([Job(f"ppo:{tmp_path}", "flat-turns", 2000, 1.0)])
    with pytest.raises(ValueError, match="played only by a final run"):
        run_jobs([Job("open-loop", "flat-turns", 4000, 1.0)])
    with pytest.raises(ValueError, match="spent seeds"):
        run_jobs([Job("open-loop", "flat-turns", 3000, 1.0)], final=True)
    assert set(METRICS) <= set(row) and all(math.isfinite(row[m]) for m in METRICS)
    with pytest.raises(ValueError, match="unknown controller"):
        make_controller("pid")


def test_axle_fight_deadband_removes_the_axle_fight_on_ice() -> None:
    """On the ice patch the slip the PI leaves inside its deadband is mostly the axle fight
    (front axle spinning, middle dragged); its own narrower deadband removes most of it."""
    import dataclasses

    from rover_env.benchmark.run import ScenarioWrapper
    from rover_env.control.slip_pi import SlipPI, load_slip_pi_config
    from rover_env.envs.proto_explorer import ProtoExplorerEnv
    from rover_env.policies.controllers import ClassicalController

    ep = load_scenario("ice-patch").episode(seed_plan.SPLITS["validation"].start, duration=10.0)
    w = ScenarioWrapper(ProtoExplorerEnv(terrain=ep.terrain))
    fight = np.array([1.0, 1.0, -1.0, -1.0]) / 4
    rms = {}
    for scale in (1.0, 0.25):
        gains = dataclasses.replace(load_slip_pi_config(), axle_fight_scale=scale)
        ctrl = ClassicalController("pi", lambda cfg, dt, g=gains: SlipPI(cfg, g, dt=dt))
        w.set_episode(ep)
        obs, _ = w.reset()
        ctrl.reset(w.base)
        late = []
        done = False
        while not done:
            obs, _, term, trunc, info = w.step(ctrl.action(w.base, obs))
            done = term or trunc
            if w.base.sim.time > 4.0:  # past the start and the patch's edge
                late.append(info["slip_true"] @ fight)
        rms[scale] = float(np.sqrt(np.mean(np.square(late))))
    assert rms[1.0] > 1e-3  # the fight is there, inside the 0.01 deadband
    assert rms[0.25] < 0.5 * rms[1.0]
    w.close()


def test_slip_mean_and_percentile_come_from_the_same_samples() -> None:
    """info["slip_abs_step"] is each wheel's step mean; the env's mean |S| is its mean, and
    the benchmark's mean and p95 both come from it."""
    from rover_env.benchmark.metrics import STEP_KEYS, metrics_of_steps
    from rover_env.benchmark.run import ScenarioWrapper
    from rover_env.envs.proto_explorer import ProtoExplorerEnv

    ep = load_scenario("split-mu").episode(seed_plan.SPLITS["validation"].start, duration=2.0)
    w = ScenarioWrapper(ProtoExplorerEnv(terrain=ep.terrain))
    w.set_episode(ep)
    _, info = w.reset()
    start = np.asarray(info["position"]).copy()
    steps: dict[str, list[object]] = {k: [] for k in STEP_KEYS}
    done = False
    while not done:
        _, _, term, trunc, info = w.step(np.full(4, 0.6, dtype=np.float32))
        assert np.mean(info["slip_abs_step"]) == pytest.approx(info["slip_true_mean_abs"])
        for k in STEP_KEYS:
            steps[k].append(info[k])
        done = term or trunc
    m = metrics_of_steps(
        steps, start=start, last_info=info, commanded_path=1.0, goal_fraction=ep.goal_fraction
    )
    samples = np.asarray(steps["slip_abs_step"])
    assert samples.shape == (20, 4)
    assert m["mean_abs_slip"] == pytest.approx(float(np.mean(samples)))
    assert m["p95_abs_slip"] == pytest.approx(float(np.percentile(samples, 95)))
    w.close()


def test_a_task_brings_its_reward_weights() -> None:
    from rover_env.envs.proto_explorer import ProtoExplorerEnv
    from rover_env.tasks import RewardWeights

    ep = load_scenario("ice-patch").episode(seed_plan.SPLITS["validation"].start, duration=0.3)
    env = ProtoExplorerEnv(terrain=ep.terrain, reward_weights={"slip": 3.0})
    a = np.full(4, 0.5, dtype=np.float32)
    infos = []
    for weights in (None, RewardWeights(slip=0.0, energy=0.0)):
        env.set_task(ScenarioTask(ep, reward_weights=weights))
        env.reset(seed=ep.seed)
        *_, info = env.step(a)
        infos.append(info)
    own, task = infos
    assert own["reward_slip"] == pytest.approx(-3.0 * own["slip_true_mean_abs"])  # the env's
    assert task["reward_slip"] == 0.0 and task["reward_energy"] == 0.0  # the task's
    assert task["reward_tracking"] == pytest.approx(own["reward_tracking"])  # same episode
    env.close()

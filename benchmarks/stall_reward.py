"""The training (mobility) reward a controller earns after T seconds, with its targets as they
are, halved and stopped: what stopping in a stall pays (issue 18, stop 36).

python benchmarks/stall_reward.py ppo:agents/mobility-ppo-rr-ft-patch 1052 7

Soft-patch, one tuning or validation seed; the reward weights of configs/agents_mobility/
ppo_rr_wide_e04.yaml (energy 0.04 per W).
"""

import sys

import numpy as np
from rover_env.benchmark.run import ScenarioWrapper
from rover_env.envs.proto_explorer import ProtoExplorerEnv
from rover_env.policies.specs import make_controller
from rover_env.seeds import split_of
from rover_env.tasks.scenarios import load_scenario

spec, seed, t_switch = sys.argv[1], int(sys.argv[2]), float(sys.argv[3])
if split_of(seed) == "test":
    sys.exit(f"error: seed {seed} is a test seed; probe tuning or validation seeds")
rw = dict(
    tracking=0.0,
    yaw_tracking=0.4,
    progress=4.0,
    energy=0.04,
    sinkage=0.05,
    slip=0.3,
    slip_scale=0.1,
)
for scale in (1.0, 0.5, 0.0):
    ctrl = make_controller(spec)
    ep = load_scenario("soft-patch").episode(seed)
    w = ScenarioWrapper(ProtoExplorerEnv(terrain=ep.terrain, reward_weights=rw))
    w.set_episode(ep)
    obs, info = w.reset()
    ctrl.reset(w.base)
    k = 0
    R = []
    keys = {}
    while True:
        a = np.asarray(ctrl.action(w.base, obs), dtype=np.float32)
        t = k * w.base.control_dt
        if t >= t_switch:
            a = a * scale
        obs, r, term, trunc, info = w.step(a)
        k += 1
        if t >= t_switch:
            R.append(r)
            for kk, v in info.items():
                if kk.startswith("reward_"):
                    keys.setdefault(kk, []).append(float(v))
        if term or trunc:
            break
    print(
        f"x{scale}: reward/step {np.mean(R):+.3f} over {len(R)} steps; "
        + " ".join(f"{kk[7:]} {np.mean(v):+.3f}" for kk, v in keys.items())
    )

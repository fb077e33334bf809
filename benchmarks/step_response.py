"""The speed loop's answer to command steps: the independent generator against this model.

    python benchmarks/step_response.py                     # table + docs/calibration/step_response.png
    python benchmarks/step_response.py --out /tmp/step.png

Both drive the same targets on flat hard ground from rest: a hard step (0 -> 3 rad/s, the
"hard" drives' kind, which saturates the motors) and a run of smaller steps (1.0, 0.6, 2.5,
2.2 rad/s, the "steps" drives' kind). The generator is :mod:`rover_env.independent` with its
nominal build (no nuisance, no effect); this model is the configuration and the speed-loop
forms ``diagnose`` can fit (the anti-windup form, the gains, the rotor inertia), among them
the generator's loop written in this model's terms: its voltage-mode PI with back-EMF
feed-forward is, unsaturated, a PI on the wheel's speed of 0.7 x (2 + 6) = 5.6 N m s/rad and
0.7 x 30 = 21 N m/rad at the wheel (0.7 N m per volt: efficiency x gear x k_t / R), and its
rotor reflects 0.05 kg m^2; its voltage line is 8.4 N m at stall and 6 rad/s at no load, and its
back-calculation tracks at a quarter of its integral time (``anti_windup: back_calculation``
with ``tracking_ratio`` 0.25). Printed per model: the driven wheels' RMS speed difference over
each plan (rad/s), the angle they lost by 2 s into the hard step (the commanded 3 rad less
their travel) and their speed 0.1 s and 0.3 s into it. The figure shows the hard step.
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

import rover_env.independent.motor as gen_motor
import rover_env.independent.nuisance as nuisance
from rover_env.config import RoverConfig, load_rover
from rover_env.drive_datasheet import VoltageDrive
from rover_env.independent.effects import resolve
from rover_env.independent.model import RoverParams
from rover_env.independent.simulate import simulate
from rover_env.sim.simulator import RoverSim

Array = NDArray[np.float64]
RATE = 50.0
PLANS: dict[str, list[tuple[float, float]]] = {
    "hard step": [(1.0, 0.0), (3.0, 3.0)],
    "steps": [(1.0, 0.0), (3.0, 1.0), (3.0, 0.6), (3.0, 2.5), (3.0, 2.2), (3.0, 0.0)],
}
DATASHEET: dict[str, Any] = VoltageDrive(
    supply=gen_motor.V_MAX,
    resistance=gen_motor.R_ARM,
    torque_constant=gen_motor.K_T_DATASHEET,
    gear=gen_motor.GEAR,
    efficiency=gen_motor.EFF,
    rotor_inertia=gen_motor.ROTOR,
    current_limit=gen_motor.I_MAX,
    kp=RoverParams().kp[0],
    ki=RoverParams().ki[0],
    tracking_time=gen_motor.T_TRACK,
).motor_fields()
"""The generator's nominal drive converted by :class:`rover_env.drive_datasheet.VoltageDrive`
(its tracking time 0.05 s is 0.19 of the wheel-referred integral time 5.6 / 21 s; the row
above writes a quarter of it, the voltage PI's own 6 / 30 s)."""
MODELS: dict[str, dict[str, Any]] = {
    "configuration (clamp, 2, 40, 0.025)": {},
    "conditional anti-windup": {"anti_windup": "conditional"},
    "rotor x 2": {"armature": 0.05},
    "conditional, rotor x 2": {"anti_windup": "conditional", "armature": 0.05},
    "generator's gains (5.6, 21)": {"speed_gain": 5.6, "integral_gain": 21.0},
    "generator's loop as back-calculation (5.6, 21, 8.4 N m stall, T_i/4, 0.05)": {
        "anti_windup": "back_calculation",
        "speed_gain": 5.6,
        "integral_gain": 21.0,
        "stall_torque": 8.4,
        "no_load_speed": 6.0,
        "tracking_ratio": 0.25,
        "armature": 0.05,
    },
    "generator's drive from its datasheet (VoltageDrive: T_t 0.05 s, limit 2.8)": DATASHEET,
    "generator's loop (conditional, 5.6, 21, 0.05)": {
        "anti_windup": "conditional",
        "speed_gain": 5.6,
        "integral_gain": 21.0,
        "armature": 0.05,
    },
}


def targets(plan: list[tuple[float, float]]) -> tuple[Array, Array]:
    """Sample times at :data:`RATE` and the (N, 4) targets, each leg held for its seconds."""
    t = np.round(np.arange(0.0, sum(d for d, _ in plan) + 0.5 / RATE, 1.0 / RATE), 9)
    cmd = np.zeros((len(t), 4))
    t0 = 0.0
    for dur, v in plan:
        cmd[(t >= t0 - 1e-9) & (t < t0 + dur - 1e-9)] = v
        t0 += dur
    return t, cmd


def generator(t: Array, cmd: Array) -> Array:
    """The generator's driven wheel angles (N, 4), nominal build."""
    p = nuisance.apply(RoverParams(), nuisance.nominal())
    return simulate(p, resolve({}), t, cmd).phi[:, :4]


def model(cfg: RoverConfig, t: Array, cmd: Array) -> Array:
    """This model's driven wheel angles (N, 4), the targets held between samples."""
    sim = RoverSim(cfg, "flat")
    sim.reset()
    steps = round(1.0 / (RATE * cfg.sim.timestep))
    phi0 = sim.sensors().phi[:4].copy()
    out = np.zeros((len(t), 4))
    for k in range(len(t)):
        out[k] = sim.sensors().phi[:4] - phi0
        sim.set_speed_targets(cmd[k])
        sim.step(steps)
    return out


def speed(t: Array, phi: Array) -> Array:
    return np.asarray(np.gradient(phi.mean(axis=1), t), dtype=np.float64)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="docs/calibration/step_response.png", help="figure path")
    args = ap.parse_args(argv)
    base = load_rover()
    runs: dict[str, dict[str, Array]] = {}
    gen: dict[str, Array] = {}
    for plan_name, plan in PLANS.items():
        t, cmd = targets(plan)
        gen[plan_name] = generator(t, cmd)
        for name, motor in MODELS.items():
            cfg = replace(base, motor=replace(base.motor, **motor))
            runs.setdefault(name, {})[plan_name] = model(cfg, t, cmd)
    t_hard, _ = targets(PLANS["hard step"])
    k2, k01, k03 = (round(x * RATE) for x in (3.0, 1.1, 1.3))
    v_gen = speed(t_hard, gen["hard step"])
    print(
        f"{'model':76s} {'rms hard':>9s} {'rms steps':>9s} {'lost rad':>8s}"
        f" {'v +0.1 s':>8s} {'v +0.3 s':>8s}"
    )
    g_lost = 3.0 * 2.0 - float(gen["hard step"][k2].mean())
    print(
        f"{'independent generator (nominal build)':76s} {'':9s} {'':9s} {g_lost:8.3f}"
        f" {v_gen[k01]:8.2f} {v_gen[k03]:8.2f}"
    )
    for name, by_plan in runs.items():
        rms = {}
        for plan_name, phi in by_plan.items():
            tp, _ = targets(PLANS[plan_name])
            rms[plan_name] = float(
                np.sqrt(np.mean((speed(tp, phi) - speed(tp, gen[plan_name])) ** 2))
            )
        v = speed(t_hard, by_plan["hard step"])
        lost = 3.0 * 2.0 - float(by_plan["hard step"][k2].mean())
        print(
            f"{name:76s} {rms['hard step']:9.4f} {rms['steps']:9.4f} {lost:8.3f}"
            f" {v[k01]:8.2f} {v[k03]:8.2f}"
        )
    plot(args.out, t_hard, v_gen, {n: speed(t_hard, r["hard step"]) for n, r in runs.items()})
    return 0


def plot(out: str, t: Array, v_gen: Array, v: dict[str, Array]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 4.0))
    ax.plot(t, v_gen, "k", lw=2.2, label="independent generator (nominal build)")
    for name, vm in v.items():
        ax.plot(t, vm, lw=1.1, label=name)
    ax.set_xlim(0.9, 2.0)
    ax.set_xlabel("time (s); target 0 -> 3 rad/s at 1 s")
    ax.set_ylabel("driven wheels' mean speed (rad/s)")
    ax.set_title("The speed loop's answer to a hard step")
    ax.legend(fontsize=7, loc="lower right")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    print(f"wrote {out}")


if __name__ == "__main__":
    raise SystemExit(main())

"""Long physical checks of the loose-soil contact (issue 15); report in docs/validation/soil.md.

- Rig: the single-wheel rig (:func:`rover_env.sim.rig.measure_soil`) on each preset at the
  rover's wheel load, held at constant slip, settles to :func:`rover_env.soil.soil_forces` at
  the static sinkage of the slip it achieved (within 2 %), and halving its timestep changes
  the settled forces by less than 1 %. Curves of drawbar pull, torque and sinkage against
  slip per preset (model lines, rig points) as PNG.
- Parking: the rover with zero speed targets on a 10 degree loose slope: creep and jitter.
- Endurance: random driving on a rough soil terrain: no NaN, no MuJoCo warning.

Bounds of the parking check (derived, not fitted; docs/soil.md):

* creep speed < ``V_EPS``: at standstill the soil's slip state relaxes at the floor rate
  ``V_EPS / sigma_x``, so a held wheel the soil carries at slip ``s`` creeps at
  ``V_EPS |s|`` in steady state, and ``|s| < 1`` unless the wheel slides outright;
* no jitter: a contact that chatters between the forward and backward stress fields (the
  direction blend at rest, ``rover_env.soil.V_BLEND``) swings its F_x by up to twice the
  compaction resistance ``|F_x(s=0)|`` from one substep to the next. Nothing jitters when
  the substep-to-substep RMS change of every wheel's F_x stays below a tenth of its preset's
  compaction resistance, and that of the middle segment's velocity below a tenth of the
  creep bound ``V_EPS`` (a velocity jumping by more than the creep speed from one substep to
  the next is not creeping).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from rover_env.config import RoverConfig, TerrainConfig, from_dict, load_rover, load_terrain
from rover_env.sim.rig import measure_soil
from rover_env.sim.simulator import RoverSim
from rover_env.soil import V_EPS, load_soil, slip_and_direction, soil_forces, static_sinkage

PRESETS: tuple[str, ...] = ("regolith", "mars-sand", "dune-sand")
SLIPS: tuple[float, ...] = (-0.3, 0.0, 0.3, 0.6, 0.9)
LOAD = 27.0
"""The rover's wheel load (N): its weight over six wheels."""
RIG_TOL = 0.02
"""Rig steady state against soil_forces (issue 15)."""
DT_TOL = 0.01
"""Timestep halving: change of the settled forces (issue 15)."""
JITTER_FRACTION = 0.1
"""Jitter bounds as a fraction of the blend's swing (module docstring)."""


def _wheel() -> tuple[float, float]:
    g = load_rover().geometry
    return g.wheel_radius, g.wheel_width


# ---------------------------------------------------------------------------- rig


def rig_point(
    soil: str, slip: float, dt: float = 1e-3, duration: float = 6.0, load: float = LOAD
) -> dict[str, Any]:
    """The rig at one slip, with SOIL.md's steady state at the slip the servos achieved.

    Relative errors ``err_*`` are |rig - model| / |model| of the drawbar pull (carrier
    servo), the motor's torque (spin servo) and the sinkage.
    """
    r, b = _wheel()
    p = load_soil(soil)
    m = measure_soil(soil, slip, load=load, radius=r, width=b, duration=duration, dt=dt)
    s = float(slip_and_direction(m["v_x"], m["v_w"])[0])
    h = static_sinkage(load, r, b, p, slip=s)
    ref = soil_forces(m["v_x"], 0.0, m["v_w"], h, r, b, p)
    out: dict[str, Any] = dict(m)
    out.update(
        soil=soil,
        slip=slip,
        s=s,
        dt=dt,
        ref_F_x=float(ref.F_x),
        ref_T=float(ref.T),
        ref_sinkage=h,
        err_F_x=abs(m["F_servo"] - float(ref.F_x)) / abs(float(ref.F_x)),
        err_T=abs(m["T_servo"] - float(ref.T)) / abs(float(ref.T)),
        err_sinkage=abs(m["sinkage"] - h) / h,
        err_F_z=abs(m["F_z"] - load) / load,
    )
    return out


def rig_sweep(
    presets: Sequence[str] = PRESETS,
    slips: Sequence[float] = SLIPS,
    dts: Sequence[float] = (1e-3, 5e-4),
    duration: float = 6.0,
    progress: Callable[[str], None] | None = None,
) -> list[dict[str, Any]]:
    """:func:`rig_point` for every preset, slip and timestep."""
    rows = []
    for soil in presets:
        for slip in slips:
            for dt in dts:
                t0 = time.perf_counter()
                rows.append(rig_point(soil, slip, dt=dt, duration=duration))
                if progress is not None:
                    progress(
                        f"rig {soil} s={slip:+.1f} dt={dt * 1e3:g} ms: {time.perf_counter() - t0:.0f} s"
                    )
    return rows


def timestep_change(rows: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per preset and slip, relative change of the settled pull, torque and sinkage from
    the coarsest to the finest timestep of ``rows``."""
    out = []
    keys = sorted({(r["soil"], r["slip"]) for r in rows}, key=lambda k: (k[0], k[1]))
    for soil, slip in keys:
        sel = sorted(
            (r for r in rows if r["soil"] == soil and r["slip"] == slip), key=lambda r: -r["dt"]
        )
        if len(sel) < 2:
            continue
        a, z = sel[0], sel[-1]
        out.append(
            {
                "soil": soil,
                "slip": slip,
                "dt": (a["dt"], z["dt"]),
                "d_F_x": abs(a["F_servo"] - z["F_servo"]) / abs(z["F_servo"]),
                "d_T": abs(a["T_servo"] - z["T_servo"]) / abs(z["T_servo"]),
                "d_sinkage": abs(a["sinkage"] - z["sinkage"]) / z["sinkage"],
            }
        )
    return out


RIG_COLUMNS = (
    "soil", "slip", "dt", "s", "v_x", "v_w", "F_servo", "F_x", "F_z", "T_servo", "T",
    "sinkage", "depth", "final_depth", "ref_F_x", "ref_T", "ref_sinkage",
    "err_F_x", "err_T", "err_sinkage", "err_F_z",
)  # fmt: skip


def write_rows(rows: Sequence[dict[str, Any]], path: Path) -> None:
    """The rig points as CSV (the data behind the report's tables and curves)."""
    lines = [",".join(RIG_COLUMNS)]
    for r in rows:
        lines.append(",".join(str(r[k]) if k == "soil" else repr(float(r[k])) for k in RIG_COLUMNS))
    path.write_text("\n".join(lines) + "\n")


def model_curves(soil: str, slips: np.ndarray, load: float = LOAD) -> dict[str, np.ndarray]:
    """SOIL.md's steady state against slip: pull, torque, sinkage (at v_x 0.1 m/s)."""
    r, b = _wheel()
    p = load_soil(soil)
    fx, tq, hs = [], [], []
    for s in slips:
        h = static_sinkage(load, r, b, p, slip=float(s))
        v_w = 0.1 / (1.0 - s) if s >= 0 else 0.1 * (1.0 + s)
        f = soil_forces(0.1, 0.0, v_w, h, r, b, p)
        fx.append(float(f.F_x))
        tq.append(float(f.T))
        hs.append(h)
    return {"s": slips, "F_x": np.array(fx), "T": np.array(tq), "sinkage": np.array(hs)}


def plot_curves(rows: Sequence[dict[str, Any]], out: Path) -> list[Path]:
    """One PNG per preset: drawbar pull, torque and sinkage against slip."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    paths = []
    grid = np.linspace(-0.3, 0.9, 61)
    dt0 = max(r["dt"] for r in rows)
    for soil in dict.fromkeys(r["soil"] for r in rows):
        model = model_curves(soil, grid)
        pts = [r for r in rows if r["soil"] == soil and r["dt"] == dt0]
        fig, axes = plt.subplots(1, 3, figsize=(13, 4))
        panels = (
            ("F_x", "F_servo", "drawbar pull F_x [N]", 1.0),
            ("T", "T_servo", "torque T [N m]", 1.0),
            ("sinkage", "sinkage", "sinkage [mm]", 1e3),
        )
        for ax, (mk, rk, label, scale) in zip(axes, panels, strict=True):
            ax.plot(model["s"], model[mk] * scale, "C0-", label="soil_forces at static sinkage")
            ax.plot(
                [r["s"] for r in pts],
                [r[rk] * scale for r in pts],
                "C3o",
                label=f"rig ({dt0 * 1e3:g} ms, settled)",
            )
            if mk == "sinkage":
                ax.plot(
                    [r["s"] for r in pts],
                    [r["depth"] * scale for r in pts],
                    "C3x",
                    label="rig: depth below virgin surface (dug hole + sinkage)",
                )
            ax.axhline(0, color="k", lw=0.5)
            ax.set_xlabel("slip s (Wong: > 0 driving)")
            ax.set_ylabel(label)
            ax.grid(True, alpha=0.3)
        axes[0].legend(fontsize=8, loc="lower right")
        axes[2].legend(fontsize=8, loc="best")
        fig.suptitle(f"{soil}: single wheel r 0.085 m, b 0.05 m, {LOAD:g} N")
        fig.tight_layout()
        p = out / f"rig-{soil}.png"
        fig.savefig(p, dpi=110)
        plt.close(fig)
        paths.append(p)
    return paths


# ---------------------------------------------------------------------------- parking


def slope_terrain(soil: str, slope_deg: float = 10.0) -> TerrainConfig:
    """configs/terrain/slope10.yaml with loose soil over the whole ground."""
    t = load_terrain("slope10")
    return dataclasses.replace(
        t, name=f"slope{slope_deg:g}-{soil}", slope_deg=(slope_deg, 0.0), soil=soil
    )


def compaction_resistance(soil: str, load: float = LOAD) -> float:
    """|F_x| of a wheel rolling at zero slip at its static sinkage (N)."""
    r, b = _wheel()
    p = load_soil(soil)
    return abs(float(soil_forces(0.1, 0.0, 0.1, static_sinkage(load, r, b, p), r, b, p).F_x))


def parked(
    soil: str,
    duration: float = 20.0,
    window: float = 10.0,
    backend: str = "plugin",
    rover: RoverConfig | str = "proto_explorer",
) -> dict[str, Any]:
    """The rover on a 10 degree loose slope, zero speed targets, for ``duration`` s.

    Samples every substep over the last ``window`` s: creep (displacement of the middle
    segment), its speed, the middle segment's velocity (RMS, and RMS of its change from one
    substep to the next) and each wheel's F_x (standard deviation about its mean, and RMS
    substep-to-substep change).
    """
    sim = RoverSim(rover, terrain=slope_terrain(soil), backend=backend)  # settles 0.5 s at rest
    p_start = sim.segment_truth().pos[1].copy()
    n_win = round(window / sim.dt)
    sim.step(round((duration - window) / sim.dt))
    p_win = sim.segment_truth().pos[1].copy()
    vel = np.empty((n_win, 3))
    fx = np.empty((n_win, 6))
    sink = np.empty((n_win, 6))
    for k in range(n_win):
        sim.step(1)
        vel[k] = sim.segment_truth().lin_vel[1]
        w = sim.wheel_truth()
        fx[k] = w.F_x
        sink[k] = w.sinkage
    p_end = sim.segment_truth().pos[1]
    return {
        "soil": soil,
        "duration": duration,
        "window": window,
        "creep": float(np.linalg.norm(p_end - p_start)),
        "creep_window": float(np.linalg.norm(p_end - p_win)),
        "creep_speed": float(np.linalg.norm(p_end - p_win)) / window,
        "vel_rms": float(np.sqrt(np.mean(np.sum(vel**2, axis=1)))),
        "vel_std": float(np.sqrt(np.mean(np.sum((vel - vel.mean(axis=0)) ** 2, axis=1)))),
        "vel_step_rms": float(np.sqrt(np.mean(np.sum(np.diff(vel, axis=0) ** 2, axis=1)))),
        "fx_mean": fx.mean(axis=0),
        "fx_std": fx.std(axis=0),
        "fx_step_rms": np.sqrt(np.mean(np.diff(fx, axis=0) ** 2, axis=0)),
        "sinkage": sink[-1],
        "resistance": compaction_resistance(soil),
    }


def parked_verdict(r: dict[str, Any]) -> dict[str, bool]:
    """The parking bounds of the module docstring."""
    return {
        "creep": r["creep_speed"] < V_EPS,
        "vel_jitter": r["vel_step_rms"] < JITTER_FRACTION * V_EPS,
        "fx_jitter": bool(np.all(r["fx_step_rms"] < JITTER_FRACTION * r["resistance"])),
    }


# ---------------------------------------------------------------------------- endurance

SOIL_ROUGH: dict[str, Any] = {
    "name": "rough-soil",
    "size": [20.0, 20.0],
    "resolution": 0.05,
    "slope_deg": [3.0, 1.0],
    "roughness": {"rms": 0.025, "correlation_length": 0.4, "modes": 32, "seed": 7},
    "soil": "regolith",
    "patches": [
        {"name": "dune", "center": [2.0, 0.0], "size": [4.0, 4.0], "soil": "dune-sand"},
        {"name": "mars", "center": [-2.5, 0.0], "size": [3.0, 4.0], "soil": "mars-sand"},
        {"name": "rock-slab", "center": [0.0, 3.5], "size": [3.0, 2.0], "mu_x": 0.6, "mu_y": 0.6},
    ],
    "obstacles": [
        {"name": "rock1", "pos": [4.5, -1.5, 0.1], "size": [0.15, 0.2, 0.1], "yaw_deg": 20},
        {"name": "rock2", "pos": [-4.0, 3.0, 0.15], "size": [0.25, 0.15, 0.1], "yaw_deg": -35},
    ],
}
"""The rough scene's relief and rocks on regolith, with dune-sand, mars-sand and hard patches
around the start (the rover starts with its front on the dune sand, its rear on mars-sand)."""


def soil_endurance(
    duration: float = 300.0,
    seed: int = 0,
    hold: tuple[float, float] = (2.0, 5.0),
    backend: str = "plugin",
    rover: RoverConfig | str = "proto_explorer",
) -> dict[str, Any]:
    """Random speed targets held for random spells on the rough soil scene.

    Raises :class:`rover_env.sim.index.SimulationError` on any MuJoCo warning or NaN.
    Flips and arena exits are counted and the rover put back.
    """
    rng = np.random.default_rng(seed)
    sim = RoverSim(rover, terrain=from_dict(TerrainConfig, SOIL_ROUGH), backend=backend)
    half = np.array(sim.terrain_cfg.size) / 2 - 1.0
    lim = sim.cfg.motor.max_wheel_speed
    chunk = round(0.05 / sim.dt)
    flips = exits = 0
    max_sink = np.zeros(6)
    on_soil = np.zeros(4)  # substep chunks on hard ground, regolith, mars, dune (by soil index)
    t = 0.0
    while t < duration - 1e-9:
        spell = min(float(rng.uniform(*hold)), duration - t)
        sim.set_speed_targets(rng.uniform(-lim, lim, 4))
        for _ in range(max(1, round(spell / (chunk * sim.dt)))):
            sim.step(chunk)
            w = sim.wheel_truth()
            max_sink = np.maximum(max_sink, w.sinkage)
            np.add.at(on_soil, np.minimum(w.soil, 3), 1)
        t += spell
        pos = sim.segment_truth().pos[1]
        if sim.flipped():
            flips += 1
            sim.reset(x=0.0, y=0.0, yaw=float(rng.uniform(-np.pi, np.pi)))
        elif np.any(np.abs(pos[:2]) > half):
            exits += 1
            sim.reset(x=0.0, y=0.0, yaw=float(rng.uniform(-np.pi, np.pi)))
    soils = ("hard", *(s.name for s in sim.terrain.soils))
    share = on_soil[: len(soils)] / on_soil.sum()
    return {
        "duration": duration,
        "seed": seed,
        "flips": flips,
        "exits": exits,
        "max_sinkage": max_sink,
        "share": dict(zip(soils, share.tolist(), strict=True)),
        "finite": bool(np.all(np.isfinite(sim.data.qpos)) and np.all(np.isfinite(sim.data.qvel))),
    }


# ---------------------------------------------------------------------------- report


def _pf(ok: bool) -> str:
    return "PASS" if ok else "FAIL"


def run(out_dir: str | Path, quick: bool = False, figures: str | Path | None = None) -> Path:
    """All soil checks; writes ``soil.md`` in ``out_dir`` and the rig PNGs beside it (or in
    ``figures``). ``quick``: one slip per preset and short runs (a smoke test)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    fig_dir = Path(figures) if figures is not None else out
    t0 = time.perf_counter()
    slips = (0.3,) if quick else SLIPS
    rows = rig_sweep(slips=slips, duration=2.5 if quick else 6.0, progress=print)
    t1 = time.perf_counter()
    pngs = plot_curves(rows, fig_dir)
    write_rows(rows, fig_dir / "rig.csv")
    lines = _rig_lines(rows, quick)
    lines += ["", "## Curves", ""]
    for p in pngs:
        lines.append(f"![{p.stem}]({p.relative_to(out) if p.is_relative_to(out) else p})")
    parked, parking_wall = _parked_lines(quick, t1 - t0)
    lines += parked + _endurance_lines(quick, parking_wall)
    report = out / "soil.md"
    report.write_text("\n".join(lines) + "\n")
    return report


def _rig_lines(rows: list[dict[str, Any]], quick: bool) -> list[str]:
    """The rig against SOIL.md's steady state, and the timestep halving, as markdown."""
    dtc = timestep_change(rows)
    dt0 = max(r["dt"] for r in rows)
    lines = [
        "# Loose-soil validation (`rover-env validate`, issue 15)",
        "",
        "The model and its design: docs/soil.md. Rover wheel r 0.085 m, b 0.05 m, load"
        f" {LOAD:g} N (the rover's weight over six wheels).",
        "",
        "## Single-wheel rig against SOIL.md's steady state",
        "",
        f"`rover_env.sim.rig.measure_soil` (numpy tire layer in a MuJoCo rig; carrier at 0.1 m/s,"
        f" wheel rate set for the slip), {rows[0]['dt'] * 1e3:g} ms, averaged over the last third"
        f" of {2.5 if quick else 6.0:g} s. Model: `soil_forces` at `static_sinkage` for the slip"
        " the servos achieved. Drawbar pull from the carrier's servo, torque from the spin servo.",
        "",
        "| preset | slip set | slip achieved | pull rig / model [N] | torque rig / model [N m] |"
        " sinkage rig / model [mm] | depth incl. dug hole [mm] | worst rel. error |",
        "|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    worst: dict[str, float] = {}
    for r in rows:
        if r["dt"] != dt0:
            continue
        e = max(r["err_F_x"], r["err_T"], r["err_sinkage"], r["err_F_z"])
        worst[r["soil"]] = max(worst.get(r["soil"], 0.0), e)
        lines.append(
            f"| {r['soil']} | {r['slip']:+.1f} | {r['s']:+.4f} | {r['F_servo']:+.3f} /"
            f" {r['ref_F_x']:+.3f} | {r['T_servo']:+.4f} / {r['ref_T']:+.4f} |"
            f" {r['sinkage'] * 1e3:.2f} / {r['ref_sinkage'] * 1e3:.2f} | {r['depth'] * 1e3:.2f} |"
            f" {100 * e:.2f} % |"
        )
    lines += ["", "Worst relative error (pull, torque, sinkage, F_z) per preset:", ""]
    for soil, e in worst.items():
        lines.append(f"- {soil}: {100 * e:.2f} % ({_pf(e < RIG_TOL)}: < {100 * RIG_TOL:g} %)")
    lines += [
        "",
        "## Timestep halving on the rig",
        "",
        "| preset | slip | pull change | torque change | sinkage change |",
        "|---|---:|---:|---:|---:|",
    ]
    worst_dt: dict[str, float] = {}
    for c in dtc:
        e = max(c["d_F_x"], c["d_T"], c["d_sinkage"])
        worst_dt[c["soil"]] = max(worst_dt.get(c["soil"], 0.0), e)
        lines.append(
            f"| {c['soil']} | {c['slip']:+.1f} | {100 * c['d_F_x']:.1e} % | {100 * c['d_T']:.1e} % |"
            f" {100 * c['d_sinkage']:.1e} % |"
        )
    lines += [
        "",
        "The settled state is algebraic (servo errors set by force / gain, the relaxation and"
        " digging states integrated exactly), so the timestep only enters through the"
        " transient: the changes are of the order of 1e-6.",
    ]
    if dtc:
        a, z = dtc[0]["dt"]
        lines += ["", f"Largest change from {a * 1e3:g} ms to {z * 1e3:g} ms per preset:", ""]
        for soil, e in worst_dt.items():
            lines.append(f"- {soil}: {100 * e:.1e} % ({_pf(e < DT_TOL)}: < {100 * DT_TOL:g} %)")
    return lines


def _parked_lines(quick: bool, rig_wall: float) -> tuple[list[str], float]:
    """Parked on a 10 degree loose slope (creep and jitter bounds) as markdown, and its wall
    time."""
    lines = [
        "",
        f"Rig wall time {rig_wall:.0f} s.",
        "",
        "## Parked on a 10 degree loose slope",
        "",
        "configs/terrain/slope10.yaml with `soil:` over the whole ground; zero speed targets from"
        f" rest (after the simulator's 0.5 s settling) for {5 if quick else 20} s, compiled plugin;"
        f" sampled on every substep over the last {2 if quick else 10} s. Bounds (derived in the"
        " module docstring of rover_env/experiments/soil_validation.py and in docs/soil.md):"
        f" creep speed < v_eps = {V_EPS * 1e3:g} mm/s; jitter, the RMS substep-to-substep change,"
        f" < {JITTER_FRACTION:g} v_eps (the creep bound) for the middle segment's velocity and"
        f" < {JITTER_FRACTION:g}"
        " x the preset's compaction resistance |F_x(s=0)| for every wheel's F_x.",
        "",
    ]
    t2 = time.perf_counter()
    for soil in ("regolith", "dune-sand"):
        r = parked(soil, duration=5.0 if quick else 20.0, window=2.0 if quick else 10.0)
        v = parked_verdict(r)
        fmt = ", ".join(f"{x:+.3f}" for x in r["fx_mean"])
        lines += [
            f"### {soil}",
            "",
            f"- creep: {r['creep'] * 1e3:.2f} mm in {r['duration']:g} s; {r['creep_window'] * 1e3:.2f} mm"
            f" over the last {r['window']:g} s = {r['creep_speed'] * 1e3:.3f} mm/s"
            f" ({_pf(v['creep'])}: < {V_EPS * 1e3:g} mm/s)",
            f"- middle segment velocity over the last {r['window']:g} s: RMS {r['vel_rms'] * 1e3:.4f}"
            f" mm/s, about its mean {r['vel_std'] * 1e3:.4f} mm/s; substep-to-substep RMS change"
            f" {r['vel_step_rms'] * 1e3:.4f} mm/s ({_pf(v['vel_jitter'])}: < {JITTER_FRACTION * V_EPS * 1e3:g} mm/s)",
            f"- wheels' F_x (1L 1R 2L 2R 3L 3R) mean {fmt} N; standard deviation "
            + ", ".join(f"{x:.4f}" for x in r["fx_std"])
            + " N; substep-to-substep RMS change "
            + ", ".join(f"{x:.4f}" for x in r["fx_step_rms"])
            + f" N ({_pf(v['fx_jitter'])}: < {JITTER_FRACTION:g} x {r['resistance']:.3f} N)",
            "- sinkage at the end (mm): " + ", ".join(f"{x * 1e3:.1f}" for x in r["sinkage"]),
            "- no MuJoCo warning, no NaN (the simulator raises on either)",
            "",
        ]
    lines += [
        "Sampled on every substep on purpose: a period-2 chatter is invisible at every 10th. With"
        " the direction blend a tanh over v_eps (before commit 0ab7405) this check failed: the"
        " free wheels' F_x flipped by +-0.42 N (regolith) every substep; docs/soil.md, 3.2.",
        "",
    ]
    return lines, time.perf_counter() - t2


def _endurance_lines(quick: bool, parking_wall: float) -> list[str]:
    """Random driving on rough soil (no warning, no NaN), as markdown."""
    t3 = time.perf_counter()
    end = soil_endurance(20.0 if quick else 300.0)
    t4 = time.perf_counter()
    return [
        f"Parking wall time {parking_wall:.0f} s.",
        "",
        "## Random driving on rough soil",
        "",
        f"{end['duration']:g} s of random speed targets (uniform over the motors' range, each held"
        f" 2-5 s, seed {end['seed']}) on the rough scene's relief and rocks with regolith over the"
        " ground and dune-sand, mars-sand and hard patches (SOIL_ROUGH in"
        " rover_env/experiments/soil_validation.py), compiled plugin: no MuJoCo warning, no NaN"
        f" ({_pf(end['finite'])}; the simulator raises on either). Flips reset {end['flips']},"
        f" arena exits reset {end['exits']}. Each driven wheel gets its own random target, so"
        " the wheels mostly fight each other: a stress test of extreme slip (S = ±1) and"
        " digging more than a drive.",
        "- time per ground: "
        + ", ".join(f"{k} {100 * v:.0f} %" for k, v in end["share"].items())
        + " (wheel-samples)",
        "- max sinkage per wheel (mm): " + ", ".join(f"{x * 1e3:.1f}" for x in end["max_sinkage"]),
        f"- wall time {t4 - t3:.0f} s.",
    ]

"""The paper's simulation (section 7, Figs. 9 and 10): from rest, left/right speed targets with turns.

The paper gives no numbers for its targets ("appropriate values"); ours accelerate straight,
turn left, straighten, turn right, at targets well inside the motors' range.

``terrain`` runs the same drive on another ground, e.g. loose soil
(``configs/terrain/paper-sand.yaml``, issue 15): the same open-loop targets, and on soil a
third figure, the sinkage of every wheel (sinkage.png).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from rover_env.config import DRIVEN_WHEELS, WHEELS, TerrainConfig, load_terrain
from rover_env.logs import write_log
from rover_env.sim.recorder import DriveRecorder, run_drive
from rover_env.sim.simulator import RoverSim


@dataclass(frozen=True)
class Phase:
    name: str
    start: float
    end: float
    left: float
    right: float


PHASES = (
    Phase("straight", 0.0, 4.0, 2.5, 2.5),
    Phase("left turn", 4.0, 16.0, 1.5, 3.0),
    Phase("straight", 16.0, 20.0, 2.5, 2.5),
    Phase("right turn", 20.0, 32.0, 3.0, 1.5),
)


def schedule(t: float) -> np.ndarray:
    """Speed targets (rad/s) for 1L 1R 2L 2R at time t."""
    for p in PHASES:
        if p.start <= t < p.end:
            return np.array([p.left, p.right, p.left, p.right])
    last = PHASES[-1]
    return np.array([last.left, last.right, last.left, last.right])


def _plots(rec: DriveRecorder, out: Path, ground: str = "") -> None:
    tr = rec.truth()
    t = tr["t"]
    on = f" on {ground}" if ground else ""
    fig, ax = plt.subplots(figsize=(6, 6))
    for i, name in enumerate(("segment 1", "segment 2", "segment 3")):
        ax.plot(tr["seg_pos"][:, i, 0], tr["seg_pos"][:, i, 1], label=name)
    ax.plot(*tr["seg_pos"][0, 1, :2], "ko", label="start")
    ax.set_aspect("equal")
    xy = tr["seg_pos"][:, :, :2].reshape(-1, 2)
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    if np.min(hi - lo) < 0.5:  # a short straight drive: give the equal axes some extent
        mid, half = 0.5 * (lo + hi), max(0.55 * float(np.max(hi - lo)), 0.5)
        ax.set_xlim(mid[0] - half, mid[0] + half)
        ax.set_ylim(mid[1] - half, mid[1] + half)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(f"Motion trace of the rover{on} (simulation, cf. paper Fig. 9)")
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / "trajectory.png", dpi=120)
    plt.close(fig)

    fig, axes = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    for i, w in enumerate(DRIVEN_WHEELS):
        ax = axes[0] if w.endswith("L") else axes[1]
        ax.plot(t, tr["S"][:, i], label=w)
    for ax, side in zip(axes, ("left", "right"), strict=True):
        for p in PHASES:
            if "turn" in p.name:
                ax.axvspan(p.start, p.end, color="0.9", zorder=0)
        ax.axhline(0, color="k", lw=0.5)
        ax.set_ylabel(f"slip ratio S ({side})")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right")
    axes[0].set_title(
        f"Slip ratio of the driven wheels{on} (S < 0 spinning, S > 0 skidding; turns shaded)"
    )
    axes[1].set_xlabel("t [s]")
    fig.tight_layout()
    fig.savefig(out / "slip.png", dpi=120)
    plt.close(fig)
    if np.any(tr["sinkage"] > 0):
        _sinkage_plot(t, tr["sinkage"], out, on)


def _sinkage_plot(t: np.ndarray, sinkage: np.ndarray, out: Path, on: str) -> None:
    """Sinkage of every wheel (mm) below the undisturbed soil surface (a follower in a rut
    counts the rut; a wheel that dug counts from the bottom of its hole)."""
    fig, axes = plt.subplots(2, 1, figsize=(8, 6), sharex=True, sharey=True)
    for i, w in enumerate(WHEELS):
        ax = axes[0] if w.endswith("L") else axes[1]
        ax.plot(t, 1e3 * sinkage[:, i], label=w)
    for ax, side in zip(axes, ("left", "right"), strict=True):
        for p in PHASES:
            if "turn" in p.name:
                ax.axvspan(p.start, p.end, color="0.9", zorder=0)
        ax.set_ylabel(f"sinkage [mm] ({side})")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right")
    axes[0].set_title(f"Sinkage of the wheels{on} (turns shaded)")
    axes[1].set_xlabel("t [s]")
    fig.tight_layout()
    fig.savefig(out / "sinkage.png", dpi=120)
    plt.close(fig)


HARD_NOTE = (
    "What it shows, as in the paper's Figs. 7 and 10: in a turn the outer driven wheels",
    "spin (negative slip) and the inner ones skid (positive slip); skid steering needs",
    "that slip. Driving straight, the front and middle wheels slip slightly against each",
    "other because they carry different loads and so roll on different rolling radii (r_e = d − δ/3).",
)
SOIL_NOTE = (
    "On loose soil (docs/soil.md) the same open-loop targets need slip for traction: the",
    "driven wheels spin (S < 0) even driving straight, the outer wheels of a turn spin more,",
    "and the wheels sink, the followers deeper in the leaders' ruts. Compare with the hard",
    "ground's run (`rover-env paper-sim` without --terrain): there |S| is 0.004 driving",
    "straight and about 0.11-0.16 in the turns.",
)


def summarise(rec: DriveRecorder, ground: str = "") -> tuple[str, dict[str, np.ndarray]]:
    """Mean slip ratio per driven wheel in the settled part of each phase (and sinkage)."""
    tr = rec.truth()
    t = tr["t"]
    t_end = float(t[-1])
    means: dict[str, np.ndarray] = {}
    rows = []
    sink_rows = []
    for k, p in enumerate(PHASES):
        sel = (t >= p.start + 2.0) & (t < p.end)
        if not sel.any():  # a shortened drive
            continue
        m = tr["S"][sel][:, :4].mean(axis=0)
        means[f"{k}:{p.name}"] = m
        rows.append(
            f"| {p.name} ({p.start:g}-{p.end:g} s) | {p.left:g} / {p.right:g} | "
            + " | ".join(f"{v:+.3f}" for v in m)
            + f" | {tr['yaw_rate'][sel][:, 1].mean():+.3f} |"
        )
        sink_rows.append(
            f"| {p.name} ({p.start:g}-{p.end:g} s) | "
            + " | ".join(f"{1e3 * v:.1f}" for v in tr["sinkage"][sel].mean(axis=0))
            + " |"
        )
    dist = float(np.sum(np.linalg.norm(np.diff(tr["seg_pos"][:, 1, :2], axis=0), axis=1)))
    sinkage: list[str] = []
    if np.any(tr["sinkage"] > 0):
        sinkage = [
            "",
            "Mean sinkage of each wheel (mm) below the undisturbed soil surface, same phases (the",
            "middle and rear wheels run in the ruts of the wheels ahead, so theirs counts the rut):",
            "",
            "| phase | " + " | ".join(WHEELS) + " |",
            "|---|" + "---|" * len(WHEELS),
            *sink_rows,
            "",
            "Largest sinkage (mm): "
            + ", ".join(
                f"{w} {1e3 * v:.1f}" for w, v in zip(WHEELS, tr["sinkage"].max(axis=0), strict=True)
            )
            + ".",
        ]
    on = f" on {ground}" if ground else ""
    text = "\n".join(
        [
            f"# Paper simulation (section 7){on}: summary",
            "",
            "Mean true slip ratio of each driven wheel over each phase (first 2 s of a phase left out),",
            "and the middle segment's yaw rate. S < 0: the wheel spins (v_w > v_x); S > 0: it skids.",
            "",
            "| phase | targets L / R [rad/s] | 1L | 1R | 2L | 2R | yaw rate [rad/s] |",
            "|---|---|---|---|---|---|---|",
            *rows,
            *sinkage,
            "",
            f"Distance travelled by segment 2: {dist:.2f} m in {t_end:.0f} s.",
            "",
            *(SOIL_NOTE if sinkage else HARD_NOTE),
        ]
    )
    return text + "\n", means


def run(
    out_dir: str | Path,
    progress: bool = True,
    terrain: str | Path | TerrainConfig | None = None,
    duration: float | None = None,
    backend: str = "numpy",
) -> Path:
    """Run the drive and write trajectory.png, slip.png, drive.csv/.yaml and summary.md.

    ``terrain``: a shipped terrain name, YAML path or configuration (default: flat ground,
    the paper's); on soil sinkage.png is written too. ``duration`` shortens the drive (s;
    default the whole schedule). ``backend``: the simulator's (the results are the same).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    ground = (
        None
        if terrain is None
        else terrain
        if isinstance(terrain, TerrainConfig)
        else load_terrain(terrain)
    )
    sim = RoverSim(terrain=ground or "flat", backend=backend)
    duration = PHASES[-1].end if duration is None else duration
    rec = run_drive(sim, schedule, duration, sample_rate_hz=50.0, progress=progress)
    name = "flat" if ground is None else ground.name
    log = rec.to_log(
        "proto_explorer",
        terrain=name,
        notes="rover-env paper-sim: the paper's section 7 drive"
        + ("" if ground is None else f" on terrain {name}"),
        pose_rate_hz=None,
    )
    write_log(log, out / "drive.csv", overwrite=True)
    label = "" if ground is None else _ground_label(ground)
    _plots(rec, out, label)
    text, _ = summarise(rec, label)
    (out / "summary.md").write_text(text)
    return out


def _ground_label(t: TerrainConfig) -> str:
    """``name`` or ``name (soil preset)`` for titles."""
    return f"{t.name} ({t.soil})" if t.soil else t.name

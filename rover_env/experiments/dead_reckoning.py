"""The paper's flat-ground drive (section 6): dead reckoning and slip from wheel/joint angles.

Three 50 s drives from rest on flat ground at a cruise target of 2 rad/s on all driven
wheels, weaving by a sinusoidal left/right target difference (none, mild, strong). Each is
recorded as a SPEC §6 log, read through ideal and through default (1998-like) sensors, and
run through the kinematic estimator of SPEC §2. Reported: the end-point error of the
free-wheel dead reckoning along and across the direction of travel, in % of the distance
travelled (the paper: about 1 % along, more across, growing with weaving), and the estimated
vs true slip ratio of the driven wheels (the paper's Fig. 7 counterpart).

Each estimate is made with two rolling-radius models: the estimator's default (one radius,
d minus the mean static deflection) and per-axle loaded radii (:func:`axle_load_radii`),
because the simulated wheels roll on their loaded radius and the axle loads differ.
"""

from __future__ import annotations

import argparse
import csv
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from rover_env.config import DRIVEN_WHEELS, RoverConfig, load_rover
from rover_env.estimation.estimator import (
    FLAG_FREE_WHEELS,
    FLAG_SLOW_WHEEL,
    FLAG_STANDSTILL,
    FLAG_WARMUP,
    EstimatorConfig,
    SlipEstimate,
    axle_load_radii,
    estimate_log,
)
from rover_env.estimation.sensors import SensorConfig, apply_sensors
from rover_env.logs import DriveLog

Array = npt.NDArray[np.float64]

CRUISE = 2.0
"""Speed target (rad/s) of every driven wheel: ~0.12 m/s, 6 m in 50 s."""
WEAVE_PERIOD = 10.0
"""Period (s) of the left/right target difference."""


@dataclass(frozen=True)
class Weave:
    name: str
    amplitude: float
    """Half the right-minus-left target difference at its peak (rad/s)."""


WEAVES = (Weave("none", 0.0), Weave("mild", 0.25), Weave("strong", 0.75))
SENSORS = {"noise-free": SensorConfig.ideal(), "default noise": SensorConfig()}
RADIUS_MODELS = ("uniform", "axle-load")


def schedule_for(weave: Weave) -> Callable[[float], Array]:
    """Targets 1L 1R 2L 2R: cruise -/+ a sine, so the weave starts smoothly from rest."""

    def schedule(t: float) -> Array:
        dv = weave.amplitude * math.sin(2 * math.pi * t / WEAVE_PERIOD)
        return np.array([CRUISE - dv, CRUISE + dv, CRUISE - dv, CRUISE + dv])

    return schedule


def estimator_config(model: str, cfg: RoverConfig) -> EstimatorConfig:
    if model == "uniform":
        return EstimatorConfig()
    if model == "axle-load":
        return EstimatorConfig(rolling_radius=axle_load_radii(cfg))
    raise ValueError(f"unknown radius model {model!r}")


def endpoint_error(true_xy: Array, est_xy: Array) -> tuple[float, float, float]:
    """(along %, across %, distance m): end-point error in the frame of the true travel.

    The direction of travel is the true start-to-end chord; across is positive to its left.
    Percentages are of the distance actually travelled (true path length).
    """
    dist = float(np.sum(np.linalg.norm(np.diff(true_xy, axis=0), axis=1)))
    chord = true_xy[-1] - true_xy[0]
    u = chord / np.linalg.norm(chord)
    n = np.array([-u[1], u[0]])
    err = est_xy[-1] - true_xy[-1]
    return 100 * float(err @ u) / dist, 100 * float(err @ n) / dist, dist


def slip_stats(est: SlipEstimate, true_s: Array) -> dict[str, Any]:
    """Per driven wheel: RMS error over reliable samples, share unreliable, flag counts."""
    ok = est.reliable
    err = est.slip_ratio - true_s
    rms = np.array(
        [
            math.sqrt(float(np.mean(err[ok[:, i], i] ** 2))) if ok[:, i].any() else math.nan
            for i in range(4)
        ]
    )
    rms_all = np.sqrt(np.mean(err**2, axis=0))
    return {
        "rms": rms,
        "rms_all": rms_all,
        "unreliable": 1.0 - ok.mean(axis=0),
        "err2": np.where(ok, err**2, np.nan),
        "flag_share": {
            name: float(np.mean(np.any(est.flags & bit, axis=1)))
            for name, bit in (
                ("warm-up", FLAG_WARMUP),
                ("standstill", FLAG_STANDSTILL),
                ("free wheels", FLAG_FREE_WHEELS),
                ("slow wheel", FLAG_SLOW_WHEEL),
            )
        },
    }


def turn_tendency(est: SlipEstimate, true_s: Array, min_yaw_rate: float = 0.02) -> list[Array]:
    """Mean S of the outer and inner wheel of segments 1 and 2 while they turn (paper Fig. 7).

    Returns, per segment, [outer estimated, outer true, inner estimated, inner true] over the
    reliable samples where the segment's estimated yaw rate exceeds ``min_yaw_rate``.
    """
    out: list[Array] = []
    for seg in (0, 1):
        yaw = est.seg_yaw_rate[:, seg]
        left, right = 2 * seg, 2 * seg + 1
        ok = est.reliable[:, left] & est.reliable[:, right]
        lt, rt = ok & (yaw > min_yaw_rate), ok & (yaw < -min_yaw_rate)
        vals = []
        for s in (est.slip_ratio, true_s):
            vals.append(np.concatenate([s[lt, right], s[rt, left]]))  # outer
        for s in (est.slip_ratio, true_s):
            vals.append(np.concatenate([s[lt, left], s[rt, right]]))  # inner
        out.append(np.array([float(np.mean(v)) if v.size else math.nan for v in vals]))
    return out


@dataclass
class DriveResult:
    weave: Weave
    log: DriveLog
    truth: dict[str, Array]
    logs: dict[str, DriveLog]
    estimates: dict[tuple[str, str], SlipEstimate]


def _simulate(cfg: RoverConfig, weave: Weave, duration: float, progress: bool) -> DriveResult:
    from rover_env.sim.recorder import run_drive
    from rover_env.sim.simulator import RoverSim

    sim = RoverSim(cfg, "flat")
    rec = run_drive(sim, schedule_for(weave), duration, sample_rate_hz=50.0, progress=progress)
    log = rec.to_log(cfg.name, terrain="flat", notes=f"dead reckoning, weave {weave.name}")
    return DriveResult(weave, log, rec.truth(), {}, {})


def _plot_trajectories(results: list[DriveResult], out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(results), 1, figsize=(9, 3.2 * len(results)))
    for ax, r in zip(np.atleast_1d(axes), results, strict=True):
        tp = r.truth["pose"]
        ax.plot(tp[:, 0], tp[:, 1], "k-", lw=2, label="true (segment 3)")
        styles = {
            ("noise-free", "uniform"): "C0--",
            ("default noise", "uniform"): "C1:",
            ("noise-free", "axle-load"): "C2-.",
        }
        for key, style in styles.items():
            p = r.estimates[key].pose
            ax.plot(p[:, 0], p[:, 1], style, label=f"dead reckoning, {key[0]}, {key[1]} radius")
        ax.plot(0, 0, "ko")
        ax.set_title(f"weave: {r.weave.name} (±{r.weave.amplitude} rad/s)")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.grid(True, alpha=0.3)
        ax.set_aspect("equal", adjustable="datalim")
        ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    fig.savefig(out / "trajectories.png", dpi=110)
    plt.close(fig)


def _plot_slip(r: DriveResult, out: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = r.log.t
    fig, axes = plt.subplots(4, 1, figsize=(9, 9), sharex=True)
    for i, (ax, w) in enumerate(zip(axes, DRIVEN_WHEELS, strict=True)):
        ax.plot(t, r.truth["S"][:, i], "k-", lw=1.5, label="true")
        for key, style in (
            (("noise-free", "uniform"), "C0-"),
            (("default noise", "uniform"), "C1-"),
            (("noise-free", "axle-load"), "C2-"),
        ):
            e = r.estimates[key]
            s = np.where(e.reliable[:, i], e.slip_ratio[:, i], np.nan)
            ax.plot(t, s, style, lw=0.8, alpha=0.8, label=f"estimated, {key[0]}, {key[1]}")
        ax.axhline(0, color="0.5", lw=0.5)
        ax.set_ylabel(f"S {w}")
        ax.grid(True, alpha=0.3)
    axes[0].legend(fontsize=7, ncol=2, loc="upper right")
    axes[0].set_title(
        f"Slip ratio of the driven wheels, weave {r.weave.name} "
        "(S < 0 spinning, S > 0 skidding; unreliable samples blank)"
    )
    axes[-1].set_xlabel("t [s]")
    fig.tight_layout()
    path = out / f"slip_{r.weave.name}.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _fmt(x: float, digits: int = 2) -> str:
    return "n/a" if not math.isfinite(x) else f"{x:.{digits}f}"


def run(
    out_dir: str | Path,
    duration: float = 50.0,
    seed: int = 0,
    progress: bool = True,
    rover: RoverConfig | str = "proto_explorer",
) -> Path:
    """Run the three drives, write tables, figures and ``summary.md`` into ``out_dir``."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    cfg = rover if isinstance(rover, RoverConfig) else load_rover(rover)
    results = _drives(cfg, duration, np.random.default_rng(seed), progress)
    dr_md = _dead_reckoning_table(results, out)
    slip_md = _slip_tables(results, out)
    turn_md = _turn_table(results)
    _plot_trajectories(results, out)
    slip_figs = [_plot_slip(r, out) for r in results]
    summary = _summary(duration, seed, dr_md, slip_md, turn_md, slip_figs)
    (out / "summary.md").write_text("\n".join(summary))
    return out


def _drives(
    cfg: RoverConfig, duration: float, rng: np.random.Generator, progress: bool
) -> list[DriveResult]:
    """The three weaves, each read through every sensor set and estimated per radius model."""
    results: list[DriveResult] = []
    for weave in WEAVES:
        if progress:
            print(f"drive: weave {weave.name}")
        r = _simulate(cfg, weave, duration, progress)
        for sname, scfg in SENSORS.items():
            r.logs[sname] = apply_sensors(r.log, scfg, rng)
            for model in RADIUS_MODELS:
                r.estimates[(sname, model)] = estimate_log(
                    r.logs[sname], cfg, estimator_config(model, cfg)
                )
        results.append(r)
    return results


def _dead_reckoning_table(results: list[DriveResult], out: Path) -> list[str]:
    """End-point errors: dead_reckoning.csv and .md; returns the table's markdown lines."""
    rows: list[dict[str, Any]] = []
    for r in results:
        tp = r.truth["pose"]
        for sname in SENSORS:
            for model in RADIUS_MODELS:
                e = r.estimates[(sname, model)]
                along, across, dist = endpoint_error(tp[:, :2], e.pose[:, :2])
                rows.append(
                    {
                        "weave": r.weave.name,
                        "amplitude_rad_s": r.weave.amplitude,
                        "sensors": sname,
                        "radius": model,
                        "distance_m": dist,
                        "along_pct": along,
                        "across_pct": across,
                        "yaw_error_deg": math.degrees(e.pose[-1, 2] - tp[-1, 2]),
                    }
                )
    with (out / "dead_reckoning.csv").open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    dr_md = [
        "| weave | sensors | radius | distance [m] | along [%] | across [%] | yaw error [deg] |",
        "|---|---|---|---|---|---|---|",
    ]
    for row in rows:
        dr_md.append(
            f"| {row['weave']} (±{row['amplitude_rad_s']}) | {row['sensors']} | {row['radius']}"
            f" | {row['distance_m']:.2f} | {row['along_pct']:+.2f} | {row['across_pct']:+.2f}"
            f" | {row['yaw_error_deg']:+.2f} |"
        )
    (out / "dead_reckoning.md").write_text(
        "# Dead reckoning from the free wheels: end-point error, % of distance travelled\n\n"
        + "\n".join(dr_md)
        + "\n"
    )
    return dr_md


def _slip_tables(results: list[DriveResult], out: Path) -> list[str]:
    """Slip-ratio errors per sensor set and radius model: slip.csv; returns markdown lines."""
    slip_md: list[str] = []
    slip_rows: list[dict[str, Any]] = []
    for sname in SENSORS:
        for model in RADIUS_MODELS:
            slip_md += [
                f"\n### {sname}, {model} rolling radius\n",
                "| drive | RMS 1L | RMS 1R | RMS 2L | RMS 2R | unreliable 1L/1R/2L/2R [%] "
                "| flagged by (any wheel) |",
                "|---|---|---|---|---|---|---|",
            ]
            pooled_err2: list[Array] = []
            pooled_ok: list[npt.NDArray[np.bool_]] = []
            for r in results:
                st = slip_stats(r.estimates[(sname, model)], r.truth["S"][:, :4])
                pooled_err2.append(st["err2"])
                pooled_ok.append(r.estimates[(sname, model)].reliable)
                why = ", ".join(f"{k} {100 * v:.2f} %" for k, v in st["flag_share"].items() if v)
                slip_md.append(
                    f"| {r.weave.name} | "
                    + " | ".join(_fmt(x, 4) for x in st["rms"])
                    + " | "
                    + "/".join(f"{100 * u:.1f}" for u in st["unreliable"])
                    + f" | {why or '-'} |"
                )
                slip_rows.append(
                    {"drive": r.weave.name, "sensors": sname, "radius": model}
                    | {f"rms_{w}": st["rms"][i] for i, w in enumerate(DRIVEN_WHEELS)}
                    | {f"unreliable_{w}": st["unreliable"][i] for i, w in enumerate(DRIVEN_WHEELS)}
                )
            e2 = np.concatenate(pooled_err2)
            ok = np.concatenate(pooled_ok)
            rms = np.sqrt(np.nanmean(e2, axis=0))
            unrel = 1.0 - ok.mean(axis=0)
            slip_md.append(
                "| **all three** | "
                + " | ".join(f"**{x:.4f}**" for x in rms)
                + " | "
                + "/".join(f"{100 * u:.1f}" for u in unrel)
                + " | |"
            )
            slip_rows.append(
                {"drive": "all", "sensors": sname, "radius": model}
                | {f"rms_{w}": rms[i] for i, w in enumerate(DRIVEN_WHEELS)}
                | {f"unreliable_{w}": unrel[i] for i, w in enumerate(DRIVEN_WHEELS)}
            )
    with (out / "slip.csv").open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(slip_rows[0]))
        w.writeheader()
        w.writerows(slip_rows)
    return slip_md


def _turn_table(results: list[DriveResult]) -> list[str]:
    """Outer vs inner wheels' mean slip in turns (paper Fig. 7), as markdown lines."""
    turn_md = [
        "| drive | sensors, radius | segment | outer: est. | outer: true | inner: est. "
        "| inner: true |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in results[1:]:
        for key in (("noise-free", "axle-load"), ("default noise", "uniform")):
            tend = turn_tendency(r.estimates[key], r.truth["S"][:, :4])
            for seg, vals in enumerate(tend, start=1):
                turn_md.append(
                    f"| {r.weave.name} | {key[0]}, {key[1]} | {seg} | "
                    + " | ".join(f"{v:+.3f}" for v in vals)
                    + " |"
                )
    return turn_md


def _summary(
    duration: float,
    seed: int,
    dr_md: list[str],
    slip_md: list[str],
    turn_md: list[str],
    slip_figs: list[Path],
) -> list[str]:
    est_default = EstimatorConfig()
    return [
        "# Dead reckoning and slip estimation on flat ground (paper section 6)\n",
        f"Three {duration:g} s drives from rest, speed target {CRUISE} rad/s on every driven "
        f"wheel, left/right difference 2·A·sin(2πt/{WEAVE_PERIOD:g} s) with A = "
        + ", ".join(f"{w.amplitude} ({w.name})" for w in WEAVES)
        + " rad/s. Logged at 50 Hz; estimated from wheel and joint angles only "
        f"({est_default.rate_method} differentiator, window {est_default.rate_window} s, "
        f"min speed {est_default.min_speed} m/s). Sensors: noise-free, or the defaults of "
        "`rover_env.estimation.sensors` (10-bit joint pots with 1/4-count noise, 0.01 rad wheel "
        f"encoders); noise seed {seed}. Rolling radius: `uniform` is the estimator's default "
        "(d − mean static deflection), `axle-load` uses each axle's static load.\n",
        "## End-point error of the dead reckoning (segment 3's centre)\n",
        "Along/across the true start-to-end direction, % of the distance travelled.\n",
        *dr_md,
        "\n![trajectories](trajectories.png)\n",
        "## Slip ratio of the driven wheels: estimated vs true\n",
        "RMS of (estimated − true) S over the samples flagged reliable; unreliable = share "
        "of samples flagged for that wheel.",
        *slip_md,
        "",
        *[f"![{p.stem}]({p.name})" for p in slip_figs],
        "\nWhat the kinematic model of SPEC §2 cannot see, and so what these errors are made "
        "of: the simulated wheels roll on r_e = d − δ/3 (TireParams.k_re), and δ follows each "
        "wheel's load (C_z), which shifts between axles and sides as the rover weaves; and "
        "segment 3 is assumed not to slide sideways, while in turns it is dragged sideways "
        "by the chain. The estimator's own approximations (differentiation lag, noise) are "
        "the rest.\n",
        "\n## In turns: outer vs inner driven wheels (paper Fig. 7)\n",
        "Mean slip ratio while the segment's estimated yaw rate exceeds 0.02 rad/s; the "
        "paper: outer wheels negative (spinning), inner positive (skidding).\n",
        *turn_md,
        "",
    ]


def _cli(args: argparse.Namespace) -> int:
    out = run(args.out, duration=args.duration, seed=args.seed, progress=not args.quiet)
    print((out / "summary.md").read_text())
    return 0


def add_cli(subparsers: Any) -> None:
    """Register ``dead-reckoning --out DIR [--duration S] [--seed N] [--quiet]``."""
    p = subparsers.add_parser(
        "dead-reckoning",
        help="the paper's flat-ground drive: dead reckoning and slip estimation (section 6)",
    )
    p.add_argument("--out", default="out/dead-reckoning", help="output folder")
    p.add_argument("--duration", type=float, default=50.0, help="seconds per drive (default 50)")
    p.add_argument("--seed", type=int, default=0, help="sensor-noise seed (default 0)")
    p.add_argument("--quiet", action="store_true", help="no progress output")
    p.set_defaults(func=_cli)

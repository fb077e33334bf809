"""Stage 7, write: the diagnosis's outputs.

Owns what a user gets in ``out``: the updated configuration (``rover.yaml``: the logs' rover
plus the chosen effects with fitted values, loadable by RoverSim and the environments as
it is), the held-out replay before/after (``replay_heldout.npz``), ``result.json`` (the
machine-readable summary, :func:`result_of`) and the Markdown report with figures
(:mod:`rover_env.calibration.report`, which reads the finished :class:`Diagnosis`).
"""

from __future__ import annotations

import json
import time
from dataclasses import replace
from typing import Any

import numpy as np
import yaml
from numpy.typing import NDArray

from rover_env.calibration import residuals as rs
from rover_env.calibration.candidates import Extensions, merge
from rover_env.calibration.diagnosis.form import with_joint_zero
from rover_env.calibration.diagnosis.judge import (
    fit_dict,
    gap,
    off_by_groups,
    strict_json,
    unexplained,
)
from rover_env.calibration.diagnosis.state import Diagnosis, Scored
from rover_env.calibration.drive_plan import proposals_from_result
from rover_env.calibration.evidence import plan_command
from rover_env.calibration.replay import SIGNALS, WindowResult, replay_config
from rover_env.calibration.report import write_report
from rover_env.config import JOINTS, RoverConfig, load_rover, to_dict


def write(d: Diagnosis) -> None:
    """Writes ``rover.yaml``, the held-out replays, ``result.json`` and the report; sets
    :attr:`Diagnosis.result`."""
    out, base, st = d.out, d.base, d.st
    mark_headings(d)
    final_ext = final_extensions(d)
    final_cfg = replace(base, extensions=merge(base.extensions, final_ext))
    if d.ev.profile_zeros:  # the zeros the final model's fit carries
        final_cfg = with_zeros(final_cfg, d.ev.zero_shift(final_ext))
    cfg_path = out / "rover.yaml"
    cfg_path.write_text(
        rover_header(d.chosen, d.balance) + yaml.safe_dump(to_dict(final_cfg), sort_keys=False)
    )
    load_rover(cfg_path)  # must load as is
    held_log_objs = [d.logs[i] for i in sorted({w.log_index for w in d.held_w})]
    replay_before = replay_config(base, held_log_objs, st)
    replay_after = replay_config(cfg_path, held_log_objs, st)
    arrays: dict[str, Any] = {f"before_{k}": v for k, v in replay_before.items()}
    arrays.update({f"after_{k}": v for k, v in replay_after.items()})
    np.savez(out / "replay_heldout.npz", **arrays)
    d.held_final = d.ev.run(final_ext, "held")
    d.table_held_after = rs.table(rs.stack(d.held_final, d.prepared), d.final_floor)
    d.result = result_of(d, str(cfg_path))
    (out / "result.json").write_text(json.dumps(strict_json(d.result), indent=2, allow_nan=False))
    write_report(d)
    r = d.result
    d.say(
        f"named: {', '.join(r['named']) if r['named'] else 'nothing'}; main residual"
        f" {r['main_signal']} {r['main_rms_before']:.4g} -> {r['main_rms_after']:.4g};"
        f" wrote {out}/report.md, rover.yaml ({r['seconds']:.0f}s)"
    )


def mark_headings(d: Diagnosis) -> None:
    """With ``--frames fit`` (:attr:`Diagnosis.frames` set) every slope fit's heading is in
    the first log's frame and not known, the windows' as much as the balance's
    (:attr:`~rover_env.calibration.fit.Fit.heading_known`): the record, the report and
    ``rover.yaml``'s comment say so."""
    if d.frames is None:
        return
    for s in [*d.ranked, *d.chosen]:
        if any(c.name == "slope" for c in s.fit.candidates):
            s.fit.heading_known = False


UNKNOWN_HEADING = (
    "# slope.heading_deg is in the first log's frame and not known: the drives share no frame\n"
    "# (diagnose --frames fit), and a slope's runs fit mirrored turns alike.\n"
)


UNKNOWN_SIZE = (
    "# slope.deg is not known: the force balance allows {lo:.2f}-{hi:.2f} degrees, the clean\n"
    "# builds' allowance counted (the runs barely cross). Drive plan `{plan}`\n"
    "# ({command})\n"
    "# and diagnose again with its log added.\n"
)


def rover_header(chosen: list[Scored], balance: dict[str, Any] | None = None) -> str:
    """``rover.yaml``'s comment: who wrote it; where a named slope's heading is not known
    (:attr:`~rover_env.calibration.fit.Fit.heading_known`) that its ``heading_deg`` only
    gives the model a direction; and where the balance named a slope whose size it could
    not pin down (``why_drive``, :data:`~.balance_stage.SPREAD`) that ``deg`` is one of the
    sizes its runs allow, and the drive that decides it. Why: a user who reads only
    ``rover.yaml`` would otherwise take the value as measured."""
    head = "# Written by rover-env diagnose: the logs' rover plus the effects it found.\n"
    blind = any(not s.fit.heading_known for s in chosen)
    bal = balance or {}
    loose = ""
    if bal.get("named") and bal.get("why_drive"):
        lo, hi = bal["truth_interval"]  # less the clean builds' allowance
        cmd = plan_command(bal["plan"], bal["seed"], bal["duration"])
        loose = UNKNOWN_SIZE.format(lo=lo, hi=hi, plan=bal["plan"], command=cmd)
    return head + (UNKNOWN_HEADING if blind else "") + loose


def final_extensions(d: Diagnosis) -> Extensions:
    """The named effects' extensions together (none named: no extensions)."""
    return merge(*(s.fit.ext for s in d.chosen))


def with_zeros(cfg: RoverConfig, shift: NDArray[np.float64]) -> RoverConfig:
    """``cfg`` with each joint sensor's zero moved by its profiled ``shift`` (the sensor
    reads ``shift`` more than ``cfg`` said, so its zero is ``shift`` less)."""
    for j, s in zip(JOINTS, shift, strict=True):
        cfg = with_joint_zero(cfg, j, cfg.joints[j].zero - float(s))
    return cfg


def result_of(d: Diagnosis, cfg_path: str) -> dict[str, Any]:
    """``result.json``'s content: what was named, every fit, the main residual before and
    after (with the gap above the floor and the median window), floors and costs."""
    noise, final_floor, opts = d.noise, d.final_floor, d.opts
    table_held_before, table_held_after = d.table_held_before, d.table_held_after
    main_sig = max(SIGNALS, key=lambda s: np.nan_to_num(table_held_before[s]["all"].ratio))
    rb, ra = table_held_before[main_sig]["all"].rms, table_held_after[main_sig]["all"].rms
    jm = SIGNALS.index(main_sig)
    # The gap: what exceeds the floor of each model (the floor is what even a perfect model
    # leaves; a tilted or lagging model can replay its own twins less exactly).
    gb = float(np.sqrt(max(rb**2 - noise[main_sig] ** 2, 0.0)))
    ga = float(np.sqrt(max(ra**2 - final_floor[main_sig] ** 2, 0.0)))
    mb = median_window_rms(d.base_held, jm)
    ma = median_window_rms(d.held_final, jm)
    elapsed = time.perf_counter() - d.t_start
    named = [n for s in d.chosen for n in (c.name for c in s.fit.candidates)]
    free_g, free_c = d.ev.free_gains(final_extensions(d))
    res: dict[str, Any] = {
        "logs": [str(f) for f in d.files],
        "start_headings": [lg.meta.start_heading_deg for lg in d.logs],
        "frames": d.frames,
        "split": d.split,
        "named": named,
        "tie": d.tie,
        "fits": {s.fit.name: fit_dict(s) for s in d.ranked},
        "partners": {s.fit.name: fit_dict(s) for s in d.partners},
        "second_tried": {s.fit.name: fit_dict(s) for s in d.tried},
        "final": {s.fit.name: fit_dict(s) for s in d.chosen},
        "main_signal": main_sig,
        "main_rms_before": rb,
        "main_rms_after": ra,
        "main_reduction": 1.0 - ra / rb if rb > 0 else 0.0,
        "main_floor_before": noise[main_sig],
        "main_floor_after": final_floor[main_sig],
        "main_gap_reduction": 1.0 - ga / gb if gb > 0 else 0.0,
        "main_median_window_rms_before": mb,
        "main_median_window_rms_after": ma,
        "main_reduction_median_window": 1.0 - ma / mb if mb > 0 else 0.0,
        "noise": noise,
        "sensor_noise": d.sensor_noise,
        "seconds": elapsed,
        "replays": d.ev.replays,
        "replay_seconds": d.ev.seconds,
        "stage_seconds": [*d.earlier_passes, d.stage_seconds],
        "config": cfg_path,
        "unexplained": gap(table_held_after, final_floor),
        "above_floor": unexplained(table_held_after, final_floor),
        "evidence": d.evidence,
        "evidence_judged": d.evidence_judged,
        "untested": d.untested,
        "plans_held": d.held_plans,
        "rotor_alternative": d.rotor,
        "rotor_profile": d.rotor_profile,
        "rotor_withdrawn": d.rotor_withdrawn,
        "allowance_withdrawn": d.allowance_withdrawn,
        "named_on_windows": on_windows(d.chosen),
        "passed_over": d.passed_over,
        "allowance_differs": d.allowance_differs,
        "one_wheel": d.one_wheel,
        "partner_limits": d.partner_limits,
        "not_named": d.traded,
        "trade_excused": d.trade_excused,
        "second_dropped": d.dropped,
        "model_form": None if not opts.model_form else {f.name: f.as_json() for f in d.forms},
        "model_form_reverted": opts.forms_reverted,
        "model_form_beside": opts.forms_beside,
        "model_form_changed": list(opts.forms_changed),
        "model_form_weak_beside": d.forms_weak,
        "free_wheel_gain": free_g if d.ev.profile_free_gain else None,
        "free_wheel_common": free_c if d.ev.free_common_max > 0 else None,
        "dead_reckoning": d.odometry,
        "effort": d.effort,
        "balance": d.balance,
    }
    res["provisional"] = pending_drives(res) if named else []
    return res


def on_windows(chosen: list[Scored]) -> list[str]:
    """The named effects whose interval for the truth reaches "off" only through the signal
    groups' disagreement (named on the windows' interval: ``Options.presence_on_windows``)."""
    return sorted(n for s in chosen for n in off_by_groups(s.fit))


def pending_drives(result: dict[str, Any]) -> list[dict[str, Any]]:
    """The drives a diagnosis asks for (:func:`~rover_env.calibration.drive_plan.proposals_from_result`),
    each with the effects it is for: while any is pending, what is named is provisional.
    Why (stop 130): in blocks 54400-54600 the names changed after the drives asked for in
    10 of 78 cases, and 2 of 6 clean builds of block 54500 were named at the first
    diagnosis and withdrawn after the crossing drive asked for a slope; a user who stops
    at the first report must be told."""
    return [
        {"plan": p.plan, "seed": p.seed, "duration": p.duration, "for": sorted(p.effects)}
        for p in proposals_from_result(result)
    ]


def median_window_rms(results: list[WindowResult], j: int) -> float:
    """Median over windows of one signal's RMS residual (robust to a few chaotic windows)."""
    vals = []
    for r in results:
        col = r.resid[:, j] if j < 11 else r.pose_resid[:, j - 11]
        if col.size:
            vals.append(float(np.sqrt(np.mean(col**2))))
    return float(np.median(vals)) if vals else float("nan")

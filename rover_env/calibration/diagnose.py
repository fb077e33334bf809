"""``rover-env diagnose LOG.csv ... --out DIR``: name the effect missing from the model.

Steps (each printed as it runs):

1. Read the logs (SPEC §6) and the rover they name. Split: the last log (by file name) is
   held out, the others are training (a drive a report asked for is held out beside it);
   with a single log, alternate windows are held out.
2. Replay every drive by multiple shooting (:mod:`.replay`) with the current model; estimate
   the sensor noise from the logs and tabulate residuals per signal and regime with a test
   against that noise (:mod:`.residuals`).
3. Fit each candidate effect of the catalogue on the training windows (bounded least
   squares, cluster-robust 95 % intervals; :mod:`.fit`), score it on the held-out windows.
4. Rank by held-out error; name a winner only if it is significant: held-out error down by
   at least ``min_gain`` with a one-sided Wilcoxon signed-rank test over held-out windows
   at ``alpha``, and a lower BIC on training. An effect that touches only a few windows (a
   torque limit the drive reaches a few times) cannot pass a test across windows; when no
   candidate does, one that takes every held-out signal it changes back under the replay
   floor (:func:`.diagnosis.judge.noise_test`) may be named instead. If the runner-up is
   statistically indistinguishable on held-out windows, report a tie and the drive that
   separates them.
5. Forward selection: refit the winner together with each of the other candidates that
   improved the held-out drive, and keep a second effect under the same rules against the
   winner alone. The chosen effects are named with confidence only if they make no held-out
   signal that they leave above its floor worse, window by window
   (:func:`.diagnosis.judge.traded_signals`): one that trades a signal for another stands in
   for an effect outside the catalogue. A torque limit is named only if the held-out
   windows favour it over the rotor inertia fitted in its place (:func:`.diagnosis.rotor.rotor_test`).
6. Write the updated rover configuration (``rover.yaml``: the logs' rover plus the chosen
   effects with fitted values, loadable by RoverSim and the environments as it is), the
   held-out replay before/after, a Markdown report with figures (:mod:`.report`) and
   ``result.json`` (machine-readable summary).

The steps are the stages of :mod:`rover_env.calibration.diagnosis` (split, form, floor, fit,
select, evidence, write) over one state, run in order by
:mod:`~rover_env.calibration.diagnosis.pipeline`; this module is the entry point:
:func:`diagnose`, its :class:`Options` and the command line.
"""

from __future__ import annotations

import argparse
import os
from typing import Any

from rover_env.calibration.diagnosis.frames import FRAMES
from rover_env.calibration.diagnosis.pipeline import diagnose
from rover_env.calibration.diagnosis.state import Options
from rover_env.calibration.replay import ReplaySettings
from rover_env.executor import add_executor_args
from rover_env.logs import LogError

__all__ = ["Options", "add_cli", "diagnose"]


def _number(text: str) -> float:
    """A command-line number, refused by argparse (naming the flag) if it is none."""
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None


def _p_level(text: str) -> float:
    """``--rotor-alpha``: a p level above 0 and at most 1."""
    if not 0.0 < (v := _number(text)) <= 1.0:  # also NaN
        raise argparse.ArgumentTypeError(f"must be above 0 and at most 1, got {text}")
    return v


def _share(text: str) -> float:
    """``--trade-share``: a share, 0 or more."""
    if not (v := _number(text)) >= 0.0:  # also NaN
        raise argparse.ArgumentTypeError(f"must be 0 or more, got {text}")
    return v


def _degrees(text: str) -> float:
    """``--balance-allowance``, ``--slip-allowance``: degrees, 0 or more and under 20."""
    if not 0.0 <= (v := _number(text)) < 20.0:  # also NaN
        raise argparse.ArgumentTypeError(f"must be 0 or more and under 20 degrees, got {text}")
    return v


def _tolerance(text: str) -> float:
    """``--effort-tolerance``: a fraction, 0 or more and under 1."""
    if not 0.0 <= (v := _number(text)) < 1.0:  # also NaN
        raise argparse.ArgumentTypeError(f"must be 0 or more and under 1, got {text}")
    return v


def _count(text: str) -> int:
    """A whole number of 0 or more, for argparse."""
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a whole number, got {text!r}") from None
    if v < 0:
        raise argparse.ArgumentTypeError(f"must be 0 or more, got {text}")
    return v


def _cli(args: argparse.Namespace) -> int:
    st = ReplaySettings(window=args.window, burn_in=args.burn_in)
    opts = Options(
        settings=st,
        candidates=args.candidates.split(",") if args.candidates else None,
        progress=not args.quiet,
        workers=args.workers,
        executor=args.executor,
        ray_address=args.ray_address,
        model_form=not args.no_model_form,
        free_common=args.free_common,
        rotor_range=args.rotor_range,
        trade_share=args.trade_share,
        rotor_alpha=args.rotor_alpha,
        fit_windup=args.fit_windup,
        form_allowance=None if args.no_form_allowance else args.form_allowance,
        odometry=None if args.no_odometry else Options().odometry,
        odometry_end=None if args.no_odometry else Options().odometry_end,
        effort_tolerance=None if args.no_effort else args.effort_tolerance,
        balance_allowance=None if args.no_balance else args.balance_allowance,
        slip_allowance=None if args.no_slip_balance else args.slip_allowance,
        frames=args.frames,
        max_draws=args.max_draws,
        **{name: getattr(args, name) for name, _ in SWITCHES},
    )
    try:
        diagnose(args.logs, args.out, opts)
    except LogError as exc:
        print(f"rover-env diagnose: bad log: {exc}")
        return 2
    return 0


SWITCHES: tuple[tuple[str, str], ...] = (
    (
        "fit_anti_windup",
        "choose the speed loop's anti-windup form (clamp or conditional integration) as model form",
    ),
    ("fit_joint_zero", "fit the joint sensors' zeros as model form"),
    ("fit_free_gain", "profile the free wheels' left/right reading difference out of every fit"),
    ("fit_yaw_spring", "fit the yaw joints' leaf-spring stiffness as model form"),
    ("fit_joint_height", "fit the height of the joints between segments as model form"),
    (
        "height_beside_soil",
        "adopt no joint height before the effects where a loose soil explains more",
    ),
    ("fit_com_height", "fit the segments' centre-of-mass height as model form"),
    ("fit_speed_loop", "fit the speed loop's proportional and integral gains as model form"),
    (
        "joint_motor_loop",
        "fit the speed loop's anti-windup form, gains and rotor inertia together as model form",
    ),
    ("fit_slip_floor", "fit the tire's low-speed slip floor as model form"),
    (
        "name_above_limit",
        "name an effect only if its fitted magnitude reaches its detection limit on these logs",
    ),
    (
        "name_beyond_allowance",
        "name an effect only if its interval with the clean-fit allowance keeps clear of off",
    ),
    (
        "presence_on_windows",
        "judge the clean-fit allowance's reach to off on the windows' interval, without the"
        " signal groups' spread (stop 132; block 54900)",
    ),
    (
        "next_after_withdrawn",
        "when the clean-fit allowance withdraws every name, try the next candidate alone"
        " (off: block 52400)",
    ),
    ("interleave", "hold out every other window of each drive instead of the last drive"),
    ("torque_forms", "search the torque limit under each anti-windup form of the speed loop"),
    (
        "one_wheel",
        "withdraw a named rolling resistance where the two free wheels' dead reckoning"
        " disagree (one wheel's own drag)",
    ),
    (
        "slip_beside_lead",
        "where dead reckoning's driven wheels slip apart from the free wheels, read the radius"
        " beside the leading unnamed fit (a drag the windows did not name)",
    ),
    (
        "partner_limit",
        "name a second effect only if it reaches its detection limit beside the winner"
        " (off: study 71000)",
    ),
    (
        "soil_from_motion",
        "read a named soil's k_phi from the pose signals' own minimum (off: study 61600)",
    ),
    (
        "soil_from_straight",
        "read a named soil's k_phi from the windows without a turn",
    ),
    (
        "soil_from_joints",
        "the straight read takes the joint signals' minimum (the wheels' sinkage), not the pose's",
    ),
    (
        "reversal_tie",
        "a slope against a significant drag is a tie while the held-out drive never reverses",
    ),
    (
        "soil_alone",
        "beside a loose-soil winner, try no effect of the tire the soil replaces",
    ),
    (
        "pegged_last",
        "name a fit at its range's far end only after fits inside their ranges",
    ),
    (
        "soft_end_unread",
        "read no soil from straight driving whose best rung is the range's soft end"
        " (off: study 64000)",
    ),
    ("screen", "screen each candidate on half the training windows before its full fit"),
    (
        "screen_coarse",
        "a screen searches the ladder alone (several parameters: half the local budget)",
    ),
    (
        "screen_middle",
        "screen a candidate's forms (the soil's) at its ladder's middle rung too",
    ),
    (
        "screen_shared",
        "a lag and a delay fitted together are screened on half the training windows first",
    ),
    (
        "shared_refit",
        "fit a command lag and a delay together, both free, when one of them is the winner",
    ),
    (
        "weak_adoption_stands",
        "a form adopted beside the winner or leader on weak evidence only (|dBIC| < 2), kept"
        " nominal before, starts no second pass",
    ),
    (
        "forms_beside_leader",
        "with nothing named, fit the model form again beside the leading candidate",
    ),
    (
        "forms_beside_rival",
        "with a winner named, fit the model form again beside the candidate the training"
        " windows favour over it (off: study 71600)",
    ),
)
"""The on/off options of :class:`Options` the command line sets, ``--name`` / ``--no-name``."""


def _add_torque_flags(p: argparse.ArgumentParser) -> None:
    """The flags of what diagnose reads from the reported motor torque (``effort_*``)."""
    p.add_argument(
        "--effort-tolerance",
        type=_tolerance,
        default=Options.effort_tolerance,
        metavar="FRACTION",
        help="where the logs report the motors' torque (effort_* columns), read the torque"
        " limit from it and name a cut beyond this tolerance of the reported torque's scale"
        f" (default {Options.effort_tolerance}; see Options.effort_tolerance)",
    )
    p.add_argument(
        "--no-effort",
        action="store_true",
        help="never read the reported motor torque (neither the torque limit nor the force"
        " balance on it; the slip balance reads the tilt instead)",
    )
    p.add_argument(
        "--balance-allowance",
        type=_degrees,
        default=Options.balance_allowance,
        metavar="DEG",
        help="where the logs report the motors' torque and the pose's yaw, read the ground's"
        " tilt from the force balance on steady straight runs and name a slope whose interval"
        f" clears this many degrees (default {Options.balance_allowance}; see"
        " Options.balance_allowance)",
    )
    p.add_argument(
        "--no-balance",
        action="store_true",
        help="never read the ground's tilt from the reported motor torque (the slip balance"
        " reads it instead)",
    )
    p.add_argument(
        "--slip-allowance",
        type=_degrees,
        default=Options.slip_allowance,
        metavar="DEG",
        help="where the logs carry the pose's yaw but no torque (or it is not read), read the"
        " ground's tilt from the driven wheels' slip against the free wheels' on steady"
        " straight runs, forwards against backwards, and name a slope whose interval clears"
        " this many degrees"
        f" (default {Options.slip_allowance}; see Options.slip_allowance)",
    )
    p.add_argument(
        "--no-slip-balance",
        action="store_true",
        help="never read the ground's tilt from the wheels' slip",
    )
    p.add_argument(
        "--frames",
        choices=FRAMES,
        default=Options.frames,
        help="each log's frame: 'given' (its YAML's start_heading_deg, or all facing the same"
        " way where no log gives one) or 'fit' (the drives share no frame: each log's turn"
        " fitted from the wheels' slip or torque on steady straight runs; the balance then"
        f" gives a slope's size, not its heading; default {Options.frames})",
    )


def add_cli(sub: Any) -> None:
    p = sub.add_parser(
        "diagnose",
        help="find where model and measured logs disagree and name the missing effect",
    )
    p.add_argument("logs", nargs="+", help="SPEC §6 log CSVs (YAML beside each)")
    p.add_argument("--out", required=True, help="output folder (report.md, rover.yaml, PNGs)")
    p.add_argument("--window", type=float, default=3.0, help="shooting window (s)")
    p.add_argument(
        "--burn-in",
        type=float,
        default=ReplaySettings.burn_in,
        help="unscored start of each window (s)",
    )
    p.add_argument(
        "--no-model-form",
        action="store_true",
        help="keep the configuration's model form: joint zeros, speed-loop anti-windup, tire"
        " relaxation length, yaw springs, joint height (no model-form stage)",
    )
    p.add_argument(
        "--free-common",
        type=float,
        default=Options.free_common,
        metavar="FRACTION",
        help="profile the free wheels' common reading gain within +-FRACTION out of every fit"
        f" (default {Options.free_common:g}: a 1 %% wheel-radius tolerance; 0: off; see"
        " Options.free_common)",
    )
    p.add_argument(
        "--rotor-range",
        type=float,
        default=Options.rotor_range,
        metavar="FACTOR",
        help="a named torque limit's interval holds its refits with the rotor inertia"
        f" (motor.armature) divided and multiplied by FACTOR (default {Options.rotor_range:g};"
        " 1: off; see Options.rotor_range)",
    )
    p.add_argument(
        "--max-draws",
        type=_count,
        default=Options.max_draws,
        metavar="N",
        help="ask for no further draw of a drive plan for a candidate the logs' N draws of it"
        f" leave unconfirmed (default {Options.max_draws}; 0: no cap; see Options.max_draws)",
    )
    p.add_argument(
        "--rotor-alpha",
        type=_p_level,
        default=Options.rotor_alpha,
        metavar="P",
        help="a named torque limit stays named only if the held-out windows favour it over the"
        f" rotor inertia (motor.armature) in its place at p < P (default {Options.rotor_alpha:g};"
        " 1: off; see Options.rotor_alpha)",
    )
    p.add_argument(
        "--trade-share",
        type=_share,
        default=Options.trade_share,
        metavar="SHARE",
        help="an effect that makes signals left above their floor worse is named only if they"
        f" lost less than SHARE of what the other signals gained (default {Options.trade_share:g};"
        " 0: any such trade leaves it unnamed; see Options.trade_share)",
    )
    p.add_argument(
        "--form-allowance",
        default=Options.form_allowance,
        metavar="NAME_OR_YAML",
        help="clean-fit allowance table widening each named effect's interval for the model's"
        f" form (default: the shipped {Options.form_allowance!r}, configs/calibration/; see"
        " Options.form_allowance)",
    )
    p.add_argument(
        "--no-form-allowance",
        action="store_true",
        help="report the intervals without the clean-fit allowance",
    )
    p.add_argument(
        "--no-odometry",
        action="store_true",
        help="never name a rolling radius from dead reckoning against the pose, between fixes"
        " or to each drive's last fix (see Options.odometry, Options.odometry_end)",
    )
    _add_torque_flags(p)
    for name, what in SWITCHES:
        on = getattr(Options, name)
        p.add_argument(
            "--" + name.replace("_", "-"),
            action=argparse.BooleanOptionalAction,
            default=on,
            help=f"{what} (default: {'on' if on else 'off'}; see Options.{name})",
        )
    p.add_argument(
        "--fit-windup",
        action="store_true",
        help="also fit the speed loop's anti-windup bound as model form (experimental: with"
        " the clamp form it biases rolling resistance low on a conditionally integrating"
        " loop)",
    )
    p.add_argument("--candidates", default=None, help="comma-separated subset of the catalogue")
    p.add_argument("--quiet", action="store_true")
    p.add_argument(
        "--workers",
        type=int,
        default=os.cpu_count() or 1,
        help="processes fitting candidates side by side (default: one per CPU)",
    )
    add_executor_args(p)
    p.set_defaults(func=_cli)

"""The report's paragraphs on why a fit is or is not named (a trade, the clean-fit allowance,
the rotor test), and the words for a fit's values: shared by :mod:`.report` and its tests."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from rover_env.calibration.diagnosis.judge import off_by_groups
from rover_env.calibration.diagnosis.state import Scored
from rover_env.calibration.effort import EVENTS, LAG, SPREAD
from rover_env.calibration.evidence import plan_command
from rover_env.calibration.plans_held import held_text


def p_text(p: float) -> str:
    """A p-value as the report prints it."""
    if not np.isfinite(p):
        return "–"
    return "<1e-6" if p < 1e-6 else f"{p:.2g}"


def phys_text(s: Scored) -> str:
    """A fit's values and intervals (one-sided where at a bound) and its forms, in words."""
    out = []
    sides = s.fit.sides()
    for eff, params in s.fit.physical().items():
        for k, (v, lo, hi) in params.items():
            side = sides.get(eff, {}).get(k, "")
            if k == "heading_deg":
                out.append(
                    f"heading {v:.0f}°"
                    if s.fit.heading_known
                    else f"heading not known ({v:.0f}° in the first log's frame; the drives"
                    " share no frame)"
                )
            elif side == "upper":
                out.append(f"{eff}.{k} < {hi:.3g} (95 %, one-sided; fitted {v:.3g})")
            elif side == "lower":
                out.append(f"{eff}.{k} > {lo:.3g} (95 %, one-sided; fitted {v:.3g})")
            elif np.isfinite(lo) and np.isfinite(hi) and lo != hi:
                out.append(f"{eff}.{k} = {v:.4g} (95 %: {lo:.3g} … {hi:.3g})")
            else:
                out.append(f"{eff}.{k} = {v:.4g}")
    out += [f"{c.name} in the form '{c.form}'" for c in s.fit.candidates if c.form]
    return "; ".join(out)


def trade_note(excused: dict[str, Any]) -> str:
    """The paragraph on a trade too small to refuse the naming (:attr:`Options.trade_share`)."""
    worse = ", ".join(f"{k} to {v['rms_ratio']:.2f} x" for k, v in excused["worse"].items())
    share = next(iter(excused["worse"].values()))["share"]
    return (
        f"{excused['effects']} takes signals left above their floor further from the logs"
        f" ({worse} their RMS before), but they lost {share:.2g} of what the other signals"
        " gained (each in units of its floor): too little to stand for an effect outside the"
        " catalogue. Read them as where the model's form differs from the rover's."
    )


def trade_refused_note(nn: dict[str, Any], demoted: list[Scored] | None, lead: str) -> str:
    """Why the best fit is not named: it trades a signal for another (:func:`.diagnosis.select.settle`)."""
    worse = "; ".join(
        f"{k} {v['rms_ratio']:.2f}x its RMS before (one-sided Wilcoxon over {v['windows']}"
        f" windows, p {p_text(v['p'])})"
        for k, v in nn["worse"].items()
    )
    return (
        f"{lead} The best fit, {' + '.join(nn['effects'])}"
        f" ({'; '.join(phys_text(s) for s in demoted or [])}), improves the held-out drive but"
        f" makes signals it leaves above their floor worse: {worse}. An effect of the"
        " catalogue that trades one signal for another is standing in for something"
        " outside it (a mass, a spring, a tire stiffness); the configuration is left as it was."
    )


def allowance_note(withdrawn: dict[str, Any], beside: bool) -> str:
    """Why a fit the windows' tests passed is not named: its interval with the clean-fit
    allowance reaches "off" (:func:`.diagnosis.select.withdraw_within_allowance`)."""
    fits = "; ".join(f"{k} {v}" for k, v in withdrawn["params"].items())
    kept, also = withdrawn.get("kept"), ", ".join(withdrawn.get("beside") or [])
    after = withdrawn.get("next")
    return (
        ("" if beside else "**Nothing named.** ")
        + f"Fitted and significant but not named: {fits}. Its interval for the truth, widened"
        " by the clean-fit allowance (what this model's own form gives on clean drives of"
        ' another implementation), reaches "off": the logs do not tell the effect from the'
        " model's form. The configuration keeps it off; a longer drive, or one that excites"
        " it more, narrows the interval."
        + (f" {kept}, fitted beside it, is named by its own fit." if kept else "")
        + (f" Not named either: {also}, fitted beside it." if also else "")
        + (f" {after}, next in the naming order, is named by its own fit." if after else "")
    )


def passed_over_note(rec: dict[str, Any]) -> str:
    """Why the fit with the most evidence was not named first: it ended at its range's far
    end (:func:`.diagnosis.select.passed_over`)."""
    return (
        f"{rec['effect']} had the most evidence but ended at its range's far end"
        f" ({rec['value']}): the effect at its largest, the logs wanting more than it gives, not"
        f" an estimate of it. {rec['named_first']}, fitted inside its range, was tried for the"
        " name first."
    )


def procedure_note(differs: list[str]) -> str:
    """The clean-fit allowance table was measured under another procedure than this
    diagnosis ran (:func:`.diagnosis.procedure.differences`): its widenings and withdrawals
    are that procedure's spread, not this one's."""
    return (
        "The clean-fit allowance this report's intervals and withdrawals use was measured"
        f" otherwise ({'; '.join(differs)}): what a clean drive fits moves with the procedure"
        " and the rover (a heavier configured rotor, another anti-windup search), so its"
        " spread may be too wide or too narrow here. Measure a table the way this diagnosis"
        " runs (clean drives of the rover diagnosed so, then `benchmarks/form_allowance.py"
        " --runs`) and give it with `--form-allowance`."
    )


def one_wheel_note(rec: dict[str, Any], beside: bool) -> str:
    """Why a fitted rolling resistance is not named: the free wheels' dead reckoning says one
    wheel drags, not the ground (:func:`.diagnosis.one_wheel.withdraw_one_wheel`)."""
    fits = "; ".join(f"{k} {v}" for k, v in rec["params"].items())
    kept, also = rec.get("kept"), ", ".join(rec.get("beside") or [])
    slow = "3L" if rec["3L"] > rec["3R"] else "3R"  # more path per turn: the wheel held back
    return (
        ("" if beside else "**Nothing named.** ")
        + f"Fitted but not named: {fits}. The ground's rolling resistance slows both free"
        f" wheels alike, but their travel against the pose differs from the model's twins by"
        f" {100 * rec['3L']:+.2f} % (3L) and {100 * rec['3R']:+.2f} % (3R), {100 * abs(rec['split']):.1f} %"
        f" apart, beyond the {100 * rec['limit']:.0f} % clean drives of another implementation"
        " leave: one wheel's own drag (a dragging brake, a tight bearing), which the catalogue"
        f" does not model. Free wheel {slow} turns the less per metre: inspect it first; the"
        " configuration keeps the rolling resistance off."
        + (f" {kept}, fitted beside it, is named by its own fit." if kept else "")
        + (f" Not named either: {also}, fitted beside it." if also else "")
    )


def rotor_note(
    withdrawn: dict[str, Any],
    demoted: list[Scored] | None,
    lead: str = "**Nothing named with confidence.**",
) -> str:
    """Why a torque limit the rotor test withdrew is not named (:func:`.diagnosis.select.rotor_check`)."""
    return (
        f"{lead} The best fit, {' + '.join(withdrawn['effects'])}"
        f" ({'; '.join(phys_text(s) for s in demoted or [])}), improves the held-out drive, but a"
        f" heavier or lighter rotor in the torque limit's place (`motor.armature`"
        f" {withdrawn['armature']:.3g} kg m²) does as well there (p {p_text(withdrawn['p_torque_better'])}"
        " that the limit is better, window by window): these drives reach the limit only while"
        " the wheels accelerate, where it is measured as the torque over the rotor inertia."
        " The configuration is left as it was; the rotor inertia from the motor's and the"
        " gearhead's data, or a drive that holds a motor at its limit without accelerating it,"
        " decides."
    )


def rotor_kept_note(withdrawn: dict[str, Any]) -> str:
    """Why a torque limit fitted beside the named effect is not named with it."""
    return (
        f"A torque limit fitted beside {withdrawn.get('kept', 'it')} was not named: a heavier or"
        f" lighter rotor in its place (`motor.armature` {withdrawn['armature']:.3g} kg m²) does"
        f" as well on the held-out windows (p {p_text(withdrawn['p_torque_better'])} that the limit is"
        f" better). {withdrawn.get('kept', 'It')} is named from its own fit, without the limit."
    )


def effort_lines(r: dict[str, Any] | None) -> list[str]:
    """The torque limit as the reported motor torque reads it (:mod:`.diagnosis.effort_stage`)."""
    if r is None:
        return []
    conf, tol = r["configured"], 100 * r["tolerance"]
    head = (
        f"Motor torque (the logs' `effort_*`, {r['samples']} samples, noise"
        f" {r['noise']:.3f} N m): asked for more than they gave in {r['asked']} samples"
    )
    if r.get("level") is None:
        ruled = r.get("deepest_ruled_out")
        tail = "; never held at a ceiling, so the limit is not read" + (
            f": the largest torque given, {r['largest']:.3f} N m, rules out cuts deeper than"
            f" {-100 * ruled:.0f} % of the configured {conf:.3f} N m (with the {tol:.0f} %"
            " scale tolerance)."
            if ruled is not None and ruled < 0
            else "."
        )
        return ["", head + tail]
    x, lo, hi = r["cut"]
    verdict = (
        "named `torque_limit` from it"
        if r.get("named")
        else f"not named: {r.get('why_not', 'within the tolerance')}"
    )
    moved = "".join(
        f" It {k} the windows' {w['effects']} {w['value']:+.3f}."
        for k in ("withdrew", "replaced")
        for w in r.get(k) or []
    )
    return [
        "",
        head
        + f"; they held at {r['level']:.3f} N m ({r['events']} events, {r['held']} samples, demands {r['spread']:.1f} x apart)"
        f" against the configured {conf:.3f} N m: a change of {100 * x:+.1f} %"
        f" [{100 * lo:+.1f}, {100 * hi:+.1f}] with the reported torque's {tol:.0f} % scale"
        f" tolerance; {verdict}." + moved,
    ]


def effort_method(tolerance: float | None, read: bool) -> list[str]:
    """The method's bullet on the torque limit read from the reported torque."""
    if tolerance is None or not read:
        return []
    return [
        "- Effort: where the logs report the motors' torque, the torque limit is where it held"
        f" while a wheel lagged its loop's target by {LAG} rad/s or more and the motor pushed"
        f" toward it: the same torque in {EVENTS} events or more (one manoeuvre's wheels one"
        f" event) at demands {SPREAD:g} x apart, never exceeded; a change beyond the reported"
        f" torque's {100 * tolerance:.0f} % scale tolerance is named."
    ]


def balance_lines(r: dict[str, Any] | None) -> list[str]:
    """The ground's tilt as the balance reads it, on the reported motor torque or on the
    wheels' slip (:mod:`.diagnosis.balance_stage`)."""
    if r is None:
        return []
    slip = r.get("source") == "slip"
    what = "the wheels' slip, forwards against backwards" if slip else "the logs' `effort_*`"
    drive = (
        f" Proposed drive `{r['plan']}` (seed {r['seed']}, {r['duration']:g} s): write it with"
        f" `{plan_command(r['plan'], r['seed'], r['duration'])}`, drive it on the rover and"
        f" diagnose again with its log added.{held_text(r)}"
        if r.get("plan")
        else ""
    )
    if not r.get("read") or r.get("separated") is False:
        # Unseparated runs give a degenerate solve (block 54900's 54917 printed a tilt of
        # 90° [0, 17783]): the numbers are not a reading (stop 133).
        return [
            "",
            f"Force balance ({what}): {r['runs']} steady straight runs; not read: {r['why_not']}."
            + drive,
        ]
    lo, hi = r["tilt_interval"]
    clo, chi = r.get("c_rr_interval") or (None, None)  # null for the slip's
    verdict = (
        f"named `slope` from it, but {r['why_drive']}"
        if r.get("named") and r.get("why_drive")
        else "named `slope` from it"
        if r.get("named")
        else f"no slope named from it: {r.get('why_not', 'see above')}"
    )
    moved = "".join(
        f" It {k} the windows' slope of {w['deg']:.2f}° [{w['interval'][0]:.2f}, {w['interval'][1]:.2f}]."
        for k in ("withdrew", "replaced")
        for w in r.get(k) or []
    )
    runs = f"{r['runs']} steady straight runs{_headed(r.get('heading_from'))}"
    head = (
        f"Force balance (the driven wheels' slip against the free wheels' times their tires'"
        f" {r['stiffness']:g} N of slip stiffness, {runs}, scatter"
        f" {r['scatter']:.2f} N): the ground rises {r['tilt']:.2f}° [{_end(lo, '.2f')},"
        f" {_end(hi, '.2f')}] toward {r['heading']:.0f}°{_across(r)} with the stiffness's"
        f" {100 * r['tolerance']:.0f} % tolerance, against the {r['allowance']:g}° clean builds"
        f" read; the same slip both ways (a radius, a resistance, the ground):"
        f" {100 * r['offset_slip']:.2f} %"
        if slip
        else f"Force balance (the logs' `effort_*` over the lever {1000 * r['lever']:.1f} mm,"
        f" {runs}, scatter {r['scatter']:.2f} N): the ground rises"
        f" {r['tilt']:.2f}° [{_end(lo, '.2f')}, {_end(hi, '.2f')}] toward {r['heading']:.0f}°{_across(r)}"
        f" with the reported torque's {100 * r['tolerance']:.0f} % scale tolerance, against the"
        f" {r['allowance']:g}° clean builds read; the rover loses {r['c_rr']:.4f} of its weight"
        f" rolling [{_end(clo, '.4f')}, {_end(chi, '.4f')}] (the ground, the tires and the"
        " drivetrain's drag together)"
    )
    frames = f" {r['frames']}" if r.get("frames") else ""
    return ["", f"{head}; {verdict}." + moved + drive + frames]


HEADED = {
    "end fix": "the free wheels' turn fitted to each drive's one pose fix",
    "free wheels": "the free wheels' turn",
}
"""Where the runs' headings came from, where not the pose's fixes
(:mod:`rover_env.calibration.heading`)."""


def _headed(source: str | None) -> str:
    """The runs' headings' source, where not the pose alone."""
    if not source or source == "pose":
        return ""
    parts = [HEADED.get(p.strip(), p.strip()) for p in source.split(",") if p.strip() != "pose"]
    return ", headed by " + " and ".join(parts) + (" and the pose" if "pose" in source else "")


def _across(r: dict[str, Any]) -> str:
    """The heading's 95 % interval, where the record has one that is not the whole circle;
    where the frames were fitted or left unread (``diagnose --frames fit``) that the heading
    is not known."""
    placed = r.get("frames_placed", "given")
    free = (
        "; its size read free of the frames, profiled over each log's turn"
        if r.get("size_bounds") is not None
        else ""
    )
    if placed != "given":
        return (
            f" (not known: the frames were {'fitted' if placed == 'fitted' else 'not fitted'}"
            + free
            + ")"
        )
    lo, hi = r.get("heading_interval") or (None, None)
    if lo is None or hi is None or hi - lo >= 360.0:
        return ""
    return f" [{lo:.0f}°, {hi:.0f}°]"


def _end(v: float | None, spec: str) -> str:
    """An interval's end, or "unbounded" where the runs leave it open (None in the JSON)."""
    return "unbounded" if v is None or not math.isfinite(v) else format(v, spec)


def balance_method(allowance: float | None, read: bool, source: str = "effort") -> list[str]:
    """The method's bullet on the tilt read from the reported torque (or the wheels' slip)."""
    if allowance is None or not read:
        return []
    if source == "slip":
        return [
            "- Balance (slip): where the logs carry no torque, each steady straight run's slip"
            " (one minus the free wheels' turn over the driven wheels') times the driven tires'"
            " slip stiffness is the traction along the track; it is fitted as the rover's"
            " weight times the ground's tilt along its heading (the pose's, or the free"
            " wheels' turn fitted to each drive's last fix) plus a term that flips with the"
            " direction of travel (a radius or a resistance slips the same both ways); a tilt"
            f" whose interval clears {allowance:g}° (what clean builds of another"
            " implementation read) names the slope."
        ]
    return [
        "- Balance: where the logs report the motors' torque, the driven wheels' summed torque"
        " over the lever to the contact point, on steady straight runs, is fitted as the"
        " rover's weight times the ground's tilt along its heading (the pose's, or the free"
        " wheels' turn fitted to each drive's last fix) plus a resistance that flips with the"
        " direction of travel; a tilt whose interval clears"
        f" {allowance:g}° (what clean builds of another implementation read) names the slope."
    ]


def groups_note(chosen: list[Scored]) -> list[str]:
    """For each named effect whose interval for the truth reaches "off" only through its
    signal groups' disagreement (named on its windows' interval,
    :attr:`~rover_env.calibration.diagnosis.state.Options.presence_on_windows`): why it is
    named, and that its size is what is loose."""
    out = []
    for s in chosen:
        if not off_by_groups(s.fit) or not s.fit.groups:
            continue
        apart = ", ".join(f"{g} {v:.3g}" for g, v in sorted(s.fit.groups.items()))
        out.append(
            f"{s.fit.name} is named on its windows' interval, which, less what clean drives"
            " of another implementation fit, stays clear of off; its interval above reaches"
            f" off only because its signal groups disagree on its size ({apart}): the effect"
            " is there, its size is loose (the model's form differs from the rover's)."
        )
    return out

"""The report's "Data and method" section: what this diagnosis did, in the words of the
options it ran with (split from :mod:`rover_env.calibration.report`, which writes it)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from rover_env.calibration.candidates import REPLACED_BY_SOIL
from rover_env.calibration.diagnosis.state import LEADING, ODOMETRY_BAND, OdometryBand, Options
from rover_env.calibration.report_notes import balance_method, effort_method


def _frames_line(result: dict[str, Any]) -> list[str]:
    """Where the logs gave their start headings: the frame every heading here is in."""
    heads = result.get("start_headings") or []
    fr = result.get("frames")
    if fr and not fr.get("fitted"):
        return [
            f"- Frames: not fitted ({fr['why_not']}); the drives read as facing the same way,"
            " and a slope's heading, wherever this report gives one, is not known."
        ]
    if not any(h is not None for h in heads):
        return []
    each = ", ".join(f"{Path(p).name} {h:g}°" for p, h in zip(result["logs"], heads, strict=True))
    if fr:
        sds = fr["turn_sd_deg"]
        each = ", ".join(
            f"{Path(p).name} {h:.0f}°" + (f" ± {sd:.0f}°" if sd else "")
            for p, h, sd in zip(result["logs"], heads, sds, strict=True)
        )
        unread = fr["unread"]
        return [
            f"- Frames fitted (`--frames fit`): each log's frame turned into {fr['first']}'s"
            f" by the {fr['source']} balance's steady straight runs ({each}; F {fr['f']:.1f});"
            " a slope's size is read in them; its heading, wherever this report gives one,"
            f" is in {fr['first']}'s frame and not known (turns fitted so can mirror it)."
            + (
                f" No runs read the frame of {', '.join(unread)}: taken as the first's."
                if unread
                else ""
            )
        ]
    return [
        f"- Frames: each log's headings turned by its `start_heading_deg` ({each}) into the"
        " frame the drives share; a slope's heading and the balance's are in that frame."
    ]


def method_lines(result: dict[str, Any], opts: Options, rover: str) -> list[str]:
    """The report's "Data and method" section."""
    st = opts.settings
    return [
        "## Data and method",
        "",
        f"- Logs: {', '.join(Path(p).name for p in result['logs'])}; rover `{rover}`.",
        *_frames_line(result),
        f"- Split: {result['split']}.",
        f"- Replay: multiple shooting, windows of {st.window:g} s re-initialised from the log (joint"
        " angles and rates, wheel rates, segment 3's motion from the free wheels, controller"
        " setpoints from the logged commands after the model's command delay or lag),"
        f" first {st.burn_in:g} s of each not scored; residuals every"
        f" {st.stride:g} s: wheel-angle increments, joint angles, and pose increments where the log has pose."
        " Open-loop replay of a whole drive was rejected: one early heading error dominates everything after it.",
        model_form_line(
            result.get("model_form"),
            result.get("model_form_reverted"),
            result.get("model_form_beside"),
            opts.forms_beside_winner,
            result.get("model_form_changed") or [],
        ),
        *weak_beside_line(result.get("model_form_weak_beside")),
        '- Fit, blind to magnitude: one parameter is searched over its whole physical range ("off" and a'
        " log-spaced ladder of 5 values per sign from 1.2 % to 100 % of the range, then a bounded Brent search"
        " between the best value's neighbours); several parameters start from the best ladder point or the"
        " single fits and are refined by bounded least squares (`scipy.optimize.least_squares`)."
        + (
            f" Each candidate is screened first on one training window in {opts.numpy_every}, fitted"
            " on all of them only if it lowers that subset's BIC by half its parameters' cost or"
            f' improves the held-out drive by {50 * opts.min_gain:.0f} % ("no (screened)" below)'
            + (
                "; the screen searches the ladder alone (its estimate the parabola through the"
                " best rungs; several parameters half the local budget)."
                if opts.screen_coarse
                else "."
            )
            if opts.screen
            else ""
        )
        + " The fits weigh the residuals"
        " per signal by the larger of the baseline training RMS and the sensor noise; a candidate"
        " that improves the training drives (BIC) is refitted with each signal scaled by its residual under that fit"
        f" (iteratively reweighted, up to {opts.reweigh} times), so the signals it fixes keep their weight."
        " 95 % intervals:"
        " one parameter, block bootstrap over training windows on the evaluated loss curves; several,"
        " cluster-robust (windows as clusters) sandwich covariance with Student t; one-sided where the"
        " estimate sits at a bound of its range, never narrower than the search's resolution, widened by"
        " the replay's own bias measured on the fitted model's twin drives. A named effect of several"
        f" parameters is finished by least squares with central differences (up to {opts.polish}"
        " evaluations); a named effect's interval is then widened to at least what the sensors alone put"
        f" on it ({opts.noise_draws} twins of the fitted model read through the logs' sensors with fresh"
        " encoder phases and noise, replayed: the estimate's scatter and bias under noise, 1.96 x)"
        + (
            f", then by the clean-fit allowance ({opts.form_allowance!r}): the 5-95 % spread of"
            " what the effect's fit finds on clean drives of another implementation, the model's"
            " own form seen through it (an interval for the truth: fitted lo - high, hi - low;"
            " a soil's k_phi: lo / high, hi / low, the spread of fitted over true k_phi on"
            " another implementation's named soils), each side at least as far as the truth sat"
            " beyond right names' own intervals there, and the end away from off at least as far"
            " from the fit as those truths sat beyond their fits (95 % quantiles)."
            if opts.form_allowance
            else "."
        ),
        f"- Decision: named only if the held-out error falls by ≥ {100 * opts.min_gain:.0f} % (geometric mean over"
        " held-out windows of the per-window ratio, so that a few very sensitive windows do not decide alone)"
        f" with a one-sided Wilcoxon signed-rank test of the per-window log ratios at p < {opts.alpha:g} and the"
        " training BIC falls (windows as observations, each with its own error scale, each signal in units of its"
        " replay floor as on the held-out drive: ΔBIC = Σ log(loss ratio) + k ln n)."
        " When no candidate passes that window test, one whose held-out replay takes at least one signal back"
        " under the current model's replay floor (the test of the tables below) and puts none above it may be"
        " named instead (an effect seen in a few windows only, such as a torque limit the drive reaches a few"
        " times, cannot pass a test across windows). Of the candidates that pass, the one with the lowest"
        " ΔBIC over all windows, training and held-out, is the winner"
        + (
            ", if its fitted magnitude reaches its detection limit on these logs (the table below):"
            " a smaller fit explains what the model itself leaves, not the effect."
            if opts.name_above_limit
            else "."
        )
        + " A runner-up (the next significant candidate, or one"
        " that improves the held-out drive more than the winner and lowers the training BIC without passing"
        " the window test) not worse than the winner at p < "
        f"{opts.tie_alpha:g} is reported as a tie. Second effect by forward selection under the same rules"
        + (
            " (its detection limit measured beside the winner)."
            if opts.name_above_limit and opts.partner_limit
            else "."
        )
        + order_clauses(opts)
        + " Named with confidence only if the chosen effects make no held-out signal they leave"
        " above its floor worse (per-window mean squares, one-sided Wilcoxon at p <"
        f" {opts.alpha:g}) by at least {opts.trade_share:g} of what the other signals gain"
        " (each in units of its floor): an effect that trades one signal for another stands"
        " in for something outside the catalogue."
        + (
            " Last, a named effect whose interval for the truth, the clean-fit allowance in"
            ' it, reaches "off" is not named (the model\'s form alone gives as much); each'
            " effect of a pair by its own, the other then named only by its own fit."
            if opts.name_beyond_allowance and opts.form_allowance
            else ""
        ),
        *odometry_method(opts),
        *(
            [
                "- One wheel: a named rolling resistance is withdrawn where the two free wheels'"
                " travel against the pose (as for odometry) differs from the named model's twins"
                f" by more than {100 * (opts.odometry or ODOMETRY_BAND).split:.0f} % between"
                " them (the ground drags both alike, a dragging brake one)."
            ]
            if opts.one_wheel
            else []
        ),
        *effort_method(opts.effort_tolerance, result.get("effort") is not None),
        *_balance_method(opts, result.get("balance")),
        f"- Cost: {result['replays']} replays, {result['replay_seconds']:.0f} s of replay,"
        f" {result['seconds']:.0f} s in all{stage_text(result.get('stage_seconds') or [])}.",
    ]


def _balance_method(opts: Options, bal: dict[str, Any] | None) -> list[str]:
    """The balance's bullet, for the source it read."""
    slip = (bal or {}).get("source") == "slip"
    allow = opts.slip_allowance if slip else opts.balance_allowance
    return balance_method(allow, bal is not None, "slip" if slip else "effort")


def order_clauses(opts: Options) -> str:
    """What the naming order and forward selection leave out or put last."""
    tire = ", ".join(sorted(REPLACED_BY_SOIL))
    return (
        f" Beside a loose soil the tire's effects ({tire}) are not tried: on loose soil the"
        " soil, not the tire, carries and resists the wheel."
        if opts.soil_alone
        else ""
    ) + (
        " A fit that ends at its range's far end (the effect at its largest) is tried for"
        " the name after the significant fits inside their ranges."
        if opts.pegged_last
        else ""
    )


def weak_beside_line(weak: dict[str, Any] | None) -> list[str]:
    """The forms adopted beside an effect on weak evidence only, which kept the first
    choice (:attr:`~.diagnosis.state.Options.weak_adoption_stands`)."""
    if not weak:
        return []
    return [
        f"- Beside {weak['beside']} the model form came out otherwise only by adoptions on weak"
        f" evidence (|dBIC| < 2: {'; '.join(weak['changes'])}): the first choice stands, and the"
        " diagnosis did not run again for it."
    ]


def stage_text(passes: list[dict[str, float]]) -> str:
    """Where the seconds went, stage by stage and pass by pass (the write not counted)."""
    if not passes:
        return ""
    parts = [", ".join(f"{k} {v:.0f} s" for k, v in p.items()) for p in passes]
    if len(parts) == 1:
        return f" (by stage: {parts[0]})"
    return " (by stage, " + "; ".join(f"pass {i + 1}: {t}" for i, t in enumerate(parts)) + ")"


def noise_clause(z: float) -> str:
    """The odometry band's widening for the pose's own noise, in the method's words."""
    if z <= 0:
        return ""
    return (
        f"; widened in quadrature by {z:g} standard errors of the statistic from the pose"
        " fixes' own noise, read from their scatter across the heading: short straight"
        " driving reads it to per cent"
    )


def odometry_method(opts: Options) -> list[str]:
    """The method's bullet on naming a rolling radius from dead reckoning."""
    b = opts.odometry
    if b is None:
        return []
    return [
        "- Odometry: after the windows (also when their name was withdrawn), a rolling radius"
        " not named is named when the free"
        " wheels' travel against the pose (straight, moving pose intervals, along the heading)"
        " differs between the logs and the named model's twins beyond what clean drives of"
        f" another implementation leave ({100 * b.lo:+.2f} to {100 * b.hi:+.2f} %, centre"
        f" {100 * b.mid:+.2f} %{noise_clause(b.noise_z)}), both free wheels agree (within {100 * b.split:.1f} %), the"
        " driven wheels read the same change (their difference within"
        f" {100 * b.driven:.0f} % of the free wheels': a radius moves every wheel alike, the"
        " slip of loose soil, a drag or a load moves them apart), the change that closes it"
        " lies in the radius's range, and loose soil is not named (another implementation's"
        " soil makes the free wheels bulldoze more than the model's); the held-out windows"
        " under it are reported, not judged (the model's turns may answer a radius otherwise"
        " than the rover's);"
        f" its 95 % interval is the clean drives' 2.5-97.5 % ({100 * b.ci_lo:+.2f} to"
        f" {100 * b.ci_hi:+.2f} %) seen through the twins' sensitivity to the radius."
        + end_clause(opts.odometry_end)
    ]


def end_clause(e: OdometryBand | None) -> str:
    """The odometry bullet's sentence on logs with the pose at each drive's end only."""
    if e is None:
        return ""
    return (
        " Where the logs hold no such interval (the pose at each drive's end only), each drive"
        " commanded straight is read from its start to its last fix (the path an arc by the"
        " fix's yaw, over the free wheels' net travel; drives ending under 1 m from the start"
        f" left out), judged by its own clean band ({100 * e.lo:+.2f} to {100 * e.hi:+.2f} %,"
        f" centre {100 * e.mid:+.2f} %, 95 % {100 * e.ci_lo:+.2f} to {100 * e.ci_hi:+.2f} %)."
    )


def model_form_line(
    mf: dict[str, Any] | None,
    reverted: dict[str, Any] | None = None,
    beside: str | None = None,
    refit_beside: bool = True,
    changed: list[str] | None = None,
) -> str:
    """The model-form stage (rover_env.calibration.diagnosis.form) in one bullet."""
    if reverted is not None:
        return (
            "- Model form: fitted first, then reverted to the configuration's when judged"
            f" beside the effects ({reverted['text']}; BIC on the same training windows"
            " against the nominal model, the form's parameters counted): the form had"
            " absorbed part of an effect, so every candidate was judged again without it."
        )
    if mf is None:
        return (
            "- Model form: not fitted (the configuration's tire relaxation length and slip floor"
            " and the speed loop's windup kept)."
        )
    what = {
        "relaxation_length": (
            "the tire's relaxation length (the SPEC's tire is steady state)",
            1e3,
            "mm",
        ),
        "slip_floor": (
            "the tire's low-speed slip floor (Gim's slip is 0/0 at rest; 0: none)",
            1e3,
            "mm/s",
        ),
        "max_angle_error": ("the speed loop's anti-windup bound", 1e3, "mrad"),
        "speed_gain": ("the speed loop's proportional gain at the wheel", 1.0, "N m s/rad"),
        "integral_gain": ("the speed loop's integral gain at the wheel", 1.0, "N m/rad"),
        "yaw_spring": ("the yaw joints' leaf springs (SPEC gives none)", 1.0, "N m/rad"),
        "joint_height": ("the joints' height above the axles (SPEC gives none)", 1e3, "mm"),
        "com_height": (
            "the segments' centres of mass above the axles (SPEC gives none)",
            1e3,
            "mm",
        ),
        "anti_windup": ("the speed loop's anti-windup form", 1.0, ""),
    }
    parts = []
    for name, f in mf.items():
        label, k, unit = what.get(name, (name, 1.0, f.get("unit", "")))
        change = 100 * f["training_gain"]
        words = f"{change:.1f} % better" if change >= 0 else f"{-change:.1f} % worse"
        verdict = "adopted" if f["adopted"] else "kept the nominal value"
        if f.get("at_end"):
            verdict += (
                " (the end of the range tried: the windows ask for more than this form gives,"
                " so something else must supply it)"
            )
        if f.get("beaten_by"):
            verdict += f" (not adopted before the effects: {f['beaten_by']})"
        if f.get("choices"):  # a choice (the anti-windup form): names, no unit
            fitted, nominal = f"{f['fitted']}", f"{f['nominal']}"
        else:
            fitted = f"{k * f['fitted']:.3g} {unit}"
            nominal = f"{k * f['nominal']:.3g} {unit}"
        parts.append(
            f"{label} {fitted} against the nominal {nominal}"
            f", training windows {words} (Wilcoxon p {f['p']:.2g}, dBIC"
            f" {f['d_bic']:+.1f}): {verdict}"
        )
    if beside and beside.endswith(LEADING):
        when = (
            f"fitted beside {beside.removesuffix(LEADING)} (the leading candidate of a first pass"
            " that named nothing, under forms fitted before any effect that came out otherwise"
            " beside it)"
        )
    elif beside:
        when = (
            f"fitted beside {beside} (named in a first pass, under forms fitted before any"
            " effect that came out otherwise beside it)"
        )
    else:
        when = "fitted before any effect" + (
            " (and, beside an effect named or leading, again: unchanged, or adopted one way"
            " and not the other on weak evidence both times, |dBIC| < 2)"
            if refit_beside
            else ""
        )
    if beside and changed:
        when += "; what changed: " + "; ".join(changed)
    return (
        f"- Model form, {when} (the implementation's choices, not the rover's definition): "
        + "; ".join(parts)
        + ". These are not effects; the adopted values are written into the updated"
        " configuration."
    )

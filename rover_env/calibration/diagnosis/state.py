"""The diagnosis's state and result types: what every stage reads and writes.

At the bottom of the diagnosis's imports (it imports no stage, nor the report): each stage
(:mod:`.pipeline` names them in order) takes a :class:`Diagnosis` and fills its part of it,
and the report (:mod:`rover_env.calibration.report`) reads the finished one. Why one state
object: the stages share some twenty values (the windows, the evaluator, the floors, the
ranked candidates); passed by name, each stage's inputs and outputs are its fields.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rover_env.calibration.balance import CLEAN_SLIP_TILT, CLEAN_TILT
from rover_env.calibration.candidates import Candidate
from rover_env.calibration.fit import Evaluator, Fit
from rover_env.calibration.form_allowance import FormAllowance, load_allowance
from rover_env.calibration.noise_interval import DRAWS as NOISE_DRAWS
from rover_env.calibration.plans_held import HeldPlans
from rover_env.calibration.replay import PreparedLog, ReplaySettings, Window, WindowResult
from rover_env.calibration.residuals import Cell
from rover_env.config import RoverConfig
from rover_env.logs import DriveLog

Array = NDArray[np.float64]
Table = dict[str, dict[str, Cell]]
"""Residual / floor per signal and regime (:func:`rover_env.calibration.residuals.table`)."""


LEADING = " (leading, not named)"
"""Suffix of :attr:`Options.forms_beside` for forms fitted beside the leading candidate of a
first pass that named nothing (:func:`.again.judge_again`); the report reads it back."""
STRAIGHT = "straight"
"""The window set of every drive's windows without a turn (:func:`.replay.straight_windows`)."""


@dataclass(frozen=True)
class OdometryBand:
    """What clean drives of another implementation leave in dead reckoning's difference
    (the logs' path over free-wheel travel minus the named model's twins'), both free
    wheels together: beyond [``lo``, ``hi``] a rolling radius may be named; ``mid`` (the
    median: the model's own offset) and [``ci_lo``, ``ci_hi``] (2.5 and 97.5 %) give its
    change and interval; the two wheels against each other stay within ``split``, and the
    driven wheels' difference within ``driven`` times the free wheels' of theirs."""

    lo: float
    hi: float
    mid: float
    ci_lo: float
    ci_hi: float
    split: float
    driven: float = 0.5
    noise_z: float = 3.0
    """The band and its interval widen, in quadrature, by this many standard errors of the
    logs' statistic from the pose fixes' own noise (:func:`.odometry.widened`; 0: not). The
    band was measured on three-drive cases, whose straight travel (10-20 m) holds that noise
    to about 0.25 %; a drive of turns reads its path over a few short straight bits (0.3-1 m
    in spent study 71000), where it is 2-3 %, and each of the three radii named wrongly on
    one drive there had under 1 m. Scored on fresh study 71200."""


ODOMETRY_BAND = OdometryBand(
    lo=-0.025, hi=0.025, mid=-0.0019, ci_lo=-0.0151, ci_hi=0.0123, split=0.05, driven=0.5
)
"""From the independent generator's spent blocks 50800-51600 (stop 75; 325 cases without a
radius or soil: 63 clean and 262 singles of the seven other effects, the difference against
each case's named model): all within -2.2 to +2.2 % but one (a slope named with a radius,
-5.5 %), so the naming band is that envelope rounded out; median -0.19 %, 2.5-97.5 %
-1.51 to +1.23 %; |3L - 3R| at most 4.2 % (a dragging brake on one free wheel: 13.6 %).
``driven`` (stop 76, blocks 50800-51700, the nominal model's twins): beyond the band the
driven wheels' difference was 0.65 to 1.37 x the free wheels' on all 20 radius singles
there, -0.64 to +0.18 x on all 37 loose soils, -0.67 x on the one rolling resistance; a
payload's extra deflection (1 of 8 beyond the band) shortens every wheel's radius and reads
0.99 x. Scored on fresh study 60000: docs/calibration/studies.md."""


END_FIX_BAND = OdometryBand(
    lo=-0.02, hi=0.02, mid=-0.0011, ci_lo=-0.0104, ci_hi=0.0080, split=0.05, driven=0.5, noise_z=0.0
)
"""Dead reckoning against each straight drive's last fix (:func:`.odometry.form_of`), logs
minus the nominal model's twins, on the independent generator's exploratory seeds
70892-70999 (stop 100, ``benchmarks/end_fix_band.py``; 3 drives of 50 s, about one in three
commanded straight): 60 of 78 clean builds read (18 had no straight drive ending 1 m or
more from its start), all within -1.08 to +1.06 %, median -0.11 %, 2.5-97.5 % -1.04 to
+0.80 % (``mid``, ``ci_lo``, ``ci_hi``); 16 singles of delay, lag, friction, torque limit,
slope and rolling resistance -1.32 to +1.93 % against the nominal twins (the band, rounded
out to hold them all). The free wheels apart (3L - 3R) at most 3.7 % clean and 4.7 % on the
singles: the interval form's 5 % split stands. No pose noise widening (``noise_z`` 0): a
fix 1 m or more from the start, its noise in the clean spread measured here. Scored on
fresh study 72000."""


@dataclass
class Options:
    settings: ReplaySettings = field(default_factory=ReplaySettings)
    alpha: float = 0.01
    min_gain: float = 0.10
    """Smallest relative held-out improvement that can name an effect."""
    tie_alpha: float = 0.05
    reversal_tie: bool = True
    """A named slope against a significant drag (rolling resistance, loose soil), or the
    reverse, is a tie whatever the held-out p while no held-out window drives backwards, the
    only regime where one helps and the other hinders (:mod:`.tie`). Why (stop 118,
    exploratory): spent soil singles 53013 and 53104 were named a slope of 11-12 degrees
    with no tie and no drive proposed; two like them that tied (53011, 53109) were named the
    soil after their reversing drive. Fresh block 53200 (registered, 23 strong singles of
    slope, rolling resistance and soil): the other kind named 0/23, named alone 21/23; the
    rule declared 2 ties, both kept their right name (docs/calibration/block53200)."""
    trade_share: float = 0.1
    """A trade keeps an effect from being named only if the traded signals lost at least
    this share of what the other signals gained (:func:`.judge.trade_share`, each signal in
    units of its floor; 0: any trade). Why (issue 47): on another implementation's logs the
    trade test refused right fits whose worsened joint lost a thousandth of what the wheels
    gained (block 49000: a 0.10 s lag for 0.102, theta_4 1.15 x, share 0.0007; block 47600:
    a torque limit, theta_4 1.63 x, share 0.0009), and the second generator's soil (k_phi 3e5,
    fitted 3.05e5 [2.86e5, 5.36e5]; wheel_1L 1.18 x, share 0.012)."""
    numpy_every: int = 2
    """Numpy-only candidates are fitted on every n-th training window (they are ~20x slower)."""
    screen: bool = True
    """Screen each plugin-replayed candidate, and each partner beside the winner, on the
    numpy candidates' subset of the training windows (every :attr:`numpy_every`-th) before
    its full fit; only a promising one (:func:`.judge.promising`) is fitted again on all of
    them. Why (issue 47, item 4): on a clean case every candidate's full fit was spent
    (stop 55: 77 of 96 s, 10 fits of 12-25 replays), and a fit that cannot reach half of the
    naming rule on half the windows cannot be named on all of them."""
    screen_coarse: bool = True
    """A screen searches coarsely (:func:`rover_env.calibration.fit.fit`'s ``coarse``): one
    parameter on its ladder alone, the estimate the parabola through the best rungs (no
    Brent search, no stencil); several parameters with half the local budget. The full
    fit a promising screen earns searches as before. Why (stop 107): a screen only asks
    whether the full fit is worth it, yet spent the full fit's refinement on half the
    windows: 5 Brent evaluations and 2 stencil points on 6-11 ladder rungs, in each of
    about 15 screens of a named case (a lag case's profile: the Brent search 21 of 100
    replay seconds)."""
    screen_middle: bool = True
    """A candidate with several forms (the soil's) screens each at the ladder's middle rung
    too, not only where its first form fits best (:func:`rover_env.calibration.fit.
    _screen_forms`). Why (stop 133): dry sand 54917's regolith-constant basin lay far from
    the mars-sand forms' and was never searched; a slope was named instead of the soil."""
    screen_shared: bool = True
    """A lag and a delay fitted together (:attr:`shared_refit`) are first fitted once on the
    screening subset with half the evaluations, not reweighed, and fitted in full only where
    that is promising (:func:`.shared.shared_screen`; with :attr:`screen`)."""
    max_nfev: int = 4
    second: int = 4
    """Partners judged as pairs with the winner in forward selection: those that improve the
    held-out drive most beside it (``blind_partners``), or alone (otherwise)."""
    reweigh: int = 2
    """Refits of each candidate that improves the training drives (BIC), with each signal
    weighed by its residual after the last fit (iteratively reweighted least squares:
    per-signal error scales estimated with the parameter; 0: the stage-one scale only).
    Why: stage one weighs each signal by its residual *before* any effect, so the signals
    an effect fixes best (a delay: the driven wheels, 0.22 rad before, 3 mrad after) weigh
    ~1e-4 of the rest afterwards and the estimate is set by signals that carry the model's form difference (stop 37, case 16105: the
    second generator's joints put the delay at 0.197 s, its driven wheels at 0.226, truth
    0.2244; the fit at 0.209 and a partner, a lag or a torque limit, to make up the rest)."""
    polish: int = 12
    """Evaluations (``least_squares``' ``max_nfev``) to finish a named effect's fit of
    several parameters (a slope's tilt vector) from where its search stopped, in the scale
    it was fitted with (0: none), by central differences. Why: the search's budget
    (:attr:`max_nfev`) is spent across every candidate, from a ladder rung up to a factor 3
    away, with forward differences (stop 38, own slope 7.19 deg, case 17001: the search
    7.175 [7.04, 7.31], finished 7.247 [7.05, 7.45]; before the steps were fixed, see
    :func:`rover_env.calibration.fit.fit`, the search stopped at 6.57)."""
    noise_draws: int = NOISE_DRAWS
    """Simulated sensor-noise draws behind each named effect's interval (0: none): the
    interval is widened to at least what the sensors alone put on the value
    (:mod:`rover_env.calibration.noise_interval`). Why: both interval methods resample
    windows, and when one window carries an effect (a torque limit reached once) they
    cannot see that window's own noise (stop 38: own logs of a torque limit of -0.09, seed
    19003, one window of 32 reaching it: -0.0968 [-0.150, -0.0932])."""
    blind_partners: bool = True
    """Forward selection: every other candidate's magnitude-blind search with the winner held
    at its fit chooses the partners (False: the candidates that improved held-out alone,
    from their single fits; the behaviour until stop 34)."""
    shared_refit: bool = True
    """Forward selection: a partner that moves the winner's response by the sum of their values
    (:data:`~rover_env.calibration.candidates.SHARED_RESPONSE`, a command lag and a delay)
    is judged as a pair fitted with the winner, both free, from the winner's value split in
    half and reweighed by what it leaves (:func:`.shared.shared_refits`); False: beside the winner held at its fit, as every
    other partner (the behaviour until stop 102). Fresh studies 72900 and 73000 (registered):
    18/20 and 20/20 pair effects named, no single lag or delay gaining a partner (0/12)."""
    frames: str = "given"
    """Each log's frame: ``given`` (its ``start_heading_deg``, or every drive facing the same
    way where no log gives one) or ``fit`` (none given and no frame the drives share: each
    log's turn fitted by the balance's runs, :mod:`.frames`)."""
    candidates: list[str] | None = None
    progress: bool = True
    workers: int = 1
    """Processes fitting candidates side by side (forked; 1: in this process)."""
    executor: str = "local"
    """Where candidate fits run: ``local`` (forked processes) or ``ray`` (rover_env.executor)."""
    ray_address: str | None = None
    evidence: int = 2
    """Candidates for which a deciding drive is proposed and simulated, at most."""
    max_draws: int = 2
    """Draws of a candidate's deciding plan after which, still unconfirmed, it asks for no
    other (``evidence_judged``: ``draws``; 0: no cap). Why (stop 130): a lean short of
    alpha asks for the next draw, and clean case 54509 asked for seeds 0, 1 and 2 of
    ``steps`` for a command delay at the allowance's edge, 50 s of driving each."""
    strong_bic: float = -6.0
    """Training ΔBIC at or below which a candidate that is not named, but improves the
    held-out drive at all, is given a deciding drive (:mod:`.evidence_stage`; Kass and
    Raftery's "strong"). Why (stop 58, registered; applied since stop 59): a torque cut of
    -0.66 fitted -0.742 with ΔBIC -6.7 and its held-out drive 8.5 % better at p 0.3 got
    neither a name nor a drive, since that drive excites the limit (case 47603)."""
    limit_resolution: float = 0.05
    """Smallest torque cut worth testing, as a fraction of the limit (issue 47: cuts from
    5 %; 0: never asked). When the drives reach the motors' limit only for larger cuts (the
    torque limit's noise threshold) and none is named, the drive that reaches it is
    proposed as ``untested`` (:func:`.evidence_stage.untested_limit`). Why (stop 59): a
    limit acts only where it is reached, unlike the catalogue's other effects, which act on
    every drive; a drive that never asks the motors for their torque says nothing of it."""
    rotor_range: float = 2.0
    """Factor of the rotor inertia's tolerance: a named torque limit is refitted with
    ``motor.armature`` divided and multiplied by it, and its interval holds theirs
    (:func:`.rotor.profile_rotor`; 1: off). Why (stop 59): the limit is measured as the
    torque over the rotor inertia, which a build's data give to about a factor 2."""
    rotor_alpha: float = 0.05
    """A named torque limit stays named only if the held-out windows favour it over the
    rotor inertia in its place at this one-sided Wilcoxon p (:func:`.rotor.rotor_test`; 1:
    off, the limit is named as before). Why (stop 62): a limit the drives reach only when
    accelerating is measured as the torque over the rotor inertia, and a configured rotor
    that is off reads as a cut (13 limits named on the independent generator, none right)."""
    name_above_limit: bool = True
    """Name an effect only if its fitted magnitude reaches its detection limit on these logs
    (:func:`.judge.below_detection_limit`): below the smallest effect the logs can show
    against what the model leaves, a fit explains the model's own mismatch. Stop 73."""
    form_allowance: str | None = "form_allowance"
    """The clean-fit allowance table (a shipped name in ``configs/calibration/`` or a YAML
    path; None: off) that widens each named effect's interval for the model's form
    (:mod:`rover_env.calibration.form_allowance`); what is named does not depend on it. Why
    (stop 74): on the independent generator's blocks 50800-51400 the stored intervals held
    the truth of a right name 34 times in 67 (delays fitted about 0.02 s long in every
    miss); widened by the clean fits' spread, 59 in 67, and on fresh block 51500 11 in 12
    (stored 7)."""
    name_beyond_allowance: bool = True
    """Name an effect only if its interval for the truth, widened by the clean-fit allowance
    (:attr:`form_allowance`), keeps clear of "off" (:func:`.select.withdraw_within_allowance`):
    a magnitude the model's own form gives on clean drives of another implementation is not
    evidence of the effect. Why (stop 77): on the independent generator's spent blocks
    50000-51800 it would have kept 200 of 225 right names and dropped 61 of 86 others,
    10 of 11 on clean drives (in-sample for the clean cases of 50800-51500, whose fits made
    the table then; stop 79 measured it again on 100 clean cases of blocks 49000-52100 with
    its own code, the same verdicts on blocks 51800-52100); on fresh block 52000 it
    withdrew 6 names, 4 not the truth (docs/calibration/method.md). Each effect of a pair is judged by its own allowance
    (stop 78: on block 52000 three false second effects of a pair fit stayed named; on
    fresh block 52100, 16 of 17 names right)."""
    presence_on_windows: bool = True
    """Judge :attr:`name_beyond_allowance` on the windows' interval (sensor noise in it),
    without the signal groups' disagreement (:func:`~rover_env.calibration.fit.widen_by_groups`),
    which then widens the reported interval only. Why (stop 132): the allowance is what
    clean builds' fits reach, the model's form already in it; the groups' spread is that form
    again, growing with the effect's size. Spent 54809's rolling resistance of 0.068 (61 %
    better held out) was fitted 0.097 [0.078, 0.102] by its windows; free wheels 0.135 and
    joints 0.036 widened it to [0, 0.239], and it was not named. On fresh block 54900
    (registered) it made no name in 55 cases; no clean build was named (0/10)."""
    next_after_withdrawn: bool = False
    """When the clean-fit allowance withdraws every named effect, try the next significant
    candidate in the naming order, named only by its own fit and judged the same way
    (:func:`.select.name_next`), as a candidate under its detection limit lets the next be
    tried. Why it was tried (stop 88): on study 65000 a 2.9 deg slope named first and
    withdrawn ended the naming while the rolling resistance behind it (0.106 [0.071, 0.114]
    for 0.076, held out 46 % better) was never tried. Off: fresh block 52400 (registered)
    failed its primary line, final names right 9/11 under 85 %, on two names the rule did
    not make (outside cases); the rule made no final name in 87 cases, 1 right one in a
    first diagnosis, and nothing on 60 clean cases (docs/calibration/method.md)."""
    one_wheel: bool = True
    """Withdraw a named rolling resistance where dead reckoning's two free wheels disagree
    beyond the odometry band's ``split`` (:mod:`.one_wheel`): the ground drags every wheel
    alike, a dragging brake one. Why (stop 89): a brake dragging on one free wheel was named
    a rolling resistance in 13 of 24 spent outside cases of the independent generator. On
    fresh study 67200 (registered) it withdrew 8 of 12 such names (final rolling resistances
    on brake drags 4/28) and no rolling-resistance single or clean case of 120 parted the
    wheels that far (docs/calibration/method.md)."""
    interleave: bool = False
    """Hold out every other window of each drive instead of the last drive (off: the
    held-out drive is one the fit never saw). Why (stop 110): an effect that only one drive
    excites cannot be fitted when that drive is held out, nor confirmed when it trains
    (exploratory 74037: a torque cut of 60 % that only the reversals drive reaches)."""
    torque_forms: bool = False
    """Search the torque limit in each anti-windup form (:data:`~rover_env.calibration.
    candidates.TORQUE_FORMS`), each form's own "off" the form alone: the limit is then
    judged against the form that hides or shows it, not against the configured loop only.
    Off: on fresh study 73900 (registered) the cut was fitted within 0.15 of its truth in 6
    of 8 (2 of 8 without), but named in none; the rotor test and the clean-fit allowance,
    both measured under the configured loop, withdrew every significant fit. And clean
    builds fit deep cuts under it (stop 111: median 45 %, 14 of 20 beyond 30 %; 18 % and 3
    of 20 without), the cut standing in for a rotor heavier than configured."""
    slip_beside_lead: bool = True
    """Where dead reckoning's driven wheels slip apart from its free wheels against the
    named model's twins, read the radius against the twins of the named model with the
    leading unnamed fit beside it (:func:`.odometry.slip_lead`): a drag the windows fitted
    but did not name makes that slip, and a radius beside it was refused. Why (stop 105):
    study 73100's two missed radii (73100, 73103's follow-up) each had a significant
    rolling-resistance fit left unnamed, their driven wheels 5 and 3.6 % apart from the
    free wheels' -3.1 and -3.9 %; the rule was then registered and scored on fresh cases
    (study 73200, docs/calibration/studies.md)."""
    partner_limit: bool = False
    """A second effect, as the winner, is named only if it reaches its detection limit,
    measured beside the winner (:func:`.select.partner_limits`; with
    :attr:`name_above_limit`). Why it was tried (stop 90): on one or two drives of a
    command lag a friction beside it below its limit was named. Off by default: fresh
    study 71000 (registered; 130 cases on one and two drives) failed its power line, 0 of 3
    wrong names in two-name diagnoses removed (all three from odometry's radius or a single
    window name, which it cannot touch); it acted in 3 cases and changed no final name,
    and removed no right one (docs/calibration/method.md)."""
    soil_from_motion: bool = False
    """Read a named soil's k_phi from the rover's motion, the pose group's own minimum, where
    the pose has one (:func:`.motion.from_motion`). Why it was tried (stop 82): the yaw
    joints, free wheels and driven wheels read the soil through forms of this model (the
    yaw springs, a wheel's reading gain, the speed loop); on spent study 60800's cases the
    pose group was within 2 x of the true k_phi on 19 of 25 first-pass fits, every signal
    on 14 of 25. Off by default: on fresh study 61600 (registered) it put k_phi within 2 x
    on 12 of 19 soil singles, short of the registered 70 % (the fit over every signal: 12
    of 23 on study 60800), at wider intervals (median hi / lo 20 against 13)."""
    soil_alone: bool = True
    """Beside a loose-soil winner, forward selection tries no effect the soil replaces
    (:data:`~rover_env.calibration.candidates.REPLACED_BY_SOIL`: the tire's). Why (stop 116,
    exploratory, spent case 52917, a dry-sand soil of k_phi 5.2e5): with :attr:`pegged_last`
    the soil was named first (k_phi 3.6e5) and a rolling resistance of 0.065 beside it (held
    out 97.9 % better against the soil's 89.3 %), the soil's own resistance under the
    catalogue's regolith constants; the independent generator's tire effects do not act on
    soil. Fresh block 53000 (registered, with :attr:`pegged_last`): 0 of 15 soil singles
    named a rolling resistance (docs/calibration/block53000)."""
    soil_from_straight: bool = True
    """Read a named soil's k_phi from straight driving: one signal group's own minimum over
    the windows without a turn (:func:`.straight.from_straight`; the joints', or the pose's
    with :attr:`soil_from_joints` off, as it was until stop 117). Why (stop 83): in a turn
    the yaw springs, whose stiffness SPEC does not give, trade with k_phi, and every signal
    over every window put k_phi within 2 x on 16 of 27 spent soil cases of study 60800; the
    pose on straight windows on 22 of 27 (and on 13 of 18 of spent study 61600's, where the
    pose over every window had 12 of 18). On fresh study 62400 (registered): 13 of 15 soil
    singles within 2 x, every named one (docs/calibration/study62400)."""
    soil_from_joints: bool = True
    """The straight read (:attr:`soil_from_straight`) takes the joint signals' minimum, not
    the pose's (:data:`.straight.SINKAGE_GROUP`): the suspension's angles are set by the
    wheels' sinkage, which k_phi governs, while the pose reads the travel, how much of the
    wheels' turning the soil's shear turns into motion, through shear constants the catalogue
    fixes at mars-sand's. Both groups' readings are recorded (``read_from``). Why (stop 117,
    exploratory, spent soil singles re-diagnosed with a grid of k_phi on the straight
    windows): the joints' minimum within 2 x of the truth on 17 of 17 (0.51-1.81 x), the
    pose's on 11, the fit over every signal on 10 (docs/calibration/block53100/prereg.md).
    Fresh block 53100 (registered): 15 of 15 named soils within 2 x, the pose's reading on
    the same cases 14 of 15 (docs/calibration/block53100)."""
    pegged_last: bool = True
    """Name a candidate whose fit ends at its range's far end (:func:`.judge.pegged`: the
    effect at its largest, the logs wanting more) only after the significant candidates
    fitted inside their ranges; never dropped. Why (stop 84, exploratory): a rolling
    resistance at c_rr 0.3, its range's top, came first on exactly the 4 spent soil singles
    that lost the soil's name; re-run with it, 3 of them named the soil. Study 64000 scored
    it only coupled with :attr:`soft_end_unread`, which cost 3 straight reads. Alone, on by
    stop 116: every named fit at a range's end of blocks 50300-52900 (about 1,600 cases)
    was a rolling resistance at 0.3 on a soil single (5, all wrong) or a torque cut at
    -0.8 (1, truth -0.76). Fresh block 53000 (registered): no soil single of 15 named a
    rolling resistance, the soil named on 14 (docs/calibration/block53000)."""
    soft_end_unread: bool = False
    """Read no soil from straight driving whose best rung is the range's soft end
    (:func:`.straight.group_minima`: the minimum may lie beyond the range). Off: on
    fresh study 64000 (registered, with :attr:`pegged_last`) it refused the straight read
    of 3 named soils, whose fits over every signal stood at 6.56, 0.65 and 4.10 x the truth."""
    odometry: OdometryBand | None = ODOMETRY_BAND
    """Name a rolling radius from dead reckoning against the pose (:mod:`.odometry`) beyond
    this band of what clean drives leave (None: off). Why (stop 75): the replay windows named
    none of 10 radius singles at 2 x threshold or more on the independent generator's spent
    blocks; on the same blocks' logs and twins the rule reads all 6 radius singles of a
    change of 0.055 or more, 19 of 37 in all, each interval holding the truth."""
    odometry_end: OdometryBand | None = END_FIX_BAND
    """The band that judges dead reckoning against each straight drive's last fix, where the
    logs hold no straight interval between fixes (the pose at the end only: SPEC §6, the
    paper's case; :func:`.odometry.form_of`); None: such logs name no radius."""
    effort_tolerance: float | None = 0.10
    """Where the logs report the motors' torque (``effort_*``), read the torque limit from it
    (:mod:`rover_env.calibration.effort`) and name a cut beyond this scale tolerance of the
    reported torque (the driver's torque constant and the gearhead's efficiency, as a
    datasheet gives them; None: not read). Why: the wheel angles show a cut under about 60 %
    only as the rotor does (``docs/calibration/limits.md``); the torque itself shows it."""
    balance_allowance: float | None = CLEAN_TILT
    """Where the logs report the motors' torque and the pose's yaw, read the ground's tilt from
    the force balance on steady straight runs (:mod:`rover_env.calibration.balance`) and name
    a slope whose interval, less this many degrees (what clean builds read), stays above
    level (None: not read). Why: the windows read a slope through the joints, which clean
    builds of another implementation lean by up to 2.4°; the summed torque does not lean."""
    slip_allowance: float | None = CLEAN_SLIP_TILT
    """Where the logs carry the pose's yaw and no torque (or it is not read), read the tilt
    from the slip balance instead: each steady straight run's driven-wheel slip against the
    free wheels', forwards against backwards (a slope adds traction one way and takes it the
    other, a radius or resistance adds the same slip both ways); a slope whose interval, less
    this many degrees, stays above level is named (None: not read)."""
    model_form: bool = True
    """Fit the model's own form first, in this order: the joint sensors' zeros, the speed
    loop's anti-windup form, the tire's relaxation length, the yaw joints' springs and the
    joints' height; the speed loop's gains, the centres of mass's height and the tire's
    low-speed slip floor when asked (:mod:`.form`)."""
    fit_joint_zero: bool = True
    """Fit the joint sensors' zeros as model form, the first stage (:func:`.form.fit_joint_zeros`;
    stop 54: on the independent generator's clean logs a 33 mrad constant on theta_4 was
    the largest residual of every window)."""
    fit_free_gain: bool = True
    """Profile the free wheels' left/right reading difference out of every fit
    (:attr:`rover_env.calibration.evaluator.Evaluator.profile_free_gain`; stop 55: a 1 %
    wheel-radius tolerance left the independent generator's straight clean drive's free
    wheels 2-3 x their floor)."""
    free_common: float = 0.01
    """Largest common reading gain of the free wheels profiled out of every fit
    (:attr:`rover_env.calibration.evaluator.Evaluator.free_common_max`; 0: none). Why (stop
    58): a 1 % wheel-radius tolerance put the independent generator's clean free wheels
    0.6 % off the driven ones, which read as a rolling resistance of c_rr 0.013-0.019."""
    fit_yaw_spring: bool = True
    """Fit the yaw joints' leaf-spring stiffness as model form, after the relaxation length
    (:func:`.form.fit_yaw_spring`; stop 54: another implementation's 15 N m/rad against
    this configuration's 10 left the yaw joints 14-18 x their floor in turns)."""
    fit_joint_height: bool = True
    """Fit the height of the joints between segments above the axles as model form
    (:func:`.form.fit_joint_height`; stop 64: the independent generator's slopes were fitted
    below the truth, 0.48-0.98 x in all 8 spent cases of 4 deg or more; its joints sit 5 cm
    above the axles, this model's on the axle line)."""
    height_beside_soil: bool = True
    """Adopt no joint height before the effects where a loose soil at the configured height
    explains the training windows better (:mod:`.form_soil`; stop 134: a very soft soil's
    roll swings took the joints 3 cm below the axles, and no soil was fitted then)."""
    fit_com_height: bool = False
    """Fit the segments' centre-of-mass height as model form (:func:`.form.fit_com_height`;
    stop 64: the independent generator's centres of mass sit 5 cm lower than this model's).
    Off by default since stop 69: adopted in 1 of 114 diagnoses (blocks 50800 and 50900),
    0 of 30 in block 50500, at the cost of a ladder of replays in every form stage."""
    fit_speed_loop: bool = False
    """Fit the speed loop's gains as model form, after the relaxation length
    (:func:`.form.fit_speed_gain`, :func:`.form.fit_integral_gain`; stop 66: another
    implementation's voltage-mode PI with back-EMF is about 3 x stiffer at the wheel than
    the configuration's 2 N m per rad/s, and on hard accelerations that motor form was the
    largest thing the model missed). Off by default since stop 69: on fresh cases adopted
    in 1 of 47 diagnoses (block 50700) and 1 of 114 (blocks 50800 and 50900; the speed gain
    never), at the cost of two ladders of replays in every form stage."""
    joint_motor_loop: bool = False
    """Fit the speed loop's form as one (:func:`.form_loop.fit_motor_loop`): its anti-windup
    form, both gains and the rotor inertia searched together and adopted as a whole, in
    place of the anti-windup form and the gains one at a time (:attr:`fit_anti_windup`,
    :attr:`fit_speed_loop`). Off by default (stop 68): on the independent generator's clean
    case 50845 it found a loop 17.8 % better on the training windows that did not pay the
    BIC and replayed the held-out drive worse; for a rover whose loop is known to differ
    from the configuration's, ``--joint-motor-loop``."""
    fit_slip_floor: bool = False
    """Fit the tire's low-speed slip floor (``TireParams.v_floor``) as model form, after the
    relaxation length (:func:`.form.fit_slip_floor`; stop 30: the second generator's
    steady-state tire regularises slip below 5 cm/s, and in a slow pivot turn its free
    wheels turned twice as fast as this model's, -0.22 against -0.11 rad/s; with the floor
    at 5 cm/s and a 2.5 mm relaxation length, -0.220). Off by default since stop 69: adopted
    in 0 of 114 diagnoses of the independent generator's logs (blocks 50800 and 50900)."""
    fit_anti_windup: bool = True
    """Choose the speed loop's anti-windup form (clamp or conditional integration) as model
    form, the first stage (:func:`.form.fit_anti_windup`). On by default since stop 30:
    with the clamp alone, every big command step of the second generator's logs (a
    conditionally integrating PI) left the driven wheels 0.1-0.2 rad ahead in the replay
    (the clamp's loop winds up and catches up the angle it lost), and a command lag was
    named for it on clean logs (stop-29 matrix: 6 foreign cases). Stop 27 had kept it opt-in
    on 9 cases (docs/calibration, stops 27 and 30). ``--no-fit-anti-windup`` keeps the
    configuration's form."""
    rejudge_form: int = 3
    """After a winner is named under an adopted model form, refit this many of the
    significant candidates under the nominal form (0: never). When one of them explains the
    training drives at a lower BIC than the winner and the adopted form together (the
    form's parameters counted) and passes the held-out window test against the nominal
    model, the adopted forms are reverted and the diagnosis runs again without them
    (:func:`.form_judge.form_rejudgement`). Why: a form stage is judged before any effect, so it can
    absorb part of one (stop 30, case 10005: a 17 ms command delay on the model's own logs;
    the conditional anti-windup form was adopted at dBIC -1.7, the delay fitted 5 ms under
    it and a lag was named; under the nominal form the delay fits 18.8 ms at dBIC -17)."""
    forms_reverted: dict[str, Any] | None = None
    """Set by the re-judgement when it reverts the forms: what it compared (for the report)."""
    forms_beside_winner: bool = True
    """Fit the model's forms again beside the first pass's named effect (one the plugin
    replays: not the soil) and, if they come out
    otherwise, run the diagnosis again under them (:attr:`forms_given`). Why: the forms are
    fitted before any effect, where a large one hides them (stop 38, second generator's
    delay 0.0831 s, case 17095: before any effect the steady-state tire's short relaxation
    gains nothing and is kept at 2 cm, and the delay is then fitted 0.0949 [0.0908, 0.0983]
    with the free wheels at 32 mrad; beside the delay the short relaxation puts the free
    wheels at 3.7 mrad and the delay's minimum at 0.084)."""
    weak_adoption_stands: bool = True
    """A form kept nominal before any effect and adopted beside the winner or leader on weak
    evidence only (|dBIC| < 2, :func:`.form.weakly_adopted_beside`) does not start a second
    pass: the first choice stands, as for a coin flip both ways (:func:`.form.weakly_judged`).
    A form adopted decisively beside it, or dropped beside it, still does. Why (stop 105): in
    16 of 85 stored diagnoses such an adoption alone ran the whole diagnosis again, and a
    re-judgement that reverted it ran it a third time (docs/calibration/limits.md); scored on
    fresh study 73300 (docs/calibration/studies.md)."""
    forms_beside_leader: bool = True
    """When nothing is named: fit the model's forms again beside the leading candidate (fully
    fitted, one the plugin replays, lowering the training BIC or improving the held-out drive
    by :data:`.again.LEADER_GAIN`) and, if they come out otherwise, run the diagnosis again under
    them, as beside a winner (:attr:`forms_beside_winner`). Why (stop 65): a form fitted
    before any effect can absorb the effect that would have been named. Case 50513 (the
    independent generator, friction +0.272): the yaw springs fit 10.8-11.1 N m/rad before any
    effect (the generator's are 15 x its +-20 % build scatter), and friction is then fitted at
    -0.018; with the springs at 15 it is fitted at +0.26-0.39. Case 50510 (a 6.9 deg slope):
    the slope is fitted at 7.41 deg [6.64, 8.19] with the training BIC lower by 2.8, yet not
    named (held-out 6 % worse) with the forms chosen without it; beside it the springs are
    adopted at 13.5 and the slope is fitted at 6.94 [6.28, 7.60], still not named (its
    held-out reversing windows bend theta_5 3-4 x more than the logs). Neither case is named
    with it: the leader's forms are a precondition, not a cure. In 50513 the leader is a
    command lag (friction was screened out), beside which the forms come out as before."""
    forms_beside_rival: bool = False
    """With a winner named and its forms unchanged beside it (:attr:`forms_beside_winner`):
    fit the model's forms again beside the rival, the candidate the training windows favour
    over the winner (fully fitted, one the plugin replays, a training BIC below the
    winner's and below nominal's) and, if they come out otherwise, run the diagnosis again
    under them (:func:`.again.rival`). Why (stop 97, exploratory seed 70862, a torque cut of
    78 %): the forms chosen before any effect kept the clamp anti-windup; the limit was
    fitted at -0.8 with the lowest training BIC (-11.1) but the held-out drive 0.9 % worse,
    and a friction of -0.44 was named (held out 24 % better). Beside the limit the
    conditional anti-windup is adopted (dBIC -5.4) and the limit's held-out drive comes out
    62 % better; the forms are re-chosen beside the winner only. Off by default: on fresh
    study 71600 (16 cases, 8 of them cuts of 51-80 %) it changed no name; no such rival
    arose (docs/calibration/studies.md)."""
    forms_given: list[FormFit] | None = None
    """The forms to use instead of fitting them (set by the second pass)."""
    forms_beside: str | None = None
    """The effect the given forms were fitted beside (for the report), ending in
    :data:`LEADING` when it led a first pass that named nothing."""
    forms_changed: tuple[str, ...] = ()
    """What differed between the first pass's forms and those fitted beside that effect (why
    the second pass ran; :func:`.form.form_changes`)."""
    fit_windup: bool = False
    """Also fit the speed loop's anti-windup bound (after sigma). Off by default: measured
    in stop 24, the bound that fits the second generator's loop (15.6 mrad) caps the
    integral's torque, so a steady load (rolling resistance) shows as droop of the driven
    wheels that a conditionally integrating PI does not have; the driven wheels' residual
    scale falls 5-7 x and their weight pulls c_rr to 30 % of the truth (case 2083)."""


@dataclass(frozen=True)
class FormFit:
    """One form parameter's fit (``name``, in ``unit``)."""

    name: str
    unit: str
    nominal: float
    """The configuration's value."""
    value: float
    """The best value found."""
    ladder: dict[float, float]
    """value -> mean over training windows of log(loss / nominal loss): < 0 is better."""
    gain: float
    """1 - geometric mean of (loss at ``value`` / nominal loss) over the training windows."""
    p: float
    """One-sided Wilcoxon signed-rank p that the windows improved at ``value``."""
    d_bic: float
    """BIC of ``value`` against the nominal, windows as observations, one parameter: the
    criterion every catalogue effect must also pass (``fit.information_criteria``)."""
    adopted: bool
    """Whether diagnose uses ``value``: it differs from the nominal one and ``d_bic`` < 0."""
    labels: tuple[str, ...] = ()
    """A choice's names (``value`` and ``nominal`` index them), empty for a number."""
    beaten_by: str = ""
    """What explains the windows better than the adopted value would, which is therefore
    not adopted (:func:`.form_soil.height_beside_soil`); empty: nothing."""
    at_end: bool = False
    """The best value pays its BIC but is an open end of the form's ladder, so it is not
    adopted (the windows ask for more than the form's range: :func:`.form_ladder.fit_ladder`)."""
    spacing: float = 0.0
    """The ladder's spacing between rungs (in log x when :attr:`log_spacing`; 0: unknown).
    Two fits of the form whose values lie within half of it are the same fit at the
    ladder's resolution (:func:`.form.forms_differ`)."""
    log_spacing: bool = False
    """Whether :attr:`spacing` is a difference of logs (a ladder of ratios)."""

    def text(self, x: float) -> str:
        """``x`` in words: a choice's name, or the number with its unit."""
        return self.labels[int(x)] if self.labels else f"{x:.3g} {self.unit}"

    def _key(self, x: float) -> object:
        return self.labels[int(x)] if self.labels else x

    def as_json(self) -> dict[str, object]:
        out = {
            "value": self._key(self.value if self.adopted else self.nominal),
            "fitted": self._key(self.value),
            "nominal": self._key(self.nominal),
            "unit": self.unit,
            "adopted": self.adopted,
            "training_gain": self.gain,
            "p": self.p,
            "d_bic": self.d_bic,
            "ladder": {
                (self.labels[int(k)] if self.labels else f"{k:.6g}"): v
                for k, v in self.ladder.items()
            },
        }
        if self.labels:
            out["choices"] = list(self.labels)
        if self.at_end:
            out["at_end"] = True
        if self.beaten_by:
            out["beaten_by"] = self.beaten_by
        return out


@dataclass
class Scored:
    fit: Fit
    held_cost: float
    held_losses: Array
    gain: float
    """Relative held-out reduction against the reference model."""
    p: float
    """One-sided Wilcoxon p that held-out windows improved."""
    d_aic: float
    d_bic: float
    n_train: int
    significant: bool = False
    test: str = ""
    """Which held-out test named it (the window test, or the noise-floor test and what it cleared)."""
    threshold: dict[str, float] = field(default_factory=dict)
    """Noise threshold of the effect on these drives (:func:`rover_env.calibration.diagnosis.fit_stage.noise_threshold`)."""
    detectable: dict[str, float] = field(default_factory=dict)
    """Smallest magnitude that would pay the training BIC's price against the residual these
    logs leave (:func:`rover_env.calibration.diagnosis.fit_stage.detection_limit`)."""
    nameable: dict[str, float] = field(default_factory=dict)
    """Smallest magnitude a diagnosis names on these logs: the larger of :attr:`detectable`
    and the clean-fit allowance's edge (:func:`rover_env.calibration.form_allowance.naming_bar`)."""
    reweighed_from: dict[str, dict[str, list[float]]] | None = None
    """The fit under the stage's own signal scale, before :attr:`Options.reweigh`'s refits."""
    read_from: dict[str, object] | None = None
    """Where a named soil's magnitude was read instead of the fit over every signal
    (:attr:`Options.soil_from_straight`, :attr:`Options.soil_from_motion`): ``rule`` and the
    ``replaced`` fit's parameters (value, interval)."""
    fit_scale: dict[str, float] | None = None
    """The signal scale the fit was made with when it is not the stage's own (a reweighed
    refit, :attr:`Options.reweigh`): the replay's bias is measured with the same weights."""
    refit: bool = False
    """A pair fitted with the winner's value free too (:func:`.shared.shared_refits`): each
    of its effects' intervals is judged, not only the partner's."""
    screened: bool = False
    """Fitted on the screening subset only (:attr:`Options.screen`): not promising there,
    so never fitted on every training window (and never named)."""


@dataclass
class Diagnosis:
    """One diagnosis as it runs: the inputs, then each stage's results (filled in order;
    a field is read only by the stages after the one that sets it)."""

    paths: list[str | Path]
    out: Path
    opts: Options
    t_start: float = field(default_factory=time.perf_counter)
    forms_weak: dict[str, Any] | None = None
    """The forms adopted beside the winner or leader on weak evidence only, which started no
    second pass (:attr:`Options.weak_adoption_stands`): what they were fitted beside and the
    changes; None: none."""
    stage_seconds: dict[str, float] = field(default_factory=dict)
    """Wall seconds per stage of this pass (:mod:`.pipeline`; the write stage not counted)."""
    earlier_passes: list[dict[str, float]] = field(default_factory=list)
    """:attr:`stage_seconds` of the passes before this one (a second pass under re-judged
    forms, :mod:`.again`); their time is in ``result.json``'s ``seconds`` too."""
    allowance: FormAllowance | None = field(init=False)
    """The clean-fit allowance table, read before any work (a bad table fails first)."""

    allowance_differs: list[str] | None = field(default=None, init=False)
    """How this diagnosis differs from the procedure the allowance table was measured with
    (:func:`.procedure.differences`), judged on the options the user gave (the first pass's:
    a second pass's options are the pipeline's own); None until the split stage."""

    def __post_init__(self) -> None:
        a = self.opts.form_allowance
        self.allowance = None if a is None else load_allowance(a)

    # split (:mod:`.split`)
    files: list[Path] = field(init=False)
    logs: list[DriveLog] = field(init=False)
    base: RoverConfig = field(init=False)
    """The logs' rover; after the form stage, with the adopted model forms."""
    st: ReplaySettings = field(init=False)
    prepared: list[PreparedLog] = field(init=False)
    all_w: list[Window] = field(init=False)
    train_w: list[Window] = field(init=False)
    held_w: list[Window] = field(init=False)
    sets: dict[str, list[Window]] = field(init=False)
    split: str = field(init=False)
    held_plans: HeldPlans = field(default_factory=dict)
    """The proposed drives' draws the logs already hold (:mod:`~rover_env.calibration.plans_held`)."""
    frames: dict[str, Any] | None = None
    """Each log's frame as fitted (:func:`.frames.fit_frames`; None: the frames as given)."""
    # form (:mod:`.form`)
    sensor_noise: dict[str, float] = field(init=False)
    base0: RoverConfig = field(init=False)
    """The logs' rover under the nominal forms (:attr:`base` before the form stage)."""
    prepared0: list[PreparedLog] = field(init=False)
    forms: list[FormFit] = field(init=False)
    # floor (:mod:`.floor`)
    ev: Evaluator = field(init=False)
    noise: dict[str, float] = field(init=False)
    """The replay floor: what a perfect model leaves, per signal."""
    base_train: list[WindowResult] = field(init=False)
    base_held: list[WindowResult] = field(init=False)
    scale: dict[str, float] = field(init=False)
    table_before: Table = field(init=False)
    table_held_before: Table = field(init=False)
    # fit (:mod:`.fit_stage`)
    cands: list[Candidate] = field(init=False)
    held0: Array = field(init=False)
    """Held-out window losses of the model without effects, in units of the floor."""
    ranked: list[Scored] = field(init=False)
    # select (:mod:`.select`)
    winner: Scored | None = None
    tie: dict[str, Any] | None = None
    tie_resolved: dict[str, Any] | None = None
    """A tie forward selection resolved by naming both its effects, reopened if one of them
    is withdrawn after (:func:`.tie.reopen`)."""
    left: list[str] = field(default_factory=list)
    """Held-out signals the winner leaves above its floor."""
    w_floor: dict[str, float] = field(default_factory=dict)
    partners: list[Scored] = field(default_factory=list)
    tried: list[Scored] = field(default_factory=list)
    chosen: list[Scored] = field(default_factory=list)
    demoted: list[Scored] = field(default_factory=list)
    traded: dict[str, Any] | None = None
    trade_excused: dict[str, Any] | None = None
    """A trade too small to refuse the naming (:attr:`Options.trade_share`): what it made
    worse, reported beside the named effects."""
    dropped: dict[str, Any] | None = None
    final_floor: dict[str, float] = field(default_factory=dict)
    # odometry (:mod:`.odometry`)
    odometry: dict[str, Any] | None = None
    """Dead reckoning on the logs and on the named model's twins, and whether it named a
    rolling radius (:func:`.odometry.name_by_odometry`; None: off)."""
    partner_limits: dict[str, dict[str, float]] | None = None
    """Each significant pair's partner's detection limit beside the winner (effect -> side
    -> magnitude; :func:`.select.partner_limits`; None: none measured)."""
    effort: dict[str, Any] | None = None
    """The torque limit read from the reported motor torque and what it named
    (:func:`.effort_stage.name_by_effort`; None: no log reports torque, or off)."""
    balance: dict[str, Any] | None = None
    """The ground's tilt read from the reported motor torque, or from the wheels' slip, and
    what it named (:func:`.balance_stage.name_by_balance`; its ``source`` says which; None:
    the balance that applies is off, or there is no slope candidate)."""
    one_wheel: dict[str, Any] | None = None
    """Beside a named rolling resistance: the free wheels' dead-reckoning split and whether
    it withdrew the name (:func:`.one_wheel.withdraw_one_wheel`)."""
    # evidence (:mod:`.evidence_stage`)
    evidence: list[dict[str, Any]] = field(default_factory=list)
    evidence_judged: list[dict[str, Any]] = field(default_factory=list)
    """Candidates no drive is asked for, and why (:func:`.evidence_stage.not_worth_asking`,
    :func:`.evidence_stage.untested_limit`)."""
    rotor: dict[str, Any] | None = None
    """Beside a named torque limit, the rotor inertia fitted in its place (:mod:`.rotor`)."""
    rotor_withdrawn: dict[str, Any] | None = None
    """The effects the rotor test left unnamed (:func:`.select.rotor_check`)."""
    allowance_withdrawn: dict[str, Any] | None = None
    """The effects whose allowance-widened interval reaches "off", left unnamed
    (:func:`.select.withdraw_within_allowance`)."""
    passed_over: dict[str, Any] | None = None
    """A fit at its range's far end that led the naming order and was tried after the fits
    inside their ranges (:attr:`.Options.pegged_last`): its effect, where it ended and what
    was named first (:func:`.select.name_winner`)."""
    untested: list[dict[str, Any]] = field(default_factory=list)
    """Drives proposed for what the logs never tested (:func:`.evidence_stage.untested_limit`)."""
    rotor_profile: dict[str, Any] = field(default_factory=dict)
    """Per named torque-limit fit: its refits over the rotor inertia's tolerance
    (:func:`.rotor.profile_rotor`)."""
    # write (:mod:`.write`)
    held_final: list[WindowResult] = field(default_factory=list)
    table_held_after: Table = field(default_factory=dict)
    result: dict[str, Any] = field(default_factory=dict)

    def say(self, msg: str) -> None:
        """Print a progress line (``opts.progress``) with the seconds since the start."""
        if self.opts.progress:
            print(f"[diagnose {time.perf_counter() - self.t_start:6.1f}s] {msg}", flush=True)

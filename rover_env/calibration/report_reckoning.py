"""The report's dead-reckoning paragraph: the free wheels' travel against the pose, the
logs' against the named model's twins (:mod:`rover_env.calibration.diagnosis.odometry`),
and what to drive where the logs cannot read a rolling radius."""

from __future__ import annotations

import math
from typing import Any


def reckoning_lines(r: dict[str, Any] | None) -> list[str]:
    """Dead reckoning from the free wheels against the pose, the logs' against the named
    model's twins' (:mod:`rover_env.calibration.diagnosis.odometry`)."""
    if r is None:
        return []
    diff = (r.get("difference") or {}).get("both")
    if diff is None and r.get("why_not"):  # decided without the twins
        return ["", f"Dead reckoning: not compared with this model's twins ({r['why_not']})."]
    if r.get("form") == "end" and (diff is None or diff != diff):
        return [
            "",
            "Dead reckoning: the logs hold a pose fix at each drive's end only, and no drive"
            " commanded straight ends 1 m or more from its start, so no rolling radius can be"
            " read from them: drive a measured straight, `rover-env drive-plan --plan straight"
            " --duration 50 --out plans`, and diagnose again with it.",
        ]
    if diff is None or diff != diff:  # none straight and moving
        return []
    return _reckoning_compared(r, diff) + _straight_advice(r)


STRAIGHT_ADVICE_SE = 0.01
"""A standard error of dead reckoning's statistic (from the pose's own noise) at which the
report suggests a measured straight: a third of the clean band's half-width, where the
widening starts to hide radii the band would otherwise see (study 71200: 0.2-0.3 % on three
drives, up to 3.7 % on one)."""


def _straight_advice(r: dict[str, Any]) -> list[str]:
    """What to drive when the logs' straight travel is too short to read a rolling radius:
    too few straight pose intervals to measure the pose's noise, or a standard error that
    widens the band by a third of it or more. Advice only; nothing is decided by it."""
    if r.get("named") or "noise_samples" not in r or r.get("form") == "end":
        return []
    se = float(r.get("noise_se") or math.nan)
    few = not math.isfinite(se)
    if not few and se < STRAIGHT_ADVICE_SE:
        return []
    why = (
        f"only {r.get('noise_samples', 0)} straight pose intervals, too few to measure the"
        " pose's own noise"
        if few
        else f"the pose's noise leaves the statistic a {100 * se:.1f} % standard error"
    )
    return [
        "",
        f"To read a rolling radius from dead reckoning these drives are short of straight"
        f" travel ({why}): drive a measured straight, `rover-env drive-plan --plan straight"
        " --duration 50 --out plans`, and diagnose again with it.",
    ]


_READ_OVER = {
    "intervals": "straight, moving seconds",
    "end": "each drive commanded straight, from its start to its last pose fix",
}
"""What dead reckoning's statistic was read over, per form (:mod:`.diagnosis.odometry`)."""


def _reckoning_compared(r: dict[str, Any], diff: float) -> list[str]:
    """The logs' statistic against the twins' and the band it was judged by."""
    lo, hi = r.get("band_with_noise") or r["band"]
    se = r.get("noise_se")
    noise = (
        f" (widened for the pose's own noise on these logs: {100 * se:.2f} % standard error)"
        if r.get("band_with_noise") and se is not None
        else ""
    )
    d = r["difference"]
    verdict = (
        "named the rolling radius (above)"
        if r.get("named")
        else f"no rolling radius named: {r.get('why_not', '')}"
    )
    driven = f", the driven wheels {100 * d['driven']:+.2f} %" if "driven" in d else ""
    held = ""
    if r.get("named") and r.get("held_gain") is not None:
        held = (
            f" Under it the held-out windows are {100 * abs(r['held_gain']):.0f} %"
            f" {'better' if r['held_gain'] >= 0 else 'worse'} (one-sided p of worse"
            f" {r['p_worse']:.2g}): where worse, the model answers the radius otherwise than the"
            " rover (on another implementation's logs, in its turns)."
        )
    return [
        "",
        f"Dead reckoning ({_READ_OVER[r.get('form') or 'intervals']}): per free-wheel turn the"
        " logs' rover travels"
        f" {100 * diff:+.2f} % against this model's twins (3L {100 * d['3L']:+.2f} %, 3R"
        f" {100 * d['3R']:+.2f} %{driven}; the logs {100 * r['logs']['both']:+.2f} %, the twins"
        f" {100 * r['model']['both']:+.2f} %, path over travel at the static rolling radius,"
        f" minus 1); clean drives of another implementation leave {100 * lo:+.2f} to"
        f" {100 * hi:+.2f} %{noise}: {verdict}. A rolling radius change shows one for one; a rolling"
        " resistance drags the free wheels (about +1 %), loose soil makes them bulldoze (up to"
        " +24 %), a dragging brake slows one of them." + held + _lead_text(r),
    ]


def _lead_text(r: dict[str, Any]) -> str:
    """The named model's reading beside which dead reckoning was read with the leading
    unnamed fit (:func:`.diagnosis.odometry.beside_lead`), or nothing."""
    lead = r.get("slip_lead")
    if not lead:
        return ""
    nd = lead["named_difference"]
    head = (
        f" Against the named model's own twins the driven wheels read {100 * nd['driven']:+.2f} %"
        f" against the free wheels' {100 * nd['both']:+.2f} %, apart as a drag makes them;"
    )
    if lead["read_beside"]:
        return head + (
            f" the figures above are read beside the unnamed {lead['effect']} fit"
            f" ({lead['fit']}), whose drag makes that slip (it stays out of the configuration)."
        )
    return head + (
        f" beside the unnamed {lead['effect']} fit ({lead['fit']}) dead reckoning names no"
        f" radius either: {lead['why_not']}."
    )

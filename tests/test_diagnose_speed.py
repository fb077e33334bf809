"""What makes a diagnose case cheaper must not change what it can find (issue 47, item 4).

The replay's coarser step applies only where it is coarser than the rover's own, and the soil's
other forms are skipped only when its first form's search is best at "off" (hard ground, where
every form is the same model); a soil that improves the fit still gets every form tried.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import ClassVar

import numpy as np
import pytest
from _bench import load_bench

import rover_env.calibration.fit as fit_mod
from rover_env.calibration.candidates import catalogue
from rover_env.calibration.diagnosis.judge import form_mismatch
from rover_env.calibration.replay import ReplaySettings, replay_step
from rover_env.config import RoverConfig


def test_replay_step_coarsens_only() -> None:
    cfg = RoverConfig()
    assert cfg.sim.timestep == pytest.approx(0.001)
    assert replay_step(cfg, 0.002).sim.timestep == pytest.approx(0.002)
    assert replay_step(cfg, None) is cfg
    fine = replay_step(cfg, 0.0005)
    assert fine is cfg  # never finer than the rover's own step
    assert ReplaySettings().timestep == pytest.approx(0.002)


def _fake_fit(c, best_at_off: bool) -> fit_mod.Fit:
    off = c.off[0]
    xs = np.array([off, off + 1.0, off + 2.0])
    per_window = np.array([[1.0, 1.0], [2.0, 2.0], [3.0, 3.0]])
    if not best_at_off:
        per_window = per_window[::-1].copy()
    z = np.zeros(1)
    return fit_mod.Fit(
        [c],
        z + xs[int(np.argmin(per_window.sum(1)))],
        z,
        z + 1,
        z,
        1.0,
        3,
        {},
        0.0,
        "train",
        curve=(xs, per_window),
    )


@pytest.mark.parametrize("best_at_off", [True, False])
def test_soil_forms_searched_in_full_only_where_the_screen_finds_soil(
    monkeypatch: pytest.MonkeyPatch, best_at_off: bool
) -> None:
    """The first form is searched in full, every other one screened (:func:`_screen_forms`);
    none more when no form beats hard ground there, else the :data:`FORMS_FITTED` best."""
    (soil,) = catalogue(["loose_soil"])
    assert len(soil.forms) > fit_mod.FORMS_FITTED
    calls: list[str] = []

    def fake(ev, c, which, fixed, refine, t0):  # type: ignore[no-untyped-def]
        calls.append(c.form)
        return _fake_fit(c, best_at_off)

    def screen(ev, c, which, fixed, first):  # type: ignore[no-untyped-def]
        # Hard ground costs 2 (the fake curve's "off", two windows); the forms cost more
        # there, or less and in reverse order of the catalogue.
        n = len(c.forms)
        costs = [5.0] * n if best_at_off else [1.0 - 0.1 * i for i in range(n)]
        return {lab: v for (lab, _), v in zip(c.forms, costs, strict=True)}, 1.0, 2.0

    monkeypatch.setattr(fit_mod, "_fit_1d", fake)
    monkeypatch.setattr(fit_mod, "_screen_forms", screen)

    class _Ev:
        def log(self, msg: str) -> None:
            pass

    fit_mod._fit_forms(_Ev(), soil, "train", {}, 3, 0.0)  # type: ignore[arg-type]
    labels = [label for label, _ in soil.forms]
    if best_at_off:
        assert calls == [labels[0]]
    else:
        assert calls == [labels[0], *labels[::-1][: fit_mod.FORMS_FITTED]]


def test_disagreeing_groups_are_reported() -> None:
    (c,) = catalogue(["torque_limit"])
    z = np.zeros(1)
    f = fit_mod.Fit([c], z - 0.3, z - 0.4, z - 0.2, z, 1.0, 3, {}, 0.0, "train")
    assert form_mismatch(f) is None
    f.groups = {"driven wheels": -0.33, "free wheels": 0.64, "joints": -0.42}
    f.between = 0.5
    text = form_mismatch(f)
    assert text is not None and "free wheels 0.64" in text
    f.between = 0.0
    assert form_mismatch(f) is None


def _write(out: Path, result: dict[str, object]) -> Path:
    out.mkdir(parents=True)
    (out / "result.json").write_text(json.dumps(result))
    return out


def test_findings_ignore_costs_and_the_folder_but_nothing_else(tmp_path: Path) -> None:
    ds = load_bench("diagnose_speed")

    def result(out: Path, secs: float, value: float) -> dict[str, object]:
        fit = {"value": value, "seconds": secs, "nfev": 7}
        return {
            "named": ["slope"],
            "fits": {"slope": fit},
            "seconds": secs,
            "replay_seconds": secs / 2,
            "replays": int(secs) * 3,  # replays made: a cost (a cache makes fewer)
            "config": str(out / "rover.yaml"),
        }

    a, b, c = tmp_path / "prev", tmp_path / "cur", tmp_path / "other"
    _write(a, result(a, 61.0, 2.5))
    _write(b, result(b, 55.0, 2.5))
    _write(c, result(c, 55.0, 2.5000001))
    assert ds.findings(a) == ds.findings(b)
    assert ds.findings(a) != ds.findings(c)  # a fitted value one part in 10^7 apart


def test_cases_are_chosen_by_name_pairs_only_when_named() -> None:
    ds = load_bench("diagnose_speed")
    assert ds.chosen(None) == ds.EFFECTS  # the default cycle holds no pair
    pair = ds.chosen("command_lag+command_delay,clean")
    assert pair == [{"command_lag": {"tau": 0.3}, "command_delay": {"delay": 0.1}}, {}]
    with pytest.raises(SystemExit, match="unknown case"):
        ds.chosen("command_delay+command_lag")


def test_named_params_are_read_from_the_final_fit(tmp_path: Path) -> None:
    ds = load_bench("diagnose_speed")
    out = _write(
        tmp_path / "o",
        {"final": {"slope": {"params": {"slope": {"deg": [2.0, 1.5, 2.5]}}, "sides": {}}}},
    )
    assert ds.named_params(out) == {"slope": {"slope": {"deg": [2.0, 1.5, 2.5]}}}
    assert ds.named_params(_write(tmp_path / "n", {"final": None})) == {}


def test_each_effect_meets_more_than_one_set_of_drive_kinds() -> None:
    """The speed benchmark's cases: every effect still comes round, and its cases are not
    all driven by the same drive kinds (the generator's kinds repeat every 7 seeds)."""
    from rover_env.independent.drive import drive_kind

    ds = load_bench("diagnose_speed")
    n = len(ds.EFFECTS)
    seed0 = 73800
    kinds: dict[str, set[tuple[str, ...]]] = {}
    for i in range(3 * n):
        name = "+".join(ds.case_effect(ds.EFFECTS, i)) or "clean"
        kinds.setdefault(name, set()).add(tuple(drive_kind(k, seed0 + i) for k in range(3)))
    assert len(kinds) == n
    assert all(len(k) == 3 for k in kinds.values()), kinds


@pytest.mark.parametrize("middle", [True, False])
def test_soil_forms_screened_at_the_middle_rung_too(
    monkeypatch: pytest.MonkeyPatch, middle: bool
) -> None:
    """A form whose basin lies far from the first form's best point is still screened where
    it fits (stop 133: dry sand 54917 under the regolith constants, best near the middle of
    the ladder while the mars-sand forms were best near hard ground)."""
    (soil,) = catalogue(["loose_soil"])
    ladder = [float(p[0]) for p in soil.ladder or ()]
    stiff, mid = ladder[0], ladder[len(ladder) // 2]
    far = soil.forms[-1][0]

    def cost(label: str, x: float) -> float:
        # The last form fits best at the middle rung and poorly at the others' best point.
        if label == far:
            return 1.0 if x == mid else 9.0
        return 3.0 if x == stiff else 6.0

    table = {
        json.dumps(soil.with_form(lab).to_ext(np.array([x])), sort_keys=True): cost(lab, x)
        for lab, _ in soil.forms
        for x in (stiff, mid)
    }

    class _Ev:
        scale: ClassVar[dict[str, float]] = {}
        screen_middle = middle  # Options.screen_middle, through the evaluator

        def run(self, ext, which):  # type: ignore[no-untyped-def]
            return [ext]

        def log(self, msg: str) -> None:
            pass

    def losses(res, scale):  # type: ignore[no-untyped-def]
        return np.array([[table[json.dumps(res[0], sort_keys=True)]]])

    monkeypatch.setattr(fit_mod, "group_losses", losses)
    xs = np.array([soil.off[0], stiff, mid])
    first_curve = np.array([[5.0], [cost(soil.forms[0][0], stiff)], [cost(soil.forms[0][0], mid)]])
    z = np.zeros(1)
    first = fit_mod.Fit([soil], z + stiff, z, z + 1, z, 3.0, 3, {}, 0.0, "train")
    first.curve = (xs, first_curve)
    screen, rung, off_cost = fit_mod._screen_forms(_Ev(), soil, "train", {}, first)  # type: ignore[arg-type]
    assert rung == stiff and off_cost == 5.0
    assert screen[far] == (1.0 if middle else 9.0)
    assert min(screen, key=lambda lab: screen[lab]) == (far if middle else soil.forms[0][0])

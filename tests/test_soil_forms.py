"""The loose-soil effect's other constants (its preset and SOIL.md's lambda) and the soil
forms' screen in the magnitude-blind fit (stop 55: on the independent generator's regolith
no mars-sand soil replayed better than hard ground, and the first form's search at "off"
ended the soil's fit)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pytest

from rover_env.calibration import fit as fit_mod
from rover_env.calibration.candidates import SOIL_FORMS, catalogue
from rover_env.calibration.replay import SIGNALS
from rover_env.config import load_terrain
from rover_env.effects import EffectError, build_effects
from rover_env.sim.build import effect_soil
from rover_env.soil import load_soil


def _soil(ext: dict[str, Any], terrain: str = "flat") -> Any:
    return effect_soil(load_terrain(terrain), build_effects({"loose_soil": ext}))


def test_the_preset_sets_the_other_constants_and_lambda_replaces_its_own() -> None:
    sand, reg = load_soil("mars-sand"), load_soil("regolith")
    s = _soil({"k_phi": 5e5})
    assert (s.k_phi, s.c, s.k_x, s.lam, s.phi_deg, s.n0) == (
        5e5, sand.c, sand.k_x, sand.lam, sand.phi_deg, sand.n0)  # fmt: skip
    r = _soil({"k_phi": 5e5, "preset": 1.0, "lam": 0.6})
    assert (r.k_phi, r.c, r.k_x, r.k_c, r.phi_deg, r.n0, r.lam) == (
        5e5, reg.c, reg.k_x, reg.k_c, reg.phi_deg, reg.n0, 0.6)  # fmt: skip
    sand = load_soil("dry-sand")
    d = _soil({"k_phi": 5e5, "preset": 2.0, "lam": 0.6})
    assert (d.k_phi, d.c, d.k_x, d.k_c, d.phi_deg, d.n0, d.n1, d.lam) == (
        5e5, sand.c, sand.k_x, sand.k_c, sand.phi_deg, sand.n0, sand.n1, 0.6)  # fmt: skip
    assert _soil({"k_phi": 5e5, "phi_deg": 30.0}).phi_deg == 30.0
    for bad in (0.5, 1.5, 3.0):
        with pytest.raises(EffectError, match="preset"):
            build_effects({"loose_soil": {"k_phi": 5e5, "preset": bad}})


def test_a_terrain_soil_keeps_its_own_constants_but_k_phi() -> None:
    """A "softer than modelled" soil on a terrain with its own soil changes k_phi only (until stop
    55 the defaults of phi_deg and n0, mars-sand's, replaced the terrain soil's too)."""
    from rover_env.config import TerrainConfig

    t = load_terrain("flat")
    t = TerrainConfig(**{**t.__dict__, "soil": "regolith"})
    s = effect_soil(t, build_effects({"loose_soil": {"k_phi": 4e5}}))
    reg = load_soil("regolith")
    assert s is not None and (s.k_phi, s.phi_deg, s.n0, s.lam) == (
        4e5,
        reg.phi_deg,
        reg.n0,
        reg.lam,
    )


@dataclass
class _Res:
    resid: np.ndarray
    pose_resid: np.ndarray


@dataclass
class _FakeEvaluator:
    """Residuals of a soil that only one form (regolith, lambda 0.6) reproduces: there the
    free wheels' residual is 0.1 |u - 2| (k_phi 5e5); in every other form 0.3 at any soil,
    and 0.25 on hard ground, so the first form is best at "off"."""

    scale: dict[str, float] = field(default_factory=lambda: dict.fromkeys(SIGNALS, 1.0))
    sets: dict[str, list[int]] = field(default_factory=lambda: {"train": list(range(8))})
    runs: int = 0
    screen_middle: bool = True

    def log(self, msg: str) -> None:
        pass

    def run(self, ext: dict[str, Any], which: str) -> list[_Res]:
        self.runs += 1
        soil = ext.get("loose_soil", {})
        k = soil.get("k_phi", 0.0)
        if k == 0.0:
            level = 0.25
        elif soil.get("preset") == 1.0 and soil.get("lam") == 0.6:
            level = 0.1 * abs(1e6 / k - 2.0)
        else:
            level = 0.3
        rng = np.random.default_rng(7)
        out = []
        for _ in self.sets[which]:
            r = np.zeros((10, 11))
            r[:, 4:6] = level * (1.0 + 0.05 * rng.standard_normal((10, 2)))
            out.append(_Res(r, np.zeros((2, 3))))
        return out

    def vector(self, ext: dict[str, Any], which: str) -> np.ndarray:
        return np.concatenate([r.resid.ravel() for r in self.run(ext, which)])


def test_the_screen_finds_the_form_whose_first_search_is_at_off() -> None:
    (soil,) = catalogue(["loose_soil"])
    assert [lab for lab, _ in soil.forms] == [lab for lab, _ in SOIL_FORMS]
    ev = _FakeEvaluator()
    f = fit_mod.fit(ev, [soil], "train", max_nfev=4)  # type: ignore[arg-type]
    (c,) = f.candidates
    assert c.form == "SOIL.md's regolith, lambda 0.6, no memory"
    k = 1e6 / float(f.x[0])
    assert 4e5 < k < 6.5e5, k
    assert f.ext["loose_soil"]["preset"] == 1.0


def test_hard_ground_stops_after_the_screen() -> None:
    """No form beats "off" at the screened rung: the first form's search is the fit, and the
    other forms cost one replay each."""

    class Hard(_FakeEvaluator):
        def run(self, ext: dict[str, Any], which: str) -> list[_Res]:
            res = super().run(ext, which)
            k = ext.get("loose_soil", {}).get("k_phi", 0.0)
            for r in res:
                r.resid[:, 4:6] = 0.25 if k == 0.0 else 0.25 + 1e-7 * k**0.5
            return res

    (soil,) = catalogue(["loose_soil"])
    ev = Hard()
    f = fit_mod.fit(ev, [soil], "train", max_nfev=4)  # type: ignore[arg-type]
    assert f.x[0] == 0.0
    assert f.candidates[0].form == SOIL_FORMS[0][0]
    # The first form's search alone, then one replay per other form.
    alone = Hard()
    fit_mod.fit(alone, [soil.with_form(SOIL_FORMS[0][0])], "train", max_nfev=4)  # type: ignore[arg-type]
    assert ev.runs == alone.runs + len(SOIL_FORMS) - 1


@pytest.mark.parametrize("middle", [True, False])
def test_a_form_whose_basin_lies_far_from_the_first_forms_is_searched(middle: bool) -> None:
    """Stop 133 (dry sand 54917): the mars-sand forms fit best near hard ground, the regolith
    form near the ladder's middle. Screened only where the first form fits best, the regolith
    form loses there and is never searched; screened at the middle rung too, it is."""

    class Apart(_FakeEvaluator):
        def run(self, ext: dict[str, Any], which: str) -> list[_Res]:
            res = super().run(ext, which)
            soil = ext.get("loose_soil", {})
            k = soil.get("k_phi", 0.0)
            u = 1e6 / k if k else 0.0
            if soil.get("preset") == 1.0 and soil.get("lam") == 0.6:
                level = 0.05 + 0.1 * abs(np.log(u / 1.2)) if k else 0.25
            else:
                level = 0.15 + 0.1 * abs(np.log(u / 0.1)) if k else 0.25
            for r in res:
                r.resid[:, 4:6] = level
            return res

    (soil,) = catalogue(["loose_soil"])
    f = fit_mod.fit(Apart(screen_middle=middle), [soil], "train", max_nfev=4)  # type: ignore[arg-type]
    (c,) = f.candidates
    u = float(f.x[0])
    if middle:
        assert c.form == "SOIL.md's regolith, lambda 0.6, no memory" and 0.8 < u < 1.8, (c.form, u)
    else:
        assert c.form in {lab for lab, _ in SOIL_FORMS[:4]} and u < 0.3, (c.form, u)

"""The evaluator's replay cache names a model by the simulator it builds: extension sets
that differ only in spelled-out defaults, or in effects that are off, share one replay;
any other difference, over the evaluator's own extensions too, replays again. A window set
replays only its windows that no other set has replayed under the same model."""

from __future__ import annotations

from dataclasses import replace
from typing import Any, ClassVar

import pytest

from rover_env.calibration import evaluator as evaluator_mod
from rover_env.calibration.evaluator import Evaluator
from rover_env.calibration.replay import ReplaySettings
from rover_env.config import load_rover

SOIL_DEFAULTS = {"memory": 1.0, "sigma": 0.0, "preset": 0.0, "lam": 0.0}


class _Replayer:
    """Counts the simulators built, what they were built from and the windows they replayed."""

    built: ClassVar[list[dict[str, Any]]] = []
    replayed: ClassVar[list[list[str]]] = []

    def __init__(self, cfg: Any, settings: Any, backend: str = "auto") -> None:
        _Replayer.built.append(dict(cfg.extensions))

    def run(self, logs: list[Any], windows: list[str]) -> list[Any]:
        _Replayer.replayed.append(list(windows))
        return [(w, len(_Replayer.built)) for w in windows]


@pytest.fixture
def built(monkeypatch: pytest.MonkeyPatch) -> list[dict[str, Any]]:
    _Replayer.built, _Replayer.replayed = [], []
    monkeypatch.setattr(evaluator_mod, "Replayer", _Replayer)
    return _Replayer.built


def _ev(extensions: dict[str, Any] | None = None) -> Evaluator:
    base = load_rover("proto_explorer")
    if extensions is not None:
        base = replace(base, extensions=extensions)
    # Windows are only named here: the stand-in replayer returns (window, simulator number).
    sets: dict[str, Any] = {"train": ["a", "b", "c", "d"], "held": ["e", "f"]}
    sets["train_sub"] = sets["train"][::2]
    return Evaluator(base, ReplaySettings(), [], sets, log=lambda s: None)


def test_spelled_out_defaults_and_effects_that_are_off_share_a_replay(
    built: list[dict[str, Any]],
) -> None:
    ev = _ev()
    ev.run({"loose_soil": {"k_phi": 2.7e6}}, "train")
    ev.run({"loose_soil": {"k_phi": 2.7e6, **SOIL_DEFAULTS}}, "train")
    assert len(built) == 1 and ev.replays == 1
    ev.run({}, "train")
    ev.run({"loose_soil": {"k_phi": 0.0}, "command_delay": {"delay": 0.0}}, "train")
    assert len(built) == 2
    ev.run({"loose_soil": {"k_phi": 2.7e6}}, "held")  # another window set
    assert len(built) == 3


def test_another_value_or_form_replays_again(built: list[dict[str, Any]]) -> None:
    ev = _ev()
    ev.run({"loose_soil": {"k_phi": 2.7e6}}, "train")
    ev.run({"loose_soil": {"k_phi": 2.7e6, "memory": 0.0}}, "train")
    ev.run({"loose_soil": {"k_phi": 2.6e6}}, "train")
    assert len(built) == 3


def test_the_key_reads_the_extensions_merged_over_the_evaluators_own(
    built: list[dict[str, Any]],
) -> None:
    """Over a base whose soil forgets (memory 0), the bare candidate keeps that memory and
    the first form's spelled-out memory 1 does not: two simulators."""
    ev = _ev({"loose_soil": {"k_phi": 1e6, "memory": 0.0}})
    ev.run({"loose_soil": {"k_phi": 2.7e6}}, "train")
    ev.run({"loose_soil": {"k_phi": 2.7e6, **SOIL_DEFAULTS}}, "train")
    assert len(built) == 2
    assert built[0]["loose_soil"]["memory"] == 0.0 and built[1]["loose_soil"]["memory"] == 1.0


def test_the_profiles_set_follows_the_spelling_replayed(built: list[dict[str, Any]]) -> None:
    """A screened fit at "off" spells the nominal model its own way: replayed on the subset
    only, it is profiled over the subset, although the nominal model was replayed on every
    training window (results as before the cache's key named the model)."""
    ev = _ev()
    off = {"loose_soil": {"k_phi": 0.0}}
    ev.run({}, "train")
    ev.run(off, "train_sub")
    assert len(built) == 1  # its windows are among those the nominal model replayed
    ev.run(off, "train")  # the nominal model on every window: no replay
    assert len(built) == 1
    fresh = _ev()
    fresh.run({}, "train")
    fresh.run(off, "train_sub")
    assert fresh.reference(off, "held") == "train_sub" and fresh.reference({}, "held") == "train"
    assert ev.reference(off, "held") == "train"


def test_a_set_replays_only_the_windows_no_other_set_replayed_under_the_model(
    built: list[dict[str, Any]],
) -> None:
    """The screening subset, then every training window: the second replays the other half
    only, and each set's results come in its own windows' order, the subset's reused."""
    ev = _ev()
    lag = {"command_lag": {"tau": 0.1}}
    sub = ev.run(lag, "train_sub")
    train = ev.run(lag, "train")
    assert _Replayer.replayed == [["a", "c"], ["b", "d"]]
    assert [r[0] for r in train] == ["a", "b", "c", "d"]
    assert train[0] is sub[0] and train[2] is sub[1]
    ev.run({"command_lag": {"tau": 0.2}}, "train")  # another model: every window
    ev.run(lag, "held")  # no other set holds these
    assert _Replayer.replayed[2:] == [["a", "b", "c", "d"], ["e", "f"]]
    ev.run({"command_lag": {"tau": 0.2}}, "train_sub")  # all replayed already
    assert len(built) == 4 and ev.replays == 4

"""The test split is touched once per agent: the test ledger (issue 17)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from rover_env.benchmark.cli import main, run_benchmark
from rover_env.benchmark.ledger import FIELDS, FinalRunRefused, agent_hash
from rover_env.benchmark.metrics import METRICS

CTRLS = ["open-loop", "slip-pi"]


def _final(tmp: Path, ledger: Path, ctrls: list[str] = CTRLS, force: bool = False) -> None:
    run_benchmark(
        ctrls,
        ["flat-turns"],
        1,
        tmp / "out",
        duration=0.2,
        progress=False,
        plots=False,
        final=True,
        force=force,
        ledger=ledger,
        command="test",
    )


def _rows(ledger: Path) -> list[dict[str, str]]:
    with ledger.open() as fh:
        return list(csv.DictReader(fh))


def test_test_split_needs_final(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="--final"):
        run_benchmark(CTRLS, ["flat-turns"], 1, tmp_path, split="test", progress=False)


def test_second_final_run_is_refused_unless_forced_then_marked(tmp_path: Path) -> None:
    ledger = tmp_path / "ledger.csv"
    _final(tmp_path, ledger)
    (row,) = _rows(ledger)
    assert tuple(row) == FIELDS
    assert row["agent"] == "slip-pi" and row["baseline"] == "open-loop"  # the baseline is not
    assert row["agent_hash"] == agent_hash("slip-pi") and row["repeat"] == ""
    assert json.loads(row["config"])["seeds"] == "3000..3000"
    assert set(json.loads(row["figures"])["flat-turns"]) == set(METRICS)
    with pytest.raises(FinalRunRefused, match="already had its final test run"):
        _final(tmp_path, ledger)
    assert len(_rows(ledger)) == 1  # refused before any episode ran
    # Another agent (other settings, another hash) has its own first run.
    _final(tmp_path, ledger, ["open-loop", "slip-pi@stuck_retry_scale=2"])
    assert [r["repeat"] for r in _rows(ledger)] == ["", ""]
    _final(tmp_path, ledger, force=True)
    rows = _rows(ledger)
    assert len(rows) == 3 and rows[-1]["agent"] == "slip-pi"
    assert rows[-1]["repeat"].startswith("repeat")
    assert "REPEATED final run" in (tmp_path / "out" / "benchmark.md").read_text()


def test_cli_defaults_to_validation_and_refuses_a_repeat(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    ledger = tmp_path / "ledger.csv"
    args = ["benchmark", "--controllers", "open-loop", "--scenarios", "flat-turns"]
    args += ["--episodes", "1", "--duration", "0.2", "--quiet", "--no-plots"]
    args += ["--out", str(tmp_path / "o"), "--ledger", str(ledger)]
    assert main(args) == 0
    assert "validation split" in capsys.readouterr().out and not ledger.exists()
    with pytest.raises(SystemExit):
        main([*args, "--split", "test"])  # not a choice: the test split needs --final
    assert main([*args, "--force"]) == 2
    assert main([*args, "--final"]) == 0 and len(_rows(ledger)) == 1
    assert main([*args, "--final"]) == 3
    assert "already had its final test run" in capsys.readouterr().err
    assert len(_rows(ledger)) == 1


def test_ppo_agent_hash_follows_its_files(tmp_path: Path) -> None:
    (tmp_path / "best_model.zip").write_bytes(b"weights-1")
    (tmp_path / "vecnormalize.pkl").write_bytes(b"stats")
    h1 = agent_hash(f"ppo:{tmp_path}")
    (tmp_path / "vecnormalize.pkl").write_bytes(b"stats-2")
    h2 = agent_hash(f"ppo:{tmp_path}")
    (tmp_path / "config.yaml").write_text("x: 1\n")
    h3 = agent_hash(f"ppo:{tmp_path}")
    assert len({h1, h2, h3}) == 3
    assert agent_hash(f"ppo:{tmp_path}") == h3


def test_ablation_grid_ranks_fixed_settings_on_validation(tmp_path: Path) -> None:
    from rover_env.benchmark.ablation import rank, run_ablation

    res = run_ablation(
        "slip-pi",
        "stuck_retry_scale",
        [0.5, 2.0],
        ["flat-turns"],
        1,
        tmp_path,
        duration=0.3,
        progress=False,
    )
    assert res.specs == ["slip-pi@stuck_retry_scale=0.5", "slip-pi@stuck_retry_scale=2"]
    assert res.best in res.specs and "validation split" in res.files["markdown"].read_text()
    assert "Best fixed setting" in res.files["ablation"].read_text()
    with pytest.raises(ValueError, match="not 'test'"):
        run_ablation("slip-pi", "kp", [0.1], ["flat-turns"], 1, tmp_path, split="test")
    with pytest.raises(ValueError, match="not numeric SlipPIConfig fields"):
        run_ablation("slip-pi", "slip_radius", [1.0], ["flat-turns"], 1, tmp_path)
    # Ranking is relative per scenario: a scenario with large slip does not dominate.
    rows = [
        {"controller": c, "scenario": s, "mean_abs_slip": v}
        for c, s, v in [
            ("a", "big", 1.0),
            ("b", "big", 1.1),
            ("a", "small", 0.02),
            ("b", "small", 0.01),
        ]
    ]
    scores = rank(rows, ["a", "b"], "mean_abs_slip")
    assert scores["b"] < scores["a"]  # -5 % on "big" but -50 % on "small"


def test_every_shipped_agent_with_a_test_run_is_the_one_tested() -> None:
    """An agent's files under agents/ are those its ledger row hashed: a re-save, a retrain or a
    swapped normaliser after the one test run would make the shipped figures someone else's."""
    repo = Path(__file__).resolve().parents[1]
    rows = _rows(repo / "docs" / "benchmark" / "test_ledger.csv")
    tested = {r["agent"]: r["agent_hash"] for r in rows if r["agent"].startswith("ppo:agents/")}
    assert "ppo:agents/mobility-ppo-sp15" in tested  # the shipped mobility agent (stop 43)
    for spec, digest in tested.items():
        folder = repo / spec.removeprefix("ppo:")  # the ledger names it from the repository root
        if folder.is_dir():
            assert agent_hash(f"ppo:{folder}") == digest, spec

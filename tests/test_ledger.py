"""The test split is touched once per agent: the test ledger (issue 17)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from rover_env.benchmark.cli import main, run_benchmark
from rover_env.benchmark.ledger import FIELDS, FIELDS_V1, FinalRunRefused, agent_hash, read_ledger
from rover_env.benchmark.metrics import METRICS
from rover_env.benchmark.questions import load_questions, question
from rover_env.benchmark.spending import nominal_alphas
from rover_env.config import ConfigError

CTRLS = ["open-loop", "slip-pi"]
QUESTIONS = """questions:
  - id: pi
    text: Does the slip PI beat the open loop on flat turns?
    baseline: open-loop
    controllers: ["slip-pi*"]
    scenarios: [flat-turns]
    alpha: 0.05
    spending: obrien-fleming
    max_looks: 2
"""


def _final(
    tmp: Path, ledger: Path, ctrls: list[str] = CTRLS, force: bool = False, qid: str = "pi"
) -> dict[str, Path]:
    qfile = tmp / "questions.yaml"
    if not qfile.exists():
        qfile.write_text(QUESTIONS)
    return run_benchmark(
        ctrls,
        ["flat-turns"],
        2,
        tmp / "out",
        duration=0.2,
        progress=False,
        plots=False,
        final=True,
        force=force,
        ledger=ledger,
        command="test",
        question=qid,
        questions=qfile,
    )


def _rows(ledger: Path) -> list[dict[str, str]]:
    with ledger.open() as fh:
        return list(csv.DictReader(fh))


def test_test_split_needs_final_and_a_question(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="--final"):
        run_benchmark(CTRLS, ["flat-turns"], 1, tmp_path, split="test", progress=False)
    with pytest.raises(ValueError, match="pre-registered question"):
        run_benchmark(CTRLS, ["flat-turns"], 1, tmp_path, final=True, progress=False)
    (tmp_path / "q.yaml").write_text(QUESTIONS)
    with pytest.raises(ConfigError, match="no question 'nope'"):
        run_benchmark(
            CTRLS,
            ["flat-turns"],
            1,
            tmp_path,
            final=True,
            question="nope",
            questions=tmp_path / "q.yaml",
        )
    with pytest.raises(ValueError, match="asked on scenarios"):
        run_benchmark(
            CTRLS,
            ["ice-patch"],
            1,
            tmp_path,
            final=True,
            question="pi",
            questions=tmp_path / "q.yaml",
        )


def test_every_controller_is_recorded_with_its_question_and_look(tmp_path: Path) -> None:
    ledger = tmp_path / "ledger.csv"
    files = _final(tmp_path, ledger)
    base, row = _rows(ledger)
    assert tuple(row) == FIELDS
    assert (base["agent"], base["role"], base["baseline"]) == ("open-loop", "baseline", "")
    assert (row["agent"], row["role"], row["baseline"]) == ("slip-pi", "agent", "open-loop")
    assert base["agent_hash"] == agent_hash("open-loop") and row["agent_hash"] == agent_hash(
        "slip-pi"
    )
    assert row["question"] == "pi" and row["look"] == "1" and row["split"] == "test"
    assert row["run"] == base["run"] and row["repeat"] == ""
    q = question("pi", tmp_path / "questions.yaml")
    assert row["question_hash"] == q.fingerprint()
    # The first of two O'Brien-Fleming-type looks spends almost nothing (0.003 of 0.05).
    assert float(row["alpha_look"]) == pytest.approx(
        nominal_alphas("obrien-fleming", 0.05, 2)[0], rel=1e-5
    )
    assert json.loads(row["config"])["seeds"] == "4000..4001"
    assert set(json.loads(row["figures"])["flat-turns"]) == set(METRICS)
    assert set(json.loads(row["verdict"])) == {"flat-turns"} and base["verdict"] == ""
    assert "Look 1 of 2 at question `pi`" in files["markdown"].read_text()


def test_looks_are_counted_per_question_and_refused_beyond_the_plan(tmp_path: Path) -> None:
    ledger = tmp_path / "ledger.csv"
    _final(tmp_path, ledger)
    with pytest.raises(FinalRunRefused, match="already had its final test run"):
        _final(tmp_path, ledger)
    assert len(_rows(ledger)) == 2  # refused before any episode ran
    # Another agent answers the same question: the second look, with what the first left.
    files = _final(tmp_path, ledger, ["open-loop", "slip-pi@stuck_retry_scale=2"])
    rows = _rows(ledger)
    assert [r["look"] for r in rows] == ["1", "1", "2", "2"]
    a2 = nominal_alphas("obrien-fleming", 0.05, 2)[1]
    assert float(rows[-1]["alpha_look"]) == pytest.approx(a2, rel=1e-5)
    assert f"alpha {a2:.4g}" in files["markdown"].read_text()
    # A third look exceeds max_looks: refused, or forced, marked and with no alpha left.
    with pytest.raises(FinalRunRefused, match="planned look"):
        _final(tmp_path, ledger, ["open-loop", "slip-pi@stuck_retry_scale=3"])
    files = _final(tmp_path, ledger, ["open-loop", "slip-pi@stuck_retry_scale=3"], force=True)
    last = _rows(ledger)[-1]
    assert last["look"] == "3" and float(last["alpha_look"]) == 0.0
    assert last["repeat"] == "beyond max looks (forced)"
    text = files["markdown"].read_text()
    assert "no alpha left" in text and "FORCED" in text
    # A forced repeat of an agent is marked too.
    _final(tmp_path, ledger, force=True)
    assert "repeat (forced)" in _rows(ledger)[-1]["repeat"]


def test_an_edited_question_is_refused_after_its_first_look(tmp_path: Path) -> None:
    ledger = tmp_path / "ledger.csv"
    _final(tmp_path, ledger)
    qfile = tmp_path / "questions.yaml"
    qfile.write_text(QUESTIONS.replace("alpha: 0.05", "alpha: 0.10"))
    with pytest.raises(FinalRunRefused, match="changed since its first look"):
        _final(tmp_path, ledger, ["open-loop", "slip-pi@stuck_retry_scale=2"])


def test_version_1_rows_stay_readable_and_count_on_the_spent_block(tmp_path: Path) -> None:
    ledger = tmp_path / "ledger.csv"
    old = {k: "" for k in FIELDS_V1}
    old.update(date="2026-11-24T15:38:29Z", agent="slip-pi", agent_hash=agent_hash("slip-pi"))
    old.update(baseline="open-loop", config=json.dumps({"seeds": "3000..3019"}))
    with ledger.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(FIELDS_V1))
        w.writeheader()
        w.writerow(old)
    (r,) = read_ledger(ledger)
    assert (r["split"], r["role"], r["question"]) == ("spent", "agent", "")
    # Its looks were on the spent block: the agent's first look at the new block is allowed,
    # and the file is rewritten with the version-2 columns, the old row kept.
    _final(tmp_path, ledger)
    rows = _rows(ledger)
    assert tuple(rows[0]) == FIELDS and len(rows) == 3
    assert rows[0]["date"] == old["date"] and rows[0]["split"] == "spent"


def test_cli_defaults_to_validation_and_refuses_a_repeat(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    ledger = tmp_path / "ledger.csv"
    (tmp_path / "q.yaml").write_text(QUESTIONS)
    args = ["benchmark", "--controllers", "open-loop,slip-pi", "--scenarios", "flat-turns"]
    args += ["--episodes", "1", "--duration", "0.2", "--quiet", "--no-plots"]
    args += ["--out", str(tmp_path / "o"), "--ledger", str(ledger)]
    assert main(args) == 0
    assert "validation split" in capsys.readouterr().out and not ledger.exists()
    with pytest.raises(SystemExit):
        main([*args, "--split", "test"])  # not a choice: the test split needs --final
    assert main([*args, "--force"]) == 2
    assert main([*args, "--final"]) == 2  # no question
    assert "--final needs --question" in capsys.readouterr().err
    final = [*args, "--final", "--question", "pi", "--questions", str(tmp_path / "q.yaml")]
    assert main(final) == 0 and len(_rows(ledger)) == 2
    assert main(final) == 3
    assert "already had its final test run" in capsys.readouterr().err
    assert len(_rows(ledger)) == 2


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
    swapped normaliser after the one test run would make the shipped figures someone else's.
    An agent that left agents/ keeps its rows (history) and is listed, with the commit holding
    its files, in docs/benchmark/removed_agents.yaml; one that is gone unlisted is an error."""
    from rover_env.config import load_yaml

    repo = Path(__file__).resolve().parents[1]
    rows = read_ledger(repo / "docs" / "benchmark" / "test_ledger.csv")
    tested = {r["agent"]: r["agent_hash"] for r in rows if r["agent"].startswith("ppo:agents/")}
    removed = load_yaml(repo / "docs" / "benchmark" / "removed_agents.yaml")
    assert "ppo:agents/axle-schedule" in tested  # the shipped hard-ground agent (issue 17)
    assert "ppo:agents/mobility-ppo-sp15" in tested and "ppo:agents/mobility-ppo-sp15" in removed
    for spec, digest in tested.items():
        folder = repo / spec.removeprefix("ppo:")  # the ledger names it from the repository root
        if spec in removed:
            assert not folder.exists(), f"{spec} is listed as removed but is in agents/"
        else:
            assert folder.is_dir(), f"{spec}: not in agents/ and not in removed_agents.yaml"
            assert agent_hash(f"ppo:{folder}") == digest, spec
    for spec, entry in removed.items():
        assert not (repo / spec.removeprefix("ppo:")).exists(), spec
        assert len(entry["commit"]) == 40 and (repo / entry["docs"]).is_file(), spec


def test_shipped_questions_load_and_old_looks_are_on_the_spent_block() -> None:
    qs = load_questions()
    assert qs and all(q.max_looks >= 1 for q in qs.values())
    repo = Path(__file__).resolve().parents[1]
    rows = read_ledger(repo / "docs" / "benchmark" / "test_ledger.csv")
    assert rows and all(r["split"] in ("spent", "test") for r in rows)
    assert {r["split"] for r in rows if not r["question"]} == {"spent"}

"""The benchmark as an API: every controller on every scenario over one split's seeds
(:func:`run_benchmark`, with the test ledger for final runs), and the slip PI's gain tuning
on the tuning seeds (:func:`run_tuning`). The command line is :mod:`rover_env.benchmark.cli`.
"""

from __future__ import annotations

import csv
import time
from collections.abc import Sequence
from pathlib import Path

__all__ = ["run_benchmark", "run_tuning"]


def run_benchmark(
    controllers: Sequence[str],
    scenarios: Sequence[str],
    episodes: int,
    out: str | Path,
    split: str = "validation",
    duration: float | None = None,
    workers: int = 1,
    progress: bool = True,
    plots: bool = True,
    command: str | None = None,
    final: bool = False,
    force: bool = False,
    ledger: str | Path | None = None,
    executor: str = "local",
    ray_address: str | None = None,
    resume: bool = False,
    question: str | None = None,
    questions: str | Path | None = None,
) -> dict[str, Path]:
    """Every controller on every scenario for the first ``episodes`` seeds of ``split``.

    Episodes go to ``out/episodes.jsonl`` as they finish; ``resume`` keeps those and runs
    the rest. ``executor``/``ray_address``: :func:`rover_env.executor.make_executor`.

    The test split is touched once per agent (:mod:`rover_env.benchmark.ledger`): it needs
    ``final=True`` and ``question``, the id of a pre-registered question in ``questions``
    (default ``configs/benchmarks/questions.yaml``); it runs the test seeds, refuses an agent
    the ledger already holds or a look beyond the question's plan unless ``force``, judges at
    the look's alpha and appends every controller of the run to ``ledger`` (default
    ``docs/benchmark/test_ledger.csv``).
    """
    from rover_env.benchmark import ledger as test_ledger
    from rover_env.benchmark.questions import question as registered
    from rover_env.benchmark.report import ALPHA, write_report
    from rover_env.benchmark.run import Job, run_job
    from rover_env.benchmark.verdict import verdicts
    from rover_env.executor import make_executor, run_study
    from rover_env.seeds import seeds as seed_split

    if final:
        split = "test"
    elif split == "test":
        raise ValueError(
            "the test split is touched once per agent: select and tune on validation, and "
            "run the test seeds with --final (final=True), which the test ledger records"
        )
    if final and not question:
        raise ValueError(
            "a final run answers a pre-registered question: pass question=ID (--question ID, "
            "configs/benchmarks/questions.yaml)"
        )
    ledger_path = Path(ledger) if ledger is not None else test_ledger.default_ledger()
    checked = None
    if final:
        q = registered(str(question), questions)
        checked = test_ledger.check_final(controllers, scenarios, ledger_path, q, force)
    seed_list = seed_split(split, episodes)
    # Scenario-major, seed, then controller: paired episodes finish close together.
    jobs = [Job(c, s, seed, duration) for s in scenarios for seed in seed_list for c in controllers]
    t0 = time.perf_counter()
    with make_executor(executor, workers, ray_address, start_method="spawn") as ex:
        where = ex.describe()
        rows = run_study(
            ex,
            run_job,
            jobs,
            [job.key for job in jobs],
            Path(out) / "episodes.jsonl",
            resume=resume,
            desc="benchmark",
            unit="ep",
            progress=progress,
            postfix=lambda row: f"{row['controller']} {row['scenario']} {row['seed']}",
        )
    wall = time.perf_counter() - t0
    meta = {
        "command": f"`{command}`" if command else "(API call)",
        "controllers": ", ".join(controllers),
        "scenarios": ", ".join(scenarios),
        "seeds": f"{split} split, first {episodes} ({seed_list[0]}..{seed_list[-1]})",
        "episode length": (
            f"{duration:g} s (overridden)"
            if duration
            else "each scenario's own (configs/scenarios)"
        ),
        "control": "10 Hz through ProtoExplorerEnv (default sensor noise), estimator at 50 Hz",
        "wall time": f"{wall:.0f} s on the {where}, {len(jobs)} episodes"
        + (" (resumed)" if resume else ""),
    }
    alpha, look = ALPHA, ""
    if checked is not None:
        marks = [f"{a}: {m}" for a, m in checked.marks.items()]
        meta["question"] = f"`{checked.question.id}`: {checked.question.text}"
        meta["test ledger"] = f"final run recorded in {ledger_path}" + (
            f"; FORCED ({'; '.join(marks)})" if marks else ""
        )
        alpha, look = checked.alpha, checked.describe()
        meta["look"] = look
    files = write_report(out, rows, meta, plots=plots, alpha=alpha, look=look)
    if checked is not None:
        config = {
            "controllers": list(controllers),
            "scenarios": list(scenarios),
            "episodes": episodes,
            "seeds": f"{seed_list[0]}..{seed_list[-1]}",
            "duration": duration,
        }
        test_ledger.record_final(
            ledger_path,
            checked,
            controllers,
            rows,
            config,
            command or "(API call)",
            verdicts(rows, controllers[0], alpha) if len(controllers) > 1 else (),
        )
    return files


def run_tuning(
    scenarios: Sequence[str],
    seeds_per_scenario: int,
    duration: float,
    out: str | Path,
    workers: int = 1,
    refine_evals: int = 8,
    report: str | Path | None = None,
    command: str | None = None,
) -> Path:
    """Tune (Kp, Ki) of the slip PI on tuning seeds and write the gains YAML."""
    import dataclasses

    from rover_env.benchmark.scenarios import load_scenario
    from rover_env.benchmark.tuning import tune, write_config
    from rover_env.control.slip_pi import SlipPIConfig, load_slip_pi_config
    from rover_env.seeds import seeds as seed_split

    seed_list = seed_split("tuning", seeds_per_scenario)
    cases = [load_scenario(s).episode(seed, duration) for s in scenarios for seed in seed_list]
    out_p = Path(out)
    base = load_slip_pi_config(out_p) if out_p.is_file() else SlipPIConfig()
    res = tune(cases, base=base, workers=workers, refine_evals=refine_evals)
    best = dataclasses.replace(base, kp=res.kp, ki=res.ki)
    header = (
        "Slip PI gains (rover_env.control.slip_pi.SlipPIConfig; the module docstring says why\n"
        "each field is there). Kp and Ki were tuned by rover_env.benchmark.tuning (grid, then\n"
        "Nelder-Mead through the env, the benchmark's episode loop); the other fields are\n"
        "design choices kept fixed.\n"
        f"Produced by: {command or '(API call)'}\n"
        f"Scenarios: {', '.join(scenarios)}; tuning seeds {', '.join(map(str, seed_list))};\n"
        f"{duration:g} s episodes; {len(res.evaluations)} gain pairs tried in {res.wall_s:.0f} s;\n"
        f"objective J = {res.score:.4f} (open loop = 1 + 0 penalties)."
    )
    path = write_config(out_p, best, header)
    if report is not None:
        rp = Path(report)
        rp.parent.mkdir(parents=True, exist_ok=True)
        with rp.open("w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=["kp", "ki", "score"])
            w.writeheader()
            w.writerows(res.evaluations)
    print(f"best kp={res.kp:.4f} ki={res.ki:.4f} J={res.score:.4f}; wrote {path}")
    return path

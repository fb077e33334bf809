"""Baselines tuned fairly: each hand-built controller tuned on the agent's own objective.

An agent is compared with a baseline only fairly when the baseline had the same chance: the
same episodes to tune on and the same score to tune for. :func:`objective_of` reads both from
the agent's training configuration (its env id entry): the scenario families and their
weights (``env_kwargs.scenarios``) and the reward weights (``env_kwargs.reward_weights``).
A controller's objective is then the agent's: the **mean episode return** under those reward
weights (the env's own reward summed over the episode,
:func:`rover_env.benchmark.run.run_episode`), averaged per family and weighted across
families as the agent's scenario weights (the same seeds for every family and setting, so
all comparisons are paired).

Procedure (:func:`tune_baselines`), for each baseline of :data:`BASELINES` (a base
controller spec and a grid over two of its knobs):

1. every setting of the grid plays every family on the tuning seeds (1000-1099) and is
   scored by the objective;
2. the best ``top`` settings (3) are re-scored on validation seeds (2000-2099);
3. the baseline's chosen setting is the finalist with the highest validation objective, and
   the best baseline overall is the chosen setting with the highest validation objective:
   the one an agent is compared against.

Test seeds (4000-4999) and spent seeds (3000-3999) are refused (:func:`check_split`).
``rover-env tune-baselines`` (:mod:`rover_env.benchmark.cli`) runs it and writes the chosen
settings (:func:`write_config`, ``configs/benchmarks/baselines.yaml``; read back with
:func:`load_tuned`) and a report (:func:`write_report`, ``docs/benchmark/baselines.md``).
"""

from __future__ import annotations

import dataclasses
import json
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from rover_env.benchmark.run import Job, run_jobs
from rover_env.config import ConfigError, load_yaml
from rover_env.seeds import check_split
from rover_env.tasks.reward import RewardWeights
from rover_env.tasks.scenarios import load_scenario

__all__ = [
    "BASELINES",
    "REPORT_METRICS",
    "Baseline",
    "BaselineResult",
    "Objective",
    "Score",
    "TunedBaselines",
    "from_rows",
    "load_tuned",
    "objective_of",
    "paired_difference",
    "read_episodes",
    "score",
    "tune_baselines",
    "weighted_interval",
    "write_config",
    "write_episodes",
    "write_report",
]

REPORT_METRICS: tuple[str, ...] = ("success", "energy_per_metre", "mean_sinkage", "pace_ratio")
"""Benchmark metrics reported beside each finalist's validation objective."""


# --------------------------------------------------------------------------- objective


@dataclass(frozen=True)
class Objective:
    """What the agent is trained to maximise: its families' episodes and reward weights."""

    source: str
    """The agent configuration it was read from."""
    env_id: str
    scenarios: dict[str, float]
    """Scenario (family) name -> weight, as the agent's env draws them."""
    reward_weights: RewardWeights

    @property
    def weight_pairs(self) -> tuple[tuple[str, float], ...]:
        """The reward weights as a :class:`~rover_env.benchmark.run.Job` takes them."""
        return tuple((f.name, float(getattr(self.reward_weights, f.name))) for f in _fields())

    def non_default_weights(self) -> dict[str, float]:
        """The reward weights that differ from :class:`RewardWeights`' defaults (for reports)."""
        base = RewardWeights()
        return {
            f.name: float(getattr(self.reward_weights, f.name))
            for f in _fields()
            if getattr(self.reward_weights, f.name) != getattr(base, f.name)
            or f.name in ("tracking", "slip", "energy")
        }


def _fields() -> tuple[dataclasses.Field[Any], ...]:
    return dataclasses.fields(RewardWeights)


def objective_of(path: str | Path) -> Objective:
    """The objective of the agent configuration at ``path`` (one env id entry whose
    ``env_kwargs`` name ``scenarios`` and, optionally, ``reward_weights``)."""
    data = load_yaml(path)
    if not isinstance(data, Mapping) or len(data) != 1:
        raise ConfigError(f"{path}: an agent configuration has one top-level key, its env id")
    ((env_id, entry),) = data.items()
    kwargs = (entry or {}).get("env_kwargs") if isinstance(entry, Mapping) else None
    if not isinstance(kwargs, Mapping):
        raise ConfigError(f"{path}: {env_id}.env_kwargs is missing (the agent's episodes)")
    mix = kwargs.get("scenarios")
    if isinstance(mix, Sequence) and not isinstance(mix, str):
        mix = dict.fromkeys(mix, 1.0)
    if not isinstance(mix, Mapping) or not mix:
        raise ConfigError(
            f"{path}: {env_id}.env_kwargs.scenarios must map scenario names to weights"
        )
    scenarios: dict[str, float] = {}
    for name, w in mix.items():
        if not (isinstance(w, int | float) and math.isfinite(w) and w > 0):
            raise ConfigError(f"{path}: {env_id}.env_kwargs.scenarios.{name}: weight must be > 0")
        try:
            load_scenario(str(name))
        except (ConfigError, ValueError, FileNotFoundError) as exc:
            raise ConfigError(f"{path}: {env_id}.env_kwargs.scenarios.{name}: {exc}") from None
        scenarios[str(name)] = float(w)
    raw = kwargs.get("reward_weights") or {}
    try:
        weights = RewardWeights(**raw)
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"{path}: {env_id}.env_kwargs.reward_weights: {exc}") from None
    return Objective(str(path), str(env_id), scenarios, weights)


# --------------------------------------------------------------------------- baselines


@dataclass(frozen=True)
class Baseline:
    """A base controller spec and a grid over two of its knobs (``@knob=value``)."""

    name: str
    base: str
    knobs: tuple[str, str]
    grid: tuple[tuple[float, ...], tuple[float, ...]]
    why: str

    def settings(self) -> list[str]:
        """Every setting of the grid as a controller spec, first knob outermost."""
        (k1, k2), (g1, g2) = self.knobs, self.grid
        return [f"{self.base}@{k1}={a:g}@{k2}={b:g}" for a in g1 for b in g2]


BASELINES: tuple[Baseline, ...] = (
    Baseline(
        "open-loop",
        "open-loop",
        ("gain", "ramp"),
        ((1.0, 1.15, 1.3, 1.5, 1.8, 2.2), (0.0, 2.0)),
        "gain: every wheel target x K, the over-speed that makes up loose soil's slip (1: "
        "kinematic; 2.2 keeps the pace on soft-patch, docs/benchmark/README.md); ramp: that "
        "target grown from rest over T s (0: a step; 2: the agent's residual base)",
    ),
    Baseline(
        "slip-pi",
        "slip-pi",
        ("kp", "ki"),
        ((0.0, 0.05, 0.2), (0.6, 1.2, 2.244, 3.2)),
        "the paper's per-wheel PI on slip (configs/control/slip_pi.yaml, Kp 0.05, Ki 2.244 "
        "/s): Kp and Ki inside the stability box of rover_env.benchmark.tuning (Kp <= 0.5, "
        "Ki <= 3.5 /s)",
    ),
    Baseline(
        "slip-pi-setpoint",
        "slip-pi:slip_pi_soil",
        ("slip_setpoint", "max_correction"),
        ((-0.15, -0.3, -0.5, -0.7), (0.3, 0.8, 1.6)),
        "the set-point PI for loose soil (configs/control/slip_pi_soil.yaml, -0.7 and 1.6): "
        "the shared slip it holds (Wong's useful drawbar pull at s = 0.2-0.6) and how far it "
        "may speed a wheel up (1 + max_correction of the target: 0.3 keeps the pace's +25 % "
        "in reach on firm ground, 1.6 is the motor's limit)",
    ),
)
"""The three baselines of issue 46 and their grids (10-12 settings each)."""


# --------------------------------------------------------------------------- scoring


def weighted_interval(
    groups: Mapping[str, Sequence[float]], weights: Mapping[str, float], level: float = 0.95
) -> tuple[float, float, float]:
    """(mean, low, high): the weighted mean of per-group means, sum_g w_g mean_g / sum w,
    with a Student-t interval on the Welch-Satterthwaite degrees of freedom (groups
    independent, each group's variance its own)."""
    from scipy import stats

    total = sum(weights[g] for g in groups)
    mean, var, dof_den = 0.0, 0.0, 0.0
    for g, xs in groups.items():
        a = np.asarray(xs, dtype=np.float64)
        c = weights[g] / total
        mean += c * float(np.mean(a))
        if a.size > 1:
            v = c * c * float(np.var(a, ddof=1)) / a.size
            var += v
            dof_den += v * v / (a.size - 1)
    if var == 0.0:
        return mean, mean, mean
    dof = var * var / dof_den
    hw = float(stats.t.ppf(0.5 + level / 2, dof)) * math.sqrt(var)
    return mean, mean - hw, mean + hw


@dataclass
class Score:
    """One setting on one seed split: its objective and the report metrics, each as
    (mean, low, high) weighted across families, and its mean return per family."""

    spec: str
    objective: tuple[float, float, float]
    by_family: dict[str, float]
    metrics: dict[str, tuple[float, float, float]]
    episodes: int


def score(spec: str, rows: Sequence[Mapping[str, Any]], objective: Objective) -> Score:
    """The objective of ``spec`` over its rows (every family of ``objective`` needed)."""

    def groups(metric: str) -> dict[str, list[float]]:
        out: dict[str, list[float]] = {s: [] for s in objective.scenarios}
        for r in rows:
            if r["controller"] == spec and r["scenario"] in out:
                out[r["scenario"]].append(float(r[metric]))
        missing = [s for s, xs in out.items() if not xs]
        if missing:
            raise ValueError(f"score({spec}): no episodes of {missing}")
        return out

    ret = groups("return")
    return Score(
        spec,
        weighted_interval(ret, objective.scenarios),
        {s: float(np.mean(xs)) for s, xs in ret.items()},
        {m: weighted_interval(groups(m), objective.scenarios) for m in REPORT_METRICS},
        sum(len(xs) for xs in ret.values()),
    )


# --------------------------------------------------------------------------- tuning


@dataclass
class BaselineResult:
    baseline: Baseline
    tuning: list[Score]
    """Every setting on the tuning seeds, in grid order."""
    finalists: list[Score]
    """The best settings on tuning, re-scored on validation, in tuning rank order."""

    @property
    def chosen(self) -> Score:
        """The finalist with the highest validation objective (tuning rank breaks a tie)."""
        return max(self.finalists, key=lambda s: s.objective[0])


@dataclass
class TunedBaselines:
    objective: Objective
    tuning_seeds: list[int]
    validation_seeds: list[int]
    duration: float | None
    results: list[BaselineResult]
    rows: list[dict[str, Any]] = field(default_factory=list)
    wall_s: float = 0.0

    @property
    def best(self) -> BaselineResult:
        """The baseline whose chosen setting has the highest validation objective."""
        return max(self.results, key=lambda r: r.chosen.objective[0])


def _play(
    specs: Sequence[str],
    objective: Objective,
    seeds: Sequence[int],
    duration: float | None,
    workers: int,
    say: Callable[[str], None],
    label: str,
) -> list[dict[str, Any]]:
    jobs = [
        Job(spec, sc, s, duration, objective.weight_pairs)
        for spec in specs
        for sc in objective.scenarios
        for s in seeds
    ]
    t0, done = time.perf_counter(), [0]
    every = max(1, len(jobs) // 10)

    def tick(_row: dict[str, Any]) -> None:
        done[0] += 1
        if done[0] % every == 0 or done[0] == len(jobs):
            dt = time.perf_counter() - t0
            eta = dt / done[0] * (len(jobs) - done[0])
            say(f"  {label}: {done[0]}/{len(jobs)} episodes, {dt:.0f} s (eta {eta:.0f} s)")

    return run_jobs(jobs, workers=workers, progress=tick)


def tune_baselines(
    objective: Objective,
    tuning_seeds: Sequence[int],
    validation_seeds: Sequence[int],
    baselines: Sequence[Baseline] = BASELINES,
    top: int = 3,
    duration: float | None = None,
    workers: int = 1,
    log: Callable[[str], None] | None = print,
) -> TunedBaselines:
    """The procedure of the module docstring; ``duration`` shortens every episode (tests)."""
    tune = check_split(tuning_seeds, "tuning", "tune-baselines --seeds-tune")
    val = check_split(validation_seeds, "validation", "tune-baselines --seeds-val")
    if not tune or not val or top < 1:
        raise ValueError("tune-baselines needs tuning seeds, validation seeds and top >= 1")
    say = log or (lambda _m: None)
    t0 = time.perf_counter()
    out = TunedBaselines(objective, tune, val, duration, [])
    for b in baselines:
        specs = b.settings()
        say(
            f"{b.name}: {len(specs)} settings x {len(objective.scenarios)} families x "
            f"{len(tune)} tuning seeds"
        )
        rows = _play(specs, objective, tune, duration, workers, say, f"{b.name} tuning")
        out.rows += [{**r, "split": "tuning"} for r in rows]
        scores = [score(s, rows, objective) for s in specs]
        for s in scores:
            say(f"  {s.spec}: objective {s.objective[0]:.2f}")
        ranked = sorted(scores, key=lambda s: -s.objective[0])[:top]
        names = [s.spec for s in ranked]
        rows = _play(names, objective, val, duration, workers, say, f"{b.name} validation")
        out.rows += [{**r, "split": "validation"} for r in rows]
        result = BaselineResult(b, scores, [score(s, rows, objective) for s in names])
        for s in result.finalists:
            lo, hi = s.objective[1:]
            say(f"  validation {s.spec}: {s.objective[0]:.2f} [{lo:.2f}, {hi:.2f}]")
        say(f"  chosen: {result.chosen.spec}")
        out.results.append(result)
    out.wall_s = time.perf_counter() - t0
    say(f"best baseline: {out.best.baseline.name} ({out.best.chosen.spec}), {out.wall_s:.0f} s")
    return out


def from_rows(
    objective: Objective,
    rows: Sequence[dict[str, Any]],
    baselines: Sequence[Baseline] = BASELINES,
    duration: float | None = None,
) -> TunedBaselines:
    """The result of a run rebuilt from its episode rows (:func:`read_episodes`): a report
    or config written again without playing anything (wall time: the episodes' sum)."""
    split = {k: [r for r in rows if r.get("split") == k] for k in ("tuning", "validation")}
    seeds = {k: sorted({int(r["seed"]) for r in v}) for k, v in split.items()}
    out = TunedBaselines(objective, seeds["tuning"], seeds["validation"], duration, [])
    played = {k: {r["controller"] for r in v} for k, v in split.items()}
    for b in baselines:
        specs = [s for s in b.settings() if s in played["tuning"]]
        if not specs:
            continue
        tuning = [score(s, split["tuning"], objective) for s in specs]
        ranked = [s.spec for s in sorted(tuning, key=lambda s: -s.objective[0])]
        finals = [
            score(s, split["validation"], objective) for s in ranked if s in played["validation"]
        ]
        if not finals:
            raise ValueError(f"from_rows: no validation episodes of {b.name}'s finalists")
        out.results.append(BaselineResult(b, tuning, finals))
    if not out.results:
        raise ValueError("from_rows: no tuning episodes of any baseline")
    out.rows = list(rows)
    out.wall_s = float(sum(float(r.get("wall_s", 0.0)) for r in rows))
    return out


# --------------------------------------------------------------------------- outputs


def _r(x: float, nd: int = 4) -> float:
    return float(round(x, nd)) if math.isfinite(x) else x


def _triple(t: tuple[float, float, float]) -> dict[str, Any]:
    return {"mean": _r(t[0]), "ci95": [_r(t[1]), _r(t[2])]}


def _ranges(seeds: Sequence[int]) -> str:
    return (
        f"{seeds[0]}-{seeds[-1]}"
        if list(seeds) == list(range(seeds[0], seeds[-1] + 1))
        else (",".join(map(str, seeds)))
    )


def config_data(res: TunedBaselines) -> dict[str, Any]:
    """What :func:`write_config` writes (plain data)."""
    obj = res.objective
    return {
        "agent_config": obj.source,
        "objective": {
            "what": "mean episode return (sum of the env's rewards), per family, weighted "
            "across families as the agent's scenarios",
            "env_id": obj.env_id,
            "scenarios": dict(obj.scenarios),
            "reward_weights": obj.non_default_weights(),
        },
        "seeds": {
            "tuning": _ranges(res.tuning_seeds),
            "validation": _ranges(res.validation_seeds),
            "per_family": {
                "tuning": len(res.tuning_seeds),
                "validation": len(res.validation_seeds),
            },
        },
        "duration": res.duration,
        "best": res.best.baseline.name,
        "baselines": {
            r.baseline.name: {
                "controller": r.chosen.spec,
                "knobs": list(r.baseline.knobs),
                "tuning_objective": _r(
                    next(s for s in r.tuning if s.spec == r.chosen.spec).objective[0]
                ),
                "validation_objective": _triple(r.chosen.objective),
                "validation": {m: _triple(r.chosen.metrics[m]) for m in REPORT_METRICS},
            }
            for r in res.results
        },
    }


def write_config(path: str | Path, res: TunedBaselines, command: str = "") -> Path:
    """The shipped choice: baseline name -> controller spec, objective, seeds and scores."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    head = (
        "# Baselines tuned fairly (issue 46; rover_env.benchmark.baselines): each baseline's\n"
        "# setting chosen on validation seeds among the best 3 of its grid on tuning seeds, by\n"
        "# the agent's own objective. `best` is the baseline an agent is compared against.\n"
        "# Report: docs/benchmark/baselines.md. Read with rover_env.benchmark.baselines.load_tuned.\n"
        + (f"# Produced by: {command}\n" if command else "")
    )
    p.write_text(
        head + yaml.safe_dump(config_data(res), sort_keys=False, default_flow_style=None, width=100)
    )
    return p


def load_tuned(path: str | Path = "configs/benchmarks/baselines.yaml") -> dict[str, str]:
    """Baseline name -> its tuned controller spec, the best baseline first."""
    data = load_yaml(path)
    try:
        specs = {str(k): str(v["controller"]) for k, v in data["baselines"].items()}
        best = str(data["best"])
    except (KeyError, TypeError, AttributeError) as exc:
        raise ConfigError(f"{path}: needs best and baselines.NAME.controller ({exc})") from None
    if best not in specs:
        raise ConfigError(f"{path}: best {best!r} is not one of the baselines {list(specs)}")
    return {best: specs[best], **{k: v for k, v in specs.items() if k != best}}


def paired_difference(
    res: TunedBaselines, a: str, b: str, split: str = "validation"
) -> tuple[float, float, float]:
    """(mean, low, high) of the objective of spec ``a`` less that of ``b``, paired by family
    and seed (both play the same episodes) and weighted across families as the objective."""
    ret = {
        (r["controller"], r["scenario"], int(r["seed"])): float(r["return"])
        for r in res.rows
        if r.get("split") == split and r["controller"] in (a, b)
    }
    groups: dict[str, list[float]] = {}
    for (c, sc, seed), x in ret.items():
        if c == a and (b, sc, seed) in ret:
            groups.setdefault(sc, []).append(x - ret[(b, sc, seed)])
    if set(groups) != set(res.objective.scenarios):
        raise ValueError(f"paired_difference({a}, {b}): not paired on every family ({split})")
    return weighted_interval(groups, res.objective.scenarios)


def _ci(t: tuple[float, float, float], fmt: str = ".3g") -> str:
    return f"{t[0]:{fmt}} ± {(t[2] - t[1]) / 2:{fmt}}"


def report_lines(res: TunedBaselines, command: str = "") -> list[str]:
    """Markdown of every setting's tuning score and the finalists' validation scores."""
    obj = res.objective
    fams = list(obj.scenarios)
    lines = [
        "# Baselines tuned fairly",
        "",
        f"Objective: the agent's (`{obj.source}`, `{obj.env_id}`): the mean episode return "
        f"under its reward weights {obj.non_default_weights()}, per family, weighted across "
        f"families as its scenarios {dict(obj.scenarios)}. Tuning seeds {_ranges(res.tuning_seeds)}"
        f", validation seeds {_ranges(res.validation_seeds)}, the same for every family and "
        f"setting; episodes of "
        + ("full length" if res.duration is None else f"{res.duration:g} s")
        + f". {len(res.rows)} episodes, {res.wall_s:.0f} s wall.",
        "",
        f"**Best baseline: {res.best.baseline.name}, `{res.best.chosen.spec}`** (validation "
        f"objective {_ci(res.best.chosen.objective, '.2f')}): the one an agent is compared "
        "against. Intervals: 95 % Student-t on the Welch-Satterthwaite degrees of freedom of "
        "the weighted mean of per-family means. Success, energy per metre (J/m), mean "
        "sinkage (m) and pace ratio are weighted across families the same way; the family "
        "columns are mean returns.",
        "",
    ]
    if command:
        lines += ["Produced by:", "", "```bash", command, "```", ""]
    best = res.best.chosen.spec
    lines += ["## Chosen settings (validation)", ""]
    lines += [
        "Δ: objective less the best baseline's, paired on the same episodes (mean ± 95 %).",
        "",
        "| baseline | controller | objective | Δ vs best | " + " | ".join(REPORT_METRICS) + " |",
        "|---|---|---|---|" + "---|" * len(REPORT_METRICS),
    ]
    for r in res.results:
        c = r.chosen
        cells = " | ".join(_ci(c.metrics[m]) for m in REPORT_METRICS)
        d = "–" if c.spec == best else _ci(paired_difference(res, c.spec, best), ".2f")
        lines.append(
            f"| {r.baseline.name} | `{c.spec}` | {_ci(c.objective, '.2f')} | {d} | {cells} |"
        )
    lines.append("")
    for r in res.results:
        b = r.baseline
        lines += [f"## {b.name}", "", f"Knobs {b.knobs[0]} x {b.knobs[1]}: {b.why}.", ""]
        lines += ["Tuning (every setting):", ""]
        lines += [
            "| setting | objective | " + " | ".join(fams) + " |",
            "|---|---|" + "---|" * len(fams),
        ]
        for s in sorted(r.tuning, key=lambda s: -s.objective[0]):
            per = " | ".join(f"{s.by_family[f]:.1f}" for f in fams)
            lines.append(f"| `{s.spec}` | {_ci(s.objective, '.2f')} | {per} |")
        lines += ["", "Finalists on validation (chosen in bold; Δ paired vs the chosen):", ""]
        lines += [
            "| setting | objective | Δ vs chosen | "
            + " | ".join(REPORT_METRICS)
            + " | "
            + " | ".join(fams)
            + " |",
            "|---|---|---|" + "---|" * (len(REPORT_METRICS) + len(fams)),
        ]
        for s in r.finalists:
            mine = s is r.chosen
            name = f"**`{s.spec}`**" if mine else f"`{s.spec}`"
            d = "–" if mine else _ci(paired_difference(res, s.spec, r.chosen.spec), ".2f")
            cells = " | ".join(_ci(s.metrics[m]) for m in REPORT_METRICS)
            per = " | ".join(f"{s.by_family[f]:.1f}" for f in fams)
            lines.append(f"| {name} | {_ci(s.objective, '.2f')} | {d} | {cells} | {per} |")
        lines.append("")
    return lines


def write_report(path: str | Path, res: TunedBaselines, command: str = "") -> Path:
    """:func:`report_lines` as a Markdown file."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text("\n".join(report_lines(res, command)))
    return p


def write_episodes(path: str | Path, res: TunedBaselines) -> Path:
    """Every episode's row as JSON lines (run output; stays out of git)."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    with p.open("w") as fh:
        for r in res.rows:
            fh.write(json.dumps(r, default=float) + "\n")
    return p


def read_episodes(path: str | Path) -> list[dict[str, Any]]:
    """The rows :func:`write_episodes` wrote."""
    with Path(path).open() as fh:
        return [json.loads(line) for line in fh if line.strip()]

"""Learning-curve figure of a run dir: return and mean |S| against env steps."""

from __future__ import annotations

import csv
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from rover_env.training.rundir import run_algo


def _read(path: Path) -> dict[str, np.ndarray]:
    if not path.is_file():
        return {}
    with path.open() as fh:
        rows = list(csv.DictReader(fh))
    if not rows:
        return {}
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


def _rolling(x: np.ndarray, n: int) -> np.ndarray:
    """Trailing mean over up to ``n`` episodes (short at the start rather than lagging)."""
    c = np.cumsum(np.insert(x, 0, 0.0))
    idx = np.arange(1, len(x) + 1)
    lo = np.maximum(idx - n, 0)
    return (c[idx] - c[lo]) / (idx - lo)


def plot_learning_curve(run_dir: str | Path, out: str | Path | None = None) -> Path:
    """Training episodes (points + rolling mean) and validation evaluations, sharing the step axis."""
    run_dir = Path(run_dir)
    out = Path(out) if out is not None else run_dir / "learning_curve.png"
    ep = _read(run_dir / "episodes.csv")
    ev = _read(run_dir / "evaluations.csv")
    fig, (ax_r, ax_s) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    if ep:
        order = np.argsort(ep["timesteps"], kind="stable")
        t = ep["timesteps"][order]
        n = max(5, len(t) // 20)
        for ax, key in ((ax_r, "return"), (ax_s, "slip_mean_abs")):
            y = ep[key][order]
            ax.plot(t, y, ".", color="C0", alpha=0.25, ms=3, label="training episode")
            ax.plot(t, _rolling(y, n), color="C0", label=f"training, mean of {n}")
    if ev:
        ax_r.errorbar(
            ev["timesteps"],
            ev["mean_reward"],
            yerr=ev["std_reward"],
            fmt="o-",
            color="C1",
            ms=4,
            capsize=2,
            label="validation (deterministic)",
        )
        ax_s.plot(ev["timesteps"], ev["slip_mean_abs"], "o-", color="C1", ms=4, label="validation")
    if not ep and not ev:
        ax_r.text(0.5, 0.5, "no finished episode yet", ha="center", transform=ax_r.transAxes)
    ax_r.set_ylabel("episode return")
    ax_s.set_ylabel("mean |S| over the episode")
    ax_s.set_xlabel("env steps")
    for ax in (ax_r, ax_s):
        ax.grid(alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=8)
    ax_r.set_title(f"{run_algo(run_dir).upper()} learning curve: {run_dir.name}")
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    plt.close(fig)
    return out

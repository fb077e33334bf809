"""Issue 15's acceptance comparisons of a soil benchmark run, corrected as one family.

The claim is that the set-point PI beats open loop on ``sand-slope`` and ``soft-patch`` in
success, mean sinkage and energy per metre: six paired comparisons (fewer when a scenario is
missing). The benchmark's own table corrects over every metric it prints (speed error,
p95 slip, distance...), which are not part of the claim; this script corrects over the six
only (Holm), and adds the exact McNemar test of the paired successes (a binary outcome for
which the Student-t interval is an approximation). Reads ``OUT/episodes.csv`` of
``rover-env benchmark --controllers open-loop,slip-pi:slip_pi_soil ... --out OUT``.

    python benchmarks/soil_acceptance.py out/benchmark-soil-test
"""

from __future__ import annotations

import argparse
import csv
from collections import defaultdict
from pathlib import Path

from scipy import stats

from rover_env.benchmark.report import holm, paired_p, t_interval

SCENARIOS = ("sand-slope", "soft-patch")
METRICS = ("success", "mean_sinkage", "energy_per_metre")


def mcnemar_exact(won: int, lost: int) -> float:
    """Two-sided exact McNemar p from the discordant pairs."""
    n = won + lost
    if n == 0:
        return 1.0
    k = min(won, lost)
    return min(1.0, 2.0 * float(stats.binom.cdf(k, n, 0.5)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path, help="benchmark output folder (episodes.csv)")
    ap.add_argument("--baseline", default="open-loop")
    ap.add_argument("--controller", default="slip-pi:slip_pi_soil")
    args = ap.parse_args()
    path = args.out / "episodes.csv"
    by: dict[tuple[str, str], dict[str, dict[str, str]]] = defaultdict(dict)
    with path.open() as fh:
        for r in csv.DictReader(fh):
            by[(r["scenario"], r["seed"])][r["controller"]] = r
    rows = []
    for sc in SCENARIOS:
        pairs = [v for (s, _), v in sorted(by.items()) if s == sc]
        pairs = [v for v in pairs if args.baseline in v and args.controller in v]
        if not pairs:
            continue
        for m in METRICS:
            d = [float(v[args.controller][m]) - float(v[args.baseline][m]) for v in pairs]
            base = sum(float(v[args.baseline][m]) for v in pairs) / len(pairs)
            rows.append((sc, m, len(pairs), base, *t_interval(d), paired_p(d)))
        won = sum(
            float(v[args.controller]["success"]) > float(v[args.baseline]["success"]) for v in pairs
        )
        lost = sum(
            float(v[args.controller]["success"]) < float(v[args.baseline]["success"]) for v in pairs
        )
        print(
            f"{sc}: {args.controller} won {won} seeds, lost {lost} "
            f"(exact McNemar p {mcnemar_exact(won, lost):.2g})"
        )
    adj = holm([r[7] for r in rows])
    print(f"\n{args.controller} - {args.baseline}, Holm over {len(rows)} comparisons ({path}):")
    for r, a in zip(rows, adj, strict=True):
        sc, m, n, base, mu, lo, hi, p = r
        rel = f"{100 * mu / base:+.1f} %" if base else "-"
        verdict = "resolved" if a < 0.05 else "not resolved"
        print(
            f"  {sc:10s} {m:17s} n={n:3d} {mu:+.4g} [{lo:+.4g}, {hi:+.4g}] {rel:>9s}"
            f"  p {p:.2g}, Holm {a:.2g}: {verdict}"
        )


if __name__ == "__main__":
    main()

"""Study 71500's one look: H1 and H2 of prereg.md from tilt_reads.jsonl.

python docs/calibration/study71500/look.py /tmp/s71500/out/tilt_reads.jsonl
"""

from __future__ import annotations

import json
import sys

KEYS = ("all", "driven wheels", "free wheels", "joints", "pose")


def heading_error(a: float, b: float) -> float:
    return abs((a - b + 180.0) % 360.0 - 180.0)


def reads_right(read: list[float], truth: list[float]) -> bool:
    ratio = read[0] / truth[0]
    return 2 / 3 <= ratio <= 3 / 2 and heading_error(read[1], truth[1]) <= 45.0


def main(path: str) -> int:
    rows = [json.loads(x) for x in open(path, encoding="utf-8") if x.strip()]
    clean = [r for r in rows if not r["truth"][0]]
    slopes = [r for r in rows if r["truth"][0]]
    print(f"{len(clean)} clean builds, {len(slopes)} slopes")
    for k in KEYS:
        flat = sum(r["reads"][k][0] <= 1.0 for r in clean)
        right = sum(reads_right(r["reads"][k], r["truth"]) for r in slopes)
        sizes = sorted(r["reads"][k][0] for r in clean)
        med = sizes[len(sizes) // 2] if sizes else float("nan")
        top = sizes[-1] if sizes else float("nan")
        print(
            f"  {k:14s} clean <= 1 deg {flat}/{len(clean)} (median {med:g}, largest"
            f" {top:g}); slopes read right {right}/{len(slopes)}"
        )
    h1 = sum(r["reads"]["free wheels"][0] <= 1.0 for r in clean) >= 18
    h2 = sum(reads_right(r["reads"]["free wheels"], r["truth"]) for r in slopes) >= 8
    print(f"H1 (free wheels: clean <= 1 deg in >= 18 of 20): {'passed' if h1 else 'FAILED'}")
    print(f"H2 (free wheels: slopes right in >= 8 of 10): {'passed' if h2 else 'FAILED'}")
    print(
        "decision:",
        "register a tilt read led by the free wheels next" if h1 and h2 else "lead dropped",
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1]))

"""benchmarks/diagnose_speed.py's comparison of two runs' findings: timings and the run's own
folder aside, any other difference in ``result.json`` counts. No diagnosis runs here."""

from __future__ import annotations

import json
from pathlib import Path

from _bench import load_bench


def _write(out: Path, result: dict[str, object]) -> Path:
    out.mkdir(parents=True)
    (out / "result.json").write_text(json.dumps(result))
    return out


def test_findings_ignore_timings_and_the_folder_but_nothing_else(tmp_path: Path) -> None:
    ds = load_bench("diagnose_speed")

    def result(out: Path, secs: float, value: float) -> dict[str, object]:
        fit = {"value": value, "seconds": secs, "nfev": 7}
        return {
            "named": ["slope"],
            "fits": {"slope": fit},
            "seconds": secs,
            "replay_seconds": secs / 2,
            "config": str(out / "rover.yaml"),
        }

    a, b, c = tmp_path / "prev", tmp_path / "cur", tmp_path / "other"
    _write(a, result(a, 61.0, 2.5))
    _write(b, result(b, 55.0, 2.5))
    _write(c, result(c, 55.0, 2.5000001))
    assert ds.findings(a) == ds.findings(b)
    assert ds.findings(a) != ds.findings(c)  # a fitted value one part in 10^7 apart

"""Would one torque limit per wheel make a deep torque cut nameable? A diagnostic that knows
the answer (issue 47, stop 98).

The independent generator's build draws each motor's torque constant (k_t, +-20 %), and its
torque limit effect scales the drivers' current limit, so each wheel's limit in N m differs
by its k_t; ``diagnose``'s ``torque_limit`` is one fraction for all four. For every case
folder given (``LOGS`` holding ``drive_*.csv`` and ``truth.yaml``, e.g. ``option_ab.py``'s
``case_*/logs``) this applies ``diagnose``'s naming test (:func:`truth_ceiling.test_at_truth`)
to the truth twice: one fraction (the catalogue's, at most the range's end) and each wheel's
own limit (that limit times the build's k_t ratio, set on the model's actuators). Nothing in
``diagnose`` reads ``truth.yaml``; the per-wheel limits are set by patching the MJCF the
replay builds, so this is not a method.

    python benchmarks/torque_per_wheel.py out/study71600/case_716{00..07}/logs --workers 2
"""

from __future__ import annotations

import argparse
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import yaml
from _independent_plan import TORQUE_RATIO
from truth_ceiling import test_at_truth

import rover_env.sim.model as model_xml
from rover_env.config import RoverConfig

SCALE: dict[str, float] = {}
"""Each driven wheel's limit over the configuration's (after the effect), while patched."""
_ROBOT_XML = model_xml.robot_xml


def per_wheel_xml(cfg: RoverConfig) -> str:
    """The robot's MJCF with each driven wheel's motor limited at the configuration's limit
    times its :data:`SCALE` (none: the configuration's model)."""
    xml = _ROBOT_XML(cfg)
    for wn, s in SCALE.items():
        tag = f'<dcmotor name="motor_{wn}" class="motor" joint="wheel_{wn}"'
        sat = f'{tag} saturation="{cfg.motor.torque_limit * s!r} 0 0"'
        assert tag in xml, f"no actuator {wn} in the model"
        xml = xml.replace(tag, sat)
    return xml


def one(logs: str) -> dict[str, Any]:
    truth = yaml.safe_load((Path(logs) / "truth.yaml").read_text())
    frac = truth["effects"]["torque_limit"]["fraction"]
    kt = truth["nuisance"]["k_t"]
    target = (1.0 + frac) * TORQUE_RATIO  # the limit over the configuration's, in N m
    common = max(target - 1.0, -0.8)  # the catalogue's range ends at -0.8
    model_xml.robot_xml = per_wheel_xml
    row: dict[str, Any] = {"logs": logs, "fraction": target - 1.0, "k_t": kt}
    for mode in ("one", "per wheel"):
        SCALE.clear()
        if mode == "per wheel" or common != target - 1.0:
            for wn, k in zip(("1L", "1R", "2L", "2R"), kt, strict=True):
                SCALE[wn] = (k if mode == "per wheel" else 1.0) * target / (1.0 + common)
        r = test_at_truth(Path(logs), {"torque_limit": {"fraction": common}})
        row[mode] = {k: r[k] for k in ("held_gain", "p", "d_bic", "passes", "per_drive")}
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("logs", nargs="+", help="case folders: drive_*.csv and truth.yaml")
    ap.add_argument("--workers", type=int, default=1)
    args = ap.parse_args()
    with ProcessPoolExecutor(args.workers) as ex:
        for row in ex.map(one, args.logs):
            print(
                f"{row['logs']}: truth {row['fraction']:+.3f}, k_t"
                f" {' '.join(f'{k:.2f}' for k in row['k_t'])}",
                flush=True,
            )
            for mode in ("one", "per wheel"):
                r = row[mode]
                drives = ", ".join(f"{k} {v:+.2f}" for k, v in r["per_drive"].items())
                print(
                    f"  {mode:9s}: held-out {r['held_gain']:+.1%} p {r['p']:.2g}"
                    f" dBIC {r['d_bic']:+.1f} passes {r['passes']} ({drives})",
                    flush=True,
                )


if __name__ == "__main__":
    main()

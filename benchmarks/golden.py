"""Golden outputs: what a refactor must leave the same to the bit.

    python benchmarks/golden.py write OUT [--only env,vec,benchmark,diagnose]  # at one commit
    python benchmarks/golden.py compare A B     # every number of what both hold, to the bit

Writes, into OUT:
- ``env_<backend>.npz``: 1,000 steps of ``rover_env/ProtoExplorer-v0`` (and 1,000 of the rough
  terrain env) under seeded random actions with resets, for the numpy and the plugin backend:
  observations, rewards, terminations and every numeric ``info`` value;
- ``vec_plugin.npz``: 250 steps of the batched env (4 rovers, plugin backend);
- ``benchmark/summary.*``: open loop and slip PI on three scenarios, 2 seeds, 8 s episodes;
- ``diagnose_<case>/result.json``: two diagnose cases on short make-logs drives.
"""

from __future__ import annotations

import argparse
import csv
import json
import shutil
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np


def _flat_info(info: dict[str, Any], prefix: str = "") -> dict[str, float]:
    out: dict[str, float] = {}
    for k, v in sorted(info.items()):
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(_flat_info(v, key + "."))
        elif isinstance(v, bool | int | float | np.integer | np.floating):
            out[key] = float(v)
        elif isinstance(v, np.ndarray) and v.dtype.kind in "biuf":
            for i, x in enumerate(np.asarray(v, dtype=np.float64).ravel()):
                out[f"{key}[{i}]"] = float(x)
    return out


def _env_run(env_id: str, backend: str, steps: int) -> dict[str, np.ndarray]:
    import gymnasium as gym

    import rover_env  # noqa: F401  (registers the ids)

    env = gym.make(env_id, backend=backend)
    rng = np.random.default_rng(0)
    obs, info = env.reset(seed=0)
    rows: list[np.ndarray] = [np.asarray(obs, dtype=np.float64)]
    infos: list[dict[str, float]] = [_flat_info(info)]
    rew, term, trunc = [], [], []
    episode = 0
    for _ in range(steps):
        obs, r, te, tr, info = env.step(rng.uniform(-1, 1, 4))
        rows.append(np.asarray(obs, dtype=np.float64))
        infos.append(_flat_info(info))
        rew.append(r)
        term.append(te)
        trunc.append(tr)
        if te or tr:
            episode += 1
            obs, info = env.reset(seed=episode)
            rows.append(np.asarray(obs, dtype=np.float64))
            infos.append(_flat_info(info))
    env.close()
    keys = sorted({k for i in infos for k in i})
    out = {
        "obs": np.array(rows),
        "reward": np.array(rew, dtype=np.float64),
        "terminated": np.array(term),
        "truncated": np.array(trunc),
    }
    for k in keys:
        out["info." + k] = np.array([i.get(k, np.nan) for i in infos])
    return out


def _vec_run(steps: int) -> dict[str, np.ndarray]:
    import gymnasium as gym

    import rover_env  # noqa: F401

    env = gym.make_vec(
        "rover_env/ProtoExplorer-v0", num_envs=4, vectorization_mode="vector_entry_point"
    )
    rng = np.random.default_rng(1)
    obs, _ = env.reset(seed=0)
    rows, rew, term, trunc = [obs], [], [], []
    for _ in range(steps):
        obs, r, te, tr, _ = env.step(rng.uniform(-1, 1, (4, 4)))
        rows.append(obs)
        rew.append(r)
        term.append(te)
        trunc.append(tr)
    env.close()
    return {
        "obs": np.array(rows, dtype=np.float64),
        "reward": np.array(rew, dtype=np.float64),
        "terminated": np.array(term),
        "truncated": np.array(trunc),
    }


def _benchmark(out: Path) -> None:
    from rover_env.benchmark.suite import run_benchmark

    files = run_benchmark(
        ["open-loop", "slip-pi"],
        ["flat-turns", "sand-slope", "soft-patch"],
        2,
        out / "benchmark_run",
        duration=8.0,
        workers=1,
        progress=False,
        plots=False,
    )
    (out / "benchmark").mkdir(exist_ok=True)
    for name, path in files.items():
        p = Path(path)
        if p.is_file() and p.suffix in (".md", ".csv", ".json", ".jsonl"):
            shutil.copy(p, out / "benchmark" / f"{name}{p.suffix}")


def _diagnose(out: Path) -> None:
    from rover_env.calibration.diagnose import Options, diagnose
    from rover_env.generators.make_logs import make_logs

    cases = {
        "rolling_resistance": {"rolling_resistance": {"c_rr": 0.05}},
        "torque_limit": {"torque_limit": {"fraction": -0.6}},
    }
    for name, truth in cases.items():
        with tempfile.TemporaryDirectory() as tmp:
            paths = make_logs(tmp, truth, drives=2, seed=7, duration=20.0, progress=False)
            diagnose(paths, out / f"diagnose_{name}", Options(workers=2, progress=False))


PARTS = ("env", "vec", "benchmark", "diagnose")


def write(out: Path, parts: tuple[str, ...] = PARTS) -> None:
    out.mkdir(parents=True, exist_ok=True)
    for backend in ("numpy", "plugin") if "env" in parts else ():
        data = _env_run("rover_env/ProtoExplorer-v0", backend, 1000)
        data |= {f"rough.{k}": v for k, v in _env_run(
            "rover_env/ProtoExplorerRough-v0", backend, 1000).items()}  # fmt: skip
        np.savez(out / f"env_{backend}.npz", **data)
        print(f"env {backend}: {len(data)} arrays", flush=True)
    if "vec" in parts:
        np.savez(out / "vec_plugin.npz", **_vec_run(250))
        print("vector env written", flush=True)
    if "benchmark" in parts:
        _benchmark(out)
        print("benchmark written", flush=True)
    if "diagnose" in parts:
        _diagnose(out)
        print("diagnose written", flush=True)


def _strip_times(obj: Any) -> Any:
    """Wall-clock figures differ between runs of the same code: left out of the comparison."""
    if isinstance(obj, dict):
        return {
            k: _strip_times(v)
            for k, v in obj.items()
            if not any(w in k for w in ("seconds", "wall", "elapsed", "time_s"))
            and k not in ("logs", "config")  # paths of the run's temporary logs and output
        }
    if isinstance(obj, list):
        return [_strip_times(v) for v in obj]
    return obj


def _text(path: Path) -> object:
    """A file's content without its wall-clock figures (a CSV's wall_s column, a report's
    wall-time and cost lines); binary files as bytes."""
    if path.suffix == ".csv":
        rows = list(csv.reader(path.read_text().splitlines()))
        drop = {i for i, name in enumerate(rows[0] if rows else []) if name in ("wall_s",)}
        return [[c for i, c in enumerate(r) if i not in drop] for r in rows]
    if path.suffix == ".md":
        return [
            line
            for line in path.read_text().splitlines()
            if not any(w in line.lower() for w in ("wall time", "cost:", "wall-clock"))
        ]
    return path.read_bytes()


def compare(a: Path, b: Path) -> int:
    bad = 0
    for fa in sorted(a.rglob("*")):
        if not fa.is_file() or fa.parent.name == "benchmark_run":
            continue
        rel = fa.relative_to(a)
        fb = b / rel
        if not fb.is_file():
            print(f"only in {a}: {rel}")
            continue
        if fa.suffix == ".npz":
            za, zb = np.load(fa), np.load(fb)
            for k in sorted(set(za.files) | set(zb.files)):
                if k not in za.files or k not in zb.files:
                    print(f"{rel}: key {k} only in {'A' if k in za.files else 'B'}")
                    bad += 1
                elif not np.array_equal(za[k], zb[k], equal_nan=True):
                    print(f"{rel}: {k} differs (max |diff| "
                          f"{np.nanmax(np.abs(za[k].astype(float) - zb[k].astype(float))):.3g})")  # fmt: skip
                    bad += 1
        elif fa.suffix == ".json":
            ja = _strip_times(json.loads(fa.read_text()))
            jb = _strip_times(json.loads(fb.read_text()))
            if ja != jb:
                print(f"{rel}: differs")
                bad += 1
        elif _text(fa) != _text(fb):
            print(f"{rel}: differs")
            bad += 1
    print("identical" if bad == 0 else f"{bad} difference(s)")
    return 0 if bad == 0 else 1


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    sub = p.add_subparsers(dest="cmd", required=True)
    w = sub.add_parser("write")
    w.add_argument("out")
    w.add_argument("--only", default=",".join(PARTS), help=f"comma list of {', '.join(PARTS)}")
    c = sub.add_parser("compare")
    c.add_argument("a")
    c.add_argument("b")
    args = p.parse_args(argv)
    if args.cmd == "write":
        write(Path(args.out), tuple(x.strip() for x in args.only.split(",") if x.strip()))
        return 0
    return compare(Path(args.a), Path(args.b))


if __name__ == "__main__":
    sys.exit(main())

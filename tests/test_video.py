"""``rover-env record-compare``: one benchmark episode per controller, side by side in one GIF."""

from __future__ import annotations

import os

import numpy as np
import pytest

from rover_env.benchmark.run import Job, run_jobs
from rover_env.benchmark.video import play, record_side_by_side


def _has_gl() -> str | None:
    if os.environ.get("MUJOCO_GL") not in (None, "egl"):
        return None
    os.environ.setdefault("MUJOCO_GL", "egl")
    try:
        import mujoco

        r = mujoco.Renderer(mujoco.MjModel.from_xml_string("<mujoco/>"), 32, 32)
        r.close()
    except Exception as exc:  # any backend failure means: no OpenGL here
        return f"no OpenGL backend for MuJoCo rendering ({type(exc).__name__}: {exc})"
    return None


SPECS = ["open-loop", "slip-pi:slip_pi_soil"]


def test_side_by_side_gif_plays_the_benchmark_episode(tmp_path) -> None:
    reason = _has_gl()
    if reason:
        pytest.skip(reason)
    import imageio.v2 as imageio

    out = tmp_path / "cmp.gif"
    path, metrics = record_side_by_side(
        SPECS, "sand-slope", 2000, out, duration=1.0, width=64, height=48
    )
    frames = imageio.mimread(path)
    assert len(frames) == 11  # the reset frame + 10 control steps at 10 Hz
    assert frames[0].shape[:2] == (48 + 34, 2 * 64)  # label bar above two panels
    left, right = frames[-1][34:, :64], frames[-1][34:, 64:]
    assert np.std(left) > 1.0 and np.std(right) > 1.0
    # exactly the benchmark's episode: the same metrics as its job for that seed
    rows = run_jobs([Job(s, "sand-slope", 2000, 1.0) for s in SPECS])
    for m, row in zip(metrics, rows, strict=True):
        for k, v in m.items():
            assert row[k] == pytest.approx(v, rel=1e-12, abs=1e-12), k
    assert metrics[0] != metrics[1]  # two controllers, two different drives


def test_video_refuses_test_seeds_and_bad_names(tmp_path) -> None:
    with pytest.raises(ValueError, match="test seed"):
        play("open-loop", "sand-slope", 4000)
    with pytest.raises(ValueError, match="spent seeds"):
        play("open-loop", "sand-slope", 3000)
    with pytest.raises(ValueError, match=r"\.gif or \.mp4"):
        record_side_by_side(SPECS, "sand-slope", 2000, tmp_path / "x.avi")
    with pytest.raises(ValueError, match="distinct"):
        record_side_by_side(["open-loop", "open-loop"], "sand-slope", 2000, tmp_path / "x.gif")

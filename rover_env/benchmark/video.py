"""``rover-env record-compare``: one benchmark episode played by several controllers, side by side.

Each controller (any benchmark spec: ``slip-pi:slip_pi_soil``, ``ppo:RUN_DIR``, ``sac:...``)
plays the same scenario episode (same seed: same start pose, ground and command schedule)
through the benchmark's own machinery (:func:`rover_env.benchmark.run.run_episode`,
:class:`ScenarioWrapper`, controllers from :func:`rover_env.policies.specs.make_controller`),
with a renderer attached; the frames are put next to each other, each panel labelled with its
controller and, from the last frame on, the episode's benchmark metrics. The episode is
therefore exactly the benchmark's: the figures printed are those the benchmark table gets for
that seed. Test seeds are refused (the test split is touched only by a final benchmark run).
Rendering is headless with ``MUJOCO_GL=egl`` (``import rover_env`` sets it by default).
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from rover_env.benchmark.run import ScenarioWrapper, run_episode
from rover_env.envs.proto_explorer import ProtoExplorerEnv
from rover_env.seeds import refuse_final_only
from rover_env.tasks.scenarios import load_scenario

__all__ = ["add_cli", "play", "record_side_by_side", "side_by_side"]

Frame = npt.NDArray[np.uint8]
_BAR = 34  # label rows above each panel, px


def play(
    spec: str,
    scenario: str,
    seed: int,
    duration: float | None = None,
    width: int = 320,
    height: int = 240,
) -> tuple[list[Frame], dict[str, float]]:
    """Frames (after the reset and after every step) and benchmark metrics of one episode."""
    from rover_env.policies.specs import make_controller

    refuse_final_only([seed], "video (videos play validation or tuning episodes)")
    ctrl = make_controller(spec)
    episode = load_scenario(scenario).episode(seed, duration)
    env = ProtoExplorerEnv(
        **episode.env_kwargs(),
        action_layout=ctrl.action_layout,
        render_mode="rgb_array",
        width=width,
        height=height,
    )
    frames: list[Frame] = []

    def grab() -> None:
        frame = env.render()
        assert frame is not None
        frames.append(np.asarray(frame, dtype=np.uint8).copy())

    try:
        metrics = run_episode(ScenarioWrapper(env), ctrl, episode, observer=grab)
    finally:
        env.close()
    return frames, metrics


def _summary(m: dict[str, float]) -> str:
    goal = "goal reached" if m.get("goal", 0.0) >= 0.5 else "goal missed"
    return (
        f"{goal} at {m['pace_ratio']:.2f} x the commanded pace, made good {m['distance_made_good']:.2f} m, |S| {m['mean_abs_slip']:.3f}, "
        f"sinkage {1000 * m['mean_sinkage']:.1f} mm, {m['energy_per_metre']:.0f} J/m"
    )


def _label(frame: Frame, lines: Sequence[str]) -> Frame:
    from PIL import Image, ImageDraw

    h, w = frame.shape[:2]
    img = Image.new("RGB", (w, h + _BAR), (20, 20, 20))
    img.paste(Image.fromarray(frame[..., :3]), (0, _BAR))
    draw = ImageDraw.Draw(img)
    for i, line in enumerate(lines[:2]):
        draw.text((4, 3 + 15 * i), line, fill=(255, 255, 255))
    return np.asarray(img, dtype=np.uint8)


def side_by_side(
    runs: Sequence[tuple[str, list[Frame], dict[str, float]]], fps: float
) -> list[Frame]:
    """One frame per step: the panels next to each other (a finished episode holds its last
    frame), each labelled with its controller, the time and, once it ended, its metrics."""
    n = max(len(frames) for _, frames, _ in runs)
    out: list[Frame] = []
    for k in range(n):
        panels = []
        for name, frames, metrics in runs:
            ended = k >= len(frames) - 1
            frame = frames[min(k, len(frames) - 1)]
            t = min(k, len(frames) - 1) / fps
            second = _summary(metrics) if ended else f"t = {t:4.1f} s"
            panels.append(_label(frame, [name, second]))
        out.append(np.concatenate(panels, axis=1))
    return out


def record_side_by_side(
    specs: Sequence[str],
    scenario: str,
    seed: int,
    out: str | Path,
    duration: float | None = None,
    width: int = 320,
    height: int = 240,
) -> tuple[Path, list[dict[str, float]]]:
    """Play the episode with every spec and write one side-by-side GIF (or MP4); returns the
    path and each controller's benchmark metrics."""
    import imageio.v2 as imageio

    out = Path(out)
    if out.suffix not in (".gif", ".mp4"):
        raise ValueError(f"video file must end in .gif or .mp4, got {out.name!r}")
    if len(specs) < 1 or len(set(specs)) != len(specs):
        raise ValueError(f"need distinct controller specs, got {list(specs)}")
    fps = float(ProtoExplorerEnv.metadata["render_fps"])
    runs = [(s, *play(s, scenario, seed, duration, width, height)) for s in specs]
    frames: list[Any] = list(side_by_side(runs, fps))
    out.parent.mkdir(parents=True, exist_ok=True)
    if out.suffix == ".gif":
        imageio.mimsave(out, frames, duration=1000 / fps, loop=0)
    else:
        try:
            imageio.mimsave(out, frames, fps=fps)
        except (ImportError, ValueError, RuntimeError) as exc:
            raise RuntimeError(
                f"writing {out.name} needs imageio-ffmpeg (pip install imageio-ffmpeg); "
                f"or use a .gif name: {exc}"
            ) from None
    return out, [m for _, _, m in runs]


def add_cli(sub: Any) -> None:
    p = sub.add_parser(
        "record-compare",
        help="one benchmark episode played by several controllers, side by side (.gif/.mp4)",
    )
    p.add_argument(
        "--controllers",
        required=True,
        help="comma list of specs, e.g. slip-pi:slip_pi_soil,ppo:runs/soil_s0",
    )
    p.add_argument("--scenario", default="sand-slope", help="scenario name (default sand-slope)")
    p.add_argument("--seed", type=int, default=2000, help="validation seed (default 2000)")
    p.add_argument("--duration", type=float, default=None, help="episode length override (s)")
    p.add_argument("--width", type=int, default=320, help="panel width in px (320)")
    p.add_argument("--height", type=int, default=240, help="panel height in px (240)")
    p.add_argument("--out", default="out/compare.gif", help="video file (.gif or .mp4)")
    p.set_defaults(func=_cli)


def _cli(args: argparse.Namespace) -> int:
    from rover_env.policies.specs import parse_specs

    specs = parse_specs(args.controllers)
    path, metrics = record_side_by_side(
        specs, args.scenario, args.seed, args.out, args.duration, args.width, args.height
    )
    for s, m in zip(specs, metrics, strict=True):
        print(f"{s}: {_summary(m)}")
    print(f"wrote {path}")
    return 0

"""``rover-env record``: a short episode of an environment to a video file, headless.

The rover drives the env's own random commands with the open-loop skid-steer feed-forward
(no learning needed to see the rover move). GIF is written with Pillow, which matplotlib
already brings; ``.mp4`` needs the optional ``imageio-ffmpeg`` package. Rendering uses
``MUJOCO_GL`` (``import rover_env`` defaults it to ``egl`` on a headless Linux machine).
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

from rover_env.control.open_loop import OpenLoop

__all__ = ["add_cli", "record_episode"]


def record_episode(
    out: str | Path,
    env_id: str = "rover_env/ProtoExplorer-v0",
    seconds: float = 10.0,
    seed: int = 0,
    width: int = 480,
    height: int = 360,
) -> Path:
    """Render ``seconds`` of one seeded episode to ``out`` (.gif or .mp4); returns the path."""
    import gymnasium as gym
    import imageio.v2 as imageio

    import rover_env

    out = Path(out)
    if out.suffix not in (".gif", ".mp4"):
        raise ValueError(f"video file must end in .gif or .mp4, got {out.name!r}")
    gym.register_envs(rover_env)
    env = gym.make(env_id, render_mode="rgb_array", width=width, height=height)
    base: Any = env.unwrapped
    ol = OpenLoop(base.rover_cfg)
    env.reset(seed=seed)
    frames = [env.render()]
    fps = int(env.metadata.get("render_fps", 10))
    for _ in range(round(seconds * fps)):
        v, w = (float(x) for x in base.command)
        action = np.clip(ol.feedforward(v, w) / base.max_wheel_speed, -1, 1).astype(np.float32)
        _, _, terminated, truncated, _ = env.step(action)
        frames.append(env.render())
        if terminated or truncated:
            break
    env.close()
    out.parent.mkdir(parents=True, exist_ok=True)
    if out.suffix == ".gif":
        imageio.mimsave(out, [np.asarray(f) for f in frames], duration=1000 / fps, loop=0)
    else:
        try:
            imageio.mimsave(out, [np.asarray(f) for f in frames], fps=fps)
        except (ImportError, ValueError, RuntimeError) as exc:
            raise RuntimeError(
                f"writing {out.name} needs imageio-ffmpeg (pip install imageio-ffmpeg); "
                f"or use a .gif name: {exc}"
            ) from None
    return out


def add_cli(sub: Any) -> None:
    p = sub.add_parser("record", help="render a short episode to a video (.gif or .mp4)")
    p.add_argument("--env-id", default="rover_env/ProtoExplorer-v0")
    p.add_argument("--seconds", type=float, default=10.0, help="episode length (default 10)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default="out/episode.gif", help="video file (.gif or .mp4)")
    p.set_defaults(func=_cli)


def _cli(args: argparse.Namespace) -> int:
    path = record_episode(args.out, args.env_id, args.seconds, args.seed)
    print(f"wrote {path}")
    return 0

"""The ground a logged drive is replayed on: what its YAML declares, or a clear refusal.

A log's YAML may say what is known of the ground (SPEC §6, key ``terrain``): a shipped
terrain name, a terrain YAML path (relative to the log's folder or the working directory) or
a terrain mapping inline. The calibration replay starts every window from the log's joint
angles and the free wheels' motion, but it does not know *where* on the ground the rover
was (the pose is relative and sparse). So it can honour a ground that is the same
everywhere: flat, a uniform slope (the terrain's ``slope_deg``, its x and y axes taken as the
log frame: segment 3 at t = 0; the frame the drives share where the logs give
``start_heading_deg``), a uniform friction (``mu_x``, ``mu_y``) and loose soil over
the whole ground (``soil``). A ground that varies from place to place (bumps, roughness,
friction or soil patches, rocks) is refused with one error naming the file and the key,
never replayed as if it were flat.
"""

from __future__ import annotations

from pathlib import Path

from rover_env.config import ConfigError, TerrainConfig, from_dict, load_terrain
from rover_env.logs import DriveLog, LogError

__all__ = ["common_ground", "is_flat_ground", "log_ground"]

FLAT = TerrainConfig()


def _meta_file(log: DriveLog) -> Path | None:
    return None if log.path is None else log.path.with_suffix(".yaml")


def _load(log: DriveLog) -> TerrainConfig:
    where = _meta_file(log)
    spec = log.meta.terrain
    try:
        if spec is None:
            return FLAT
        if isinstance(spec, dict):
            return from_dict(TerrainConfig, spec, "terrain")
        return load_terrain(log.beside(spec))
    except ConfigError as exc:
        raise LogError(f"key 'terrain': {exc}", where) from None


def _varies(t: TerrainConfig) -> list[str]:
    """What makes ``t`` differ from place to place (empty: the same everywhere)."""
    out = []
    if any(b.amplitude > 0 for b in t.bumps):
        out.append("bumps")
    if t.roughness.rms > 0:
        out.append("roughness")
    if t.patches:
        out.append(f"patches ({', '.join(p.name for p in t.patches)})")
    if t.obstacles:
        out.append(f"obstacles ({', '.join(o.name for o in t.obstacles)})")
    return out


def log_ground(log: DriveLog) -> TerrainConfig:
    """The terrain ``log`` declares, if the replay can honour it; else :class:`LogError`."""
    t = _load(log)
    varies = _varies(t)
    if varies:
        raise LogError(
            f"key 'terrain': terrain {t.name!r} varies over the ground ({'; '.join(varies)}),"
            " and the replay does not know where on it the rover was; declare the ground the"
            " drive was on as flat, a uniform slope (slope_deg), a uniform friction (mu_x, mu_y)"
            " or soil over the whole ground (soil), or leave the key out for flat hard ground",
            _meta_file(log),
        )
    return t


def is_flat_ground(t: TerrainConfig) -> bool:
    """Flat hard ground with the tire's own friction: the replay's default ground."""
    return t.is_flat and t.soil is None and t.mu_x is None and t.mu_y is None


def common_ground(logs: list[DriveLog]) -> TerrainConfig | None:
    """The one ground all ``logs`` were driven on; None for flat hard ground.

    One diagnosis replays every window on one simulator, so logs that declare different
    grounds are refused (diagnose them apart)."""
    grounds = [log_ground(lg) for lg in logs]
    first = grounds[0]
    for lg, g in zip(logs[1:], grounds[1:], strict=True):
        if _same(g, first):
            continue
        raise LogError(
            f"key 'terrain': this log's ground ({_describe(g)}) differs from"
            f" {_meta_file(logs[0]) or 'the first log'}'s ({_describe(first)}); one diagnosis"
            " replays its logs on one ground: diagnose them separately",
            _meta_file(lg),
        )
    return None if is_flat_ground(first) else first


def _same(a: TerrainConfig, b: TerrainConfig) -> bool:
    return (a.slope_deg, a.mu_x, a.mu_y, a.soil) == (b.slope_deg, b.mu_x, b.mu_y, b.soil)


def _describe(t: TerrainConfig) -> str:
    parts = [t.name]
    if t.slope_deg != (0.0, 0.0):
        parts.append(f"slope_deg {list(t.slope_deg)}")
    if t.soil is not None:
        parts.append(f"soil {t.soil}")
    if t.mu_x is not None or t.mu_y is not None:
        parts.append(f"mu {t.mu_x}/{t.mu_y}")
    return ", ".join(parts)

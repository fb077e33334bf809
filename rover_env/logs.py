"""Measured drive logs (SPEC §6): a CSV of samples plus a YAML of metadata with the same stem.

This is the interface to real or recorded data, so reading is strict: every problem raises one
:class:`LogError` that names the file and, where it applies, the column and the CSV line, so a
bad log is fixed at the source instead of silently feeding NaNs to the estimators. Writing uses
``repr`` floats so a log read back is bit-for-bit the log written. Kept free of MuJoCo so
calibration and analysis tools can read logs without the simulator.
"""

from __future__ import annotations

import csv
import io
import math
import os
import tempfile
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from numpy.typing import NDArray

from rover_env.config import DRIVEN_WHEELS, JOINTS, WHEELS

Array = NDArray[np.float64]

T_COLUMN = "t"
CMD_COLUMNS: tuple[str, ...] = tuple(f"cmd_{w}" for w in DRIVEN_WHEELS)
PHI_COLUMNS: tuple[str, ...] = tuple(f"phi_{w}" for w in WHEELS)
THETA_COLUMNS: tuple[str, ...] = JOINTS
POSE_COLUMNS: tuple[str, ...] = ("x", "y", "yaw")
EFFORT_COLUMNS: tuple[str, ...] = tuple(f"effort_{w}" for w in DRIVEN_WHEELS)
"""Optional: the driven wheels' motor torque as the drivers report it (N m at the wheel shaft,
after the gearhead, as ``motor.torque_limit`` is given), e.g. ROS 2 ``JointState.effort``."""
REQUIRED_COLUMNS: tuple[str, ...] = (T_COLUMN, *CMD_COLUMNS, *PHI_COLUMNS, *THETA_COLUMNS)
META_KEYS: tuple[str, ...] = ("rover", "sample_rate_hz", "terrain", "notes", "start_heading_deg")


class LogError(ValueError):
    """A drive log cannot be used as it is.

    The message names the file, then the column and the line where they apply. Lines are CSV
    line numbers as an editor shows them: the header is line 1, the first data row line 2.
    """

    def __init__(
        self,
        message: str,
        file: str | Path | None = None,
        *,
        column: str | None = None,
        line: int | None = None,
    ) -> None:
        where = [str(file)] if file is not None else []
        if line is not None:
            where.append(f"line {line}")
        if column is not None:
            where.append(f"column {column!r}")
        super().__init__(f"{', '.join(where)}: {message}" if where else message)
        self.file = None if file is None else Path(file)
        self.column = column
        self.line = line


@dataclass
class LogMeta:
    """The YAML beside the CSV."""

    rover: str
    """A shipped rover configuration name or a path to one."""
    sample_rate_hz: float
    """Nominal rate; the CSV's ``t`` column is the truth."""
    terrain: str | dict[str, Any] | None = None
    notes: str | None = None
    extra: dict[str, Any] = field(default_factory=dict)
    """Unknown YAML keys, kept so a round trip loses nothing (they warn on read)."""
    start_heading_deg: float | None = None
    """Optional: segment 3's heading at t = 0 (degrees, counter-clockwise) in a frame every
    drive of the rover shares (a compass, the site's survey). The pose is in each log's own
    frame (SPEC §6); this places those frames in one, so a slope found on drives that
    started facing different ways has one direction. Absent: the drives started facing
    the same way."""

    def __post_init__(self) -> None:
        _check_meta(self, None)


@dataclass(eq=False)
class DriveLog:
    """One drive: per-sample arrays of equal length N, checked on construction.

    ``cmd`` in row k is the speed target sent at ``t[k]`` and held until ``t[k + 1]``.
    """

    t: Array
    """(N,) seconds since the start of the log, strictly increasing."""
    cmd: Array
    """(N, 4) speed targets (rad/s) of 1L 1R 2L 2R."""
    phi: Array
    """(N, 6) wheel angles (rad), WHEELS order, cumulative."""
    theta: Array
    """(N, 5) joint angles theta_1..theta_5 (rad)."""
    pose: Array
    """(N, 3) x, y, yaw of segment 3 in its frame at t = 0; NaN where not measured."""
    meta: LogMeta
    path: Path | None = None
    effort: Array = field(default_factory=lambda: np.zeros((0, 4)))
    """(N, 4) motor torque of 1L 1R 2L 2R (N m at the wheel, :data:`EFFORT_COLUMNS`); NaN
    where not measured. Left out (or given with no rows): not measured at all."""

    def __post_init__(self) -> None:
        self.t = np.array(self.t, dtype=np.float64)
        self.cmd = np.array(self.cmd, dtype=np.float64)
        self.phi = np.array(self.phi, dtype=np.float64)
        self.theta = np.array(self.theta, dtype=np.float64)
        self.pose = np.array(self.pose, dtype=np.float64)
        eff = np.array(self.effort, dtype=np.float64)
        if eff.size == 0 and self.t.ndim == 1:
            eff = np.full((self.t.shape[0], 4), np.nan)
        self.effort = eff
        _check_arrays(self)

    def __len__(self) -> int:
        return int(self.t.shape[0])

    @property
    def has_pose(self) -> bool:
        """Whether any pose sample was measured."""
        return bool(np.any(np.isfinite(self.pose)))

    @property
    def has_effort(self) -> bool:
        """Whether any motor torque sample was measured."""
        return bool(np.any(np.isfinite(self.effort)))

    def beside(self, ref: str) -> str | Path:
        """``ref`` (a configuration the YAML names) as a file beside the log if one is there,
        else as written: a shipped name or a path from the working directory."""
        p = Path(ref)
        if self.path is not None and not p.is_absolute() and (self.path.parent / p).is_file():
            return self.path.parent / p
        return ref


# --------------------------------------------------------------------------- validation


def _check_meta(meta: LogMeta, file: Path | None) -> None:
    """One set of rules for YAML read and for logs built in code, so writes can always be read."""
    if not isinstance(meta.rover, str) or not meta.rover.strip():
        raise LogError(f"'rover' must be a non-empty string, got {meta.rover!r}", file)
    rate = meta.sample_rate_hz
    if isinstance(rate, bool) or not isinstance(rate, int | float | np.floating | np.integer):
        raise LogError(f"'sample_rate_hz' must be a number, got {rate!r}", file)
    if not (math.isfinite(rate) and rate > 0):
        raise LogError(f"'sample_rate_hz' must be finite and > 0, got {rate!r}", file)
    meta.sample_rate_hz = float(rate)
    if meta.terrain is not None and not isinstance(meta.terrain, str | dict):
        raise LogError(f"'terrain' must be a name, a mapping or absent, got {meta.terrain!r}", file)
    if meta.notes is not None and not isinstance(meta.notes, str):
        raise LogError(f"'notes' must be text, got {meta.notes!r}", file)
    head = meta.start_heading_deg
    if head is not None:
        if isinstance(head, bool) or not isinstance(head, int | float | np.floating | np.integer):
            raise LogError(f"'start_heading_deg' must be a number or absent, got {head!r}", file)
        if not math.isfinite(head):
            raise LogError(f"'start_heading_deg' must be finite, got {head!r}", file)
        meta.start_heading_deg = float(head)
    if not isinstance(meta.extra, dict):
        raise LogError(f"extra must be a mapping, got {meta.extra!r}", file)
    clash = sorted(set(map(str, meta.extra)) & set(META_KEYS))
    if clash:
        raise LogError(f"extra repeats reserved key(s) {', '.join(clash)}", file)


def _check_arrays(log: DriveLog) -> None:
    src = log.path if log.path is not None else "DriveLog"
    n = log.t.shape[0] if log.t.ndim == 1 else -1
    if n < 0:
        raise LogError(f"t must have shape (N,), got {log.t.shape}", src)
    for name, width in (("cmd", 4), ("phi", 6), ("theta", 5), ("pose", 3), ("effort", 4)):
        arr = getattr(log, name)
        if arr.shape != (n, width):
            raise LogError(f"{name} must have shape ({n}, {width}), got {arr.shape}", src)
    if n < 2:
        raise LogError(f"a log needs at least 2 samples, got {n}", src)
    for name in ("t", "cmd", "phi", "theta"):
        bad = np.argwhere(~np.isfinite(getattr(log, name)))
        if bad.size:
            raise LogError(f"{name} is not finite at sample {bad[0][0]}", src)
    for name in ("pose", "effort"):
        if np.any(np.isinf(getattr(log, name))):
            raise LogError(f"{name} is infinite (use NaN for not measured)", src)
    dec = np.flatnonzero(np.diff(log.t) <= 0)
    if dec.size:
        k = int(dec[0])
        raise LogError(
            f"t not strictly increasing at sample {k + 1}: {log.t[k]!r} then {log.t[k + 1]!r}",
            src,
        )
    if not isinstance(log.meta, LogMeta):
        raise LogError(f"meta must be a LogMeta, got {type(log.meta).__name__}", src)


# --------------------------------------------------------------------------- reading


def _yaml_path(csv_path: Path) -> Path:
    if csv_path.suffix.lower() in (".yaml", ".yml"):
        raise LogError("give the path of the log's .csv file, not its YAML", csv_path)
    return csv_path.with_suffix(".yaml")


def _read_meta(path: Path) -> LogMeta:
    if not path.is_file():
        alt = path.with_suffix(".yml")
        if not alt.is_file():
            raise LogError("log metadata file not found (same stem as the CSV)", path)
        path = alt
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        problem = getattr(exc, "problem", None) or str(exc)
        if mark is not None:
            raise LogError(
                f"malformed YAML at line {mark.line + 1}, column {mark.column + 1}: {problem}",
                path,
            ) from None
        raise LogError(f"malformed YAML: {problem}", path) from None
    except UnicodeDecodeError as exc:
        raise LogError(f"not UTF-8 text: {exc}", path) from None
    if not isinstance(data, dict):
        raise LogError(f"expected a mapping of keys, got {type(data).__name__}", path)
    for key in ("rover", "sample_rate_hz"):
        if key not in data:
            raise LogError(f"missing required key {key!r}", path)
    unknown = [k for k in data if k not in META_KEYS]
    if unknown:
        warnings.warn(
            f"{path}: unknown key(s) {', '.join(map(str, unknown))} kept in meta.extra, ignored",
            stacklevel=3,
        )
    try:
        return LogMeta(
            rover=data["rover"],
            sample_rate_hz=data["sample_rate_hz"],
            terrain=data.get("terrain"),
            notes=data.get("notes"),
            extra={str(k): data[k] for k in unknown},
            start_heading_deg=data.get("start_heading_deg"),
        )
    except LogError as exc:
        raise LogError(str(exc), path) from None


def _cell(text: str, path: Path, column: str, line: int, optional: bool) -> float:
    s = text.strip()
    if not s:
        if optional:
            return math.nan
        raise LogError("empty cell in a required column", path, column=column, line=line)
    try:
        v = float(s)
    except ValueError:
        raise LogError(f"not a number: {text!r}", path, column=column, line=line) from None
    if math.isnan(v) and not optional:
        raise LogError("NaN in a required column", path, column=column, line=line)
    if math.isinf(v):
        raise LogError(f"not finite: {text!r}", path, column=column, line=line)
    return v


def _together(group: tuple[str, ...], seen: set[str], what: str, path: Path) -> bool:
    """Whether the header has ``group``'s columns; some but not all is refused."""
    present = [c for c in group if c in seen]
    if present and len(present) < len(group):
        absent = [c for c in group if c not in seen]
        raise LogError(
            f"{what} go together: have {', '.join(present)}, missing {', '.join(absent)}",
            path,
            line=1,
        )
    return bool(present)


def read_log(path: str | Path) -> DriveLog:
    """Read and check a drive log; ``path`` is the CSV, the YAML has the same stem."""
    csv_path = Path(path)
    meta = _read_meta(_yaml_path(csv_path))
    if not csv_path.is_file():
        raise LogError("log CSV file not found", csv_path)
    try:
        text = csv_path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as exc:
        raise LogError(f"not UTF-8 text: {exc}", csv_path) from None
    reader = csv.reader(io.StringIO(text, newline=""))
    try:
        header = next(reader)
    except StopIteration:
        raise LogError("empty file: no header row", csv_path, line=1) from None
    except csv.Error as exc:
        raise LogError(f"malformed CSV: {exc}", csv_path, line=1) from None
    names = [h.strip() for h in header]
    seen: set[str] = set()
    for name in names:
        if not name:
            raise LogError("header has an empty column name", csv_path, line=1)
        if name in seen:
            raise LogError("column appears twice in the header", csv_path, column=name, line=1)
        seen.add(name)
    missing = [c for c in REQUIRED_COLUMNS if c not in seen]
    if missing:
        raise LogError(f"missing required column(s) {', '.join(missing)}", csv_path, line=1)
    pose_present = _together(POSE_COLUMNS, seen, "pose columns x, y, yaw", csv_path)
    effort_present = _together(
        EFFORT_COLUMNS, seen, "effort columns (leave cells empty where not measured)", csv_path
    )
    wanted = (
        REQUIRED_COLUMNS
        + (POSE_COLUMNS if pose_present else ())
        + (EFFORT_COLUMNS if effort_present else ())
    )
    unknown = [n for n in names if n not in wanted]
    if unknown:
        warnings.warn(f"{csv_path}: unknown column(s) {', '.join(unknown)} ignored", stacklevel=2)
    index = [names.index(c) for c in wanted]
    optional = [c in POSE_COLUMNS or c in EFFORT_COLUMNS for c in wanted]
    rows: list[list[float]] = []
    lines: list[int] = []
    while True:
        try:
            row = next(reader)
        except StopIteration:
            break
        except csv.Error as exc:
            raise LogError(f"malformed CSV: {exc}", csv_path, line=reader.line_num) from None
        line = reader.line_num
        if len(row) <= 1 and not "".join(row).strip():
            continue  # blank line, e.g. a trailing newline
        if len(row) != len(names):
            raise LogError(
                f"row has {len(row)} cells, the header has {len(names)}", csv_path, line=line
            )
        rows.append(
            [
                _cell(row[i], csv_path, c, line, opt)
                for i, c, opt in zip(index, wanted, optional, strict=True)
            ]
        )
        lines.append(line)
    if len(rows) < 2:
        raise LogError(f"a log needs at least 2 data rows, got {len(rows)}", csv_path)
    data = np.array(rows, dtype=np.float64)
    t = data[:, 0]
    dec = np.flatnonzero(np.diff(t) <= 0)
    if dec.size:
        k = int(dec[0])
        raise LogError(
            f"time not strictly increasing: {t[k]!r} at line {lines[k]}, then {t[k + 1]!r}",
            csv_path,
            column=T_COLUMN,
            line=lines[k + 1],
        )
    n_cmd, n_phi, n_theta = len(CMD_COLUMNS), len(PHI_COLUMNS), len(THETA_COLUMNS)
    c0 = 1
    cmd = data[:, c0 : c0 + n_cmd]
    phi = data[:, c0 + n_cmd : c0 + n_cmd + n_phi]
    theta = data[:, c0 + n_cmd + n_phi : c0 + n_cmd + n_phi + n_theta]
    c1 = c0 + n_cmd + n_phi + n_theta
    pose = data[:, c1 : c1 + 3] if pose_present else np.full((len(rows), 3), np.nan)
    c1 += 3 if pose_present else 0
    effort = data[:, c1 : c1 + 4] if effort_present else np.full((len(rows), 4), np.nan)
    return DriveLog(
        t=t, cmd=cmd, phi=phi, theta=theta, pose=pose, meta=meta, path=csv_path, effort=effort
    )


# --------------------------------------------------------------------------- writing


def _fmt(v: float) -> str:
    """Shortest text that parses back to the same double; empty for NaN (not measured)."""
    return "" if math.isnan(v) else repr(float(v))


def _csv_text(log: DriveLog) -> str:
    with_pose, with_effort = log.has_pose, log.has_effort
    cols = (
        REQUIRED_COLUMNS
        + (POSE_COLUMNS if with_pose else ())
        + (EFFORT_COLUMNS if with_effort else ())
    )
    parts = [log.t[:, None], log.cmd, log.phi, log.theta]
    if with_pose:
        parts.append(log.pose)
    if with_effort:
        parts.append(log.effort)
    data = np.hstack(parts)
    buf = io.StringIO(newline="")
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(cols)
    for row in data:
        w.writerow([_fmt(v) for v in row.tolist()])
    return buf.getvalue()


def _yaml_text(meta: LogMeta) -> str:
    data: dict[str, Any] = {"rover": meta.rover, "sample_rate_hz": float(meta.sample_rate_hz)}
    if meta.terrain is not None:
        data["terrain"] = meta.terrain
    if meta.notes is not None:
        data["notes"] = meta.notes
    if meta.start_heading_deg is not None:
        data["start_heading_deg"] = float(meta.start_heading_deg)
    data.update(meta.extra)
    try:
        return yaml.safe_dump(data, sort_keys=False, allow_unicode=True)
    except yaml.YAMLError as exc:
        raise LogError(f"metadata cannot be written as YAML: {exc}") from None


def _atomic_write(path: Path, text: str) -> None:
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline="") as fh:
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _same_text(path: Path, text: str) -> bool:
    try:
        return path.is_file() and path.read_text(encoding="utf-8") == text
    except (OSError, UnicodeDecodeError):
        return False


def write_log(log: DriveLog, path: str | Path, *, overwrite: bool = False) -> Path:
    """Write ``log`` as ``path`` (CSV) and its same-stem YAML; returns the CSV path.

    Each file is replaced atomically, the YAML first, so a reader never sees a partial file.
    Rewriting identical content is allowed; replacing a different log needs ``overwrite``,
    since recorded drives are not reproducible.
    """
    csv_path = Path(path)
    yaml_path = _yaml_path(csv_path)
    _check_meta(log.meta, yaml_path)
    _check_arrays(log)
    csv_text, yaml_text = _csv_text(log), _yaml_text(log.meta)
    if not overwrite:
        for p, text in ((csv_path, csv_text), (yaml_path, yaml_text)):
            if p.exists() and not _same_text(p, text):
                raise FileExistsError(
                    f"{p}: a different log is already there; pass overwrite=True to replace it"
                )
    csv_path.parent.mkdir(parents=True, exist_ok=True)
    _atomic_write(yaml_path, yaml_text)
    _atomic_write(csv_path, csv_text)
    return csv_path

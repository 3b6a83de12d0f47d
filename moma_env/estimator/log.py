"""Detection logs: what a localiser is told, one JSON object per line, and its replay.

A localiser (the MOMA estimator, or any other with its interface: ``add_robot``,
``set_static``, ``update``, ``estimates``) learns everything from four calls, so a
log of those calls is all it needs to run again, on this machine or another, and
all a real robot has to write to run it offline. :class:`RecordingLocaliser` wraps
a localiser and records every call it forwards; :func:`read_detection_log` reads a
log back, checking every line; :func:`replay` makes the calls again on a fresh
localiser and returns every robot's estimated trajectory.

The format (``moma-detection-log``, version 1), UTF-8 JSON Lines:

* line 1, the header: ``{"format": "moma-detection-log", "version": 1,
  "estimator": {...}}``, the :class:`~moma_env.estimator.EstimatorConfig` of the
  recorded localiser (its fields; ``"gate"`` the
  :class:`~moma_env.estimator.OutlierGateConfig` fields or null);
* ``{"kind": "robot", "name", "boards": {board id: T_b_m}, "cameras": {camera id:
  T_b_c}, "static", "initial_pose": T_w_b or null, "time": s or null, "planar"}``:
  ``add_robot``;
* ``{"kind": "static", "name", "static", "time"}``: ``set_static``;
* ``{"kind": "frame", "time", "detections": [...]}``: ``update``, each detection
  ``{"camera_id", "board_id", "T_c_m", "corners_px", "marker_ids", "time",
  "reprojection_error_px" (null for NaN), "covariance" (null for none),
  "persistent_covariance" (null for none)}``, the fields of
  :class:`~moma_env.estimator.Detection`;
* ``{"kind": "odometry", "name", "increment": [dx, dy, dyaw], "covariance": 3x3,
  "time"}``: ``odometry`` (wheel odometry, for a localiser that takes it; the MOMA
  estimator does not, and a replay on it skips these).

Poses are 4x4 nested lists, row by row (m); covariances 6x6 in the conventions of
:class:`~moma_env.estimator.Detection` (m^2, rad^2, m rad). Numbers are written as
Python's shortest round-trip representation, so a replay on the same localiser gets
the recorded numbers bit for bit and, on the same machine, computes the recorded
run's estimates bit for bit (``tests/test_detection_log.py`` checks this against the
simulator). The file is standard JSON Lines: no NaN or infinity is written.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from moma_env.config import ConfigError
from moma_env.estimator.config import EstimatorConfig, OutlierGateConfig
from moma_env.estimator.detection import Detection

__all__ = [
    "LOG_FORMAT",
    "LOG_VERSION",
    "DetectionLogError",
    "RobotRecord",
    "StaticRecord",
    "FrameRecord",
    "OdometryRecord",
    "DetectionLog",
    "RecordingLocaliser",
    "recording_localiser",
    "RecordingFactory",
    "read_detection_log",
    "parse_detection_log",
    "replay",
]

#: The header's ``format``.
LOG_FORMAT = "moma-detection-log"
#: The header's ``version``: the one this module writes and reads.
LOG_VERSION = 1


class DetectionLogError(ValueError):
    """A detection log that cannot be read: the message names the file, the line and what is wrong."""


@dataclass(frozen=True)
class RobotRecord:
    """``add_robot`` (see :meth:`~moma_env.estimator.MomaEstimator.add_robot`)."""

    name: str
    boards: Mapping[int, np.ndarray]
    cameras: Mapping[str, np.ndarray]
    static: bool
    initial_pose: np.ndarray | None
    time: float | None
    planar: bool


@dataclass(frozen=True)
class StaticRecord:
    """``set_static(name, static, time)``."""

    name: str
    static: bool
    time: float


@dataclass(frozen=True)
class FrameRecord:
    """``update(time, detections)``: one camera frame."""

    time: float
    detections: tuple[Detection, ...]


@dataclass(frozen=True)
class OdometryRecord:
    """``odometry(name, increment, covariance, time)``: a robot's wheel odometry since its last."""

    name: str
    increment: tuple[float, float, float]
    covariance: np.ndarray
    time: float


LogRecord = RobotRecord | StaticRecord | FrameRecord | OdometryRecord


@dataclass(frozen=True)
class DetectionLog:
    """A read log: the recorded localiser's configuration and its calls in order."""

    estimator: EstimatorConfig
    records: tuple[LogRecord, ...]

    @property
    def frames(self) -> int:
        """The number of camera frames (``update`` calls)."""
        return sum(isinstance(r, FrameRecord) for r in self.records)


# ---------------------------------------------------------------- writing
def _matrix(value: Any) -> list:
    return np.asarray(value, dtype=float).tolist()


def _optional_matrix(value: Any) -> list | None:
    return None if value is None else _matrix(value)


def _detection_json(d: Detection) -> dict[str, Any]:
    error = float(d.reprojection_error_px)
    return {
        "camera_id": d.camera_id,
        "board_id": int(d.board_id),
        "T_c_m": _matrix(d.T_c_m),
        "corners_px": np.asarray(d.corners_px, dtype=float).reshape(-1, 2).tolist(),
        "marker_ids": [int(m) for m in d.marker_ids],
        "time": float(d.time),
        "reprojection_error_px": error if math.isfinite(error) else None,
        "covariance": _optional_matrix(d.covariance),
        "persistent_covariance": _optional_matrix(d.persistent_covariance),
    }


def _line(obj: Mapping[str, Any]) -> str:
    return json.dumps(obj, allow_nan=False, separators=(",", ":"))


def _header(config: EstimatorConfig) -> str:
    estimator = {f.name: getattr(config, f.name) for f in dataclasses.fields(config)}
    gate = config.gate
    estimator["gate"] = None if gate is None else {f.name: getattr(gate, f.name) for f in dataclasses.fields(gate)}
    return _line({"format": LOG_FORMAT, "version": LOG_VERSION, "estimator": estimator})


class RecordingLocaliser:
    """A localiser that forwards every call to ``inner`` and records it in a detection log.

    A call is recorded once ``inner`` has taken it, with its arguments as given; a call
    ``inner`` refuses raises its error and is not recorded, so a log replays without one.
    :attr:`lines` holds the log so far (header first); :meth:`text` is the file's
    content, for :func:`moma_env.io.atomic_write_text`. This class takes no wheel
    odometry; :func:`recording_localiser` wraps a localiser in it, or in its subclass
    with ``odometry`` when the localiser takes odometry, so that a driver that feeds
    odometry only to localisers that take it drives the recorded run exactly as it
    drives the inner localiser alone.

    Args:
        inner: the localiser that does the work.
        config: the configuration ``inner`` was made with (the log's header).
    """

    def __init__(self, inner: Any, config: EstimatorConfig):
        if not isinstance(config, EstimatorConfig):
            raise TypeError(f"config must be an EstimatorConfig, got {type(config).__name__}")
        self.inner = inner
        self.lines: list[str] = [_header(config)]

    def text(self) -> str:
        """The log as a file's content: one JSON object per line."""
        return "\n".join(self.lines) + "\n"

    def add_robot(self, name: str, *, boards: Mapping[int, np.ndarray] | None = None,
                  cameras: Mapping[str, np.ndarray] | None = None, static: bool, initial_pose: np.ndarray | None = None,
                  time: float | None = None, planar: bool = False) -> None:
        """Declare a robot (the arguments of ``MomaEstimator.add_robot``), then record it."""
        self.inner.add_robot(name, boards=boards, cameras=cameras, static=static, initial_pose=initial_pose, time=time, planar=planar)
        self.lines.append(_line({
            "kind": "robot",
            "name": name,
            "boards": {str(int(k)): _matrix(v) for k, v in (boards or {}).items()},
            "cameras": {str(k): _matrix(v) for k, v in (cameras or {}).items()},
            "static": bool(static),
            "initial_pose": _optional_matrix(initial_pose),
            "time": None if time is None else float(time),
            "planar": bool(planar),
        }))

    def set_static(self, name: str, static: bool, time: float) -> None:
        """The owner's switch, then record it."""
        self.inner.set_static(name, static, time)
        self.lines.append(_line({"kind": "static", "name": name, "static": bool(static), "time": float(time)}))

    def update(self, time: float, detections: Iterable[Detection]) -> None:
        """One camera frame, then record it."""
        if isinstance(detections, Iterable) and not isinstance(detections, (str, bytes, Detection)):
            detections = list(detections)  # read once, by both
        self.inner.update(time, detections)
        self.lines.append(_line({"kind": "frame", "time": float(time), "detections": [_detection_json(d) for d in detections]}))

    def estimates(self) -> dict[str, Any]:
        return self.inner.estimates()

    def estimate(self, name: str) -> Any:
        return self.inner.estimate(name)

    def window_ready(self, name: str) -> bool:
        return self.inner.window_ready(name)


class _RecordingOdometryLocaliser(RecordingLocaliser):
    """A :class:`RecordingLocaliser` of a localiser that takes wheel odometry."""

    def odometry(self, name: str, increment: tuple[float, float, float], covariance: np.ndarray, time: float) -> None:
        """Wheel odometry, then record it."""
        self.inner.odometry(name, increment, covariance, time)
        self.lines.append(_line({
            "kind": "odometry",
            "name": name,
            "increment": [float(v) for v in increment],
            "covariance": _matrix(covariance),
            "time": float(time),
        }))


def recording_localiser(inner: Any, config: EstimatorConfig) -> RecordingLocaliser:
    """``inner`` (made with ``config``) wrapped in a :class:`RecordingLocaliser` that also
    takes and records wheel odometry when ``inner`` takes it."""
    cls = _RecordingOdometryLocaliser if callable(getattr(inner, "odometry", None)) else RecordingLocaliser
    return cls(inner, config)


class RecordingFactory:
    """A localiser factory (``EstimatorConfig -> localiser``, as ``Simulation`` and
    ``EnvConfig.localiser`` take one) whose localisers are ``factory``'s, each wrapped by
    :func:`recording_localiser`; :attr:`made` holds them, the newest last (a simulation
    makes one per episode: ``made[-1].text()`` is the episode's log once it ends). It
    pickles and copies with what it holds when ``factory`` does (a class, a module-level
    function)."""

    def __init__(self, factory: Callable[[EstimatorConfig], Any]):
        if not callable(factory):
            raise TypeError(f"factory must be a callable EstimatorConfig -> localiser, got {type(factory).__name__}")
        self.factory = factory
        self.made: list[RecordingLocaliser] = []

    def __call__(self, config: EstimatorConfig) -> RecordingLocaliser:
        recorder = recording_localiser(self.factory(config), config)
        self.made.append(recorder)
        return recorder


# ---------------------------------------------------------------- reading
class _Line:
    """Checked access to one line's object; every error names the file and the line."""

    def __init__(self, where: str, obj: Mapping[str, Any]):
        self.where = where
        self.obj = obj

    def fail(self, message: str) -> DetectionLogError:
        return DetectionLogError(f"{self.where}: {message}")

    def get(self, key: str, obj: Mapping[str, Any] | None = None, what: str = "") -> Any:
        source = self.obj if obj is None else obj
        if key not in source:
            raise self.fail(f"{what}missing {key!r}")
        return source[key]

    def text(self, key: str, obj: Mapping[str, Any] | None = None, what: str = "") -> str:
        value = self.get(key, obj, what)
        if not isinstance(value, str) or not value:
            raise self.fail(f"{what}{key!r} must be a non-empty string, got {value!r}")
        return value

    def flag(self, key: str) -> bool:
        value = self.get(key)
        if not isinstance(value, bool):
            raise self.fail(f"{key!r} must be true or false, got {value!r}")
        return value

    def number(self, key: str, obj: Mapping[str, Any] | None = None, what: str = "", optional: bool = False) -> float | None:
        value = self.get(key, obj, what)
        if value is None and optional:
            return None
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(f"{what}{key!r} must be a number, got {value!r}")
        return float(value)

    def array(self, key: str, shape: tuple[int, ...], obj: Mapping[str, Any] | None = None, what: str = "", optional: bool = False) -> np.ndarray | None:
        value = self.get(key, obj, what)
        if value is None and optional:
            return None
        try:
            array = np.array(value, dtype=float)
        except (TypeError, ValueError):
            array = None
        if array is None or array.shape != shape or isinstance(value, (str, bytes)):
            got = "not an array of numbers" if array is None else f"shape {array.shape}"
            raise self.fail(f"{what}{key!r} must be {'x'.join(map(str, shape))} numbers, got {got}")
        return array


def _estimator_config(line: _Line, value: Any) -> EstimatorConfig:
    if not isinstance(value, dict):
        raise line.fail(f"'estimator' must be an object of EstimatorConfig fields, got {value!r}")
    fields = dict(value)
    gate = fields.pop("gate", None)
    try:
        if gate is not None:
            if not isinstance(gate, dict):
                raise ConfigError("estimator.gate", f"must be an object of OutlierGateConfig fields or null, got {gate!r}")
            gate = OutlierGateConfig(**gate)
        return EstimatorConfig(**fields, gate=gate)
    except TypeError as err:  # an unknown field
        raise line.fail(f"'estimator': {err}") from None
    except ConfigError as err:  # names the field: estimator.window, estimator.gate, ...
        raise line.fail(str(err)) from None


def _detection(line: _Line, value: Any, k: int) -> Detection:
    what = f"detections[{k}]: "
    if not isinstance(value, dict):
        raise line.fail(f"{what}must be an object, got {value!r}")
    corners = line.get("corners_px", value, what)
    if not isinstance(corners, list):
        raise line.fail(f"{what}'corners_px' must be a list of [u, v] pairs, got {corners!r}")
    corners_px = line.array("corners_px", (len(corners), 2), value, what) if corners else np.empty((0, 2))
    marker_ids = line.get("marker_ids", value, what)
    if not isinstance(marker_ids, list) or not all(isinstance(m, int) and not isinstance(m, bool) for m in marker_ids):
        raise line.fail(f"{what}'marker_ids' must be a list of integers, got {marker_ids!r}")
    board_id = line.get("board_id", value, what)
    if not isinstance(board_id, int) or isinstance(board_id, bool):
        raise line.fail(f"{what}'board_id' must be an integer, got {board_id!r}")
    error = line.number("reprojection_error_px", value, what, optional=True)
    return Detection(
        camera_id=line.text("camera_id", value, what),
        board_id=board_id,
        T_c_m=line.array("T_c_m", (4, 4), value, what),
        corners_px=corners_px,
        marker_ids=tuple(marker_ids),
        time=line.number("time", value, what),
        reprojection_error_px=math.nan if error is None else error,
        covariance=line.array("covariance", (6, 6), value, what, optional=True),
        persistent_covariance=line.array("persistent_covariance", (6, 6), value, what, optional=True),
    )


def _mounts(line: _Line, key: str, integer_ids: bool) -> dict:
    value = line.get(key)
    if not isinstance(value, dict):
        raise line.fail(f"{key!r} must be an object id -> 4x4 pose, got {value!r}")
    mounts: dict = {}
    for name, pose in value.items():
        ident: int | str = name
        if integer_ids:
            try:
                ident = int(name)
            except ValueError:
                raise line.fail(f"{key!r}: board id {name!r} is not an integer") from None
        mounts[ident] = line.array(name, (4, 4), value, f"{key}: ")
    return mounts


def _record(line: _Line) -> LogRecord:
    kind = line.get("kind")
    if kind == "frame":
        detections = line.get("detections")
        if not isinstance(detections, list):
            raise line.fail(f"'detections' must be a list, got {detections!r}")
        return FrameRecord(line.number("time"), tuple(_detection(line, d, k) for k, d in enumerate(detections)))
    if kind == "static":
        return StaticRecord(line.text("name"), line.flag("static"), line.number("time"))
    if kind == "robot":
        return RobotRecord(
            name=line.text("name"),
            boards=_mounts(line, "boards", integer_ids=True),
            cameras=_mounts(line, "cameras", integer_ids=False),
            static=line.flag("static"),
            initial_pose=line.array("initial_pose", (4, 4), optional=True),
            time=line.number("time", optional=True),
            planar=line.flag("planar"),
        )
    if kind == "odometry":
        increment = line.array("increment", (3,))
        return OdometryRecord(line.text("name"), tuple(increment.tolist()), line.array("covariance", (3, 3)), line.number("time"))
    raise line.fail(f"unknown record kind {kind!r}; expected 'robot', 'static', 'frame' or 'odometry'")


def parse_detection_log(lines: Iterable[str], source: str = "<log>") -> DetectionLog:
    """The log of ``lines`` (a file's lines; blank lines are skipped); ``source`` names it in errors.

    Raises:
        DetectionLogError: no header, another format or version, a line that is not a
            JSON object, an unknown record kind, or a field missing or of the wrong
            type or shape (naming the line and the field).
    """
    estimator: EstimatorConfig | None = None
    records: list[LogRecord] = []
    for number, raw in enumerate(lines, start=1):
        if not raw.strip():
            continue
        where = f"{source}:{number}"
        try:
            obj = json.loads(raw)
        except json.JSONDecodeError as err:
            raise DetectionLogError(f"{where}: not JSON ({err.msg})") from None
        if not isinstance(obj, dict):
            raise DetectionLogError(f"{where}: a record must be a JSON object, got {type(obj).__name__}")
        line = _Line(where, obj)
        if estimator is None:
            if obj.get("format") != LOG_FORMAT:
                raise line.fail(f"not a detection log: the first record must be the header with format {LOG_FORMAT!r}")
            if obj.get("version") != LOG_VERSION:
                raise line.fail(f"version {obj.get('version')!r} of the format; this version reads {LOG_VERSION}")
            estimator = _estimator_config(line, line.get("estimator"))
            continue
        records.append(_record(line))
    if estimator is None:
        raise DetectionLogError(f"{source}: empty, not a detection log")
    return DetectionLog(estimator, tuple(records))


def read_detection_log(path: str | os.PathLike[str]) -> DetectionLog:
    """The detection log in the file at ``path`` (see :func:`parse_detection_log`; OSError if unreadable)."""
    with open(path, encoding="utf-8") as handle:
        return parse_detection_log(handle, os.fspath(path))


# ---------------------------------------------------------------- replay
def replay(log: DetectionLog, localiser: Any, sample: Callable[[float, Mapping[str, Any]], None]) -> None:
    """Make the calls of ``log`` on ``localiser``, in order, and report its estimates.

    ``sample(time, estimates)`` gets ``localiser.estimates()`` (robot name -> estimate)
    after every frame, and once after the first robots are declared when that is
    earlier than the first frame (at the latest time of their declarations; 0 for a
    declaration without one), as a simulation records its first frame. Odometry records
    go to a localiser that takes odometry (has ``odometry``) and are skipped otherwise.
    A call the localiser refuses raises its error.
    """
    odometry = getattr(localiser, "odometry", None)
    declared_at: float | None = None
    started = False
    for record in log.records:
        if isinstance(record, FrameRecord):
            if not started and declared_at is not None and declared_at < record.time:
                sample(declared_at, localiser.estimates())
            started = True
            localiser.update(record.time, record.detections)
            sample(record.time, localiser.estimates())
        elif isinstance(record, RobotRecord):
            localiser.add_robot(
                record.name, boards=dict(record.boards), cameras=dict(record.cameras), static=record.static,
                initial_pose=record.initial_pose, time=record.time, planar=record.planar,
            )
            if not started:
                at = 0.0 if record.time is None else record.time
                declared_at = at if declared_at is None else max(declared_at, at)
        elif isinstance(record, StaticRecord):
            localiser.set_static(record.name, record.static, record.time)
        elif callable(odometry):
            odometry(record.name, record.increment, record.covariance, record.time)

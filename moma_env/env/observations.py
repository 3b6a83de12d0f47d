"""What each agent observes: only what the robot could know, in fixed, bounded layouts.

Every value comes from the MOMA estimator, the camera's detections, the robot's
own declarations or the clock, never from the truth (the truth is in
``state()`` and ``infos``). Layouts are lists of named features with bounds;
:func:`describe` prints them for the README and the docstrings.

Normalisation: positions are relative to the arena centre and divided by the
arena's half-diagonal ``R``, so a position inside the arena lies in [-1, 1];
relative positions are divided by ``2R``. Angles appear as (cos, sin). A feature
of something unknown (no estimate) is 0 with its ``valid`` flag 0.

UGV ``ugv_k`` (one block per other device, in the order of ``devices``):

==================  ==========================================================
own pose            x, y, cos(yaw), sin(yaw), valid
own state           static (1 if declared static), status one-hot
                    (localised, holding, lost), staleness (age of the last
                    fresh estimate / lost_after, clipped to 1), and the
                    estimator's uncertainty: position standard deviation
                    (root of the trace of the position covariance) / 0.1 m and
                    heading standard deviation / 0.1 rad, clipped to 1 (1 also
                    without an estimate)
goal                dx, dy in the robot's estimated body frame, cos(dyaw),
                    sin(dyaw), distance / 2R, has_goal
timing              time since the last switch / the switch horizon (5 s by
                    default, ``EnvConfig.switch_horizon_s``; clipped to 1),
                    dwell remaining / dwell
seen                1 if its board was detected, or its camera saw a board, in
                    the latest frame
others (each)       dx, dy in its body frame, cos(dyaw), sin(dyaw), valid,
                    static, status one-hot
sled (towing only)  rope length / max rope
==================  ==========================================================

Each observer (``observer``, or ``observer_<k>`` with several): own pose (x, y, cos, sin, valid), altitude estimate / 4 m,
status one-hot, position and heading standard deviations (scaled as a UGV's), then per device: seen, x/z and y/z of its board in the camera
frame (clipped to [-2, 2]), depth z / 4 m (clipped to [0, 2]); then timing.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numba
import numpy as np
from gymnasium import spaces

from moma_env.estimator import Status
from moma_env.geometry import hypot_kernel
from moma_env.sim import Frame

__all__ = ["DEVICE_COLUMNS", "Feature", "ObservationLayout", "describe", "device_table", "padded", "STATUS_ORDER"]

#: Order of the status one-hot.
STATUS_ORDER = (Status.LOCALISED, Status.HOLDING, Status.LOST)
_ALTITUDE_SCALE_M = 4.0
#: Scales of the position (m) and heading (rad) standard deviations in observations.
_POSITION_STD_SCALE_M = 0.1
_HEADING_STD_SCALE_RAD = 0.1
#: Status -> its one-hot, in STATUS_ORDER.
_ONE_HOT = {status: tuple(1.0 if status is s else 0.0 for s in STATUS_ORDER) for status in Status}
#: The x, y, yaw of a device without a usable estimate in :func:`device_table`.
_NO_POSE = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class Feature:
    """One observation feature: its name and bounds."""

    name: str
    low: float
    high: float


def _pose_features(prefix: str) -> list[Feature]:
    return [
        Feature(f"{prefix}.x", -2.0, 2.0),
        Feature(f"{prefix}.y", -2.0, 2.0),
        Feature(f"{prefix}.cos_yaw", -1.0, 1.0),
        Feature(f"{prefix}.sin_yaw", -1.0, 1.0),
        Feature(f"{prefix}.valid", 0.0, 1.0),
    ]


def _status_features(prefix: str) -> list[Feature]:
    return [Feature(f"{prefix}.status.{s.name.lower()}", 0.0, 1.0) for s in STATUS_ORDER]


def _uncertainty_features(prefix: str) -> list[Feature]:
    return [Feature(f"{prefix}.position_std", 0.0, 1.0), Feature(f"{prefix}.heading_std", 0.0, 1.0)]


@numba.njit(cache=True)
def _scaled_std(std: float, scale: float) -> float:
    """An uncertainty feature: ``std / scale`` clipped to 1; NaN (no estimate) is 1."""
    v = std / scale
    return v if v < 1.0 else 1.0  # NaN compares False: 1.0


@numba.njit(cache=True)
def _timing_values(since: float, horizon: float, dwell_left: float, dwell: float) -> tuple[float, float]:
    """The two timing features: time since the last switch / the switch horizon and dwell
    remaining / dwell (0 without a dwell), each clipped to 1 (s / s)."""
    since_feature = since / horizon
    dwell_feature = 0.0
    if dwell > 0:
        dwell_feature = dwell_left / dwell
        dwell_feature = dwell_feature if dwell_feature < 1.0 else 1.0
    return (since_feature if since_feature < 1.0 else 1.0), dwell_feature


def uncertainty(position_std_m: float, heading_std_rad: float) -> list[float]:
    """The two uncertainty features: standard deviations over their scales, clipped
    to [0, 1]; NaN (no estimate) is 1."""
    return [_scaled_std(position_std_m, _POSITION_STD_SCALE_M), _scaled_std(heading_std_rad, _HEADING_STD_SCALE_RAD)]


def _timing_features() -> list[Feature]:
    return [Feature("time_since_switch", 0.0, 1.0), Feature("dwell_remaining", 0.0, 1.0)]


def ugv_features(devices: Sequence[str], me: str, tows_sled: bool) -> list[Feature]:
    """Feature list of UGV ``me`` among ``devices``."""
    feats = _pose_features("own")
    feats += [
        Feature("own.static", 0.0, 1.0),
        *_status_features("own"),
        Feature("own.staleness", 0.0, 1.0),
        *_uncertainty_features("own"),
    ]
    feats += [
        Feature("goal.dx", -2.0, 2.0),
        Feature("goal.dy", -2.0, 2.0),
        Feature("goal.cos_dyaw", -1.0, 1.0),
        Feature("goal.sin_dyaw", -1.0, 1.0),
        Feature("goal.distance", 0.0, 2.0),
        Feature("goal.has_goal", 0.0, 1.0),
    ]
    feats += _timing_features()
    feats.append(Feature("seen", 0.0, 1.0))
    for other in devices:
        if other == me:
            continue
        feats += [
            Feature(f"{other}.dx", -2.0, 2.0),
            Feature(f"{other}.dy", -2.0, 2.0),
            Feature(f"{other}.cos_dyaw", -1.0, 1.0),
            Feature(f"{other}.sin_dyaw", -1.0, 1.0),
            Feature(f"{other}.valid", 0.0, 1.0),
            Feature(f"{other}.static", 0.0, 1.0),
            *_status_features(other),
        ]
    if tows_sled:
        feats.append(Feature("sled.rope", 0.0, 1.0))
    return feats


def observer_features(devices: Sequence[str]) -> list[Feature]:
    """Feature list of the observer."""
    feats = _pose_features("own") + [Feature("own.altitude", 0.0, 2.0), *_status_features("own"), *_uncertainty_features("own")]
    for d in devices:
        feats += [
            Feature(f"{d}.seen", 0.0, 1.0),
            Feature(f"{d}.x_over_z", -2.0, 2.0),
            Feature(f"{d}.y_over_z", -2.0, 2.0),
            Feature(f"{d}.depth", 0.0, 2.0),
        ]
    return feats + _timing_features()


def describe(features: Sequence[Feature]) -> str:
    """A readable table of a layout."""
    return "\n".join(f"{i:3d}  {f.name:<28} [{f.low:g}, {f.high:g}]" for i, f in enumerate(features))


def _box(features: Sequence[Feature]) -> spaces.Box:
    low = np.array([f.low for f in features], dtype=np.float32)
    high = np.array([f.high for f in features], dtype=np.float32)
    return spaces.Box(low=low, high=high, dtype=np.float32)


#: Columns of :func:`device_table`, one row per device: what its owner knows of it.
DEVICE_COLUMNS = (
    "x",  # estimated pose in W (m, rad); 0 without one
    "y",
    "yaw",
    "has_pose",  # 1 if it has an estimate that is not LOST
    "static",  # 1 if declared static
    "localised",  # status one-hot, in STATUS_ORDER
    "holding",
    "lost",
    "staleness",  # age of the last fresh estimate / lost_after_s, clipped to 1 (1 without one)
    "position_std_m",  # root of the trace of the position covariance (m), NaN without one
    "heading_std_rad",  # heading standard deviation (rad), NaN without one
    "seen",  # 1 if the frame's detections involve it
)
_X, _Y, _YAW, _HAS_POSE, _STATIC, _LOCALISED, _HOLDING, _LOST, _STALENESS, _POSITION_STD, _HEADING_STD, _SEEN = range(len(DEVICE_COLUMNS))


def device_table(
    frame: Frame, devices: Sequence[str], board_device: Callable[[int], str], camera_owner: Mapping[str, str], lost_after_s: float
) -> np.ndarray:
    """What every device's owner knows at ``frame``, one float64 row per device of
    ``devices`` with the columns of :data:`DEVICE_COLUMNS`: its estimate (none when LOST),
    status, declared state, staleness (age of the last fresh estimate / ``lost_after_s``
    (s), clipped to 1), standard deviations, and whether the frame's detections involve it."""
    seen: set[str] = set()
    add = seen.add
    for d in frame.detections:
        add(board_device(d.board_id))
        add(camera_owner[d.camera_id])
    t = frame.time
    mobile = frame.mobile
    estimates, estimated = frame.estimates, frame.estimated
    lost = Status.LOST
    values: list[float] = []
    for device in devices:
        e = estimates[device]
        status = e.status
        pose = None if status is lost else estimated[device]
        has_pose = 1.0
        if pose is None:
            pose, has_pose = _NO_POSE, 0.0
        fresh = e.last_fresh_time
        # One row: x, y, yaw, has_pose, static, the status one-hot, staleness, the deviations, seen.
        values += (
            *pose,
            has_pose,
            0.0 if device in mobile else 1.0,
            *_ONE_HOT[status],
            1.0 if fresh is None else min(1.0, (t - fresh) / lost_after_s),
            e.position_std_m,
            e.heading_std_rad,
            1.0 if device in seen else 0.0,
        )
    return np.array(values, dtype=np.float64).reshape(len(devices), len(DEVICE_COLUMNS))


@numba.njit(cache=True)
def _put(out: np.ndarray, k: int, value: float, low: np.ndarray, high: np.ndarray) -> int:
    """``out[k] = value`` as float32, clipped to ``[low[k], high[k]]`` as numpy's ``clip``
    does it (NaN kept; ``-0.0`` against a bound ``0.0`` becomes ``0.0``); returns ``k + 1``."""
    v = np.float32(value)
    if not math.isnan(v):
        lo = low[k]
        hi = high[k]
        v = v if v > lo else lo
        v = v if v < hi else hi
    out[k] = v
    return k + 1


@numba.njit(cache=True)
def _ugv_rows(
    table: np.ndarray,
    rows: np.ndarray,
    goals: np.ndarray,
    ropes: np.ndarray,
    scalars: np.ndarray,
    low: np.ndarray,
    high: np.ndarray,
    sizes: np.ndarray,
    out: np.ndarray,
) -> None:
    """Every UGV's observation (the layout of the module docstring) into ``out[u, :sizes[u]]``.

    ``rows[u]``: the row of ``table`` of UGV ``u``, then those of the other devices in
    order; ``goals[u]``: goal x, y, yaw and 1 (0 without a goal); ``ropes[u]``: the rope
    feature (read when ``sizes[u]`` leaves room for it); ``scalars``: arena centre x, y,
    half-diagonal ``R``, time since the last switch, the switch horizon, dwell remaining,
    dwell (m, s). The same float64 arithmetic as the Python it replaces, then float32.
    """
    cx, cy, r = scalars[0], scalars[1], scalars[2]
    since, horizon, dwell_left, dwell = scalars[3], scalars[4], scalars[5], scalars[6]
    two_r = 2.0 * r
    since_feature, dwell_feature = _timing_values(since, horizon, dwell_left, dwell)
    for u in range(rows.shape[0]):
        o = out[u]
        lo = low[u]
        hi = high[u]
        me = rows[u, 0]
        has_pose = table[me, _HAS_POSE] != 0.0
        x = table[me, _X]
        y = table[me, _Y]
        yaw = table[me, _YAW]
        c = 0.0
        s = 0.0
        k = 0
        if has_pose:
            c = math.cos(yaw)
            s = math.sin(yaw)
            k = _put(o, k, (x - cx) / r, lo, hi)
            k = _put(o, k, (y - cy) / r, lo, hi)
            k = _put(o, k, c, lo, hi)
            k = _put(o, k, s, lo, hi)
            k = _put(o, k, 1.0, lo, hi)
        else:
            for _ in range(5):
                k = _put(o, k, 0.0, lo, hi)
        for column in (_STATIC, _LOCALISED, _HOLDING, _LOST, _STALENESS):
            k = _put(o, k, table[me, column], lo, hi)
        k = _put(o, k, _scaled_std(table[me, _POSITION_STD], _POSITION_STD_SCALE_M), lo, hi)
        k = _put(o, k, _scaled_std(table[me, _HEADING_STD], _HEADING_STD_SCALE_RAD), lo, hi)
        has_goal = goals[u, 3] != 0.0
        if has_goal and has_pose:
            dx = goals[u, 0] - x
            dy = goals[u, 1] - y
            dyaw = goals[u, 2] - yaw
            k = _put(o, k, (c * dx + s * dy) / two_r, lo, hi)
            k = _put(o, k, (-s * dx + c * dy) / two_r, lo, hi)
            k = _put(o, k, math.cos(dyaw), lo, hi)
            k = _put(o, k, math.sin(dyaw), lo, hi)
            k = _put(o, k, hypot_kernel(dx, dy) / two_r, lo, hi)
            k = _put(o, k, 1.0, lo, hi)
        else:
            for _ in range(5):
                k = _put(o, k, 0.0, lo, hi)
            k = _put(o, k, 1.0 if has_goal else 0.0, lo, hi)
        k = _put(o, k, since_feature, lo, hi)
        k = _put(o, k, dwell_feature, lo, hi)
        k = _put(o, k, table[me, _SEEN], lo, hi)
        for j in range(1, rows.shape[1]):
            other = rows[u, j]
            if table[other, _HAS_POSE] != 0.0 and has_pose:
                dx = table[other, _X] - x
                dy = table[other, _Y] - y
                dyaw = table[other, _YAW] - yaw
                k = _put(o, k, (c * dx + s * dy) / two_r, lo, hi)
                k = _put(o, k, (-s * dx + c * dy) / two_r, lo, hi)
                k = _put(o, k, math.cos(dyaw), lo, hi)
                k = _put(o, k, math.sin(dyaw), lo, hi)
                k = _put(o, k, 1.0, lo, hi)
            else:
                for _ in range(5):
                    k = _put(o, k, 0.0, lo, hi)
            for column in (_STATIC, _LOCALISED, _HOLDING, _LOST):
                k = _put(o, k, table[other, column], lo, hi)
        if k < sizes[u]:
            _put(o, k, ropes[u], lo, hi)


def padded(value: spaces.Box | np.ndarray, size: int) -> spaces.Box | np.ndarray:
    """A vector space or observation grown to ``size`` entries with zeros (bounds [0, 0])."""
    if isinstance(value, spaces.Box):
        extra = size - value.shape[0]
        low = np.concatenate([value.low, np.zeros(extra, dtype=np.float32)])
        high = np.concatenate([value.high, np.zeros(extra, dtype=np.float32)])
        return spaces.Box(low=low, high=high, dtype=np.float32)
    extra = size - value.shape[0]
    return value if extra == 0 else np.concatenate([value, np.zeros(extra, dtype=value.dtype)])


class ObservationLayout:
    """Spaces and vector builders of every agent of one environment instance.

    Args:
        devices: UGVs then sleds, in a fixed order.
        ugv_agents: the UGV agents.
        tows: UGV -> the sled it tows (if any).
        observer_agents: the observer agents (none, one or several), each with the observer's features.
        centre: arena centre (x, y) in W (m).
        half_diagonal: arena half-diagonal (m).
        dwell_s: the rules' dwell time (s).
        switch_horizon_s: the time since the last switch (s) at which its feature
            reaches 1 (and stays: it is clipped).
        goals: UGV agent -> its goal ``(x, y, yaw)`` in W (m, rad); a UGV left out has none.
        previous: the layout of the env's previous episode, if any: its features and spaces
            (which depend only on the devices and agents) are kept when those are the same.
    """

    def __init__(
        self,
        devices: Sequence[str],
        ugv_agents: Sequence[str],
        tows: Mapping[str, str],
        observer_agents: Sequence[str],
        centre: tuple[float, float],
        half_diagonal: float,
        dwell_s: float,
        switch_horizon_s: float,
        goals: Mapping[str, tuple[float, float, float]] | None = None,
        previous: ObservationLayout | None = None,
    ):
        self.devices = tuple(devices)
        self.tows = dict(tows)
        #: What the features and spaces depend on.
        self._agents_key = (self.devices, tuple(ugv_agents), tuple(self.tows.items()), tuple(observer_agents))
        if previous is not None and previous._agents_key == self._agents_key:
            self.features, self.spaces, self._bounds = previous.features, previous.spaces, previous._bounds
        else:
            self.features = {a: ugv_features(self.devices, a, a in self.tows) for a in ugv_agents}
            for agent in observer_agents:
                self.features[agent] = observer_features(self.devices)
            self.spaces = {a: _box(f) for a, f in self.features.items()}
            self._bounds = {a: (space.low, space.high) for a, space in self.spaces.items()}
        self._cx, self._cy = centre
        self._r = half_diagonal
        self._dwell = dwell_s
        self._switch_horizon = switch_horizon_s
        # The UGVs' builders' inputs that hold for the episode (see _ugv_rows).
        self._ugv_agents = tuple(ugv_agents)
        goals = {} if goals is None else goals
        index = {d: i for i, d in enumerate(self.devices)}
        self._rows = np.array(
            [[index[a], *(index[d] for d in self.devices if d != a)] for a in self._ugv_agents], dtype=np.int64
        ).reshape(len(self._ugv_agents), len(self.devices))
        self._goals = np.array(
            [(*goals[a], 1.0) if a in goals else (0.0, 0.0, 0.0, 0.0) for a in self._ugv_agents], dtype=np.float64
        ).reshape(len(self._ugv_agents), 4)
        self._sizes = np.array([len(self.features[a]) for a in self._ugv_agents], dtype=np.int64)
        width = int(self._sizes.max(initial=0))
        self._low = np.zeros((len(self._ugv_agents), width), dtype=np.float32)
        self._high = np.zeros((len(self._ugv_agents), width), dtype=np.float32)
        for u, agent in enumerate(self._ugv_agents):
            low, high = self._bounds[agent]
            self._low[u, : low.shape[0]] = low
            self._high[u, : high.shape[0]] = high
        # Per call, only the timing scalars and the towing agents' ropes change: the kernel's
        # input arrays are kept and those entries written in place (the kernel only reads them).
        self._scalars = np.array((self._cx, self._cy, self._r, 0.0, self._switch_horizon, 0.0, self._dwell))
        self._rope = np.zeros(len(self._ugv_agents))
        #: (row, agent) of the UGVs with a rope feature (the kernel reads only their rope entries).
        self._towing = tuple((u, a) for u, a in enumerate(self._ugv_agents) if a in self.tows)
        #: (agent, row, its length or None for the full width) of every UGV's vector in the kernel's output.
        self._views = tuple((a, u, None if size == width else int(size)) for u, (a, size) in enumerate(zip(self._ugv_agents, self._sizes)))

    # ------------------------------------------------------------------ helpers
    def _abs_pose(self, out: list[float], pose: tuple[float, float, float] | None) -> None:
        if pose is None:
            out += [0.0, 0.0, 0.0, 0.0, 0.0]
            return
        x, y, yaw = pose
        out += [(x - self._cx) / self._r, (y - self._cy) / self._r, math.cos(yaw), math.sin(yaw), 1.0]

    def _timing(self, out: list[float], since_switch: float, dwell_remaining: float) -> None:
        out += _timing_values(since_switch, self._switch_horizon, dwell_remaining, self._dwell)

    def _finish(self, agent: str, out: list[float]) -> np.ndarray:
        low, high = self._bounds[agent]
        obs = np.array(out, dtype=np.float32)
        obs.clip(low, high, out=obs)  # np.clip's ufunc, without its wrappers
        return obs

    # ------------------------------------------------------------------ builders
    def ugvs(
        self, table: np.ndarray, since_switch: float, dwell_remaining: float, ropes: Mapping[str, float] | None = None
    ) -> dict[str, np.ndarray]:
        """Observation vectors of every UGV agent (agent -> float32 vector, in ``ugv_agents``
        order), in one compiled call.

        Args:
            table: :func:`device_table` of ``devices``.
            since_switch: time since the last switch (s).
            dwell_remaining: the rules' dwell remaining (s).
            ropes: towing agent -> its rope length / its maximum (none: 0).
        """
        rope = self._rope
        for u, agent in self._towing:
            value = ropes.get(agent) if ropes else None
            rope[u] = 0.0 if value is None else value
        scalars = self._scalars
        scalars[3] = since_switch
        scalars[5] = dwell_remaining
        out = np.empty(self._low.shape, dtype=np.float32)
        _ugv_rows(table, self._rows, self._goals, rope, scalars, self._low, self._high, self._sizes, out)
        return {a: out[u] if size is None else out[u, :size] for a, u, size in self._views}

    def observer(
        self,
        agent: str,
        pose: tuple[float, float, float] | None,
        altitude: float | None,
        status: Status,
        std: tuple[float, float],
        board_in_camera: Mapping[str, np.ndarray],
        since_switch: float,
        dwell_remaining: float,
    ) -> np.ndarray:
        """Observation vector of observer ``agent``; ``std``: its position and heading standard
        deviations (m, rad; NaN without an estimate); ``board_in_camera``: device -> board
        position in C (m)."""
        out: list[float] = []
        self._abs_pose(out, pose)
        out.append(0.0 if altitude is None else altitude / _ALTITUDE_SCALE_M)
        out += _ONE_HOT[status]
        out += uncertainty(*std)
        for d in self.devices:
            p = board_in_camera.get(d)
            if p is None or p[2] <= 0.0:
                out += [0.0, 0.0, 0.0, 0.0]
            else:
                out += [1.0, p[0] / p[2], p[1] / p[2], p[2] / _ALTITUDE_SCALE_M]
        self._timing(out, since_switch, dwell_remaining)
        return self._finish(agent, out)

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

import numpy as np
from gymnasium import spaces

from moma_env.estimator import Status
from moma_env.sim import Frame

__all__ = ["DeviceSnapshot", "Feature", "ObservationLayout", "describe", "device_snapshots", "padded", "STATUS_ORDER"]

#: Order of the status one-hot.
STATUS_ORDER = (Status.LOCALISED, Status.HOLDING, Status.LOST)
_ALTITUDE_SCALE_M = 4.0
#: Scales of the position (m) and heading (rad) standard deviations in observations.
_POSITION_STD_SCALE_M = 0.1
_HEADING_STD_SCALE_RAD = 0.1
#: Status -> its one-hot, in STATUS_ORDER.
_ONE_HOT = {status: tuple(1.0 if status is s else 0.0 for s in STATUS_ORDER) for status in Status}


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


def uncertainty(position_std_m: float, heading_std_rad: float) -> list[float]:
    """The two uncertainty features: standard deviations over their scales, clipped
    to [0, 1]; NaN (no estimate) is 1."""
    p = position_std_m / _POSITION_STD_SCALE_M
    h = heading_std_rad / _HEADING_STD_SCALE_RAD
    return [p if p < 1.0 else 1.0, h if h < 1.0 else 1.0]  # NaN compares False: 1.0


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


@dataclass(slots=True)
class DeviceSnapshot:
    """What the estimator and the owner know of one device at this step."""

    pose: tuple[float, float, float] | None  # estimated (x, y, yaw) in W
    status: Status
    static: bool
    staleness: float  # in [0, 1]
    position_std_m: float  # root of the trace of the position covariance (m), NaN without one
    heading_std_rad: float  # heading standard deviation (rad), NaN without one
    seen: bool


def device_snapshots(
    frame: Frame, board_device: Callable[[int], str], camera_owner: Mapping[str, str], lost_after_s: float
) -> dict[str, DeviceSnapshot]:
    """What every device's owner knows at ``frame``: its estimate (None when LOST), status,
    declared state, staleness (age of the last fresh estimate / ``lost_after_s`` (s),
    clipped to 1), standard deviations, and whether the frame's detections involve it."""
    seen: set[str] = set()
    for d in frame.detections:
        seen.add(board_device(d.board_id))
        seen.add(camera_owner[d.camera_id])
    t = frame.time
    snaps = {}
    for device in frame.truth:
        e = frame.estimates[device]
        pose = None if e.status is Status.LOST else frame.estimated[device]
        age = 1.0 if e.last_fresh_time is None else min(1.0, (t - e.last_fresh_time) / lost_after_s)
        snaps[device] = DeviceSnapshot(
            pose, e.status, device not in frame.mobile, age, e.position_std_m, e.heading_std_rad, device in seen
        )
    return snaps


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
    ):
        self.devices = tuple(devices)
        self.tows = dict(tows)
        self.features = {a: ugv_features(self.devices, a, a in self.tows) for a in ugv_agents}
        for agent in observer_agents:
            self.features[agent] = observer_features(self.devices)
        self.spaces = {a: _box(f) for a, f in self.features.items()}
        self._bounds = {a: (space.low, space.high) for a, space in self.spaces.items()}
        self._others = {a: tuple(d for d in self.devices if d != a) for a in ugv_agents}
        self._cx, self._cy = centre
        self._r = half_diagonal
        self._dwell = dwell_s
        self._switch_horizon = switch_horizon_s

    # ------------------------------------------------------------------ helpers
    def _abs_pose(self, out: list[float], pose: tuple[float, float, float] | None) -> None:
        if pose is None:
            out += [0.0, 0.0, 0.0, 0.0, 0.0]
            return
        x, y, yaw = pose
        out += [(x - self._cx) / self._r, (y - self._cy) / self._r, math.cos(yaw), math.sin(yaw), 1.0]

    def _timing(self, out: list[float], since_switch: float, dwell_remaining: float) -> None:
        out.append(min(1.0, since_switch / self._switch_horizon))
        out.append(0.0 if self._dwell <= 0 else min(1.0, dwell_remaining / self._dwell))

    def _finish(self, agent: str, out: list[float]) -> np.ndarray:
        low, high = self._bounds[agent]
        obs = np.array(out, dtype=np.float32)
        obs.clip(low, high, out=obs)  # np.clip's ufunc, without its wrappers
        return obs

    # ------------------------------------------------------------------ builders
    def ugv(
        self,
        agent: str,
        snap: Mapping[str, DeviceSnapshot],
        goal: tuple[float, float, float] | None,
        since_switch: float,
        dwell_remaining: float,
        rope_fraction: float | None,
    ) -> np.ndarray:
        """Observation vector of UGV ``agent``."""
        me = snap[agent]
        pose = me.pose
        out: list[float] = []
        self._abs_pose(out, pose)
        out.append(1.0 if me.static else 0.0)
        out += _ONE_HOT[me.status]
        out.append(me.staleness)
        out += uncertainty(me.position_std_m, me.heading_std_rad)
        two_r = 2.0 * self._r
        if pose is not None:
            x, y, yaw = pose
            c, s = math.cos(yaw), math.sin(yaw)
        if goal is not None and pose is not None:
            dx, dy = goal[0] - x, goal[1] - y
            dyaw = goal[2] - yaw
            out += [(c * dx + s * dy) / two_r, (-s * dx + c * dy) / two_r, math.cos(dyaw), math.sin(dyaw), math.hypot(dx, dy) / two_r, 1.0]
        else:
            out += [0.0, 0.0, 0.0, 0.0, 0.0, 1.0 if goal is not None else 0.0]
        self._timing(out, since_switch, dwell_remaining)
        out.append(1.0 if me.seen else 0.0)
        for other in self._others[agent]:
            o = snap[other]
            if o.pose is not None and pose is not None:
                dx, dy = o.pose[0] - x, o.pose[1] - y
                dyaw = o.pose[2] - yaw
                out += [(c * dx + s * dy) / two_r, (-s * dx + c * dy) / two_r, math.cos(dyaw), math.sin(dyaw), 1.0]
            else:
                out += [0.0, 0.0, 0.0, 0.0, 0.0]
            out.append(1.0 if o.static else 0.0)
            out += _ONE_HOT[o.status]
        if agent in self.tows:
            out.append(0.0 if rope_fraction is None else rope_fraction)
        return self._finish(agent, out)

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

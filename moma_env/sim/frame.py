"""The public snapshot of one simulation step: :class:`Frame`.

Everything that reads the simulation (the PettingZoo env, rendering, the
experiments, the evaluation, the benchmarks) reads a Frame or the
:class:`~moma_env.sim.Simulation`'s public API. A Frame never changes after it
is made: its mappings are read-only views of dicts the simulation does not keep.

Frames and units: world frame W (x, y on the floor, z up), metres, radians,
seconds; planar poses ``(x, y, yaw)``; estimates as the localiser reports them
(:class:`~moma_env.estimator.RobotEstimate`: ``T_w_b``, status, phase,
covariance in W).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from types import MappingProxyType

from moma_env.estimator import Detection, RobotEstimate, Status
from moma_env.records import slot_setter_init
from moma_env.world import UAVState

__all__ = ["Frame", "Switch", "Pose2D"]

Pose2D = tuple[float, float, float]


@dataclass(frozen=True, slots=True)
class Switch:
    """A state change the simulation handled this step.

    Attributes:
        device: the UGV or sled.
        kind: ``"static"`` or ``"mobile"`` (granted), or ``"refused"``.
        reason: why a mobile request was refused (a ``moma_env.sim.rules``
            ``REFUSED_*`` value), None otherwise.
    """

    device: str
    kind: str
    reason: str | None = None


@slot_setter_init
@dataclass(frozen=True, eq=False, slots=True, init=False)
class Frame:
    """The simulation after a ``reset`` or a ``step``.

    Attributes:
        time: simulated time (s).
        steps: control steps since the reset.
        truth: true planar pose of every device (UGVs, then sleds) (m, rad).
        uavs: every observer's true state, by UAV name (empty without one);
            :attr:`uav` is the only one's.
        estimates: every robot's estimate (devices and the UAV) as the
            localiser reports it after this frame's update.
        estimated: planar pose of every device's estimate, None without one
            (whatever its status; see :meth:`usable_pose`).
        errors: planar position error of every device's estimate (m), NaN
            without one.
        detections: this frame's camera measurements, every camera's.
        mobile: the devices declared mobile now.
        switches: the state changes requested or declared during the step,
            in the order they were handled.
        contacts: collision pairs recorded during the step's physics
            (each a frozenset of two names).
        ropes: rope length of every sled (m).
        last_switch_time: time (s) of the last granted state change.
        dwell_remaining: seconds before a mobile request can be granted.
    """

    time: float
    steps: int
    truth: Mapping[str, Pose2D]
    uavs: Mapping[str, UAVState]
    estimates: Mapping[str, RobotEstimate]
    estimated: Mapping[str, Pose2D | None]
    errors: Mapping[str, float]
    detections: tuple[Detection, ...]
    mobile: frozenset[str]
    switches: tuple[Switch, ...]
    contacts: frozenset[frozenset[str]]
    ropes: Mapping[str, float]
    last_switch_time: float
    dwell_remaining: float

    def __getstate__(self) -> dict:
        # Read-only views cannot be pickled: store their dicts, and rewrap them on load.
        values = {f.name: getattr(self, f.name) for f in fields(self)}
        return {k: dict(v) if isinstance(v, MappingProxyType) else v for k, v in values.items()}

    def __setstate__(self, state: dict) -> None:
        for k, v in state.items():
            object.__setattr__(self, k, MappingProxyType(v) if isinstance(v, dict) else v)

    @property
    def uav(self) -> UAVState | None:
        """The true state of the only observer, None without one (ValueError with several: read :attr:`uavs`)."""
        if len(self.uavs) > 1:
            raise ValueError(f"this frame has {len(self.uavs)} observers ({', '.join(self.uavs)}); read Frame.uavs")
        for state in self.uavs.values():
            return state
        return None

    def usable_pose(self, device: str) -> Pose2D | None:
        """The planar estimate of ``device`` a controller may act on: None if LOST or absent."""
        if self.estimates[device].status is Status.LOST:
            return None
        return self.estimated[device]

    def error(self, device: str) -> float | None:
        """:attr:`errors` of ``device`` with None for NaN (what infos carry)."""
        value = self.errors[device]
        return None if math.isnan(value) else value



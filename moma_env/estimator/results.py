"""What the estimator reports: phases, statuses, per-robot estimates and switch events."""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import numpy as np

from moma_env.records import slot_setter_init

__all__ = ["Phase", "Status", "RobotEstimate", "SwitchEvent", "EVENT_KINDS"]


class Phase(enum.Enum):
    """Where a robot is in the MOMA cycle.

    MOBILE: tracked at every update from reference robots.
    SETTLING: declared static, collecting its switch window.
    REFERENCE: static with a frozen pose; it locates cameras.
    """

    MOBILE = "mobile"
    SETTLING = "settling"
    REFERENCE = "reference"


class Status(enum.Enum):
    """How current a robot's reported pose is.

    LOCALISED: the pose is fresh this update (a mobile robot measured in this
        update, a settling robot with at least one window sample, or a
        reference).
    HOLDING: the last fresh pose, not measured this update.
    LOST: holding for longer than ``lost_after_s``, or never localised.
    """

    LOCALISED = "localised"
    HOLDING = "holding"
    LOST = "lost"


#: Kinds of :class:`SwitchEvent`.
EVENT_KINDS = ("static", "mobile", "frozen", "lost", "relocalised")


@slot_setter_init
@dataclass(frozen=True, eq=False, slots=True, init=False)
class RobotEstimate:
    """A snapshot of one robot's estimate.

    Attributes:
        name: the robot.
        T_w_b: 4x4 pose of the body frame B in the world frame W (m), a copy
            owned by the caller; None if the robot was never localised.
        status: LOCALISED, HOLDING or LOST.
        phase: MOBILE, SETTLING or REFERENCE.
        last_fresh_time: last time (s) the pose was fresh, None if never.
        n_window: samples in the switch window: collected so far while
            SETTLING, averaged into the frozen pose while REFERENCE (the
            inliers of the window; 0 for an initial pose), 0 while MOBILE.
        covariance: 6x6 covariance of the error of ``T_w_b`` (a copy; None
            without a pose), in the world frame W, translation first, rotation
            perturbed on the left (the convention of
            :mod:`moma_env.estimator.uncertainty`, a ROS ``PoseWithCovariance``):
            position in ``[:3, :3]`` (m^2), heading in ``[5, 5]`` (rad^2). It is
            the covariance of the pose when it was last fresh: a HOLDING robot
            that moves is further off than it says. Zero for an initial pose
            (it defines W).
    """

    name: str
    T_w_b: np.ndarray | None
    status: Status
    phase: Phase
    last_fresh_time: float | None
    n_window: int
    covariance: np.ndarray | None = None

    @property
    def position_std_m(self) -> float:
        """Root of the trace of the position covariance (m): the RMS distance of the
        true position from the estimate; NaN without a covariance."""
        cov = self.covariance
        if cov is None:
            return math.nan
        # math.sqrt and np.sqrt are both the correctly rounded square root.
        return math.sqrt(max(0.0, float(cov[0, 0] + cov[1, 1] + cov[2, 2])))

    @property
    def heading_std_rad(self) -> float:
        """Standard deviation of the heading (rotation about the world z axis, rad); NaN without a covariance."""
        cov = self.covariance
        if cov is None:
            return math.nan
        return math.sqrt(max(0.0, float(cov[5, 5])))


@dataclass(frozen=True, slots=True)
class SwitchEvent:
    """A change in a robot's phase or status.

    Attributes:
        time: when it happened (s).
        robot: the robot's name.
        kind: one of :data:`EVENT_KINDS`: ``"static"`` / ``"mobile"`` (owner's
            declaration), ``"frozen"`` (pose frozen, robot becomes a
            reference), ``"lost"``, ``"relocalised"``.
        n_samples: for ``"frozen"``, the window samples averaged (0: frozen at
            the last fresh pose); 0 for the other kinds.
    """

    time: float
    robot: str
    kind: str
    n_samples: int = 0

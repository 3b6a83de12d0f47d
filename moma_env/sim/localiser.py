"""What the simulation needs of an estimator: the :class:`Localiser` protocol.

:class:`~moma_env.estimator.MomaEstimator` implements it; another estimator
(a pose graph, an EKF, an oracle for ablations) that implements it can be
passed to :class:`~moma_env.sim.Simulation` by its factory, and the
environments, rules, rewards and observations work unchanged.

Frames and units follow :mod:`moma_env.estimator`: the world frame W is fixed
by the UGVs' initial poses, poses are 4x4 ``T_w_b`` (m), times are seconds,
covariances 6x6 over (translation m, rotation rad) in W.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from typing import Protocol, runtime_checkable

import numpy as np

from moma_env.estimator import Detection, EstimatorConfig, RobotEstimate

__all__ = ["Localiser", "LocaliserFactory", "OdometryConsumer"]


@runtime_checkable
class Localiser(Protocol):
    """A cooperative localiser driven by owner declarations and camera detections.

    The contract is the one of :class:`~moma_env.estimator.MomaEstimator`:

    * ``add_robot`` declares a robot with its boards (board id -> ``T_b_m``) and
      cameras (camera id -> ``T_b_c``), static or not, with an initial pose
      ``T_w_b`` if known; ``planar`` robots move upright on the floor;
    * ``set_static(name, static, time)`` is the owner's declaration of a switch;
    * ``update(time, detections)`` takes one camera frame (every
      :class:`~moma_env.estimator.Detection` of the frame);
    * ``estimates()`` returns a :class:`~moma_env.estimator.RobotEstimate` per
      robot (status, phase, pose, covariance), ``estimate(name)`` one of them;
    * ``window_ready(name)``: the robot is a reference, or would become one at
      the next switch (the motion rules ask it before granting a move).
    """

    def add_robot(
        self,
        name: str,
        *,
        boards: Mapping[int, np.ndarray] | None = None,
        cameras: Mapping[str, np.ndarray] | None = None,
        static: bool,
        initial_pose: np.ndarray | None = None,
        time: float | None = None,
        planar: bool = False,
    ) -> None: ...

    def set_static(self, name: str, static: bool, time: float) -> None: ...

    def update(self, time: float, detections: Iterable[Detection]) -> None: ...

    def estimates(self) -> dict[str, RobotEstimate]: ...

    def estimate(self, name: str) -> RobotEstimate: ...

    def window_ready(self, name: str) -> bool: ...


@runtime_checkable
class OdometryConsumer(Protocol):
    """A localiser that also takes wheel odometry (an EKF); others get none.

    A driver with odometry (the paper's experiments) calls, before each
    :meth:`Localiser.update`, ``odometry(name, increment, covariance, time)``
    per robot: ``increment = (dx, dy, dyaw)``, the planar motion since the
    previous call in the robot's body frame at the previous pose (m, m, rad),
    and ``covariance``, its 3x3 covariance (m^2, rad^2). A localiser that is not
    an ``OdometryConsumer`` (the MOMA estimator) is simply not called.
    """

    def odometry(self, name: str, increment: tuple[float, float, float], covariance: np.ndarray, time: float) -> None: ...


#: Builds a fresh localiser for an episode from the scenario's estimator settings.
LocaliserFactory = Callable[[EstimatorConfig], Localiser]

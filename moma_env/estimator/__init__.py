"""The MOMA estimator (paper section II): robots localise each other in turns.

It imports nothing but the standard library, numpy, numba and the package's base
modules (:mod:`moma_env.geometry`, :mod:`moma_env.config`, :mod:`moma_env.records`),
so it runs as well on a real camera's detections as on the simulator's.

Entities and frames
-------------------
Every entity is a *robot* with a body frame B. A robot may carry boards (board
frame M, mount ``T_b_m``) and cameras (OpenCV camera frame C, mount ``T_b_c``).
The estimator tracks ``T_w_b`` (4x4, SE(3), metres) of every robot in the
odometry frame W, which is defined by the initial poses of the robots that start
static. ``T_a_b`` maps points of frame b to frame a: ``p_a = T_a_b @ p_b``.
A :class:`Detection` gives ``T_c_m``, the board in the camera (solvePnP).

The paper's G notation in ours
------------------------------
The paper's ``G_X`` is the world-to-X transform, ``G_X = inv(T_w_x)``, and its
``G^t``, "the relative pose of the marker in camera frame", is our ``T_c_m``.

* ``G_C^t = G^t G_M`` (camera from a static marker) is
  ``T_w_c = T_w_m @ inv(T_c_m)``.
* While the camera is static the marker is measured: ``T_w_m = T_w_c @ T_c_m``.
* The marker update ``G_M^{tau2} = (^{tau2}G_M^{tau1}) G_M^{tau1}`` with
  ``^{tau2}G_M^{tau1} = [G^{tau2}]^{-1} G^{tau1}`` is
  ``T_w_m(tau2) = T_w_m(tau1) @ inv(T_c_m(tau1)) @ T_c_m(tau2)``.

Phases and statuses
-------------------
A robot is MOBILE, SETTLING (declared static, collecting its switch window) or
REFERENCE (static with a frozen pose). Its status is LOCALISED (fresh this
update), HOLDING (last fresh pose) or LOST (holding for longer than
``lost_after_s``, or never localised). A stale pose is never reported as fresh.

One update (:meth:`MomaEstimator.update`)
-----------------------------------------
1. Cameras. A camera on a REFERENCE robot: ``T_w_c = T_w_b @ T_b_c``. Any other
   camera that sees boards of REFERENCE robots (not its own):
   ``T_w_c = T_w_b_ref @ T_b_m @ inv(T_c_m)``, fused by their mean (the average
   of ``geometry.mean_pose``; with ``EstimatorConfig(fusion="information")``
   weighted by their covariances, :mod:`moma_env.estimator.fusion`). Other
   cameras are not located.
2. Samples of non-reference robots: each of their boards seen by a located
   camera gives ``T_w_b = T_w_c @ T_c_m @ inv(T_b_m)``; each located camera they
   carry gives ``T_w_b = T_w_c @ inv(T_b_c)``; a robot's samples are fused by
   the same mean. A camera located through a non-reference board locates
   nothing (one level of chaining), so error accumulates only at switches.
   After the outlier gate, the sample is a MOBILE robot's pose; a SETTLING
   robot appends it to its window (after ``settle_delay_s``), reports the window
   mean and is frozen when the window is full.
3. Status and lost / relocalised events.

Declarations (:meth:`MomaEstimator.set_static`) move robots between phases; when a
robot is declared mobile, every other SETTLING robot is frozen first.

Detection logs (:mod:`moma_env.estimator.log`): every call an estimator takes, one
JSON object per line, recorded by :class:`RecordingLocaliser` and replayed on any
estimator by :func:`replay` (``moma-env localise``): how a real robot's detections
reach the same code the simulator runs.
"""

from moma_env.config import ConfigError
from moma_env.estimator.config import EstimatorConfig, OutlierGateConfig
from moma_env.estimator.detection import Detection
from moma_env.estimator.errors import (
    UnknownBoardError,
    UnknownCameraError,
    UnknownIdError,
    UnknownRobotError,
)
from moma_env.estimator.gate import OutlierGate
from moma_env.estimator.log import (
    DetectionLog,
    DetectionLogError,
    RecordingFactory,
    RecordingLocaliser,
    read_detection_log,
    recording_localiser,
    replay,
)
from moma_env.estimator.moma import MomaEstimator
from moma_env.estimator.results import EVENT_KINDS, Phase, RobotEstimate, Status, SwitchEvent
from moma_env.estimator.window import SwitchWindow

__all__ = [
    "ConfigError",
    "Detection",
    "EstimatorConfig",
    "OutlierGateConfig",
        "UnknownIdError",
    "UnknownRobotError",
    "UnknownBoardError",
    "UnknownCameraError",
    "OutlierGate",
    "SwitchWindow",
    "MomaEstimator",
    "Phase",
    "Status",
    "RobotEstimate",
    "SwitchEvent",
    "EVENT_KINDS",
    "DetectionLog",
    "DetectionLogError",
    "RecordingLocaliser",
    "RecordingFactory",
    "recording_localiser",
    "read_detection_log",
    "replay",
]

"""Pose-graph MOMA: every detection a factor, static phases as one pose, smoothed by iSAM2.

The paper's estimator averages 25 samples at each switch and throws the rest
away. Here every detection of every frame is a factor of a pose graph solved
incrementally by GTSAM's iSAM2 (the optional ``graph`` extra, ``pip install
gtsam``), so that a static robot's pose keeps gaining information for as long
as it stays static, and earlier poses are re-estimated as later frames arrive.

Variables (``gtsam.Pose3``, the pose ``T_w_b`` of a robot's body in W)
-----------------------------------------------------------------------
* a robot that is static (SETTLING or REFERENCE) has **one variable per static
  phase**: its pose is the same in every frame of the phase, which is the
  static-phase constraint;
* a MOBILE robot (the observer, a moving UGV) gets a new variable in every frame
  in which it is measured;
* a robot with an initial pose that starts static is anchored by a prior of
  ``anchor_sigma`` (it defines W); a *planar* robot (a UGV) has a prior on its
  height, roll and pitch of ``planar_sigma`` (and none on x, y, yaw).

Factors
-------
A detection ``T_c_m`` of a board on robot r by a camera on robot o is the
``BetweenFactorPose3`` ``T_o_b = T_o_c T_c_m inv(T_r_m)`` between their current
variables, with the detection's covariance carried to it (GTSAM's convention:
rotation first, perturbed on the right; with a ``persistent_covariance``, the
covariance of :func:`~moma_env.estimator.detection.frame_fusion_covariance`
for the frame's place in the run of frames its board stands still,
``Bookkeeper.still_frames``, once odometry chains the frames of moving robots;
before any odometry, and in ``graph_vision``, in the run of frames the robots
its camera relates stand still together, ``Bookkeeper.still_together``) plus a floor of ``detection_floor_m`` /
``detection_floor_rad``. As in MOMA, only cameras *located* in the frame (seeing
a board of a REFERENCE robot, or carried by one) add factors, so that the
graph stays connected to the anchors; a robot seen for the first time is
initialised through the camera.

Estimates
---------
After each frame iSAM2 is updated once; a robot's reported pose is the current
estimate of its latest variable (projected upright for a planar robot) and its
covariance the marginal of that variable, converted to the convention of
:mod:`moma_env.estimator.uncertainty` (translation first, perturbed on the left
in W). Phases, statuses and events follow
:mod:`moma_env.estimator.bookkeeping` (the MOMA semantics).

Cost: iSAM2's update grows slowly with the graph (a variable per frame for the
observer); see ``docs/estimators.md`` for the measured time per update.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np

from moma_env.config import check_bool, check_positive
from moma_env.estimator.bookkeeping import BookkeptLocaliser, Bookkeeper, RobotRecord
from moma_env.estimator.config import EstimatorConfig
from moma_env.estimator.detection import Detection, frame_fusion_covariance
from moma_env.estimator.results import Phase
from moma_env.geometry import invert, se2_to_se3, upright_body_from_mount

try:
    import gtsam
except ImportError as err:  # pragma: no cover - depends on the environment
    # ModuleNotFoundError, as for the missing module itself: pytest.importorskip skips on it
    raise ModuleNotFoundError(
        "the graph estimator needs GTSAM: pip install 'moma_env[graph]' (or pip install gtsam)", name=err.name
    ) from err

__all__ = ["GraphConfig", "GraphLocaliser", "graph_vision", "ros_from_gtsam", "gtsam_from_ros"]


@dataclass(frozen=True)
class GraphConfig:
    """Settings of :class:`GraphLocaliser` beyond the shared :class:`EstimatorConfig`.

    Attributes:
        detection_floor_m, detection_floor_rad: standard deviations added to
            every detection's covariance (m, rad).
        anchor_sigma: standard deviation of the priors that anchor the robots
            with initial poses (m and rad).
        planar_sigma: standard deviation of a planar robot's height (m), roll
            and pitch (rad) about their known values.
        relinearize_threshold: iSAM2's relinearisation threshold.
        odometry: turn the wheel odometry a driver gives
            (:meth:`GraphLocaliser.odometry`) into factors between a robot's
            consecutive variables; False ignores it (detections only).
        unmeasured_sigma: standard deviation (m, rad) given to the height, roll
            and pitch of an odometry factor, which wheels do not measure.
    """

    detection_floor_m: float = 1e-4
    detection_floor_rad: float = 1e-4
    anchor_sigma: float = 1e-6
    planar_sigma: float = 1e-5
    relinearize_threshold: float = 0.01
    odometry: bool = True
    unmeasured_sigma: float = 1.0

    def __post_init__(self) -> None:
        check_bool("graph.odometry", self.odometry)
        check_positive("graph.unmeasured_sigma", self.unmeasured_sigma)
        for name in ("detection_floor_m", "detection_floor_rad", "anchor_sigma", "planar_sigma", "relinearize_threshold"):
            check_positive(f"graph.{name}", getattr(self, name))


def _swap(R: np.ndarray) -> np.ndarray:
    """``[[0, R], [R, 0]]`` (6x6)."""
    B = np.zeros((6, 6))
    B[:3, 3:] = R
    B[3:, :3] = R
    return B


def ros_from_gtsam(T: np.ndarray, covariance: np.ndarray) -> np.ndarray:
    """A pose's covariance in GTSAM's convention (rotation first, ``T Exp(xi)``) in the
    convention of :mod:`moma_env.estimator.uncertainty` (translation first, left, frame of T's parent)."""
    B = _swap(np.asarray(T)[:3, :3])
    return B @ covariance @ B.T


def gtsam_from_ros(T: np.ndarray, covariance: np.ndarray) -> np.ndarray:
    """The inverse of :func:`ros_from_gtsam`."""
    B = _swap(np.asarray(T)[:3, :3].T)
    return B @ covariance @ B.T


class GraphLocaliser(BookkeptLocaliser):
    """Pose-graph MOMA behind the :class:`moma_env.sim.Localiser` protocol; see the module docstring."""

    def __init__(self, config: EstimatorConfig | None = None, graph: GraphConfig | None = None):
        self._book = Bookkeeper(EstimatorConfig() if config is None else config)
        if graph is None:
            graph = GraphConfig()
        if not isinstance(graph, GraphConfig):
            raise TypeError(f"graph must be a GraphConfig, got {type(graph).__name__}")
        self.graph = graph
        self._isam = self._new_isam()
        # Every iSAM2 update so far: its factors, its new values and the variables read after it
        # (iSAM2 does not pickle; a copy replays these into a new one, see __setstate__).
        self._history: list[tuple[gtsam.NonlinearFactorGraph, gtsam.Values, tuple[int, ...]]] = []
        self._factors = gtsam.NonlinearFactorGraph()
        self._values = gtsam.Values()
        self._next_key = 0
        self._key: dict[str, int | None] = {}  # the robot's current variable (None: none yet this phase / frame)
        self._in_graph: set[int] = set()
        self._guess: dict[str, np.ndarray | None] = {}  # latest pose (a new variable's initial value)
        self._pose: dict[str, np.ndarray | None] = {}
        self._cov: dict[str, np.ndarray | None] = {}
        floor = [graph.detection_floor_rad**2] * 3 + [graph.detection_floor_m**2] * 3  # GTSAM order
        self._floor = np.diag(floor)
        self._planar_noise = gtsam.noiseModel.Diagonal.Sigmas(
            np.array([graph.planar_sigma, graph.planar_sigma, 1e4, 1e4, 1e4, graph.planar_sigma])
        )
        self._anchor_noise = gtsam.noiseModel.Isotropic.Sigma(6, graph.anchor_sigma)
        self._n_variables = 0
        self._n_factors = 0
        self._last_key: dict[str, int] = {}  # the robot's latest variable, whatever its kind
        self._motion: dict[str, tuple[np.ndarray, np.ndarray]] = {}  # odometry since it: (T, GTSAM covariance)
        self._chained = False  # an odometry factor was added (see update)

    def _new_isam(self) -> gtsam.ISAM2:
        params = gtsam.ISAM2Params()
        params.setRelinearizeThreshold(self.graph.relinearize_threshold)
        params.relinearizeSkip = 1
        return gtsam.ISAM2(params)

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        del state["_isam"]  # GTSAM's ISAM2 does not pickle: rebuilt from the history
        return state

    def __setstate__(self, state: dict) -> None:
        """Rebuild iSAM2 by replaying every update in order, with the reads that followed each
        (iSAM2 solves for its estimate lazily, when read), so that the new iSAM2 is made by
        the same calls as the original and the copy continues bit for bit like it
        (``tests/test_env_copy.py``)."""
        self.__dict__.update(state)
        self._isam = self._new_isam()
        for factors, values, read in self._history:
            self._isam.update(factors, values)
            for key in read:
                self._isam.calculateEstimatePose3(key)
                self._isam.marginalCovariance(key)

    # ------------------------------------------------------------------ queries
    @property
    def size(self) -> tuple[int, int]:
        """``(variables, factors)`` in the graph so far."""
        return self._n_variables, self._n_factors

    def estimate_of(self, name: str) -> tuple[np.ndarray | None, np.ndarray | None]:
        """Robot ``name``'s pose and covariance from the latest smoothing."""
        return self._pose[name], self._cov[name]

    # ------------------------------------------------------------ declarations
    def add_robot(self, name: str, *, boards: Mapping[int, np.ndarray] | None = None,
                  cameras: Mapping[str, np.ndarray] | None = None, static: bool, initial_pose: np.ndarray | None = None,
                  time: float | None = None, planar: bool = False) -> None:
        """Declare a robot (the arguments of ``MomaEstimator.add_robot``)."""
        r = self._book.add_robot(name, boards=boards, cameras=cameras, static=static, initial_pose=initial_pose, time=time, planar=planar)
        pose = r.initial_pose
        self._guess[name] = None if pose is None else pose.copy()
        self._pose[name] = None if pose is None else pose.copy()
        self._cov[name] = None if pose is None else np.zeros((6, 6))
        self._key[name] = None
        if pose is not None and static:
            key = self._new_variable(r, pose)
            self._factors.add(gtsam.PriorFactorPose3(key, gtsam.Pose3(pose), self._anchor_noise))
            self._n_factors += 1

    def set_static(self, name: str, static: bool, time: float) -> None:
        """The owner's declaration (MOMA's semantics); a new static phase gets a new variable when measured."""
        r = self._book.robot(name)
        was_mobile = r.phase is Phase.MOBILE
        self._book.set_static(name, static, time)
        if was_mobile != (r.phase is Phase.MOBILE):
            self._key[name] = None

    def odometry(self, name: str, increment: tuple[float, float, float], covariance: np.ndarray, time: float) -> None:
        """Wheel odometry of robot ``name`` (:class:`moma_env.sim.OdometryConsumer`): the planar
        ``increment`` (dx, dy, dyaw) in its body frame (m, rad) of 3x3 ``covariance``. Composed
        until the robot's next variable, to which it becomes a factor from its previous one."""
        self._book.robot(name)
        try:
            dx, dy, dyaw = (float(v) for v in increment)
        except (TypeError, ValueError):
            raise ValueError(f"odometry of {name!r}: increment must be three numbers, got {increment!r}") from None
        Q3 = np.asarray(covariance, dtype=float)
        if Q3.shape != (3, 3) or not np.isfinite(Q3).all() or not np.isfinite([dx, dy, dyaw]).all():
            raise ValueError(f"odometry of {name!r}: increment must be finite and covariance a finite 3x3 array")
        self._book.time = self._book.checked_time(time)
        if not self.graph.odometry or name not in self._last_key:
            return
        self._chained = True  # odometry factors chain the frames of a moving robot
        delta = se2_to_se3(dx, dy, dyaw)
        Q = np.zeros((6, 6))
        Q[np.ix_((0, 1, 5), (0, 1, 5))] = Q3
        step = gtsam_from_ros(delta, Q)
        T, C = self._motion.get(name, (np.eye(4), np.zeros((6, 6))))
        Ad = gtsam.Pose3(invert(delta)).AdjointMap()
        self._motion[name] = (T @ delta, Ad @ C @ Ad.T + step)

    # ------------------------------------------------------------------ update
    def update(self, time: float, detections: Iterable[Detection]) -> None:
        """One camera frame at ``time`` (s): the located cameras' detections become factors, iSAM2 updates."""
        book = self._book
        t, by_camera = book.begin_update(time, detections)
        for name, r in book.robots.items():
            if r.phase is Phase.MOBILE:
                self._key[name] = None  # a mobile robot's pose of this frame is a new variable
        located = [c for c, group in by_camera.items() if self._is_located(c, group)]
        measured: set[str] = set()
        for camera_id in located:
            own = book.camera_owner[camera_id]
            group = by_camera[camera_id]
            T_o_c = own.cameras[camera_id]
            if self._key[own.name] is None:
                anchor = next(d for d in group if self._is_reference_board(d, own))
                ref = book.board_owner[anchor.board_id]
                T_w_c = self._pose_of(ref) @ ref.boards[anchor.board_id] @ invert(anchor.T_c_m)
                self._variable(own, T_w_c @ invert(T_o_c))
            key_o = self._key[own.name]
            T_w_o = self._guess[own.name]
            measured.add(own.name)
            # Which still frame each detection is (its persistent noise): odometry chains the frames of a
            # moving robot, so every frame of a still board shares its error; without, only the frames
            # relating robots that stand still together are combined.
            together = book.still_together(camera_id, group)
            still = (lambda d: book.still_frames(d.board_id)) if self._chained else (lambda d, k=together: k)
            for d in group:
                r = book.board_owner[d.board_id]
                if r is own:
                    continue
                T_r_m = r.boards[d.board_id]
                if self._key[r.name] is None:
                    self._variable(r, T_w_o @ T_o_c @ d.T_c_m @ invert(T_r_m))
                Z = T_o_c @ d.T_c_m @ invert(T_r_m)
                noise = self._noise(d, T_r_m, still(d))
                self._factors.add(gtsam.BetweenFactorPose3(key_o, self._key[r.name], gtsam.Pose3(Z), noise))
                self._n_factors += 1
                measured.add(r.name)
        if self._factors.size() or self._values.size():
            self._isam.update(self._factors, self._values)
            for key in self._values.keys():
                self._in_graph.add(key)
            read = self._read(measured)
            self._history.append((self._factors, self._values, read))
            self._factors = gtsam.NonlinearFactorGraph()
            self._values = gtsam.Values()
        book.end_update(t, measured)

    # ---------------------------------------------------------------- helpers
    def _is_reference_board(self, d: Detection, own: RobotRecord) -> bool:
        r = self._book.board_owner[d.board_id]
        return r is not own and r.phase is Phase.REFERENCE and self._key[r.name] is not None

    def _is_located(self, camera_id: str, group: list[Detection]) -> bool:
        own = self._book.camera_owner[camera_id]
        if own.phase is Phase.REFERENCE and self._key[own.name] is not None:
            return bool(group)
        return any(self._is_reference_board(d, own) for d in group)

    def _pose_of(self, r: RobotRecord) -> np.ndarray:
        pose = self._guess[r.name]
        assert pose is not None
        return pose

    def _new_variable(self, r: RobotRecord, pose: np.ndarray) -> int:
        key = self._next_key
        self._next_key += 1
        motion = self._motion.pop(r.name, None)
        previous = self._last_key.get(r.name)
        if motion is not None and previous is not None:
            T, C = motion
            C = C + self._floor
            C[[0, 1, 5], [0, 1, 5]] += self.graph.unmeasured_sigma**2  # rx, ry, tz in GTSAM's order
            noise = gtsam.noiseModel.Gaussian.Covariance(0.5 * (C + C.T))
            self._factors.add(gtsam.BetweenFactorPose3(previous, key, gtsam.Pose3(T), noise))
            self._n_factors += 1
        self._values.insert(key, gtsam.Pose3(pose))
        self._key[r.name] = key
        self._last_key[r.name] = key
        self._guess[r.name] = pose
        self._n_variables += 1
        if r.planar:
            upright = upright_body_from_mount(pose, np.eye(4), r.plane_z)
            self._factors.add(gtsam.PriorFactorPose3(key, gtsam.Pose3(upright), self._planar_noise))
            self._n_factors += 1
        return key

    def _variable(self, r: RobotRecord, pose: np.ndarray) -> int:
        """A new variable for ``r`` at ``pose`` (upright for a planar robot)."""
        if r.planar:
            pose = upright_body_from_mount(pose, np.eye(4), r.plane_z)
        return self._new_variable(r, pose)

    def _noise(self, d: Detection, T_r_m: np.ndarray, still: int = 1):
        """The noise of the factor ``T_o_c T_c_m inv(T_r_m)``: the detection's covariance on the right of
        ``T_c_m`` (GTSAM order), carried through ``inv(T_r_m)`` by the adjoint of ``T_r_m``; with a
        persistent part, that of the ``still``-th still frame (:func:`frame_fusion_covariance`)."""
        cov = frame_fusion_covariance(d, still)
        cov = np.zeros((6, 6)) if cov is None else gtsam_from_ros(d.T_c_m, cov)
        Ad = gtsam.Pose3(T_r_m).AdjointMap()
        C = Ad @ cov @ Ad.T + self._floor
        return gtsam.noiseModel.Gaussian.Covariance(0.5 * (C + C.T))

    def _read(self, measured: set[str]) -> tuple[int, ...]:
        """Current poses and marginal covariances of every robot's current variable; the
        variables read, in order."""
        read = []
        for name, r in self._book.robots.items():
            key = self._key[name]
            if key is None or key not in self._in_graph:
                continue
            if r.phase is Phase.MOBILE and name not in measured:
                continue
            read.append(key)
            T = self._isam.calculateEstimatePose3(key).matrix()
            cov = ros_from_gtsam(T, self._isam.marginalCovariance(key))
            if r.planar:
                T = upright_body_from_mount(T, np.eye(4), r.plane_z)
                cov[[2, 3, 4], :] = 0.0
                cov[:, [2, 3, 4]] = 0.0
            self._guess[name] = T
            self._pose[name] = T
            self._cov[name] = cov
        return tuple(read)


def graph_vision(config: EstimatorConfig) -> GraphLocaliser:
    """The pose graph of detections alone (``GraphConfig(odometry=False)``): the ``graph_vision`` estimator."""
    return GraphLocaliser(config, GraphConfig(odometry=False))

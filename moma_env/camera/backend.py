"""The interface every camera backend implements, and what it is given to look at.

Two backends turn the true scene into :class:`~moma_env.estimator.detection.Detection`
objects through the same call:

* :class:`~moma_env.camera.geometric.GeometricCamera` projects the board corners,
  adds pixel noise and runs solvePnP (fast; for training).
* :class:`~moma_env.camera.rendered.RenderedCamera` draws a synthetic image of
  the floor and the boards and runs ``cv2.aruco.ArucoDetector`` and solvePnP on
  it (the real pipeline).

The simulator hands a backend the camera pose and a :class:`BoardView` per board
in the scene; it never tells the backend which boards are visible.
"""

from __future__ import annotations

import math
import operator
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from moma_env.camera.pinhole import PinholeCamera
from moma_env.config import all_finite
from moma_env.estimator.detection import Detection
from moma_env.markers import BoardLayout

__all__ = ["BoardView", "CameraBackend", "OcclusionQuery", "as_pose", "up_in_board"]

#: ``occluded(p_w_from, p_w_to) -> bool``: True if the line of sight between two
#: world points (m, shape (3,)) is blocked, e.g. by a pymunk segment query.
OcclusionQuery = Callable[[np.ndarray, np.ndarray], bool]


def as_pose(T: object, name: str) -> np.ndarray:
    """``T`` as a finite float 4x4 array (no copy if it already is one); ValueError naming ``name`` otherwise."""
    T = np.asarray(T, dtype=float)
    if T.shape != (4, 4):
        raise ValueError(f"{name} must be a 4x4 pose, got shape {T.shape}")
    if not all_finite(T):
        raise ValueError(f"{name} must be finite, got {T.tolist()}")
    return T


def up_in_board(T_b_m: object) -> np.ndarray:
    """World up in the board frame M, as declared by the board's mount ``T_b_m`` (4x4, M in B).

    For a board on a body that stays upright (a ground robot or sled on the
    floor: ``z_B = z_W``), whatever its position and yaw: ``R_b_m^T e_z``, the
    third row of the mount's rotation. Face-up boards give ``(0, 0, 1)``.
    """
    T = as_pose(T_b_m, "T_b_m")
    return T[2, :3].copy()


@dataclass(frozen=True, slots=True)
class BoardView:
    """A board in the scene, as the camera backends see it.

    Attributes:
        board_id: integer id of the board (copied into its detections).
        layout: marker layout (ids and corners in the board frame M).
        T_w_m: 4x4 pose of the board frame M in the world W (m). Stored as a
            float array without copying; do not mutate it while the view is in use.
            The true pose: the backends use it to make the measurement only.
        up_m: world up ``z_W`` expressed in M (unit 3-vector) as the board's
            mount declares it (:func:`up_in_board`), not from the true pose: the
            prior the backends use to resolve the planar flip ambiguity
            (``CameraConfig.pose_disambiguation``). None (default): not known
            (the lower reprojection cost decides).
    """

    board_id: int
    layout: BoardLayout
    T_w_m: np.ndarray
    up_m: np.ndarray | None = None

    def __post_init__(self) -> None:
        # Written for speed (the simulator makes a view per board per frame): plain-float
        # checks instead of numpy calls, the same rejections as as_pose and all_finite.
        board_id = self.board_id
        if type(board_id) is not int:
            try:
                object.__setattr__(self, "board_id", operator.index(board_id))
            except TypeError:
                raise TypeError(f"board_id must be an integer, got {board_id!r}") from None
        if not isinstance(self.layout, BoardLayout):
            raise TypeError(f"layout must be a BoardLayout, got {type(self.layout).__name__}")
        T = self.T_w_m
        if type(T) is not np.ndarray or T.dtype.char != "d" or T.shape != (4, 4):
            T = as_pose(T, "T_w_m")
            object.__setattr__(self, "T_w_m", T)
        elif not math.isfinite(sum(T.ravel().tolist())):
            as_pose(T, "T_w_m")  # raises unless finite (an overflowing sum of finite values passes)
        up = self.up_m
        if up is not None:
            if type(up) is not np.ndarray or up.dtype.char != "d":
                up = np.asarray(up, dtype=float)
            if up.shape != (3,):
                raise ValueError(f"up_m must be a finite 3-vector, got {self.up_m!r}")
            x, y, z = up.tolist()
            if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)):
                raise ValueError(f"up_m must be a finite 3-vector, got {self.up_m!r}")
            norm_sq = x * x + y * y + z * z
            if abs(norm_sq - 1.0) > 1e-6:
                raise ValueError(f"up_m must be a unit vector, got norm {math.sqrt(norm_sq)!r}")
            up = up.copy()
            up.setflags(write=False)
            object.__setattr__(self, "up_m", up)

    @classmethod
    def trusted(cls, board_id: int, layout: BoardLayout, T_w_m: np.ndarray, up_m: np.ndarray | None = None) -> BoardView:
        """A view made without the constructor's checks, for a caller whose arguments are
        already in the form the constructor would store: ``board_id`` an ``int``, ``layout``
        a :class:`BoardLayout`, ``T_w_m`` a finite float64 (4, 4) array (m; kept, not copied)
        and ``up_m`` None or a finite float64 unit 3-vector that is read-only (kept, not
        copied). The simulator makes its views this way (a view per board per frame, of
        its own poses and of up vectors checked once by :func:`up_in_board`); anything else
        goes through ``BoardView(...)``, which checks and converts.
        """
        view = object.__new__(cls)
        # Frozen: set through the slots' own setters (what object.__setattr__ does, cheaper).
        _set_board_id(view, board_id)
        _set_layout(view, layout)
        _set_T_w_m(view, T_w_m)
        _set_up_m(view, up_m)
        return view


#: The setters of BoardView's slots, for BoardView.trusted.
_set_board_id = BoardView.board_id.__set__
_set_layout = BoardView.layout.__set__
_set_T_w_m = BoardView.T_w_m.__set__
_set_up_m = BoardView.up_m.__set__


@runtime_checkable
class CameraBackend(Protocol):
    """A camera that turns the true scene into board detections.

    Attributes:
        camera_id: name copied into every detection.
        camera: the intrinsic model (image size, K, distortion, limits).

    ``measure`` returns one :class:`Detection` per board it detects, in the order
    of ``boards``, each with ``T_c_m`` from solvePnP on the detected corners, the
    corners in pixels, the ids of the markers used, ``time`` and the RMS
    reprojection error. Boards with no detectable marker are left out. Every
    random draw comes from ``rng`` (same state, same scene -> same detections).
    ``occluded`` is an optional line-of-sight query (see :data:`OcclusionQuery`).
    """

    camera_id: str
    camera: PinholeCamera

    def measure(
        self,
        T_w_c: np.ndarray,
        boards: Sequence[BoardView],
        time: float,
        rng: np.random.Generator,
        occluded: OcclusionQuery | None = None,
    ) -> list[Detection]:
        """Detections of ``boards`` seen from the camera pose ``T_w_c`` (4x4, C in W) at ``time`` (s)."""
        ...

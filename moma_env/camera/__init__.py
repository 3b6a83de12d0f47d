"""Camera models: from the true scene to board detections.

* :class:`CameraConfig` -- intrinsics, distortion, pixel noise, visibility limits.
* :class:`PinholeCamera` -- projection with OpenCV distortion, undistortion,
  field of view, ground footprint.
* :func:`visible_markers` / :func:`marker_visibility` -- which markers a camera
  can detect (front, image, size, incidence, range, occlusion).
* :class:`CameraBackend` -- the interface of a backend; :class:`BoardView` -- a
  board in the scene; :class:`GeometricCamera` -- the fast geometric backend;
  :class:`RenderedCamera` -- the rendered backend (synthetic image, ArUco
  detector), with :class:`RenderConfig`; :func:`make_camera` builds either.
* :class:`FloorGrainConfig` -- the weak texture of a real floor (grain, seams, specks).
* :class:`FloorConfig` / :class:`FloorTexture` -- the floor's texture and its
  rendering; :class:`FloorCamera` -- a robot camera's floor frames (for VO).

Imports only geometry, config, markers and the estimator's Detection type (no
physics), so it can be used on its own.
"""

from moma_env.camera.backend import BoardView, CameraBackend, OcclusionQuery, up_in_board
from moma_env.camera.batch import MeasureRequest, measure_batch
from moma_env.camera.config import PNP_METHODS, PNP_SIGMA_SOURCES, POSE_DISAMBIGUATIONS, CameraConfig
from moma_env.camera.factory import CAMERA_BACKENDS, make_camera
from moma_env.camera.floor import FloorConfig, FloorTexture
from moma_env.camera.floor_grain import FloorGrainConfig
from moma_env.camera.floor_camera import FloorCamera
from moma_env.camera.geometric import GeometricCamera
from moma_env.camera.pinhole import PinholeCamera
from moma_env.camera.render_config import CORNER_REFINEMENTS, RenderConfig
from moma_env.camera.rendered import RenderedCamera
from moma_env.camera.visibility import apply_occlusion, marker_visibility, visible_markers

__all__ = [
    "MeasureRequest",
    "measure_batch",
    "BoardView",
    "CAMERA_BACKENDS",
    "CORNER_REFINEMENTS",
    "FloorCamera",
    "FloorConfig",
    "FloorGrainConfig",
    "FloorTexture",
    "RenderConfig",
    "RenderedCamera",
    "make_camera",
    "CameraBackend",
    "CameraConfig",
    "GeometricCamera",
    "OcclusionQuery",
    "PNP_METHODS",
    "PNP_SIGMA_SOURCES",
    "POSE_DISAMBIGUATIONS",
    "PinholeCamera",
    "apply_occlusion",
    "marker_visibility",
    "up_in_board",
    "visible_markers",
]

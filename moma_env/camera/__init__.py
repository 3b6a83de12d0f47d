"""Camera models: from the true scene to board detections.

* :class:`CameraConfig` -- intrinsics, distortion, pixel noise, visibility limits.
* :class:`PinholeCamera` -- projection with OpenCV distortion, undistortion,
  field of view, ground footprint.
* :func:`visible_markers` / :func:`marker_visibility` -- which markers a camera
  can detect (front, image, size, incidence, range, occlusion).
* :class:`CameraBackend` -- the interface of a backend; :class:`BoardView` -- a
  board in the scene; :class:`GeometricCamera` -- the fast geometric backend.

Imports only geometry, config, markers and the estimator's Detection type (no
physics), so it can be used on its own.
"""

from moma_env.camera.backend import BoardView, CameraBackend, OcclusionQuery
from moma_env.camera.config import PNP_METHODS, CameraConfig
from moma_env.camera.geometric import GeometricCamera
from moma_env.camera.pinhole import PinholeCamera
from moma_env.camera.visibility import apply_occlusion, marker_visibility, visible_markers

__all__ = [
    "BoardView",
    "CameraBackend",
    "CameraConfig",
    "GeometricCamera",
    "OcclusionQuery",
    "PNP_METHODS",
    "PinholeCamera",
    "apply_occlusion",
    "marker_visibility",
    "visible_markers",
]

"""One constructor for every camera backend, chosen by name (configuration)."""

from __future__ import annotations

from moma_env.camera.backend import CameraBackend
from moma_env.camera.config import CameraConfig
from moma_env.camera.floor import FloorTexture
from moma_env.camera.geometric import GeometricCamera
from moma_env.camera.render_config import RenderConfig
from moma_env.camera.rendered import RenderedCamera
from moma_env.config import ConfigError, check_choice

__all__ = ["CAMERA_BACKENDS", "make_camera"]

#: Names of the camera backends: ``geometric`` (projected corners, fast) and
#: ``rendered`` (synthetic image, ArUco detector).
CAMERA_BACKENDS = ("geometric", "rendered")


def make_camera(
    camera_id: str,
    config: CameraConfig,
    backend: str = "geometric",
    render: RenderConfig | None = None,
    floor: FloorTexture | None = None,
) -> CameraBackend:
    """A camera backend called ``camera_id`` with intrinsics ``config``.

    Args:
        camera_id: name copied into every detection.
        config: intrinsics, noise and visibility limits.
        backend: one of :data:`CAMERA_BACKENDS`.
        render: image formation of the rendered backend (its defaults if None).
        floor: floor texture of the rendered backend (a plain floor if None).

    ``render`` and ``floor`` are errors with the geometric backend (it draws no image).
    """
    check_choice("camera.backend", backend, CAMERA_BACKENDS)
    if backend == "geometric":
        if render is not None:
            raise ConfigError("camera.render", "only the rendered backend renders; got a RenderConfig with 'geometric'")
        if floor is not None:
            raise ConfigError("camera.floor", "only the rendered backend draws a floor; got a FloorTexture with 'geometric'")
        return GeometricCamera(camera_id, config)
    return RenderedCamera(camera_id, config, render, floor)

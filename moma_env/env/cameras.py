"""The environment's cameras: one backend per camera of the scenario, as the config chooses.

The rendered backend shares one :class:`FloorTexture` among the cameras of an
environment; it is rebuilt only when its configuration changes (e.g. a random
scenario with another arena and no explicit floor).
"""

from __future__ import annotations

from collections.abc import Iterable

from moma_env.camera import CameraBackend, CameraConfig, FloorConfig, FloorTexture, make_camera
from moma_env.env.config import EnvConfig

__all__ = ["FLOOR_MARGIN_M", "build_cameras", "floor_for"]

#: Margin (m) of the default floor texture around the arena.
FLOOR_MARGIN_M = 1.0


def floor_for(
    config: EnvConfig, arena_bounds: tuple[float, float, float, float], previous: FloorTexture | None
) -> FloorTexture | None:
    """The floor texture of the rendered backend (None for the geometric one).

    ``config.floor``, or the arena ``(xmin, ymin, xmax, ymax)`` (m) grown by
    :data:`FLOOR_MARGIN_M` and textured all over; ``previous`` is reused when
    its configuration is the one wanted.
    """
    if config.camera_backend != "rendered":
        return None
    wanted = config.floor
    if wanted is None:
        x0, y0, x1, y1 = arena_bounds
        m = FLOOR_MARGIN_M
        wanted = FloorConfig(extent=(x0 - m, y0 - m, x1 + m, y1 + m))
    if previous is not None and previous.config == wanted:
        return previous
    return FloorTexture(wanted)


def build_cameras(
    names: Iterable[str], camera: CameraConfig, config: EnvConfig, floor: FloorTexture | None
) -> dict[str, CameraBackend]:
    """A backend per camera name, all with intrinsics ``camera``, of ``config.camera_backend``."""
    if config.camera_backend == "geometric":
        return {name: make_camera(name, camera) for name in names}
    return {name: make_camera(name, camera, "rendered", config.render, floor) for name in names}

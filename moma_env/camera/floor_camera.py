"""A robot-mounted camera's view of the floor: the frames the visual odometry runs on.

The simulator side of the VO baseline (:mod:`moma_env.odometry.visual`): given
the robot's true pose, :class:`FloorCamera` renders what its camera sees of the
floor texture, through the same image formation as the rendered backend (lens,
blur, noise, optional interlacing), so the VO gets a real camera's frames.
"""

from __future__ import annotations

import numpy as np

from moma_env.camera.config import CameraConfig
from moma_env.camera.floor import FloorTexture
from moma_env.camera.render_config import RenderConfig
from moma_env.camera.rendered import RenderedCamera
from moma_env.config import check_rigid_transform

__all__ = ["FloorCamera"]


class FloorCamera:
    """Floor frames of a camera mounted on a robot.

    Args:
        config: the camera's intrinsics.
        T_b_c: 4x4 pose of the camera frame C in the robot body frame B
            (body origin on the floor, z up).
        floor: the floor texture.
        render: image formation (the rendered backend's defaults if None).

    Attributes:
        camera: the intrinsic model (a :class:`PinholeCamera`).
        T_b_c: the mount (read-only copy).
    """

    def __init__(self, config: CameraConfig, T_b_c: np.ndarray, floor: FloorTexture, render: RenderConfig | None = None):
        if not isinstance(floor, FloorTexture):
            raise TypeError(f"floor must be a FloorTexture, got {type(floor).__name__}")
        self.T_b_c = check_rigid_transform("floor_camera.T_b_c", T_b_c)
        self.T_b_c.setflags(write=False)
        self._renderer = RenderedCamera("floor_camera", config, render, floor)
        self.camera = self._renderer.camera

    def frame(self, T_w_b: np.ndarray, rng: np.random.Generator, time: float | None = None) -> np.ndarray:
        """The camera's image (uint8, (height, width)) with the robot at ``T_w_b`` (4x4, B in W).

        ``time`` (s) is needed only for interlacing; ``rng`` draws the sensor noise.
        """
        return self._renderer.render(np.asarray(T_w_b, dtype=float) @ self.T_b_c, (), rng, time=time)

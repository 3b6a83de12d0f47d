"""Rigid mounts of boards and cameras on a body: 4x4 ``T_b_m`` / ``T_b_c``.

The body frame B follows ``moma_env.geometry``: origin on the floor at the robot's
centre (for the UAV: at its centre of mass), x forward, y left, z up; metres.
The mounted frame is a board frame M (face-up, on the robot's back, or on a
body's front such as a sled's) or an OpenCV camera frame C (looking down,
forward or backward); see the ``R_BODY_*`` constants.
"""

from __future__ import annotations

import numpy as np

from moma_env.config import check_finite, check_non_negative, check_rigid_transform
from moma_env.geometry import (
    R_BODY_BOARD_BACK,
    R_BODY_BOARD_FRONT,
    R_BODY_BOARD_UP,
    R_BODY_CAM_BACKWARD,
    R_BODY_CAM_DOWN,
    R_BODY_CAM_FORWARD,
    make_transform,
)

__all__ = [
    "board_on_top",
    "board_on_back",
    "board_on_front",
    "camera_forward",
    "camera_backward",
    "camera_down",
    "rigid_transform",
]


def _mount(
    what: str, R: np.ndarray, direction: float, offset: float, height: float, *, offset_sign_free: bool = True
) -> np.ndarray:
    """A mount ``offset`` m along ``direction`` * x_B and ``height`` m above the floor, validated."""
    check_non_negative(f"{what}.height", height)
    (check_finite if offset_sign_free else check_non_negative)(f"{what}.offset", offset)
    return make_transform(R, (direction * float(offset), 0.0, float(height)))


def board_on_top(height: float = 0.40) -> np.ndarray:
    """``T_b_m`` of a board lying face-up, centred on the robot, ``height`` m above the floor."""
    check_non_negative("board_on_top.height", height)
    return make_transform(R_BODY_BOARD_UP, (0.0, 0.0, float(height)))


def board_on_back(height: float = 0.30, offset: float = 0.23) -> np.ndarray:
    """``T_b_m`` of a vertical board on the robot's back, its printed face looking backward.

    Args:
        height: height of the board centre above the floor (m).
        offset: distance of the board face behind the body origin (m), along -x_B.
    """
    return _mount("board_on_back", R_BODY_BOARD_BACK, -1.0, offset, height, offset_sign_free=False)


def board_on_front(height: float = 0.25, offset: float = 0.15) -> np.ndarray:
    """``T_b_m`` of a vertical board on a body's front (a sled's), its printed face looking forward.

    Args:
        height: height of the board centre above the floor (m).
        offset: distance of the board face ahead of the body origin (m), along +x_B.
    """
    return _mount("board_on_front", R_BODY_BOARD_FRONT, 1.0, offset, height, offset_sign_free=False)


def camera_forward(height: float = 0.30, offset: float = 0.23) -> np.ndarray:
    """``T_b_c`` of a forward-looking camera (optical axis +x_B).

    Args:
        height: height of the optical centre above the floor (m).
        offset: distance of the optical centre ahead of the body origin (m), along +x_B.
    """
    return _mount("camera_forward", R_BODY_CAM_FORWARD, 1.0, offset, height)


def camera_backward(height: float = 0.30, offset: float = 0.23) -> np.ndarray:
    """``T_b_c`` of a backward-looking camera (optical axis -x_B), e.g. towards a towed sled.

    Args:
        height: height of the optical centre above the floor (m).
        offset: distance of the optical centre behind the body origin (m), along -x_B.
    """
    return _mount("camera_backward", R_BODY_CAM_BACKWARD, -1.0, offset, height)


def camera_down(height: float = -0.05, offset: float = 0.0) -> np.ndarray:
    """``T_b_c`` of a downward-looking camera (optical axis -z_B, image top forward).

    Args:
        height: z of the optical centre in B (m); the UAV default -0.05 puts it
            5 cm below the UAV's centre.
        offset: distance of the optical centre ahead of the body origin (m).
    """
    check_finite("camera_down.height", height)
    check_finite("camera_down.offset", offset)
    return make_transform(R_BODY_CAM_DOWN, (float(offset), 0.0, float(height)))


def rigid_transform(field: str, value: object) -> np.ndarray:
    """Validate a 4x4 rigid transform (``config.check_rigid_transform``) and return it read-only."""
    T = check_rigid_transform(field, value)
    T.setflags(write=False)
    return T

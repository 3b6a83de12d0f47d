"""The observer's image as an observation: its latest camera frame, downscaled, uint8.

With ``EnvConfig.observer_image = (width, height)`` the observer observes a
``Dict``: ``"features"``, its usual vector (:mod:`moma_env.env.observations`),
and ``"image"``, ``Box(0, 255, (height, width, 1), uint8)``: the rendered
camera's latest frame (after noise) averaged down (``cv2.INTER_AREA``), in the
channel-last layout image policies (e.g. SB3's ``MultiInputPolicy``) expect.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import cv2
import numpy as np
from gymnasium import spaces

__all__ = ["image_space", "observation_spaces", "observer_observation"]


def image_space(size: tuple[int, int]) -> spaces.Box:
    """``Box(0, 255, (height, width, 1), uint8)`` for ``size = (width, height)``."""
    width, height = size
    return spaces.Box(0, 255, shape=(height, width, 1), dtype=np.uint8)


def observation_spaces(
    vector_spaces: Mapping[str, spaces.Space], observers: Sequence[str], size: tuple[int, int] | None
) -> dict[str, spaces.Space]:
    """Every agent's observation space: the vector spaces, each observer's in a Dict with its image if ``size``."""
    out = dict(vector_spaces)
    if size is not None:
        for observer in observers:
            out[observer] = spaces.Dict({"features": out[observer], "image": image_space(size)})
    return out


def observer_observation(features: np.ndarray, image: np.ndarray | None, size: tuple[int, int] | None):
    """``features`` unchanged if ``size`` is None, else ``{"features", "image"}`` with ``image``
    (the camera's uint8 frame, (H, W)) resized to ``size = (width, height)``; a black image if there is none."""
    if size is None:
        return features
    width, height = size
    if image is None:
        small = np.zeros((height, width), dtype=np.uint8)
    else:
        small = cv2.resize(image, (width, height), interpolation=cv2.INTER_AREA)
    return {"features": features, "image": small.reshape(height, width, 1)}

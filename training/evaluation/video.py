"""Animated GIF of rendered frames (like Gymnasium's RecordVideo, for one episode).

:class:`GifRecorder` is a frame sink: it keeps every ``stride``-th frame,
downscaled to at most ``max_width`` pixels and reduced to a 256-colour palette
(about 0.1 MB per 320x320 frame), and :meth:`GifRecorder.write` saves them with
Pillow (shipped with matplotlib), atomically.
"""

from __future__ import annotations

import os

import numpy as np
from PIL import Image

from moma_env.io import atomic_path

__all__ = ["GifRecorder"]


class GifRecorder:
    """Collects ``(H, W, 3) uint8`` frames and writes them as an animated GIF.

    Args:
        fps: frame rate of the source frames (Hz), e.g. the env's ``render_fps``.
        stride: keep one frame in ``stride`` (the GIF plays at ``fps / stride``).
        max_width: frames wider than this (px) are downscaled, aspect kept.
    """

    def __init__(self, fps: float, stride: int = 2, max_width: int = 320):
        if not fps > 0:
            raise ValueError(f"fps must be > 0, got {fps!r}")
        if isinstance(stride, bool) or not isinstance(stride, int) or stride < 1:
            raise ValueError(f"stride must be an integer >= 1, got {stride!r}")
        if isinstance(max_width, bool) or not isinstance(max_width, int) or max_width < 16:
            raise ValueError(f"max_width must be an integer >= 16, got {max_width!r}")
        self.fps = float(fps)
        self.stride = stride
        self.max_width = max_width
        self._frames: list[Image.Image] = []
        self._seen = 0

    def __len__(self) -> int:
        return len(self._frames)

    def __call__(self, frame: np.ndarray) -> None:
        """Offer one frame (kept if it falls on the stride)."""
        k = self._seen
        self._seen += 1
        if k % self.stride:
            return
        a = np.asarray(frame)
        if a.ndim != 3 or a.shape[2] != 3 or a.dtype != np.uint8:
            raise ValueError(f"frames must be (H, W, 3) uint8 arrays, got {a.shape} {a.dtype}")
        image = Image.fromarray(a)
        if image.width > self.max_width:
            height = max(1, round(image.height * self.max_width / image.width))
            image = image.resize((self.max_width, height), Image.Resampling.BILINEAR)
        self._frames.append(image.quantize(colors=256, method=Image.Quantize.MEDIANCUT))

    def write(self, path: str | os.PathLike[str]) -> None:
        """Save the kept frames as a looping GIF at ``path`` (written whole or not at all).

        Raises:
            ValueError: no frame was recorded.
        """
        if not self._frames:
            raise ValueError("no frames recorded: nothing to write")
        duration_ms = max(20, round(1000.0 * self.stride / self.fps))
        first, *rest = self._frames
        with atomic_path(path) as tmp:
            first.save(tmp, format="GIF", save_all=True, append_images=rest, duration=duration_ms, loop=0)

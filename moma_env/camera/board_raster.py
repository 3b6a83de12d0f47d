"""A printed ArUco board as an image: markers from ``cv2.aruco`` on white paper.

:class:`BoardRaster` draws a :class:`~moma_env.markers.BoardLayout` once: each
marker is ``cv2.aruco.generateImageMarker`` of its id (one black border bit),
placed at its corners in the board frame M, on white paper that extends a quiet
zone beyond the outer markers. A pyramid of halved copies lets the renderer
sample a level no finer than needed (no aliasing of far boards).

Board frame M (see :mod:`moma_env.markers`): origin at the board centre, x right
and y up on the printed face; metres. Raster pixel ``(col, row)`` is centred on
``x = -W/2 + (col + 0.5) / px_per_m``, ``y = H/2 - (row + 0.5) / px_per_m``
with ``W, H`` the paper's size.
"""

from __future__ import annotations

import cv2
import numpy as np

from moma_env.markers import BoardLayout

__all__ = ["BoardRaster", "aruco_dictionary"]

#: Smallest side (px) of a pyramid level.
_MIN_LEVEL_PX = 8


def aruco_dictionary(name: str) -> cv2.aruco.Dictionary:
    """The ``cv2.aruco`` predefined dictionary called ``name`` (e.g. ``"DICT_4X4_50"``)."""
    return cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, name))


class BoardRaster:
    """The image of one printed board, with its pyramid and its outline.

    Args:
        layout: marker ids and geometry.
        quiet_zone_m: white margin around the outer markers (m).
        bit_px: raster pixels per marker bit at the finest level.
        white, black: gray levels (0-255) of the paper and of the ink.

    Attributes:
        layout: the layout.
        px_per_m: resolution of the finest level (px/m).
        levels: list of ``(image, A_px_m)``: uint8 images, finest first, each
            with the 3x3 affine map from board ``(x, y, 1)`` (m) to its pixels.
        outline_m: (n, 3) points along the paper's border in M (m), to bound
            the board's image.
        next_index: ``outline_m[next_index]`` is the outline shifted by one point (cyclic).
        area_m2: area of the outline's bounding box (m^2), the paper's area.

    Markers are placed at their layout position rounded to the raster grid:
    exact when the gaps and the quiet zone are whole multiples of a raster
    pixel (the default 16 cm markers, 2 cm gaps and quiet zone with 16 px per
    bit: 600 px/m), otherwise within half a pixel (< 1 mm).
    """

    def __init__(self, layout: BoardLayout, quiet_zone_m: float, bit_px: int, white: int, black: int) -> None:
        if not isinstance(layout, BoardLayout):
            raise TypeError(f"layout must be a BoardLayout, got {type(layout).__name__}")
        self.layout = layout
        dictionary = aruco_dictionary(layout.dictionary)
        marker_px = (dictionary.markerSize + 2) * int(bit_px)
        ppm = marker_px / layout.marker_size
        self.px_per_m = ppm
        width_m = layout.width + 2.0 * quiet_zone_m
        height_m = layout.height + 2.0 * quiet_zone_m
        cols, rows = int(round(width_m * ppm)), int(round(height_m * ppm))
        image = np.full((rows, cols), white, dtype=np.uint8)
        ink = np.array([black, white], dtype=np.uint8)
        for marker_id, corners in zip(layout.marker_ids, layout.marker_corners):
            left, top = corners[0, 0], corners[0, 1]
            col = int(round((left + width_m / 2.0) * ppm))
            row = int(round((height_m / 2.0 - top) * ppm))
            marker = cv2.aruco.generateImageMarker(dictionary, marker_id, marker_px, borderBits=1)
            image[row : row + marker_px, col : col + marker_px] = ink[(marker > 127).astype(np.intp)]
        A = np.array([[ppm, 0.0, width_m / 2.0 * ppm - 0.5], [0.0, -ppm, height_m / 2.0 * ppm - 0.5], [0.0, 0.0, 1.0]])
        self.levels = [(image, A)]
        half = np.diag([0.5, 0.5, 1.0])  # pyrDown: pixel c of the coarser level sits on 2c of the finer one
        while min(image.shape) // 2 >= _MIN_LEVEL_PX:
            image = cv2.pyrDown(image)
            A = half @ A
            self.levels.append((image, A))
        for image, A in self.levels:
            image.setflags(write=False)
            A.setflags(write=False)
        t = np.linspace(0.0, 1.0, 8, endpoint=False)
        hw, hh = width_m / 2.0, height_m / 2.0
        box = np.array([[-hw, hh], [hw, hh], [hw, -hh], [-hw, -hh]])
        edges = np.concatenate([box[k] + t[:, None] * (box[(k + 1) % 4] - box[k]) for k in range(4)])
        self.outline_m = np.column_stack([edges, np.zeros(len(edges))])
        self.outline_m.setflags(write=False)
        extent = self.outline_m[:, :2].max(axis=0) - self.outline_m[:, :2].min(axis=0)
        self.area_m2 = float(extent[0] * extent[1])
        self.next_index = np.roll(np.arange(len(self.outline_m)), -1)

    def level_for(self, image_px_per_m: float) -> tuple[np.ndarray, np.ndarray]:
        """The coarsest level still at least as fine as ``image_px_per_m`` (the board's
        scale in the camera image), or the finest one."""
        chosen = self.levels[0]
        for level in self.levels[1:]:
            if level[1][0, 0] < image_px_per_m:  # A[0, 0] is the level's px/m
                break
            chosen = level
        return chosen

"""ArUco board layouts: marker ids and corner coordinates in the board frame M.

Board frame M (OpenCV ArUco object frame): origin at the centre of the board,
x to the right and y up on the printed face, z out of the printed face; metres.
Corners of every marker are listed in ArUco order: top-left, top-right,
bottom-right, bottom-left (as seen looking at the printed face). Markers are laid
out row by row from the top-left of the grid.

This module is pure geometry: the simulator's camera projects these points and a
real camera pipeline would feed them to solvePnP.
"""

from __future__ import annotations

import numbers
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np

from moma_env.config import ConfigError, check_choice, check_non_negative, check_positive, check_unique

__all__ = [
    "BoardLayout",
    "ARUCO_DICTIONARIES",
    "TEAM_DICTIONARIES",
    "MARKERS_PER_BOARD",
    "MAX_TEAM_BOARDS",
    "board_for_robot",
    "team_dictionary",
]

#: Names of the cv2.aruco predefined dictionaries a layout may use, with the number
#: of markers each holds (read-only).
ARUCO_DICTIONARIES: Mapping[str, int] = MappingProxyType(
    {
        "DICT_4X4_50": 50,
        "DICT_4X4_100": 100,
        "DICT_4X4_250": 250,
        "DICT_4X4_1000": 1000,
        "DICT_5X5_100": 100,
        "DICT_6X6_250": 250,
        "DICT_ARUCO_ORIGINAL": 1024,
    }
)
#: The dictionaries a team's boards are printed from, smallest first; the team uses
#: the first that holds every id (:func:`team_dictionary`). In OpenCV each of these
#: 4x4-bit dictionaries starts with the markers of the smaller ones (id k is the same
#: pattern in all of them), so a team must not mix them.
TEAM_DICTIONARIES = ("DICT_4X4_50", "DICT_4X4_100", "DICT_4X4_250", "DICT_4X4_1000")
#: Markers on one robot's default board (a 2x2 grid; ids ``4k .. 4k+3`` on robot k).
MARKERS_PER_BOARD = 4
#: Most boards of :func:`board_for_robot` with distinct ids: the largest team dictionary's
#: markers, :data:`MARKERS_PER_BOARD` a board (250).
MAX_TEAM_BOARDS = ARUCO_DICTIONARIES[TEAM_DICTIONARIES[-1]] // MARKERS_PER_BOARD


@dataclass(frozen=True)
class BoardLayout:
    """A planar grid of square ArUco markers.

    Attributes:
        marker_ids: ids of the markers, row by row from the top-left.
        rows, cols: grid size.
        marker_size: side of one marker's black square (m).
        gap: distance between neighbouring markers (m).
        dictionary: name of the cv2.aruco predefined dictionary.
    """

    marker_ids: tuple[int, ...] = (0, 1, 2, 3)
    rows: int = 2
    cols: int = 2
    marker_size: float = 0.16
    gap: float = 0.02
    dictionary: str = "DICT_4X4_50"
    _points: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        check_positive("board.rows", self.rows)
        check_positive("board.cols", self.cols)
        check_positive("board.marker_size", self.marker_size)
        check_non_negative("board.gap", self.gap)
        check_choice("board.dictionary", self.dictionary, ARUCO_DICTIONARIES)
        object.__setattr__(self, "marker_ids", tuple(int(i) for i in self.marker_ids))
        if len(self.marker_ids) != self.rows * self.cols:
            raise ConfigError(
                "board.marker_ids",
                f"needs rows*cols = {self.rows * self.cols} ids, got {len(self.marker_ids)}",
            )
        check_unique("board.marker_ids", self.marker_ids)
        limit = ARUCO_DICTIONARIES[self.dictionary]
        for i in self.marker_ids:
            if not 0 <= i < limit:
                raise ConfigError("board.marker_ids", f"id {i} outside {self.dictionary} (0..{limit - 1})")
        object.__setattr__(self, "_points", self._make_points())

    @property
    def width(self) -> float:
        """Overall width of the grid (m), x extent."""
        return self.cols * self.marker_size + (self.cols - 1) * self.gap

    @property
    def height(self) -> float:
        """Overall height of the grid (m), y extent."""
        return self.rows * self.marker_size + (self.rows - 1) * self.gap

    def _make_points(self) -> np.ndarray:
        s, g = self.marker_size, self.gap
        x0, y0 = -self.width / 2.0, self.height / 2.0
        pts = np.empty((self.rows * self.cols, 4, 3))
        for k in range(self.rows * self.cols):
            r, c = divmod(k, self.cols)
            left = x0 + c * (s + g)
            top = y0 - r * (s + g)
            pts[k] = [[left, top, 0.0], [left + s, top, 0.0], [left + s, top - s, 0.0], [left, top - s, 0.0]]
        pts.setflags(write=False)
        return pts

    @property
    def marker_corners(self) -> np.ndarray:
        """Read-only array (n_markers, 4, 3): corners of each marker in M (m)."""
        return self._points

    def object_points(self, marker_mask: np.ndarray | None = None) -> np.ndarray:
        """Corners in M as an (4k, 3) array, for the markers selected by ``marker_mask``."""
        pts = self._points if marker_mask is None else self._points[np.asarray(marker_mask, dtype=bool)]
        return pts.reshape(-1, 3).copy()


def board_for_robot(index: int, *, markers_per_board: int = MARKERS_PER_BOARD, **layout: object) -> BoardLayout:
    """Default layout of robot ``index``: ids ``4*index .. 4*index+3`` (DESIGN.md).

    ``layout`` sets other :class:`BoardLayout` fields, e.g. ``dictionary=team_dictionary(n)``
    for a team of ``n`` boards.
    """
    first = markers_per_board * index
    return BoardLayout(marker_ids=tuple(range(first, first + markers_per_board)), **layout)  # type: ignore[arg-type]


def team_dictionary(n_boards: int) -> str:
    """The dictionary of a team whose boards are ``board_for_robot(0 .. n_boards - 1)``.

    The first of :data:`TEAM_DICTIONARIES` holding the ``MARKERS_PER_BOARD * n_boards``
    ids: ``"DICT_4X4_50"`` up to 12 boards, then ``"DICT_4X4_100"`` (25),
    ``"DICT_4X4_250"`` (62) and ``"DICT_4X4_1000"`` (:data:`MAX_TEAM_BOARDS`, 250).

    Raises:
        ValueError: if ``n_boards`` is not an integer in ``[0, MAX_TEAM_BOARDS]``.
    """
    if isinstance(n_boards, bool) or not isinstance(n_boards, numbers.Integral) or n_boards < 0:
        raise ValueError(f"n_boards must be an integer >= 0, got {n_boards!r}")
    needed = MARKERS_PER_BOARD * n_boards
    for name in TEAM_DICTIONARIES:
        if needed <= ARUCO_DICTIONARIES[name]:
            return name
    raise ValueError(
        f"{n_boards} boards need {needed} marker ids; the largest team dictionary {TEAM_DICTIONARIES[-1]} "
        f"holds {ARUCO_DICTIONARIES[TEAM_DICTIONARIES[-1]]} (at most {MAX_TEAM_BOARDS} boards)"
    )

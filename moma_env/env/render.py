"""Images for ``render_mode="rgb_array"``: a top-down map and the camera's view.

Pure functions on plain data; nothing here knows about PettingZoo, pymunk or the
estimator's internals. The environment fills a :class:`SceneView` (and, for the
inset, hands over its camera, camera pose and :class:`~moma_env.camera.BoardView`
list) and gets ``(H, W, 3)`` uint8 RGB arrays back.

* :func:`render_top_down` -- the arena seen from above: world x to the right,
  world y up (image rows are flipped), the arena letterboxed into the image with
  its aspect ratio kept. Truth is drawn as filled shapes with a white heading
  line (static robots slate grey, mobile robots blue); the estimate as an outline
  with its own heading line, coloured by status (green localised, orange holding,
  red lost; nothing without an estimate). Goals are crosses with a heading tick,
  what the cameras see of the floor translucent blue polygons (overlaps filled
  once), the observer a quadrotor marker
  (truth) and a cyan square (estimate); a legend and an info block in the corners.
* :func:`render_camera_view` -- a synthetic image of what a camera sees: grey
  floor, white board plates with black marker squares (projected through the
  lens distortion), a green outline on detected boards, a dark image border.
* :func:`compose` -- paste a (camera) inset into a corner of the top-down image.

All drawing uses OpenCV with anti-aliasing and 4-bit sub-pixel coordinates: a
640x640 top-down frame costs about 1.5 ms, a camera view about 0.4 ms, and moving
objects move smoothly (no pixel snapping) in videos.
Pixel convention (OpenCV): pixel centres at integer ``(u, v)``, ``u`` right,
``v`` down.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType

import cv2
import numpy as np

from moma_env.camera.backend import BoardView, as_pose
from moma_env.camera.pinhole import PinholeCamera
from moma_env.estimator.results import Status
from moma_env.geometry import invert
from moma_env.markers import BoardLayout

__all__ = [
    "RobotView",
    "SceneView",
    "TopDownMapping",
    "ROBOT_STATUSES",
    "ROBOT_SHAPES",
    "INSET_CORNERS",
    "STATUS_COLOURS",
    "DETECTED_COLOUR",
    "render_top_down",
    "render_camera_view",
    "inset_size",
    "compose",
]

#: Estimator statuses a :class:`RobotView` may carry (``Status`` values).
ROBOT_STATUSES = ("localised", "holding", "lost")
#: Outlines a robot may be drawn with.
ROBOT_SHAPES = ("disk", "box")
#: Corners :func:`compose` can place an inset in.
INSET_CORNERS = ("top-left", "top-right", "bottom-left", "bottom-right")
#: RGB colour of a robot's estimate outline, by status.
STATUS_COLOURS = MappingProxyType({"localised": (0, 170, 0), "holding": (255, 140, 0), "lost": (225, 30, 30)})
#: RGB colour of the outline of a detected board in :func:`render_camera_view`.
DETECTED_COLOUR = (0, 200, 0)

# ----------------------------------------------------------------------- style
# Colours are RGB (the arrays are RGB; OpenCV does not care about channel order).
_OUTSIDE = (46, 48, 56)
_FLOOR = (236, 236, 230)
_GRID = (214, 214, 208)
_WALL = (70, 70, 76)
_OBSTACLE = (104, 104, 116)
_FOOTPRINT = (60, 140, 255)
_FOOTPRINT_ALPHA = 0.22
_ROPE = (150, 95, 40)
_GOAL = (200, 0, 200)
_STATIC_TRUTH = (96, 104, 128)
_MOBILE_TRUTH = (30, 110, 230)
_HEADING_TRUTH = (255, 255, 255)
_BOARD_OUTLINE = (25, 25, 25)
_LABEL = (30, 30, 35)
_OBSERVER_TRUE = (25, 25, 25)
_OBSERVER_EST = (0, 170, 200)
_PANEL_TEXT = (245, 245, 245)

_CAM_FLOOR = (128, 128, 128)
_CAM_PLATE = (255, 255, 255)
_CAM_MARKER = (0, 0, 0)
_CAM_BORDER = (25, 25, 25)

_FONT = cv2.FONT_HERSHEY_SIMPLEX
_SHIFT = 4  # sub-pixel bits of OpenCV's fixed-point drawing coordinates
_ONE = 1 << _SHIFT
#: Pixel coordinates are clipped to this many image sizes around the image before
#: the fixed-point conversion (keeps int32 safe for objects far off-screen).
_CLIP_IMAGES = 8.0
#: Grid spacings (m) the top-down floor grid may use; the first giving >= 40 px.
_GRID_STEPS_M = (0.1, 0.2, 0.25, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0)
_GRID_MIN_PX = 40.0
#: Camera view: points along each edge of a marker or plate outline (the edges of
#: a square bend under lens distortion), and the nearest depth drawn (m).
_EDGE_SAMPLES = 4
_NEAR_M = 0.01


# ------------------------------------------------------------------ validation
def _check_size(size: object, name: str = "size") -> tuple[int, int]:
    """``(width, height)`` as two positive ints; ValueError otherwise."""
    try:
        w, h = size  # type: ignore[misc]
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a (width, height) pair of positive integers, got {size!r}") from None
    for v in (w, h):
        if isinstance(v, (bool, np.bool_)) or not isinstance(v, numbers.Integral) or v <= 0:
            raise ValueError(f"{name} must be a (width, height) pair of positive integers, got {size!r}")
    return int(w), int(h)


def _floats(name: str, value: object, n: int) -> tuple[float, ...]:
    """``value`` as a tuple of ``n`` finite floats; ValueError naming ``name`` otherwise."""
    try:
        out = tuple(float(v) for v in value)  # type: ignore[union-attr]
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be {n} finite numbers, got {value!r}") from None
    if len(out) != n or not all(math.isfinite(v) for v in out):
        raise ValueError(f"{name} must be {n} finite numbers, got {value!r}")
    return out


def _points(name: str, value: object, min_rows: int, allow_nan: bool = False) -> np.ndarray:
    """``value`` as a read-only float ``(k, 2)`` array with ``k >= min_rows``."""
    try:
        a = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a (k, 2) array of world xy (m), got {value!r}") from None
    if a.ndim != 2 or a.shape[1] != 2 or a.shape[0] < min_rows:
        raise ValueError(f"{name} must be a (k, 2) array with k >= {min_rows}, got shape {a.shape}")
    bad = np.isinf(a) if allow_nan else ~np.isfinite(a)
    if bad.any():
        raise ValueError(f"{name} must be {'NaN or finite' if allow_nan else 'finite'}, got {a.tolist()}")
    a.setflags(write=False)
    return a


# ------------------------------------------------------------------ scene data
@dataclass(frozen=True, eq=False, slots=True)
class RobotView:
    """One UGV or sled as the top-down renderer draws it (world frame W, metres, radians).

    Attributes:
        name: label drawn next to the robot.
        true_pose: true ``(x, y, yaw)``.
        est_pose: estimated ``(x, y, yaw)``, or None (no estimate: nothing drawn).
        radius: radius of the disk (m); for a box, used only to place the label.
        static: True if the robot is (declared) static; selects the truth colour.
        status: ``"localised"``, ``"holding"`` or ``"lost"`` (or an estimator
            :class:`~moma_env.estimator.results.Status`); colours the estimate.
        shape: ``"disk"`` or ``"box"``.
        size: ``(length, width)`` (m) of a box along body x and y; required for
            boxes, ignored for disks.
        board_corners_w: ``(k, 2)`` world xy (m) of the board's outline on the
            robot, drawn as a closed polyline, or None.
    """

    name: str
    true_pose: tuple[float, float, float]
    est_pose: tuple[float, float, float] | None
    radius: float
    static: bool
    status: str
    shape: str = "disk"
    size: tuple[float, float] | None = None
    board_corners_w: np.ndarray | None = None

    def __post_init__(self) -> None:
        who = f"robot {self.name!r}"
        object.__setattr__(self, "true_pose", _floats(f"{who}.true_pose", self.true_pose, 3))
        if self.est_pose is not None:
            object.__setattr__(self, "est_pose", _floats(f"{who}.est_pose", self.est_pose, 3))
        r = _floats(f"{who}.radius", (self.radius,), 1)[0]
        if r <= 0.0:
            raise ValueError(f"{who}.radius must be > 0 m, got {self.radius!r}")
        object.__setattr__(self, "radius", r)
        object.__setattr__(self, "static", bool(self.static))
        status = self.status.value if isinstance(self.status, Status) else self.status
        if status not in ROBOT_STATUSES:
            raise ValueError(f"{who}.status must be one of {ROBOT_STATUSES}, got {self.status!r}")
        object.__setattr__(self, "status", status)
        if self.shape not in ROBOT_SHAPES:
            raise ValueError(f"{who}.shape must be one of {ROBOT_SHAPES}, got {self.shape!r}")
        if self.shape == "box":
            if self.size is None:
                raise ValueError(f"{who}.size (length, width) is required for a box")
            size = _floats(f"{who}.size", self.size, 2)
            if min(size) <= 0.0:
                raise ValueError(f"{who}.size must be positive, got {self.size!r}")
            object.__setattr__(self, "size", size)
        if self.board_corners_w is not None:
            object.__setattr__(
                self, "board_corners_w", _points(f"{who}.board_corners_w", self.board_corners_w, 2)
            )


@dataclass(frozen=True, eq=False, slots=True)
class SceneView:
    """Everything the top-down renderer draws, in the world frame W (metres, radians).

    Attributes:
        bounds: ``(xmin, ymin, xmax, ymax)`` of the arena interior (m).
        obstacles: world-xy polygons ``(k, 2)``, ``k >= 3`` (usually boxes, ``k = 4``).
        robots: the UGVs and sleds.
        goals: robot name -> goal ``(x, y, yaw)``.
        observer_true: the observer's true ``(x, y, yaw, altitude)``, or None.
        observer_est: the observer's estimated ``(x, y, yaw)``, or None.
        more_observers: further observers (a team watched by several), each
            ``(true (x, y, yaw, altitude), estimated (x, y, yaw) or None)``, drawn alike.
        footprints: what each camera sees of the floor, ``(k, 2)`` world-xy polygons
            (a downward camera's footprint, a forward camera's field of view up to
            its range); NaN rows (rays above the horizon) are dropped and a polygon
            with fewer than 3 finite rows is not drawn.
        ropes: sled ropes as ``((x0, y0), (x1, y1))`` segments.
        time: simulation time (s), shown in the info block.
        info_lines: further lines of the info block (step, switches, ...).
    """

    bounds: tuple[float, float, float, float]
    obstacles: tuple[np.ndarray, ...] = ()
    robots: tuple[RobotView, ...] = ()
    goals: Mapping[str, tuple[float, float, float]] = field(default_factory=dict)
    observer_true: tuple[float, float, float, float] | None = None
    observer_est: tuple[float, float, float] | None = None
    more_observers: tuple[tuple[tuple[float, float, float, float], tuple[float, float, float] | None], ...] = ()
    footprints: tuple[np.ndarray, ...] = ()
    ropes: tuple[tuple[tuple[float, float], tuple[float, float]], ...] = ()
    time: float = 0.0
    info_lines: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        xmin, ymin, xmax, ymax = _floats("scene.bounds", self.bounds, 4)
        if not (xmin < xmax and ymin < ymax):
            raise ValueError(f"scene.bounds must be (xmin, ymin, xmax, ymax) with xmin < xmax, ymin < ymax, "
                             f"got {self.bounds!r}")
        object.__setattr__(self, "bounds", (xmin, ymin, xmax, ymax))
        object.__setattr__(
            self, "obstacles", tuple(_points(f"scene.obstacles[{i}]", p, 3) for i, p in enumerate(self.obstacles))
        )
        robots = tuple(self.robots)
        for i, r in enumerate(robots):
            if not isinstance(r, RobotView):
                raise TypeError(f"scene.robots[{i}] must be a RobotView, got {type(r).__name__}")
        object.__setattr__(self, "robots", robots)
        if not isinstance(self.goals, Mapping):
            raise TypeError(f"scene.goals must be a mapping name -> (x, y, yaw), got {type(self.goals).__name__}")
        goals = {str(k): _floats(f"scene.goals[{k!r}]", v, 3) for k, v in self.goals.items()}
        object.__setattr__(self, "goals", MappingProxyType(goals))
        if self.observer_true is not None:
            object.__setattr__(self, "observer_true", _floats("scene.observer_true", self.observer_true, 4))
        if self.observer_est is not None:
            object.__setattr__(self, "observer_est", _floats("scene.observer_est", self.observer_est, 3))
        object.__setattr__(
            self,
            "more_observers",
            tuple(
                (
                    _floats(f"scene.more_observers[{k}][0]", true, 4),
                    None if est is None else _floats(f"scene.more_observers[{k}][1]", est, 3),
                )
                for k, (true, est) in enumerate(self.more_observers)
            ),
        )
        object.__setattr__(
            self,
            "footprints",
            tuple(_points(f"scene.footprints[{i}]", p, 0, allow_nan=True) for i, p in enumerate(self.footprints)),
        )
        ropes = []
        for i, seg in enumerate(self.ropes):
            try:
                a, b = seg
            except (TypeError, ValueError):
                raise ValueError(f"scene.ropes[{i}] must be ((x0, y0), (x1, y1)), got {seg!r}") from None
            ropes.append((_floats(f"scene.ropes[{i}][0]", a, 2), _floats(f"scene.ropes[{i}][1]", b, 2)))
        object.__setattr__(self, "ropes", tuple(ropes))
        object.__setattr__(self, "time", _floats("scene.time", (self.time,), 1)[0])
        if isinstance(self.info_lines, str):
            raise TypeError("scene.info_lines must be a sequence of strings, not one string")
        object.__setattr__(self, "info_lines", tuple(str(s) for s in self.info_lines))


# -------------------------------------------------------------- world -> image
@dataclass(frozen=True, slots=True)
class TopDownMapping:
    """World xy (m) to top-down image pixels: x right, y up, aspect ratio kept.

    ``u = u_left + (x - xmin) * scale``, ``v = v_top + (ymax - y) * scale``, with
    pixel centres at integer coordinates. Build it with :meth:`fit`.

    Attributes:
        scale: pixels per metre.
        u_left, v_top: pixel coordinates of the arena's (xmin, ymax) corner
            (the outer edge of the top-left arena pixel).
        xmin, ymax: world coordinates of that corner (m).
    """

    scale: float
    u_left: float
    v_top: float
    xmin: float
    ymax: float

    @classmethod
    def fit(cls, bounds: Sequence[float], size: tuple[int, int]) -> TopDownMapping:
        """Letterbox ``bounds = (xmin, ymin, xmax, ymax)`` (m) into an image of
        ``size = (width, height)`` px, centred, with a margin of 3 % of the
        smaller image side."""
        width, height = _check_size(size)
        xmin, ymin, xmax, ymax = _floats("bounds", bounds, 4)
        if not (xmin < xmax and ymin < ymax):
            raise ValueError(f"bounds must be (xmin, ymin, xmax, ymax) with xmin < xmax, ymin < ymax, got {bounds!r}")
        pad = math.floor(0.03 * min(width, height))
        scale = min((width - 2 * pad) / (xmax - xmin), (height - 2 * pad) / (ymax - ymin))
        u_left = 0.5 * (width - scale * (xmax - xmin)) - 0.5
        v_top = 0.5 * (height - scale * (ymax - ymin)) - 0.5
        return cls(scale=scale, u_left=u_left, v_top=v_top, xmin=xmin, ymax=ymax)

    def to_pixels(self, xy: np.ndarray) -> np.ndarray:
        """Pixels ``(..., 2)`` (float ``u, v``) of world points ``(..., 2)`` (m)."""
        xy = np.asarray(xy, dtype=float)
        px = np.empty(xy.shape)
        px[..., 0] = self.u_left + (xy[..., 0] - self.xmin) * self.scale
        px[..., 1] = self.v_top + (self.ymax - xy[..., 1]) * self.scale
        return px

    def to_world(self, px: np.ndarray) -> np.ndarray:
        """World xy ``(..., 2)`` (m) of pixels ``(..., 2)``; inverse of :meth:`to_pixels`."""
        px = np.asarray(px, dtype=float)
        xy = np.empty(px.shape)
        xy[..., 0] = self.xmin + (px[..., 0] - self.u_left) / self.scale
        xy[..., 1] = self.ymax - (px[..., 1] - self.v_top) / self.scale
        return xy

    def point(self, x: float, y: float) -> tuple[float, float]:
        """Pixel ``(u, v)`` of one world point (m), in plain floats."""
        return self.u_left + (x - self.xmin) * self.scale, self.v_top + (self.ymax - y) * self.scale


# -------------------------------------------------------------- drawing helpers
def _fixed(px: np.ndarray, limit: float) -> np.ndarray:
    """Float pixels -> int32 fixed point (``_SHIFT`` bits), clipped to ``[-limit, limit]``."""
    return np.rint(np.clip(px, -limit, limit) * _ONE).astype(np.int32)


def _fixed_pt(u: float, v: float, limit: float) -> tuple[int, int]:
    """One float pixel -> fixed-point ``(u, v)`` ints, clipped to ``[-limit, limit]``."""
    return (
        int(round(min(max(u, -limit), limit) * _ONE)),
        int(round(min(max(v, -limit), limit) * _ONE)),
    )


def _blend_polygons(img: np.ndarray, polys: list[np.ndarray], colour: tuple[int, int, int], alpha: float) -> None:
    """Fill fixed-point polygons with ``colour`` at opacity ``alpha``, in place,
    touching only their bounding box. Overlapping polygons fill their union (one
    ``fillPoly`` per polygon: a single call would leave the overlap of two
    polygons empty, as the holes of one shape)."""
    h, w = img.shape[:2]
    allpts = np.concatenate(polys)
    x0 = max(int(allpts[:, 0].min()) >> _SHIFT, 0)
    y0 = max(int(allpts[:, 1].min()) >> _SHIFT, 0)
    x1 = min((int(allpts[:, 0].max()) >> _SHIFT) + 2, w)
    y1 = min((int(allpts[:, 1].max()) >> _SHIFT) + 2, h)
    if x0 >= x1 or y0 >= y1:
        return
    roi = img[y0:y1, x0:x1]
    overlay = roi.copy()
    for poly in polys:
        cv2.fillPoly(overlay, [poly], colour, cv2.LINE_AA, _SHIFT, (-x0 * _ONE, -y0 * _ONE))
    cv2.addWeighted(overlay, alpha, roi, 1.0 - alpha, 0.0, dst=roi)


def _filled(width: int, height: int, colour: tuple[int, int, int]) -> np.ndarray:
    """A new ``(height, width, 3)`` uint8 image of one colour (cv2 fills ~40x faster
    than numpy broadcasting a 3-vector)."""
    img = np.empty((height, width, 3), dtype=np.uint8)
    cv2.rectangle(img, (0, 0), (width - 1, height - 1), colour, -1)
    return img


def _darken(img: np.ndarray, x0: int, y0: int, x1: int, y1: int) -> None:
    """Darken a rectangle to a third of its brightness (a translucent text panel)."""
    h, w = img.shape[:2]
    x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
    if x0 < x1 and y0 < y1:
        roi = img[y0:y1, x0:x1]
        np.floor_divide(roi, 3, out=roi)


def _text_metrics(width: int, height: int) -> tuple[float, int]:
    """Font scale and line height (px) for an image of this size."""
    scale = max(0.3, 0.4 * min(width, height) / 640.0)
    (_, th), base = cv2.getTextSize("Hg", _FONT, scale, 1)
    return scale, th + base + 3


def _rotated(points_b: np.ndarray, x: float, y: float, yaw: float) -> np.ndarray:
    """Body-frame xy ``(k, 2)`` placed at the planar pose ``(x, y, yaw)``: world xy ``(k, 2)``."""
    c, s = math.cos(yaw), math.sin(yaw)
    out = np.empty(points_b.shape)
    out[:, 0] = x + c * points_b[:, 0] - s * points_b[:, 1]
    out[:, 1] = y + s * points_b[:, 0] + c * points_b[:, 1]
    return out


def _box_corners_b(length: float, width: float) -> np.ndarray:
    hl, hw = 0.5 * length, 0.5 * width
    return np.array([[hl, hw], [-hl, hw], [-hl, -hw], [hl, -hw]])


class _Canvas:
    """A top-down image and its mapping; the drawing primitives in world units."""

    __slots__ = ("img", "map", "limit", "line")

    def __init__(self, img: np.ndarray, mapping: TopDownMapping) -> None:
        self.img = img
        self.map = mapping
        self.limit = _CLIP_IMAGES * max(img.shape[:2])
        self.line = max(1, round(min(img.shape[:2]) / 320))

    def fixed(self, xy: np.ndarray) -> np.ndarray:
        return _fixed(self.map.to_pixels(xy), self.limit)

    def pt(self, x: float, y: float) -> tuple[int, int]:
        u, v = self.map.point(x, y)
        return _fixed_pt(u, v, self.limit)

    def px(self, metres: float, minimum: float = 1.0) -> int:
        """A length (m) as fixed-point pixels, at least ``minimum`` px."""
        return int(round(max(metres * self.map.scale, minimum) * _ONE))

    def segment(self, x0: float, y0: float, x1: float, y1: float, colour: tuple[int, int, int], thickness: int) -> None:
        cv2.line(self.img, self.pt(x0, y0), self.pt(x1, y1), colour, thickness, cv2.LINE_AA, _SHIFT)

    def heading(self, x: float, y: float, yaw: float, length_m: float, colour: tuple[int, int, int],
                thickness: int) -> None:
        length = max(length_m, 3.0 / self.map.scale)
        self.segment(x, y, x + length * math.cos(yaw), y + length * math.sin(yaw), colour, thickness)

    def label(self, text: str, x: float, y: float, offset_m: float, font_scale: float, below: bool = False) -> None:
        """``text`` up and right of ``(x, y)`` (down and right if ``below``), ``offset_m`` away."""
        u, v = self.map.point(x, y)
        off = 0.7 * max(offset_m * self.map.scale, 3.0)
        if below:
            off = -off - cv2.getTextSize(text, _FONT, font_scale, 1)[0][1]
        org = (int(round(min(max(u + abs(off), -self.limit), self.limit))),
               int(round(min(max(v - off, -self.limit), self.limit))))
        cv2.putText(self.img, text, org, _FONT, font_scale, _LABEL, 1, cv2.LINE_AA)


# ------------------------------------------------------------------- top-down
def _draw_floor(c: _Canvas, bounds: tuple[float, float, float, float]) -> None:
    xmin, ymin, xmax, ymax = bounds
    corners = np.array([[xmin, ymax], [xmax, ymax], [xmax, ymin], [xmin, ymin]])
    rect = c.fixed(corners)
    cv2.fillPoly(c.img, [rect], _FLOOR, cv2.LINE_8, _SHIFT)
    step = next((s for s in _GRID_STEPS_M if s * c.map.scale >= _GRID_MIN_PX), None)
    if step is not None:
        for gx in np.arange(math.ceil(xmin / step) * step, xmax, step)[:500]:
            cv2.line(c.img, c.pt(gx, ymin), c.pt(gx, ymax), _GRID, 1, cv2.LINE_8, _SHIFT)
        for gy in np.arange(math.ceil(ymin / step) * step, ymax, step)[:500]:
            cv2.line(c.img, c.pt(xmin, gy), c.pt(xmax, gy), _GRID, 1, cv2.LINE_8, _SHIFT)
    cv2.polylines(c.img, [rect], True, _WALL, c.line + 1, cv2.LINE_AA, _SHIFT)


def _draw_footprints(c: _Canvas, footprints: tuple[np.ndarray, ...]) -> None:
    polys = []
    for fp in footprints:
        finite = fp[np.isfinite(fp).all(axis=1)]
        if len(finite) >= 3:
            polys.append(c.fixed(finite))
    if polys:
        _blend_polygons(c.img, polys, _FOOTPRINT, _FOOTPRINT_ALPHA)
        cv2.polylines(c.img, polys, True, _FOOTPRINT, 1, cv2.LINE_AA, _SHIFT)


def _draw_goal(c: _Canvas, name: str, pose: tuple[float, float, float], font_scale: float) -> None:
    x, y, yaw = pose
    arm = max(0.07, 5.0 / c.map.scale)
    c.segment(x - arm, y - arm, x + arm, y + arm, _GOAL, c.line)
    c.segment(x - arm, y + arm, x + arm, y - arm, _GOAL, c.line)
    c.heading(x, y, yaw, 2.5 * arm, _GOAL, c.line)
    c.label(name, x, y, arm, font_scale)


def _draw_robot_truth(c: _Canvas, r: RobotView, font_scale: float) -> None:
    x, y, yaw = r.true_pose
    colour = _STATIC_TRUTH if r.static else _MOBILE_TRUTH
    if r.shape == "box":
        length, width = r.size  # type: ignore[misc]
        body = c.fixed(_rotated(_box_corners_b(length, width), x, y, yaw))
        cv2.fillPoly(c.img, [body], colour, cv2.LINE_AA, _SHIFT)
        reach = 0.5 * length
    else:
        cv2.circle(c.img, c.pt(x, y), c.px(r.radius, 2.0), colour, -1, cv2.LINE_AA, _SHIFT)
        reach = r.radius
    if r.board_corners_w is not None:
        cv2.polylines(c.img, [c.fixed(r.board_corners_w)], True, _BOARD_OUTLINE, 1, cv2.LINE_AA, _SHIFT)
    c.heading(x, y, yaw, reach, _HEADING_TRUTH, c.line)
    c.label(r.name, x, y, r.radius, font_scale)


def _draw_robot_estimate(c: _Canvas, r: RobotView) -> None:
    if r.est_pose is None:
        return
    x, y, yaw = r.est_pose
    colour = STATUS_COLOURS[r.status]
    if r.shape == "box":
        length, width = r.size  # type: ignore[misc]
        reach = 0.5 * length
        outline = c.fixed(_rotated(_box_corners_b(length, width), x, y, yaw))
        cv2.polylines(c.img, [outline], True, colour, c.line + 1, cv2.LINE_AA, _SHIFT)
    else:
        reach = r.radius
        cv2.circle(c.img, c.pt(x, y), c.px(r.radius, 2.0), colour, c.line + 1, cv2.LINE_AA, _SHIFT)
    c.heading(x, y, yaw, 1.35 * reach, colour, c.line + 1)


def _draw_observer(c: _Canvas, true: tuple[float, ...] | None, est: tuple[float, ...] | None,
                   font_scale: float) -> None:
    arm = max(0.14, 7.0 / c.map.scale)
    if true is not None:
        x, y, yaw, altitude = true
        ends = _rotated(arm * np.array([[1.0, 1.0], [-1.0, -1.0], [1.0, -1.0], [-1.0, 1.0]]) / math.sqrt(2.0),
                        x, y, yaw)
        fx = c.fixed(ends)
        cv2.line(c.img, tuple(fx[0]), tuple(fx[1]), _OBSERVER_TRUE, c.line + 1, cv2.LINE_AA, _SHIFT)
        cv2.line(c.img, tuple(fx[2]), tuple(fx[3]), _OBSERVER_TRUE, c.line + 1, cv2.LINE_AA, _SHIFT)
        rotor = c.px(0.4 * arm, 2.0)
        for p in fx:
            cv2.circle(c.img, tuple(p), rotor, _OBSERVER_TRUE, 1, cv2.LINE_AA, _SHIFT)
        c.heading(x, y, yaw, 1.2 * arm, _OBSERVER_TRUE, c.line)
        c.label(f"observer {altitude:.2f} m", x, y, 1.4 * arm, font_scale, below=True)
    if est is not None:
        x, y, yaw = est
        half = 0.55 * arm
        square = c.fixed(_rotated(_box_corners_b(2 * half, 2 * half), x, y, yaw))
        cv2.polylines(c.img, [square], True, _OBSERVER_EST, c.line + 1, cv2.LINE_AA, _SHIFT)
        c.heading(x, y, yaw, 1.5 * arm, _OBSERVER_EST, c.line + 1)


def _draw_text_block(img: np.ndarray, lines: Sequence[str], font_scale: float, line_h: int, bottom: bool) -> None:
    """White text lines on a darkened panel in the top-left (or bottom-left) corner."""
    if not lines:
        return
    h = img.shape[0]
    pad = max(3, line_h // 3)
    width = max(cv2.getTextSize(s, _FONT, font_scale, 1)[0][0] for s in lines)
    y0 = h - pad * 2 - line_h * len(lines) if bottom else 0
    _darken(img, 0, y0, width + 2 * pad, y0 + 2 * pad + line_h * len(lines))
    for i, s in enumerate(lines):
        org = (pad, y0 + pad + line_h * (i + 1) - line_h // 4)
        cv2.putText(img, s, org, _FONT, font_scale, _PANEL_TEXT, 1, cv2.LINE_AA)


_LEGEND = (
    ("truth, static", "disk", _STATIC_TRUTH),
    ("truth, mobile", "disk", _MOBILE_TRUTH),
    ("est. localised", "ring", STATUS_COLOURS["localised"]),
    ("est. holding", "ring", STATUS_COLOURS["holding"]),
    ("est. lost", "ring", STATUS_COLOURS["lost"]),
    ("goal", "cross", _GOAL),
    ("camera view", "square", _FOOTPRINT),
    ("observer truth / est.", "square", _OBSERVER_EST),
)


def _draw_legend(img: np.ndarray, font_scale: float, line_h: int) -> None:
    """Colour key in the bottom-left corner, one swatch per entry."""
    h = img.shape[0]
    pad = max(3, line_h // 3)
    sw = line_h  # swatch column width
    width = max(cv2.getTextSize(s, _FONT, font_scale, 1)[0][0] for s, _, _ in _LEGEND) + sw + 3 * pad
    y0 = h - 2 * pad - line_h * len(_LEGEND)
    _darken(img, 0, y0, width, h)
    r = max(2, line_h // 3)
    for i, (text, kind, colour) in enumerate(_LEGEND):
        cy = y0 + pad + line_h * i + line_h // 2
        cx = pad + sw // 2
        if kind == "disk":
            cv2.circle(img, (cx, cy), r, colour, -1, cv2.LINE_AA)
        elif kind == "ring":
            cv2.circle(img, (cx, cy), r, colour, 2, cv2.LINE_AA)
        elif kind == "cross":
            cv2.line(img, (cx - r, cy - r), (cx + r, cy + r), colour, 2, cv2.LINE_AA)
            cv2.line(img, (cx - r, cy + r), (cx + r, cy - r), colour, 2, cv2.LINE_AA)
        else:
            cv2.rectangle(img, (cx - r, cy - r), (cx + r, cy + r), colour, 2, cv2.LINE_AA)
        cv2.putText(img, text, (pad + sw + pad, cy + line_h // 4), _FONT, font_scale, _PANEL_TEXT, 1, cv2.LINE_AA)


def render_top_down(scene: SceneView, size: tuple[int, int] = (640, 640), *, legend: bool = True) -> np.ndarray:
    """Top-down RGB image ``(height, width, 3)`` uint8 of ``scene``; ``size = (width, height)`` px.

    The arena ``scene.bounds`` is letterboxed into the image (see
    :meth:`TopDownMapping.fit`), world y pointing up. Drawn back to front:
    floor and grid, obstacles, camera footprints, ropes, goals, true robots,
    estimates, observer, then the info block (top left: time and
    ``scene.info_lines``) and, if ``legend``, the colour key (bottom left).
    The same scene and size always give the same array.
    """
    if not isinstance(scene, SceneView):
        raise TypeError(f"scene must be a SceneView, got {type(scene).__name__}")
    width, height = _check_size(size)
    mapping = TopDownMapping.fit(scene.bounds, (width, height))
    img = _filled(width, height, _OUTSIDE)
    c = _Canvas(img, mapping)
    font_scale, line_h = _text_metrics(width, height)

    _draw_floor(c, scene.bounds)
    if scene.obstacles:
        cv2.fillPoly(img, [c.fixed(p) for p in scene.obstacles], _OBSTACLE, cv2.LINE_AA, _SHIFT)
    _draw_footprints(c, scene.footprints)
    for (x0, y0), (x1, y1) in scene.ropes:
        c.segment(x0, y0, x1, y1, _ROPE, c.line + 1)
    for name, pose in scene.goals.items():
        _draw_goal(c, name, pose, font_scale)
    for r in scene.robots:
        _draw_robot_truth(c, r, font_scale)
    for r in scene.robots:
        _draw_robot_estimate(c, r)
    _draw_observer(c, scene.observer_true, scene.observer_est, font_scale)
    for true, est in scene.more_observers:
        _draw_observer(c, true, est, font_scale)

    _draw_text_block(img, (f"t = {scene.time:.2f} s", *scene.info_lines), font_scale, line_h, bottom=False)
    if legend:
        _draw_legend(img, font_scale, line_h)
    return img


# ----------------------------------------------------------------- camera view
def _outline_samples(corners: np.ndarray) -> np.ndarray:
    """Closed outlines ``(n, 4, 3)`` -> ``(n, 4 * _EDGE_SAMPLES, 3)`` points along their edges."""
    nxt = np.roll(corners, -1, axis=1)
    t = np.arange(_EDGE_SAMPLES, dtype=float) / _EDGE_SAMPLES
    pts = corners[:, :, None, :] + t[None, None, :, None] * (nxt - corners)[:, :, None, :]
    return pts.reshape(corners.shape[0], 4 * _EDGE_SAMPLES, 3)


def _plate_corners(layout: BoardLayout) -> np.ndarray:
    """The white plate of a board in M ``(1, 4, 3)``: the marker grid plus a margin of
    one gap (at least an eighth of a marker) on every side, ArUco corner order."""
    m = max(layout.gap, layout.marker_size / 8.0)
    hx, hy = 0.5 * layout.width + m, 0.5 * layout.height + m
    return np.array([[[-hx, hy, 0.0], [hx, hy, 0.0], [hx, -hy, 0.0], [-hx, -hy, 0.0]]])


def render_camera_view(
    camera: PinholeCamera,
    T_w_c: np.ndarray,
    boards: Sequence[BoardView],
    detected_ids: Iterable[int] | None = None,
    size: tuple[int, int] | None = None,
) -> np.ndarray:
    """Synthetic RGB image ``(height, width, 3)`` uint8 of what ``camera`` sees from ``T_w_c``.

    Args:
        camera: intrinsics and lens distortion.
        T_w_c: 4x4 pose of the camera frame C (OpenCV) in the world W (m).
        boards: the boards in the scene.
        detected_ids: board ids (``BoardView.board_id``) outlined in green, e.g. the
            boards the backend detected in this frame. None: no outlines.
        size: output ``(width, height)`` px; None means the camera's own resolution.
            Pixel coordinates are scaled per axis (like resizing the sensor image).

    Every board facing the camera (printed face towards it) is drawn as a white
    plate with a black square per marker, farthest board first. Outlines are
    sampled along the edges and projected with :meth:`PinholeCamera.project`, so
    edges bend with the distortion. A marker (or plate) is skipped if any of its
    outline points is closer than 1 cm in depth (in particular behind the camera)
    or outside the lens model's one-to-one region. The floor is uniform grey and
    the image has a dark 1-2 px border.
    """
    if not isinstance(camera, PinholeCamera):
        raise TypeError(f"camera must be a PinholeCamera, got {type(camera).__name__}")
    T_w_c = as_pose(T_w_c, "T_w_c")
    cfg = camera.config
    width, height = (cfg.width, cfg.height) if size is None else _check_size(size)
    detected = frozenset() if detected_ids is None else frozenset(int(i) for i in detected_ids)
    img = _filled(width, height, _CAM_FLOOR)

    T_c_w = invert(T_w_c)
    sx, sy = width / cfg.width, height / cfg.height
    limit = _CLIP_IMAGES * max(width, height)
    thickness = max(2, round(min(width, height) / 200))
    drawn = []  # (depth, board_id, plate or None, markers list)
    for i, board in enumerate(boards):
        if not isinstance(board, BoardView):
            raise TypeError(f"boards[{i}] must be a BoardView, got {type(board).__name__}")
        T_c_m = T_c_w @ board.T_w_m
        R, t = T_c_m[:3, :3], T_c_m[:3, 3]
        if float(R[:, 2] @ t) >= 0.0:  # printed face turned away from the camera
            continue
        outlines_m = _outline_samples(np.concatenate([_plate_corners(board.layout), board.layout.marker_corners]))
        pts_c = outlines_m @ R.T + t
        px, r2 = camera.project_with_r2(pts_c)
        ok = (pts_c[..., 2] > _NEAR_M).all(axis=1) & (r2 < camera.fold_r2).all(axis=1)
        if not ok.any():
            continue
        px[..., 0] = (px[..., 0] + 0.5) * sx - 0.5
        px[..., 1] = (px[..., 1] + 0.5) * sy - 0.5
        fx = _fixed(px, limit)
        plate = fx[0] if ok[0] else None
        markers = [fx[k] for k in range(1, len(fx)) if ok[k]]
        drawn.append((float(np.linalg.norm(t)), board.board_id, plate, markers))

    drawn.sort(key=lambda d: -d[0])
    for _, board_id, plate, markers in drawn:
        if plate is not None:
            cv2.fillPoly(img, [plate], _CAM_PLATE, cv2.LINE_AA, _SHIFT)
        if markers:
            cv2.fillPoly(img, markers, _CAM_MARKER, cv2.LINE_AA, _SHIFT)
        if board_id in detected:
            outline = plate if plate is not None else np.concatenate(markers)
            if plate is None:
                outline = cv2.convexHull(outline)
            cv2.polylines(img, [outline], True, DETECTED_COLOUR, thickness, cv2.LINE_AA, _SHIFT)

    b = max(1, round(min(width, height) / 300))
    for k in range(b):
        cv2.rectangle(img, (k, k), (width - 1 - k, height - 1 - k), _CAM_BORDER, 1)
    return img


# --------------------------------------------------------------------- compose
def _check_rgb(name: str, img: object) -> np.ndarray:
    if not isinstance(img, np.ndarray) or img.dtype != np.uint8 or img.ndim != 3 or img.shape[2] != 3:
        desc = f"{img.dtype} array of shape {img.shape}" if isinstance(img, np.ndarray) else type(img).__name__
        raise ValueError(f"{name} must be a uint8 (H, W, 3) image, got {desc}")
    if img.shape[0] == 0 or img.shape[1] == 0:
        raise ValueError(f"{name} must not be empty, got shape {img.shape}")
    return img


def _inset_margin(width: int, height: int) -> int:
    """Gap (px) between an inset and the image edges: 1.5 % of the smaller side."""
    return round(0.015 * min(width, height))


def _check_scale(scale: object) -> float:
    if isinstance(scale, bool) or not isinstance(scale, numbers.Real) or not 0.0 < scale <= 1.0:
        raise ValueError(f"scale must be a number in (0, 1], got {scale!r}")
    return float(scale)


def inset_size(top_size: tuple[int, int], native_size: tuple[int, int], scale: float = 0.3) -> tuple[int, int]:
    """``(width, height)`` px that :func:`compose` gives an inset of ``native_size``
    on an image of ``top_size`` (all sizes ``(width, height)``).

    The inset is ``scale * width`` wide (``scale`` in (0, 1]), keeps its aspect
    ratio and shrinks further to fit inside the margins. Render the camera view
    at this size (``render_camera_view(..., size=inset_size(...))``) and
    :func:`compose` pastes it without resampling.
    """
    W, H = _check_size(top_size, "top_size")
    w, h = _check_size(native_size, "native_size")
    scale = _check_scale(scale)
    margin = _inset_margin(W, H)
    width = scale * W
    height = width * h / w
    room_w, room_h = max(W - 2 * margin, 1), max(H - 2 * margin, 1)
    shrink = min(1.0, room_w / width, room_h / height)
    return max(1, min(round(width * shrink), room_w)), max(1, min(round(height * shrink), room_h))


def compose(top: np.ndarray, inset: np.ndarray | None, corner: str = "top-right", scale: float = 0.3) -> np.ndarray:
    """``top`` with ``inset`` pasted into one corner, as a new array.

    Args:
        top: the main image, uint8 ``(H, W, 3)``.
        inset: the image to paste, uint8 ``(h, w, 3)``, or None (a copy of ``top``).
        corner: one of :data:`INSET_CORNERS`.
        scale: inset width as a fraction of ``W``, in (0, 1]; the inset keeps its
            aspect ratio and shrinks further if it would not fit the height.

    The inset sits a small margin (1.5 % of the smaller side of ``top``) from the
    two image edges of its corner. Its size is :func:`inset_size`; an inset of a
    different size is resampled (area interpolation when shrinking), which costs
    about 0.5 ms: render the inset at that size to skip it.
    """
    top = _check_rgb("top", top)
    if corner not in INSET_CORNERS:
        raise ValueError(f"corner must be one of {INSET_CORNERS}, got {corner!r}")
    _check_scale(scale)
    out = top.copy()
    if inset is None:
        return out
    inset = _check_rgb("inset", inset)
    H, W = top.shape[:2]
    h, w = inset.shape[:2]
    tw, th = inset_size((W, H), (w, h), scale)
    margin = _inset_margin(W, H)
    if (tw, th) != (w, h):
        interp = cv2.INTER_AREA if tw < w else cv2.INTER_LINEAR
        inset = cv2.resize(inset, (tw, th), interpolation=interp)
    x0 = margin if corner.endswith("left") else W - margin - tw
    y0 = margin if corner.startswith("top") else H - margin - th
    out[y0:y0 + th, x0:x0 + tw] = inset
    return out

"""From a running simulation to pictures: the rgb_array frame and the human window.

:func:`render_simulation` gathers the truth, the estimates, the goals, the camera
footprints and the first camera's view of a :class:`~moma_env.sim.Simulation`
(its latest :class:`~moma_env.sim.Frame` and its public API) into the plain data
of :mod:`moma_env.env.render` and draws them. :class:`HumanWindow` shows frames
in a pygame window (``render_mode="human"``).
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence

import cv2
import numpy as np

from moma_env.camera import PinholeCamera
from moma_env.env.render import RobotView, SceneView, compose, inset_size, render_camera_view, render_top_down
from moma_env.estimator import Status
from moma_env.geometry import se3_to_se2
from moma_env.sim import Simulation

__all__ = ["render_simulation", "scene_of", "HumanWindow", "FRAME_SIZE"]

#: Size (width, height) of a rendered frame in pixels.
FRAME_SIZE = (640, 640)


def _board_outline(T_w_m: np.ndarray, half_w: float, half_h: float) -> np.ndarray:
    corners = np.array([[-half_w, half_h, 0, 1], [half_w, half_h, 0, 1], [half_w, -half_h, 0, 1], [-half_w, -half_h, 0, 1]])
    return (T_w_m @ corners.T).T[:, :2]


def scene_of(sim: Simulation, info_lines: Sequence[str] = ()) -> SceneView:
    """The plain-data scene of the simulation's latest frame, with ``info_lines`` of text."""
    world = sim.world
    frame = sim.frame
    scenario = sim.scenario
    wc = scenario.world
    robots = []
    boards = {device: (layout, world.board_transform(device)) for device, _, layout in sim.boards}
    for device in sim.devices:
        e = frame.estimates[device]
        est = frame.estimated[device]
        outline = None
        if device in boards:
            layout, T = boards[device]
            outline = _board_outline(T, layout.width / 2, layout.height / 2)
        if device in sim.sleds:
            cfg = next(s for s in wc.sleds if s.name == device)
            robots.append(
                RobotView(device, world.sled_pose(device), est, max(cfg.size) / 2, world.is_static(device), e.status, shape="box", size=tuple(cfg.size), board_corners_w=outline)
            )
        else:
            cfg = wc.ugv(device)
            robots.append(RobotView(device, world.ugv_pose(device), est, cfg.radius, world.is_static(device), e.status, board_corners_w=outline))
    observers = []
    footprints = []
    camera = PinholeCamera(scenario.camera)
    for uav in wc.uavs:
        s = frame.uavs[uav.name]
        e = frame.estimates[uav.name]
        est = se3_to_se2(e.T_w_b) if e.T_w_b is not None and e.status is not Status.LOST else None
        observers.append(((s.x, s.y, s.yaw, s.z), est))
        footprints.append(camera.ground_footprint(world.camera_transform(uav.camera_name)))
    uav_cameras = {uav.camera_name for uav in wc.uavs}
    observer_true, observer_est = observers[0] if observers else (None, None)
    for name in world.camera_names:
        if name not in uav_cameras:  # a robot's forward camera: its view up to its range
            wedge = camera.view_wedge(world.camera_transform(name), scenario.camera.max_range_m)
            footprints.append(_inside(wedge, wc.arena.bounds))
    ropes = []
    for sled in getattr(wc, "sleds", ()):
        rx, ry, ryaw = world.ugv_pose(sled.robot)
        sx, sy, syaw = world.sled_pose(sled.name)
        ropes.append(((rx - math.cos(ryaw) * wc.ugv(sled.robot).radius, ry - math.sin(ryaw) * wc.ugv(sled.robot).radius), (sx, sy)))
    return SceneView(
        bounds=wc.arena.bounds,
        obstacles=tuple(_box_polygon(o) for o in wc.arena.obstacles),
        robots=tuple(robots),
        goals=dict(scenario.goals),
        observer_true=observer_true,
        observer_est=observer_est,
        more_observers=tuple(observers[1:]),
        footprints=tuple(footprints),
        ropes=tuple(ropes),
        time=frame.time,
        info_lines=tuple(info_lines),
    )


def _inside(polygon: np.ndarray, bounds: tuple[float, float, float, float]) -> np.ndarray:
    """The part of a convex floor polygon ``(k, 2)`` (m) inside the arena ``bounds``
    (the walls block the view beyond); rows with NaN are dropped first."""
    finite = polygon[np.isfinite(polygon).all(axis=1)]
    if len(finite) < 3:
        return np.empty((0, 2))
    xmin, ymin, xmax, ymax = bounds
    box = np.array([[xmin, ymin], [xmax, ymin], [xmax, ymax], [xmin, ymax]], dtype=np.float32)
    area, part = cv2.intersectConvexConvex(finite.astype(np.float32), box)
    return np.empty((0, 2)) if part is None or area <= 0.0 else part.reshape(-1, 2).astype(float)


def _box_polygon(o) -> np.ndarray:
    c, s = math.cos(o.yaw), math.sin(o.yaw)
    hw, hh = o.width / 2, o.height / 2
    local = np.array([[-hw, -hh], [hw, -hh], [hw, hh], [-hw, hh]])
    return local @ np.array([[c, s], [-s, c]]) + (o.x, o.y)


def render_simulation(sim: Simulation, info_lines: Sequence[str] = (), size: tuple[int, int] = FRAME_SIZE) -> np.ndarray:
    """Top-down frame with the first camera's view as an inset, (H, W, 3) uint8 RGB."""
    frame = render_top_down(scene_of(sim, info_lines), size)
    camera_names = list(sim.cameras)
    if not camera_names:
        return frame
    name = camera_names[0]
    cam = sim.cameras[name].camera
    views = sim.board_views()
    detected = {d.board_id for d in sim.frame.detections if d.camera_id == name}
    cfg = sim.scenario.camera
    inset = render_camera_view(cam, sim.world.camera_transform(name), views, detected, size=inset_size(size, (cfg.width, cfg.height)))
    return compose(frame, inset)


class HumanWindow:
    """A pygame window that shows rgb_array frames (created on first use)."""

    def __init__(self, title: str, fps: int):
        self._title = title
        self._fps = fps
        self._screen = None
        self._clock = None

    def show(self, frame: np.ndarray) -> None:
        os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
        import pygame

        if self._screen is None:
            pygame.init()
            pygame.display.set_caption(self._title)
            self._screen = pygame.display.set_mode((frame.shape[1], frame.shape[0]))
            self._clock = pygame.time.Clock()
        surface = pygame.surfarray.make_surface(np.ascontiguousarray(frame.swapaxes(0, 1)))
        self._screen.blit(surface, (0, 0))
        pygame.event.pump()
        pygame.display.flip()
        self._clock.tick(self._fps)

    def close(self) -> None:
        if self._screen is not None:
            import pygame

            pygame.display.quit()
            self._screen = None

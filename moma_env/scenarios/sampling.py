"""Random draws shared by the configurations' seeded generators.

Every draw comes from the ``np.random.Generator`` the caller passes, in a fixed
order, so the same generator state gives the same configuration (dataclass
equality). A draw that cannot be completed (arena too small, camera that folds
over, a required board out of view) is thrown away and drawn again, at most
:data:`MAX_ATTEMPTS` times; then a RuntimeError names the configuration and the
last reason.

A generator keeps a team field (``n_ugvs``) at a given value in one of two ways,
both giving the free generator's distribution conditioned on that value: for a
value the free generator draws itself, :func:`first_with_team` takes the first
free configuration that has it (the stream of layouts the environment has always
drawn, bit for bit); beyond that range the generator skips that field's draw and
draws the others as the free generator does given the value, rejecting the same
invalid layouts.

Ranges (m, rad, px): arena sides 4-10 m, 0-4 box obstacles of 0.2-1.0 m sides,
goal distance 1-3 m, headings uniform, camera fx 350-600 px, corner noise 0-1
px, mild radial distortion, UAV altitude 1.2-2.5 m.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any, TypeVar

import numpy as np

from moma_env.camera import CameraConfig
from moma_env.config import ConfigError
from moma_env.scenarios.common import ScenarioConfig
from moma_env.scenarios.layout import Disk, convex_hull, convex_polygons_distance
from moma_env.scenarios.views import missing_views
from moma_env.world import BoxObstacle
from moma_env.world.arena import box_corners

__all__ = [
    "MAX_ATTEMPTS",
    "ARENA_SIDE_RANGE_M",
    "RANDOM_WALL_CLEARANCE_M",
    "MAX_OBSTACLES",
    "OBSTACLE_SIDE_RANGE_M",
    "CORRIDOR_CLEARANCE_M",
    "GOAL_DISTANCE_RANGE_M",
    "ALTITUDE_RANGE_M",
    "FX_RANGE_PX",
    "NOISE_RANGE_PX",
    "Redraw",
    "random_heading",
    "random_goal_distance",
    "random_camera",
    "random_surroundings",
    "draw_until_valid",
    "MAX_TEAM_DRAWS",
    "first_with_team",
]

C = TypeVar("C", bound=ScenarioConfig)

#: Draws tried before giving up.
MAX_ATTEMPTS = 100
#: Free configurations :func:`first_with_team` draws before giving up.
MAX_TEAM_DRAWS = 200
#: Range of each arena side (m).
ARENA_SIDE_RANGE_M = (4.0, 10.0)
#: Smallest gap (m) between a start or goal footprint and a wall in a random arena.
RANDOM_WALL_CLEARANCE_M = 0.5
#: Largest number of box obstacles.
MAX_OBSTACLES = 4
#: Range of a box obstacle's sides (m).
OBSTACLE_SIDE_RANGE_M = (0.2, 1.0)
#: Gap (m) kept between an obstacle and the devices' footprints along the corridor.
CORRIDOR_CLEARANCE_M = 0.3
#: Tries to place one obstacle before leaving it out.
_OBSTACLE_TRIES = 20
#: Range of the distance from a start to its goal (m).
GOAL_DISTANCE_RANGE_M = (1.0, 3.0)
#: Range of the observer's altitude (m).
ALTITUDE_RANGE_M = (1.2, 2.5)
#: Range of the focal length (px), square pixels.
FX_RANGE_PX = (350.0, 600.0)
#: Range of the corner noise's standard deviation (px).
NOISE_RANGE_PX = (0.0, 1.0)
#: Ranges of the radial distortion coefficients k1, k2 (mild barrel or pincushion).
_K1_RANGE = (-0.10, 0.05)
_K2_RANGE = (-0.02, 0.02)


class Redraw(Exception):
    """A draw that cannot be completed; the generator starts over."""


def random_heading(rng: np.random.Generator) -> float:
    """A heading uniform in [-pi, pi) (rad)."""
    return float(rng.uniform(-math.pi, math.pi))


def random_goal_distance(rng: np.random.Generator) -> float:
    """A start-to-goal distance uniform in :data:`GOAL_DISTANCE_RANGE_M` (m)."""
    return float(rng.uniform(*GOAL_DISTANCE_RANGE_M))


def random_camera(rng: np.random.Generator) -> CameraConfig:
    """PAL 720x576 camera with random focal length, corner noise and radial distortion.

    Raises ConfigError if the drawn distortion folds over inside the image.
    """
    fx, noise, k1, k2 = rng.uniform(
        (FX_RANGE_PX[0], NOISE_RANGE_PX[0], _K1_RANGE[0], _K2_RANGE[0]),
        (FX_RANGE_PX[1], NOISE_RANGE_PX[1], _K1_RANGE[1], _K2_RANGE[1]),
    ).tolist()
    return CameraConfig(fx=fx, noise_px=noise, dist=(k1, k2, 0.0, 0.0, 0.0))


def random_surroundings(rng: np.random.Generator, disks: tuple[Disk, ...]) -> dict[str, Any]:
    """Random ``arena``, ``arena_origin`` and ``obstacles`` around the footprints ``disks``.

    Each arena side is uniform between the larger of 4 m and what the footprints
    need (with :data:`RANDOM_WALL_CLEARANCE_M` to the walls) and 10 m, placed at
    random around them. Up to :data:`MAX_OBSTACLES` boxes of random size and yaw
    lie inside the arena, each at least the footprints' largest radius plus
    :data:`CORRIDOR_CLEARANCE_M` away from the corridor (the convex hull of the
    footprints' centres); a box that finds no such place in a few tries is left out.

    Raises :class:`Redraw` if the footprints do not fit in a 10 m arena.
    """
    centres = np.array([(x, y) for _, x, y, _ in disks])
    radii = np.array([r for *_, r in disks])
    lo = (centres - radii[:, None]).min(axis=0) - RANDOM_WALL_CLEARANCE_M
    hi = (centres + radii[:, None]).max(axis=0) + RANDOM_WALL_CLEARANCE_M
    need = hi - lo
    low_side, high_side = ARENA_SIDE_RANGE_M
    if (need > high_side).any():
        raise Redraw(f"the footprints need a {need[0]:.2f} x {need[1]:.2f} m arena (largest {high_side} m)")
    size = rng.uniform(np.maximum(need, low_side), high_side)
    origin = rng.uniform(hi - size, lo)
    n_obstacles = int(rng.integers(0, MAX_OBSTACLES + 1))
    corridor = convex_hull(centres)
    keep_out = float(radii.max()) + CORRIDOR_CLEARANCE_M
    low_corner, high_corner = origin, origin + size
    obstacles = []
    for _ in range(n_obstacles):
        for _ in range(_OBSTACLE_TRIES):
            width, height = rng.uniform(*OBSTACLE_SIDE_RANGE_M, size=2).tolist()
            yaw = random_heading(rng)
            x, y = rng.uniform(low_corner, high_corner).tolist()
            box = BoxObstacle(x=x, y=y, width=width, height=height, yaw=yaw)
            corners = box_corners(box)
            inside = (corners >= low_corner).all() and (corners <= high_corner).all()
            if inside and convex_polygons_distance(corridor, corners) >= keep_out:
                obstacles.append(box)
                break
    return {
        "arena": (float(size[0]), float(size[1])),
        "arena_origin": (float(origin[0]), float(origin[1])),
        "obstacles": tuple(obstacles),
    }


def draw_until_valid(config_type: type[C], rng: np.random.Generator, draw: Callable[[np.random.Generator], C]) -> C:
    """The first configuration ``draw(rng)`` returns that constructs and whose cameras
    see every required board whole at the start.

    Raises TypeError if ``rng`` is not a Generator, RuntimeError after
    :data:`MAX_ATTEMPTS` rejected draws.
    """
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
    reason = "none"
    for _ in range(MAX_ATTEMPTS):
        try:
            config = draw(rng)
        except (ConfigError, Redraw) as error:
            reason = str(error)
            continue
        missing = missing_views(config.scenario(), config.required_views())
        if not missing:
            return config
        reason = "; ".join(missing)
    raise RuntimeError(
        f"no valid random {config_type.NAME} configuration in {MAX_ATTEMPTS} draws; last rejection: {reason}"
    )


def first_with_team(
    config_type: type[C], rng: np.random.Generator, draw_free: Callable[[np.random.Generator], C], team: Mapping[str, int]
) -> C:
    """The first configuration ``draw_free(rng)`` returns whose fields have the values of ``team``.

    For values the free generator draws itself (each team then has a fair chance
    per draw). Raises RuntimeError after :data:`MAX_TEAM_DRAWS` draws without it.
    """
    for _ in range(MAX_TEAM_DRAWS):
        config = draw_free(rng)
        if all(getattr(config, name) == value for name, value in team.items()):
            return config
    raise RuntimeError(f"no random {config_type.NAME} configuration with {dict(team)} in {MAX_TEAM_DRAWS} draws")

"""The MOMA rule checker: :func:`validate` a :class:`~moma_env.planning.plan.Plan` against its scenario.

Rules, checked on samples every ``step_m`` metres (and every ``YAW_STEP_RAD``
of rotation) along every turn's polyline:

1. *Move in turns*: each turn names one known device and starts at that
   device's current pose; every other device keeps its pose (a turn starting
   elsewhere means the device moved outside its own turn).
2. *One advance*: each turn's translation is at most ``scenario.leg_length``.
3. *No collision*: the moving device's disk (a UGV's radius; a sled's
   circumscribed circle) keeps ``CLEARANCE_M`` from the walls, the box
   obstacles and the static devices' disks.
4. *Observability*, as the configuration's
   :class:`~moma_env.scenarios.spec.ScenarioSpec` states it (a scenario whose
   name is not registered has no observability rule but the ropes'):

   - ``observer_coverage`` (``top_observer``): the smallest circle enclosing
     every robot's centre, grown by the boards' half-diagonal, fits in the
     inscribed circle of the downward camera's floor footprint at the coverage
     height (see :func:`coverage_radius`);
   - ``motion_views(world)`` (``caterpillar``, ``caterpillar_multi``: each
     follower's forward camera on the back board of the robot ahead;
     ``caterpillar_sled``: the robot's backward camera on the sled's front
     board): whenever a camera's carrier or the board's carrier moves, the
     camera sees the board: depth >= the camera's ``min_range_m``, range <=
     ``min(max_range_m, PRACTICAL_MAX_RANGE_M)``, the whole board within the
     horizontal half-FOV minus ``BEARING_MARGIN_RAD`` and within the vertical
     half-FOV, incidence <= ``max_incidence_deg`` minus ``INCIDENCE_MARGIN_DEG``;
   - every sled's rope (anchor to anchor) stays within ``[min_rope, max_rope]``.

5. *Goals*: the final poses are within the scenario's goal tolerances.

:class:`RuleChecker` holds what the checks need, precomputed per scenario;
the planner uses its :meth:`RuleChecker.leg_violations` to test candidate legs.
Units: metres, radians; poses ``(x, y, yaw)`` in the world frame W.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from moma_env.geometry import wrap_angle
from moma_env.planning.paths import box_distances
from moma_env.planning.plan import Plan, Pose2D
from moma_env.scenarios.base import Scenario
from moma_env.scenarios.registry import SCENARIO_SPECS
from moma_env.world import SledConfig

__all__ = [
    "CLEARANCE_M",
    "PRACTICAL_MAX_RANGE_M",
    "BEARING_MARGIN_RAD",
    "INCIDENCE_MARGIN_DEG",
    "COVERAGE_ALTITUDE_MARGIN_M",
    "COVERAGE_MARKER_PX_FACTOR",
    "YAW_STEP_RAD",
    "POSE_TOLERANCE",
    "coverage_radius",
    "enclosing_circle",
    "sample_polyline",
    "RuleChecker",
    "validate",
]

#: Smallest gap (m) between a moving device and walls, obstacles, static devices.
CLEARANCE_M = 0.05
#: Longest camera-to-board range (m) a follower may watch from (the camera's max_range_m is larger).
PRACTICAL_MAX_RANGE_M = 2.0
#: Margin (rad) kept between the board's horizontal extent and the edge of the horizontal FOV.
BEARING_MARGIN_RAD = math.radians(2.0)
#: Margin (deg) below the camera's max_incidence_deg.
INCIDENCE_MARGIN_DEG = 5.0
#: The observer's coverage height is at most its max altitude minus this (m).
COVERAGE_ALTITUDE_MARGIN_M = 0.5
#: ... and at most the height at which a marker still images this many times ``min_marker_px``.
COVERAGE_MARKER_PX_FACTOR = 1.5
#: Largest yaw change (rad) between two samples of a leg.
YAW_STEP_RAD = 0.1
#: A turn starts "at the device's pose" within this (m and rad).
POSE_TOLERANCE = 1e-6


def coverage_radius(scenario: Scenario) -> float:
    """Radius (m) of the floor disk the top observer's camera covers whole, at the board plane.

    A level downward camera at height ``h`` above the boards sees a rectangle of
    half-sides ``h (width/2 - margin_px) / fx`` and ``h (height/2 - margin_px) / fy``;
    the result is the smaller half-side (the disk fits whatever the UAV's yaw).
    ``h`` is the UAV's ``max_altitude - COVERAGE_ALTITUDE_MARGIN_M`` (capped by
    the height at which a marker still images ``COVERAGE_MARKER_PX_FACTOR *
    min_marker_px``) plus the camera mount's z offset minus the highest board.
    With several observers, the largest of their radii: one observer that keeps
    the whole team in view is enough to localise it.
    """
    uavs = scenario.world.uavs
    if not uavs:
        raise ValueError(f"scenario {scenario.name!r} has no observer")
    cam = scenario.camera
    boards = [u for u in scenario.world.ugvs if u.board is not None]
    board_z = max(u.board_height for u in boards)
    marker = min(u.board.marker_size for u in boards)  # type: ignore[union-attr]
    h_marker = min(cam.fx, cam.fy) * marker / (COVERAGE_MARKER_PX_FACTOR * max(cam.min_marker_px, 1e-9))
    half_u = (cam.width / 2.0 - cam.margin_px) / cam.fx
    half_v = (cam.height / 2.0 - cam.margin_px) / cam.fy
    radii = []
    for uav in uavs:
        cam_dz = float(uav.camera_mount[2, 3])
        h = min(uav.max_altitude - COVERAGE_ALTITUDE_MARGIN_M + cam_dz - board_z, h_marker)
        radii.append(max(h, 0.0) * min(half_u, half_v))
    return max(radii)


def enclosing_circle(points: np.ndarray) -> tuple[float, float, float]:
    """Smallest circle ``(cx, cy, radius)`` (m) enclosing the points (n, 2); brute force, for small n."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    if len(pts) == 1:
        return float(pts[0, 0]), float(pts[0, 1]), 0.0
    best = (0.0, 0.0, math.inf)

    def consider(cx: float, cy: float, r: float) -> None:
        nonlocal best
        if r < best[2] and np.all(np.hypot(pts[:, 0] - cx, pts[:, 1] - cy) <= r + 1e-9):
            best = (cx, cy, r)

    for a, b in itertools.combinations(pts, 2):
        consider(0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1]), 0.5 * math.dist(a, b))
    for a, b, c in itertools.combinations(pts, 3):
        d = 2.0 * (a[0] * (b[1] - c[1]) + b[0] * (c[1] - a[1]) + c[0] * (a[1] - b[1]))
        if abs(d) < 1e-12:
            continue
        a2, b2, c2 = a @ a, b @ b, c @ c
        ux = (a2 * (b[1] - c[1]) + b2 * (c[1] - a[1]) + c2 * (a[1] - b[1])) / d
        uy = (a2 * (c[0] - b[0]) + b2 * (a[0] - c[0]) + c2 * (b[0] - a[0])) / d
        consider(float(ux), float(uy), math.dist((ux, uy), a))
    return best


def sample_polyline(waypoints: Sequence[Pose2D], step_m: float, yaw_step: float = YAW_STEP_RAD) -> np.ndarray:
    """(m, 3) poses along the polyline, every ``step_m`` m and ``yaw_step`` rad at most,
    first and last waypoints included; yaw turns linearly the short way round."""
    pts = np.asarray(waypoints, dtype=float).reshape(-1, 3)
    chunks = [pts[:1]]
    for p, q in zip(pts[:-1], pts[1:]):
        dyaw = float(wrap_angle(q[2] - p[2]))
        n = max(1, math.ceil(math.hypot(q[0] - p[0], q[1] - p[1]) / step_m), math.ceil(abs(dyaw) / yaw_step))
        t = np.arange(1, n + 1)[:, None] / n
        seg = p + t * np.array([q[0] - p[0], q[1] - p[1], dyaw])
        chunks.append(seg)
    return np.concatenate(chunks)


@dataclass(frozen=True)
class _View:
    """A camera on one device that must see the board on another.

    ``T_b_c`` and ``T_b_m`` are the 4x4 mounts in their owners' body frames;
    ``half_w``, ``half_h`` the board's half-sides (m).
    """

    camera: str
    camera_owner: str
    T_b_c: np.ndarray
    board_owner: str
    T_b_m: np.ndarray
    half_w: float
    half_h: float


def _mount_in_world(poses: np.ndarray, T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Positions (m, 3) and rotations (m, 3, 3) in W of a mount T (4x4, body frame) on bodies at planar poses (m, 3)."""
    c, s = np.cos(poses[:, 2]), np.sin(poses[:, 2])
    Rz = np.zeros((len(poses), 3, 3))
    Rz[:, 0, 0], Rz[:, 0, 1], Rz[:, 1, 0], Rz[:, 1, 1], Rz[:, 2, 2] = c, -s, s, c, 1.0
    pos = Rz @ T[:3, 3]
    pos[:, :2] += poses[:, :2]
    return pos, Rz @ T[:3, :3]


class RuleChecker:
    """The rules of :func:`validate` for one scenario, precomputed (see the module docstring).

    Args:
        scenario: the scenario the plans move in.
        step_m: sampling step along each leg (m).
    """

    def __init__(self, scenario: Scenario, step_m: float = 0.05) -> None:
        if not isinstance(scenario, Scenario):
            raise TypeError(f"scenario must be a Scenario, got {type(scenario).__name__}")
        if not (isinstance(step_m, (int, float)) and math.isfinite(step_m) and step_m > 0.0):
            raise ValueError(f"step_m must be a positive number, got {step_m!r}")
        self.scenario = scenario
        self.step_m = float(step_m)
        world = scenario.world
        self.arena = world.arena
        self.start: dict[str, Pose2D] = {u.name: tuple(u.initial_pose) for u in world.ugvs}
        self.start.update({s.name: tuple(s.initial_pose) for s in world.sleds})
        self.radius: dict[str, float] = {u.name: u.radius for u in world.ugvs}
        self.radius.update({s.name: 0.5 * math.hypot(*s.size) for s in world.sleds})
        self.coverage: float | None = None
        self.board_half_diagonal = 0.0
        spec = SCENARIO_SPECS.get(scenario.name)  # None: a configuration without observability rules
        if spec is not None and spec.observer_coverage:
            self.coverage = coverage_radius(scenario)
            self.board_half_diagonal = max(
                0.5 * math.hypot(u.board.width, u.board.height) for u in world.ugvs if u.board is not None
            )
        self.views = self._views(spec.motion_views(world) if spec is not None else {})
        cam = scenario.camera
        self.half_fov_u = math.atan((cam.width / 2.0 - cam.margin_px) / cam.fx)
        self.half_fov_v = math.atan((cam.height / 2.0 - cam.margin_px) / cam.fy)
        self.max_range = min(cam.max_range_m, PRACTICAL_MAX_RANGE_M)
        self.cos_max_incidence = math.cos(math.radians(max(cam.max_incidence_deg - INCIDENCE_MARGIN_DEG, 0.0)))
        self.sleds = {s.name: s for s in world.sleds}

    def _views(self, required: Mapping[str, Sequence[str]]) -> list[_View]:
        """The :class:`_View` of every ``camera -> board owners`` pair of ``required``, in order."""
        world = self.scenario.world
        cameras = {mount.name: (ugv, mount) for ugv in world.ugvs for mount in ugv.cameras}
        carriers = {ugv.name: ugv for ugv in world.ugvs if ugv.board is not None}
        carriers.update({sled.name: sled for sled in world.sleds})
        views = []
        for cam, owners in required.items():
            if cam not in cameras:
                raise ValueError(f"{self.scenario.name}: motion view of unknown camera {cam!r}; cameras: {sorted(cameras)}")
            robot, mount = cameras[cam]
            for owner in owners:
                if owner not in carriers:
                    raise ValueError(f"{self.scenario.name}: motion view of {cam!r} on {owner!r}, which carries no board")
                carrier = carriers[owner]
                half = (0.5 * carrier.board.width, 0.5 * carrier.board.height)
                views.append(_View(cam, robot.name, mount.T_b_c, carrier.name, carrier.board_mount, *half))
        return views

    # -- per-leg checks ------------------------------------------------------------------

    def leg_violations(self, device: str, waypoints: Sequence[Pose2D], poses: Mapping[str, Pose2D]) -> list[str]:
        """Violations of rules 2-4 by ``device`` driving ``waypoints`` while the other
        devices stay at ``poses`` (device -> pose; the mover's own entry is ignored).

        Raises KeyError for an unknown device."""
        if device not in self.radius:
            raise KeyError(f"unknown device {device!r}; devices are {sorted(self.radius)}")
        out: list[str] = []
        length = sum(math.hypot(b[0] - a[0], b[1] - a[1]) for a, b in zip(waypoints, waypoints[1:]))
        if length > self.scenario.leg_length + 1e-9:
            out.append(f"leg length {length:.3f} m exceeds leg_length {self.scenario.leg_length} m")
        samples = sample_polyline(waypoints, self.step_m)
        out += self._collisions(device, samples, poses)
        out += self._observability(device, samples, poses)
        return out

    def _collisions(self, device: str, samples: np.ndarray, poses: Mapping[str, Pose2D]) -> list[str]:
        out = []
        r = self.radius[device]
        xy = samples[:, :2]
        xmin, ymin, xmax, ymax = self.arena.bounds
        wall_gap = np.minimum.reduce([xy[:, 0] - xmin, xy[:, 1] - ymin, xmax - xy[:, 0], ymax - xy[:, 1]]) - r
        if wall_gap.min() < CLEARANCE_M - 1e-9:
            k = int(wall_gap.argmin())
            where = tuple(np.round(xy[k], 3).tolist())
            out.append(f"collision: {device} comes {wall_gap[k]:.3f} m from a wall at {where}")
        for j, box in enumerate(self.arena.obstacles):
            gap = box_distances(xy, box) - r
            if gap.min() < CLEARANCE_M - 1e-9:
                k = int(gap.argmin())
                where = tuple(np.round(xy[k], 3).tolist())
                out.append(f"collision: {device} comes {gap[k]:.3f} m from obstacle[{j}] at {where}")
        for other, pose in poses.items():
            if other == device:
                continue
            gap = np.hypot(xy[:, 0] - pose[0], xy[:, 1] - pose[1]) - r - self.radius[other]
            if gap.min() < CLEARANCE_M - 1e-9:
                k = int(gap.argmin())
                where = tuple(np.round(xy[k], 3).tolist())
                out.append(f"collision: {device} comes {gap[k]:.3f} m from static {other} at {where}")
        return out

    def _observability(self, device: str, samples: np.ndarray, poses: Mapping[str, Pose2D]) -> list[str]:
        out = []
        if self.coverage is not None and device in self.radius:
            others = np.array([p[:2] for name, p in poses.items() if name != device], dtype=float).reshape(-1, 2)
            # Fast pass: the circle about the others' centroid through the farthest point bounds the
            # smallest enclosing circle from above; only samples it cannot clear get the exact test.
            centre = others.mean(axis=0) if len(others) else samples[0, :2]
            reach = np.hypot(*(others - centre).T).max(initial=0.0)
            bound = np.maximum(np.hypot(samples[:, 0] - centre[0], samples[:, 1] - centre[1]), reach)
            unsure = bound + self.board_half_diagonal > self.coverage
            pts = np.empty((len(others) + 1, 2))
            pts[1:] = others
            for pose in samples[unsure]:
                pts[0] = pose[:2]
                spread = enclosing_circle(pts)[2] + self.board_half_diagonal
                if spread > self.coverage + 1e-9:
                    out.append(
                        f"observability: the robots' spread {spread:.3f} m exceeds the observer's coverage "
                        f"radius {self.coverage:.3f} m with {device} at {tuple(np.round(pose[:2], 3).tolist())}"
                    )
                    break
        for view in self.views:
            if device not in (view.camera_owner, view.board_owner):
                continue
            m = len(samples)
            cam_poses = samples if device == view.camera_owner else np.tile(poses[view.camera_owner], (m, 1))
            board_poses = samples if device == view.board_owner else np.tile(poses[view.board_owner], (m, 1))
            reason = self._view_failure(view, np.asarray(cam_poses, float), np.asarray(board_poses, float))
            if reason:
                out.append(f"observability: {view.camera} loses the board of {view.board_owner} ({reason}) "
                           f"while {device} moves")
        for name, sled in self.sleds.items():
            if device not in (name, sled.robot):
                continue
            m = len(samples)
            robot = samples if device == sled.robot else np.tile(poses[sled.robot], (m, 1))
            sled_p = samples if device == name else np.tile(poses[name], (m, 1))
            rope = self._rope_lengths(sled, np.asarray(robot, float), np.asarray(sled_p, float))
            if rope.max() > sled.max_rope + 1e-9 or rope.min() < sled.min_rope - 1e-9:
                out.append(f"observability: rope of {name} reaches [{rope.min():.3f}, {rope.max():.3f}] m, outside "
                           f"[{sled.min_rope}, {sled.max_rope}] m while {device} moves")
        return out

    def _view_failure(self, view: _View, cam_poses: np.ndarray, board_poses: np.ndarray) -> str:
        cam_pos, cam_R = _mount_in_world(cam_poses, view.T_b_c)
        board_pos, board_R = _mount_in_world(board_poses, view.T_b_m)
        v = board_pos - cam_pos
        lateral = np.einsum("mi,mi->m", v, cam_R[:, :, 0])
        vertical = np.einsum("mi,mi->m", v, cam_R[:, :, 1])
        depth = np.einsum("mi,mi->m", v, cam_R[:, :, 2])
        rng = np.linalg.norm(v, axis=1)
        cam = self.scenario.camera
        if depth.min() < cam.min_range_m:
            return f"depth {depth.min():.3f} m < min_range {cam.min_range_m} m"
        if rng.max() > self.max_range:
            return f"range {rng.max():.3f} m > {self.max_range} m"
        spread_u = np.abs(np.arctan2(lateral, depth)) + np.arctan(view.half_w / depth)
        if spread_u.max() > self.half_fov_u - BEARING_MARGIN_RAD:
            return f"horizontal bearing {math.degrees(spread_u.max()):.1f} deg beyond the half-FOV with margin"
        spread_v = np.abs(np.arctan2(vertical, depth)) + np.arctan(view.half_h / depth)
        if spread_v.max() > self.half_fov_v:
            return f"vertical extent {math.degrees(spread_v.max()):.1f} deg beyond the half-FOV"
        facing = -np.einsum("mi,mi->m", v, board_R[:, :, 2]) / rng
        if facing.min() < self.cos_max_incidence:
            return f"incidence {math.degrees(math.acos(min(max(facing.min(), -1.0), 1.0))):.1f} deg too large"
        return ""

    @staticmethod
    def _rope_lengths(sled: SledConfig, robot: np.ndarray, sled_poses: np.ndarray) -> np.ndarray:
        """(m,) anchor-to-anchor rope lengths (m) for robot and sled poses (m, 3)."""
        (ax, ay), (bx, by) = sled.robot_anchor, sled.sled_anchor
        c, s = np.cos(robot[:, 2]), np.sin(robot[:, 2])
        px, py = robot[:, 0] + c * ax - s * ay, robot[:, 1] + s * ax + c * ay
        c, s = np.cos(sled_poses[:, 2]), np.sin(sled_poses[:, 2])
        qx, qy = sled_poses[:, 0] + c * bx - s * by, sled_poses[:, 1] + s * bx + c * by
        return np.hypot(qx - px, qy - py)

    # -- whole plans ---------------------------------------------------------------------

    def goal_violations(self, poses: Mapping[str, Pose2D]) -> list[str]:
        """Rule 5: devices at ``poses`` that miss their goals."""
        out = []
        sc = self.scenario
        for name, goal in sc.goals.items():
            x, y, yaw = poses[name]
            d = math.hypot(x - goal[0], y - goal[1])
            dyaw = abs(float(wrap_angle(yaw - goal[2])))
            if d > sc.goal_tolerance_m or dyaw > sc.goal_tolerance_rad:
                out.append(f"goal: {name} ends {d:.3f} m and {dyaw:.3f} rad from its goal {goal}")
        return out

    def plan_violations(self, plan: Plan) -> list[str]:
        """Every rule violation of ``plan`` (see :func:`validate`)."""
        out = []
        if plan.scenario_name != self.scenario.name:
            out.append(f"plan: made for {plan.scenario_name!r}, scenario is {self.scenario.name!r}")
        if set(plan.start) != set(self.start):
            out.append(f"plan: start names {sorted(plan.start)} differ from the devices {sorted(self.start)}")
            return out
        for name, pose in plan.start.items():
            if not _same_pose(pose, self.start[name]):
                out.append(f"plan: start pose of {name} {pose} is not its initial pose {self.start[name]}")
        poses = dict(self.start)
        for k, turn in enumerate(plan.turns):
            where = f"turn {k} ({turn.device})"
            if turn.device not in poses:
                out.append(f"{where}: move in turns: unknown device; devices are {sorted(poses)}")
                continue
            if not _same_pose(turn.waypoints[0], poses[turn.device]):
                out.append(
                    f"{where}: move in turns: starts at {turn.waypoints[0]}, but {turn.device} was left at "
                    f"{poses[turn.device]}: it moved outside its turn, while another device moved"
                )
            out += [f"{where}: {v}" for v in self.leg_violations(turn.device, turn.waypoints, poses)]
            poses[turn.device] = turn.goal
        out += self.goal_violations(poses)
        return out


def _same_pose(a: Sequence[float], b: Sequence[float]) -> bool:
    return (
        math.hypot(a[0] - b[0], a[1] - b[1]) <= POSE_TOLERANCE
        and abs(float(wrap_angle(a[2] - b[2]))) <= POSE_TOLERANCE
    )


def validate(scenario: Scenario, plan: Plan, *, step_m: float = 0.05) -> list[str]:
    """Violations of the MOMA rules (module docstring) by ``plan`` in ``scenario``; [] if valid.

    Each message starts with the turn (``"turn 3 (ugv_1): "``) and names the rule
    (``move in turns``, ``leg length``, ``collision``, ``observability``, ``goal``).
    """
    if not isinstance(plan, Plan):
        raise TypeError(f"plan must be a Plan, got {type(plan).__name__}")
    return RuleChecker(scenario, step_m).plan_violations(plan)

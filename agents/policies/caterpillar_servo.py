"""The authors' two-robot caterpillar in velocity mode: the follower servos to its stand-off.

:class:`CaterpillarServo` alternates two turns until the leader is at its goal,
then gives the follower one last turn:

* leader turn (``ugv_0``): request mobile, drive with a
  :class:`~moma_env.control.WaypointFollower` on the ESTIMATED pose
  (``infos["ugv_0"]["estimate"]``) to the next point on the straight line to
  the goal, at most ``scenario.leg_length`` m away (keeping the heading; the
  last leg ends at the goal with the goal's yaw), request static;
* follower turn (``ugv_1``): request mobile, servo on the leader's pose relative
  to the follower, read from the follower's observation (``ugv_0.dx``,
  ``ugv_0.dy`` times 2R, ``ugv_0.cos_dyaw``, ``ugv_0.sin_dyaw``), to the pose
  from which its camera sits ``standoff`` m in front of the leader's board along
  the board's normal, facing it; stop within ``position_tolerance`` m and
  ``yaw_tolerance`` rad (the authors' 2 cm and 0.04 rad), request static.

Before every mobile request the turn's robot waits until its ``dwell_remaining``
feature is 0; refused requests are retried every step. Only estimates are read:
observation vectors and the ``infos`` keys of
:data:`~agents.policies.base.ALLOWED_INFO_KEYS`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from agents.policies.base import MOVE, REQUEST, STOP, WAIT, FeatureIndex, read_info
from moma_env.control import WaypointFollower, WaypointFollowerConfig
from moma_env.env.parallel import MomaParallelEnv
from moma_env.geometry import wrap_angle

__all__ = ["CaterpillarServo", "standoff_target"]

LEADER, FOLLOWER = "ugv_0", "ugv_1"


def _planar_axis(v: np.ndarray, what: str) -> float:
    """Heading (rad) of the horizontal part of the 3-vector ``v``."""
    if math.hypot(v[0], v[1]) < 1e-6:
        raise ValueError(f"the {what} is vertical: no planar stand-off is defined")
    return math.atan2(v[1], v[0])


def standoff_target(T_b_c: np.ndarray, T_b_m: np.ndarray, standoff: float) -> tuple[float, float, float]:
    """Follower pose ``(x, y, yaw)`` in the LEADER's body frame (m, m, rad) at the stand-off.

    At that pose the follower's camera (``T_b_c``, follower body <- camera)
    sits ``standoff`` m in front of the leader's board (``T_b_m``, leader body
    <- board) along the board's normal (+z of M, the printed face), with its
    optical axis (+z of C) pointing back at the board. Planar: heights are
    left as mounted.
    """
    if not (isinstance(standoff, (int, float)) and math.isfinite(standoff) and standoff > 0):
        raise ValueError(f"standoff must be a positive finite number (m), got {standoff!r}")
    T_b_c = np.asarray(T_b_c, dtype=float)
    T_b_m = np.asarray(T_b_m, dtype=float)
    if T_b_c.shape != (4, 4) or T_b_m.shape != (4, 4):
        raise ValueError(f"mounts must be 4x4 transforms, got {T_b_c.shape} and {T_b_m.shape}")
    normal_yaw = _planar_axis(T_b_m[:3, 2], "board normal")
    axis_yaw = _planar_axis(T_b_c[:3, 2], "camera axis")
    # Camera position in the leader's frame, and the follower yaw that makes the axis face the board.
    cam_x = T_b_m[0, 3] + standoff * math.cos(normal_yaw)
    cam_y = T_b_m[1, 3] + standoff * math.sin(normal_yaw)
    yaw = float(wrap_angle(normal_yaw + math.pi - axis_yaw))
    c, s = math.cos(yaw), math.sin(yaw)
    tx, ty = T_b_c[0, 3], T_b_c[1, 3]
    return (cam_x - (c * tx - s * ty), cam_y - (s * tx + c * ty), yaw)


class CaterpillarServo:
    """Leader advances, dwell, follower servos to its stand-off, dwell, repeat (module docstring).

    Args:
        standoff: camera-to-board distance of the follower's target (m); the authors' 0.539 m.
        position_gain: proportional gain of the servo on the position error (1/s).
        yaw_gain: proportional gain of the servo on the heading error (1/s).
        position_tolerance: the servo stops within this distance (m).
        yaw_tolerance: ... and within this heading error (rad).
        min_speed: speed floor of the servo outside the position tolerance (m/s).
        settle_s: once inside both tolerances the servo keeps converging (plain
            proportional law) for this long (s) before it stops, so that it does
            not stop on the tolerance's edge; 0 stops at once.
        leader: gains and tolerances of the leader's waypoint follower.
    """

    def __init__(
        self,
        standoff: float = 0.539,
        position_gain: float = 1.5,
        yaw_gain: float = 2.0,
        position_tolerance: float = 0.02,
        yaw_tolerance: float = 0.04,
        min_speed: float = 0.02,
        settle_s: float = 1.0,
        leader: WaypointFollowerConfig | None = None,
    ):
        for name, value in (
            ("standoff", standoff),
            ("position_gain", position_gain),
            ("yaw_gain", yaw_gain),
            ("position_tolerance", position_tolerance),
            ("yaw_tolerance", yaw_tolerance),
            ("min_speed", min_speed),
        ):
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
                raise ValueError(f"{name} must be a positive finite number, got {value!r}")
        self.standoff = float(standoff)
        self.position_gain = float(position_gain)
        self.yaw_gain = float(yaw_gain)
        self.position_tolerance = float(position_tolerance)
        self.yaw_tolerance = float(yaw_tolerance)
        self.min_speed = float(min_speed)
        if isinstance(settle_s, bool) or not isinstance(settle_s, (int, float)) or not math.isfinite(settle_s) or settle_s < 0:
            raise ValueError(f"settle_s must be a non-negative finite number, got {settle_s!r}")
        self.settle_s = float(settle_s)
        self.leader = WaypointFollower(leader or WaypointFollowerConfig(max_speed=0.3, position_tolerance=0.02, yaw_tolerance=0.04))
        self._ready = False

    # ------------------------------------------------------------------ episode facts
    def reset(self, env: MomaParallelEnv, seed: int | None = None) -> None:
        """Read the goal, mounts, limits and layouts (call after ``env.reset``).

        Raises:
            ValueError: the env is not the ``caterpillar`` configuration in velocity action mode.
        """
        if env.config.action_mode != "velocity":
            raise ValueError(f"CaterpillarServo needs action_mode='velocity', got {env.config.action_mode!r}")
        scenario = env.scenario
        if scenario.name != "caterpillar":
            raise ValueError(f"CaterpillarServo needs the 'caterpillar' configuration, got {scenario.name!r}")
        if tuple(env.possible_agents) != (LEADER, FOLLOWER):
            raise ValueError(f"CaterpillarServo needs agents {(LEADER, FOLLOWER)}, got {tuple(env.possible_agents)}")
        world = scenario.world
        follower_cameras = world.ugv(FOLLOWER).cameras
        if not follower_cameras:
            raise ValueError(f"{FOLLOWER} has no camera to servo with")
        self._target = standoff_target(follower_cameras[0].T_b_c, world.ugv(LEADER).board_mount, self.standoff)
        self._goal: tuple[float, float, float] = tuple(float(v) for v in scenario.goals[LEADER])  # type: ignore[assignment]
        self._leg_length = float(scenario.leg_length)
        self._dt = 1.0 / world.control_hz
        self._settled_s = 0.0
        xmin, ymin, xmax, ymax = world.arena.bounds
        self._two_r = math.hypot(xmax - xmin, ymax - ymin)  # 2R, R = the arena half-diagonal
        self._features = {a: FeatureIndex(env.layout.features[a]) for a in env.possible_agents}
        self._shapes = {a: env.action_space(a).shape for a in env.possible_agents}
        # Body-velocity command (m/s, m/s, rad/s) -> action scale.
        self._scale = {u.name: np.array([u.max_speed, u.max_speed, u.max_yaw_rate]) for u in world.ugvs}
        f = self._features[FOLLOWER]
        self._rel = (f[f"{LEADER}.dx"], f[f"{LEADER}.dy"], f[f"{LEADER}.cos_dyaw"], f[f"{LEADER}.sin_dyaw"], f[f"{LEADER}.valid"])
        self.mover = LEADER
        self.leader_at_goal = False
        self.done = False
        self.follower_turns = 0
        self._phase = WAIT
        self._leg: tuple[float, float, float] | None = None
        self._ready = True

    # ------------------------------------------------------------------ acting
    def act(self, observations: Mapping[str, np.ndarray], infos: Mapping[str, Mapping[str, Any]]) -> dict[str, np.ndarray]:
        """Actions of both robots: the turn's robot moves, the other holds static."""
        if not self._ready:
            raise RuntimeError("call reset(env) before act()")
        actions = {a: self._hold(a) for a in observations}
        if self.done or self.mover not in observations:
            return actions
        events = read_info(infos, self.mover, "events") or ()
        if self._phase == REQUEST and f"mobile:{self.mover}" in events:
            self._phase = MOVE
        elif self._phase == STOP and f"static:{self.mover}" in events:
            self._next_turn()
            if self.done:
                return actions
        mover = self.mover
        if self._phase == WAIT and observations[mover][self._features[mover]["dwell_remaining"]] <= 0.0:
            self._phase = REQUEST
        action = actions[mover]
        if self._phase == REQUEST:  # retried every step until granted
            action[3] = 1.0
        elif self._phase == MOVE:
            action[3] = 1.0
            if mover == LEADER:
                self._drive(action, infos)
            else:
                self._servo(action, observations[FOLLOWER], infos)
        return actions

    def _hold(self, agent: str) -> np.ndarray:
        action = np.zeros(self._shapes[agent], dtype=np.float32)
        action[3] = -1.0
        return action

    def _next_turn(self) -> None:
        if self.mover == FOLLOWER:
            self.follower_turns += 1
            self.done = self.leader_at_goal
            self.mover = LEADER
        else:
            self.mover = FOLLOWER
        self._phase = WAIT
        self._leg = None
        self._settled_s = 0.0

    def _localised_estimate(self, infos: Mapping[str, Mapping[str, Any]], agent: str) -> tuple[float, float, float] | None:
        estimate = read_info(infos, agent, "estimate")
        if estimate is None or read_info(infos, agent, "status") != "localised":
            return None
        return estimate

    def _drive(self, action: np.ndarray, infos: Mapping[str, Mapping[str, Any]]) -> None:
        """Leader: follow the leg on its estimate (stop while not localised); at its end request static."""
        estimate = self._localised_estimate(infos, LEADER)
        if estimate is None:
            return  # hold still, mobile, until localised again
        if self._leg is None:
            self._leg = self._next_leg(estimate)
        if self.leader.reached(estimate, self._leg):
            if self._leg == self._goal:
                self.leader_at_goal = True
            action[3] = -1.0
            self._phase = STOP
            return
        command = self.leader.command(estimate, self._leg)
        np.clip(command / self._scale[LEADER], -1.0, 1.0, out=command)
        action[:3] = command

    def _next_leg(self, pose: tuple[float, float, float]) -> tuple[float, float, float]:
        """At most ``leg_length`` along the straight line to the goal, keeping the heading; else the goal."""
        x, y, yaw = pose
        dx, dy = self._goal[0] - x, self._goal[1] - y
        dist = math.hypot(dx, dy)
        if dist <= self._leg_length:
            return self._goal
        f = self._leg_length / dist
        return (x + f * dx, y + f * dy, yaw)

    def _servo(self, action: np.ndarray, observation: np.ndarray, infos: Mapping[str, Mapping[str, Any]]) -> None:
        """Follower: proportional servo to the stand-off on the leader's relative pose; at it request static."""
        i_dx, i_dy, i_cos, i_sin, i_valid = self._rel
        if observation[i_valid] < 0.5 or read_info(infos, FOLLOWER, "status") != "localised":
            return  # hold still, mobile, until the relative pose is known again
        # T_F_L: the leader in the follower's body frame.
        lx, ly = float(observation[i_dx]) * self._two_r, float(observation[i_dy]) * self._two_r
        lyaw = math.atan2(float(observation[i_sin]), float(observation[i_cos]))
        # Target in the follower's frame: T_F_target = T_F_L * T_L_target.
        tx, ty, tyaw = self._target
        c, s = math.cos(lyaw), math.sin(lyaw)
        ex, ey = lx + c * tx - s * ty, ly + s * tx + c * ty
        eyaw = float(wrap_angle(lyaw + tyaw))
        dist = math.hypot(ex, ey)
        scale = self._scale[FOLLOWER]
        if dist <= self.position_tolerance and abs(eyaw) <= self.yaw_tolerance:
            if self._settled_s >= self.settle_s:
                action[3] = -1.0
                self._phase = STOP
                return
            self._settled_s += self._dt
            vx, vy, omega = self.position_gain * ex, self.position_gain * ey, self.yaw_gain * eyaw
        else:
            self._settled_s = 0.0
            if dist > self.position_tolerance:
                speed = min(scale[0], max(self.min_speed, self.position_gain * dist)) / dist
                vx, vy = ex * speed, ey * speed
            else:
                vx = vy = 0.0
            omega = self.yaw_gain * eyaw if abs(eyaw) > self.yaw_tolerance else 0.0
        action[0] = min(1.0, max(-1.0, vx / scale[0]))
        action[1] = min(1.0, max(-1.0, vy / scale[1]))
        action[2] = min(1.0, max(-1.0, omega / scale[2]))

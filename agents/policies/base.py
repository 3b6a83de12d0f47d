"""The policy protocol and what every scripted policy reads from an episode.

A policy acts on ESTIMATED state only: the observation vectors (decoded through
``env.layout.features``) and the non-truth keys of ``infos`` listed in
:data:`ALLOWED_INFO_KEYS`. At ``reset`` it may read the static facts a robot
knows beforehand: its agents, action spaces, feature layouts, goals, the arena
normalisation and the switching parameters (leg length, dwell, goal tolerance).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any, Protocol, runtime_checkable

import numpy as np

from moma_env.env.parallel import MomaParallelEnv

__all__ = [
    "Policy",
    "ALLOWED_INFO_KEYS",
    "FORBIDDEN_INFO_KEYS",
    "read_info",
    "FeatureIndex",
    "GoalReader",
    "StallWatch",
    "check_stall_settings",
    "HOLD",
    "ADVANCE",
    "REEL",
    "WAIT",
    "REQUEST",
    "MOVE",
    "STOP",
]

#: ``infos`` keys a policy may read (nothing here is ground truth).
ALLOWED_INFO_KEYS = frozenset({"events", "refused", "status", "static", "estimate", "action_mask"})
#: ``infos`` keys that carry ground truth (or are derived from it): never read by a policy.
FORBIDDEN_INFO_KEYS = frozenset({"truth", "localisation_error", "sled_truth", "sled_localisation_error", "reached_goal"})


#: Phases of a velocity-mode turn: wait for the dwell, request mobile, move, request static.
WAIT, REQUEST, MOVE, STOP = "wait", "request", "move", "stop"


def read_info(infos: Mapping[str, Mapping[str, Any]], agent: str, key: str) -> Any:
    """``infos[agent][key]`` for a non-truth key only (None if the agent has no info)."""
    if key not in ALLOWED_INFO_KEYS:
        raise KeyError(f"a policy may not read infos[{agent!r}][{key!r}] (allowed: {sorted(ALLOWED_INFO_KEYS)})")
    info = infos.get(agent)
    return None if info is None else info.get(key)

#: Switching-mode actions of a UGV.
HOLD, ADVANCE, REEL = 0, 1, 2


@runtime_checkable
class Policy(Protocol):
    """A team policy: one call decides every live agent's action."""

    def reset(self, env: MomaParallelEnv, seed: int | None = None) -> None:
        """Read the episode's static facts (call after ``env.reset``)."""

    def act(self, observations: Mapping[str, np.ndarray], infos: Mapping[str, Mapping[str, Any]]) -> dict[str, Any]:
        """Actions of every agent in ``observations``."""


class FeatureIndex:
    """Named access to one agent's observation vector.

    Args:
        features: the agent's layout, ``env.layout.features[agent]``.
    """

    def __init__(self, features: Sequence[Any]):
        self._index = {f.name: i for i, f in enumerate(features)}

    def __getitem__(self, name: str) -> int:
        try:
            return self._index[name]
        except KeyError:
            raise KeyError(f"no feature {name!r} in this layout") from None

    def __contains__(self, name: str) -> bool:
        return name in self._index


class GoalReader:
    """Decodes the UGVs' observations of one episode: own pose, goal distance, at goal.

    Read at reset from the static facts a robot knows (the layouts, goals, arena
    normalisation and goal tolerances); every estimate comes from the observation.

    Args:
        env: the env, just reset.
        agents: the UGV agents to decode.
    """

    def __init__(self, env: MomaParallelEnv, agents: Sequence[str]):
        scenario = env.scenario
        xmin, ymin, xmax, ymax = scenario.world.arena.bounds
        self.two_r = math.hypot(xmax - xmin, ymax - ymin)  # 2 * half-diagonal: the goal.distance scale (m)
        self.half_diagonal = 0.5 * self.two_r  # the own.x, own.y scale (m)
        self.goal_tolerance_m = scenario.goal_tolerance_m
        self.goal_tolerance_rad = scenario.goal_tolerance_rad
        self.goals = dict(scenario.goals)
        self._features = {a: FeatureIndex(env.layout.features[a]) for a in agents}

    def feature(self, agent: str, observations: Mapping[str, np.ndarray], name: str) -> float:
        """One named feature of ``agent``'s observation."""
        return float(observations[agent][self._features[agent][name]])

    def goal_distance(self, agent: str, observations: Mapping[str, np.ndarray]) -> float:
        """Estimated distance (m) from ``agent`` to its goal; inf if unknown, 0 without a goal."""
        if agent not in self.goals:
            return 0.0
        if self.feature(agent, observations, "own.valid") < 0.5:
            return math.inf
        return self.feature(agent, observations, "goal.distance") * self.two_r

    def at_goal(self, agent: str, observations: Mapping[str, np.ndarray]) -> bool:
        """Whether ``agent``'s estimate is within its goal's position and heading tolerances,
        as the env judges a goal reached (an agent without a goal is always there)."""
        if agent not in self.goals:
            return True
        if self.goal_distance(agent, observations) > self.goal_tolerance_m:
            return False
        f = self.feature
        dyaw = math.atan2(f(agent, observations, "goal.sin_dyaw"), f(agent, observations, "goal.cos_dyaw"))
        return abs(dyaw) <= self.goal_tolerance_rad

    def pose(self, agent: str, observations: Mapping[str, np.ndarray]) -> tuple[float, float, float] | None:
        """``agent``'s estimated ``(x m, y m, yaw rad)`` in W, None when it has none."""
        f = self.feature
        if f(agent, observations, "own.valid") < 0.5:
            return None
        return (
            f(agent, observations, "own.x") * self.half_diagonal,
            f(agent, observations, "own.y") * self.half_diagonal,
            math.atan2(f(agent, observations, "own.sin_yaw"), f(agent, observations, "own.cos_yaw")),
        )


class StallWatch:
    """Tells a mover that has not moved: its estimate changed by less than ``stall_m`` (m)
    and ``stall_rad`` (rad) for more than ``stall_steps`` steps (an unknown pose counts as
    not moving)."""

    def __init__(self, stall_steps: int, stall_m: float, stall_rad: float):
        self.stall_steps = stall_steps
        self.stall_m = stall_m
        self.stall_rad = stall_rad
        self.clear()

    def clear(self) -> None:
        """Forget the anchor (a new leg starts)."""
        self._anchor: tuple[float, float, float] | None = None
        self._age = 0

    def stalled(self, pose: tuple[float, float, float] | None) -> bool:
        """Note this step's pose; True once the mover has not moved for ``stall_steps``."""
        anchor = self._anchor
        if pose is not None and (
            anchor is None
            or math.hypot(pose[0] - anchor[0], pose[1] - anchor[1]) > self.stall_m
            or abs(math.remainder(pose[2] - anchor[2], math.tau)) > self.stall_rad
        ):
            self._anchor = pose
            self._age = 0
            return False
        self._age += 1
        return self._age > self.stall_steps


def check_stall_settings(**settings: float) -> None:
    """ValueError naming the first setting that is not a positive finite number."""
    for name, value in settings.items():
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
            raise ValueError(f"{name} must be a positive finite number, got {value!r}")

"""Named coordination tasks: a configuration with the options that make a study.

A configuration (``top_observer``, ...) is a kind of rig; a *task* fixes what a
comparison of policies needs: the team, random layouts with held-out seeds, the
action mode, the masks and the team objective (the reward's weights). Every
constructor that takes a configuration name takes a task name too
(``parallel_env("top_observer_team4")``, ``moma_env.vector.make(...)``, ``moma-env
evaluate --scenario``, ``moma-env train --scenario``); keywords given there override
the task's. Each task also has a Gymnasium id (``gymnasium.make("moma_env/TopObserverTeam4-v0")``
and ``gymnasium.make_vec``), registered with the configurations' ids.

Every task runs in switching mode with the action masks and ``commit_legs`` (a leg
once started runs to its end: a learner decides when to start a robot, not when to
interrupt it).

Tasks where coordination matters (with two robots one must always stay behind as
the reference, so there is little to coordinate):

* ``top_observer_team4`` and ``top_observer_team6``: 4 (6) UGVs under the UAV on
  random layouts, arriving twice (1.5 times) as spread out as they start, so the
  UAV climbs to keep the team in view and its ceiling bounds the spread; several
  robots may move at once as long as each stays observed from a static reference.
* ``top_observer_team4_legs``: ``top_observer_team4`` where each robot also chooses
  how far a leg goes (0.5, 1, 1.5 or 2 m; ``EnvConfig.leg_lengths``): short legs stop
  often and wait out a switch window each time, long ones carry a robot out of the
  UAV's view; the same layouts and objective.
* ``caterpillar_multi_bend4``: a file of 4 robots, each follower's camera on the
  board of the robot ahead, that must jog 0.5 m sideways around a wall on random
  layouts: the file bends, so a follower keeps its board in view only if the
  robots ahead do not run too far into the turn; several robots may move at once
  as long as each keeps a static neighbour in view.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from moma_env.config import ConfigError

__all__ = ["Task", "TASKS", "TEAM_REWARDS", "task_options"]


@dataclass(frozen=True)
class Task:
    """A named study setting of one configuration.

    Attributes:
        name: the task's name (what constructors take in place of a configuration).
        gymnasium_id: its Gymnasium id (the whole team as one agent, as the
            configurations' ids), e.g. ``"moma_env/TopObserverTeam4-v0"``.
        configuration: the configuration it runs.
        options: keywords of ``moma_env.env.factory.parallel_env``: env options and
            configuration fields.
        objective: one line on what the team is rewarded for.
    """

    name: str
    gymnasium_id: str
    configuration: str
    options: Mapping[str, Any] = field(default_factory=dict)
    objective: str = ""

    def __post_init__(self) -> None:
        object.__setattr__(self, "options", MappingProxyType(dict(self.options)))


#: The team objective of the coordination tasks (``RewardConfig`` weights): reach every
#: goal soon (a time cost per step, a bonus per goal, progress per metre), keep the
#: estimates accurate on the way (a cost per metre of mean error per step) and at the end
#: (a cost per metre of mean error when the last goal is reached), and ask only for what
#: the rules grant (refusals cost). The other weights are ``RewardConfig``'s defaults.
TEAM_REWARDS: Mapping[str, float] = MappingProxyType(
    {"progress": 1.0, "localisation_error": -0.5, "refused": -0.05, "goal_bonus": 5.0, "time": -0.01, "final_error": -50.0}
)

#: The leg lengths (m) of ``top_observer_team4_legs``: the task's own 0.5 m and up to
#: 2 m, beyond which the greedy policy's robots lose track in about a third of the
#: episodes (docs/baselines.md).
TEAM4_LEG_LENGTHS = (0.5, 1.0, 1.5, 2.0)


def _coordination(**fields: Any) -> dict[str, Any]:
    """A coordination task's options: ``fields`` (its team and layouts) and what every task
    fixes: random layouts, switching mode with the masks and committed legs, the team objective."""
    common = {"random_scenarios": True, "action_mode": "switching", "action_masks": True, "commit_legs": True}
    return {**fields, **common, "rewards": dict(TEAM_REWARDS)}


_TASK_LIST = (
    Task(
        "top_observer_team4",
        "moma_env/TopObserverTeam4-v0",
        "top_observer",
        _coordination(n_ugvs=4, goal_spread=2.0),
        "4 UGVs to spread goals under one UAV: time, goals, localisation error on the way and at the end, refusals",
    ),
    Task(
        "top_observer_team6",
        "moma_env/TopObserverTeam6-v0",
        "top_observer",
        _coordination(n_ugvs=6, goal_spread=1.5),
        "6 UGVs to spread goals under one UAV: time, goals, localisation error on the way and at the end, refusals",
    ),
    Task(
        "top_observer_team4_legs",
        "moma_env/TopObserverTeam4Legs-v0",
        "top_observer",
        _coordination(n_ugvs=4, goal_spread=2.0, leg_lengths=TEAM4_LEG_LENGTHS),
        "4 UGVs to spread goals under one UAV, each leg's length chosen: time, goals, localisation error on the way and at the end, refusals",
    ),
    Task(
        "caterpillar_multi_bend4",
        "moma_env/CaterpillarMultiBend4-v0",
        "caterpillar_multi",
        _coordination(n_ugvs=4, bend=0.5, goal_distance=2.5),
        "a file of 4 robots around a wall: time, goals, localisation error on the way and at the end, refusals",
    ),
)

#: Task name -> :class:`Task` (read-only).
TASKS: Mapping[str, Task] = MappingProxyType({task.name: task for task in _TASK_LIST})


def task_options(name: str, **overrides: Any) -> tuple[str, dict[str, Any]]:
    """``(configuration, options)`` of task ``name`` with ``overrides`` applied on top.

    Raises:
        ConfigError: naming ``task`` if ``name`` is no task.
    """
    task = TASKS.get(name) if isinstance(name, str) else None
    if task is None:
        raise ConfigError("task", f"unknown task {name!r}; known: {sorted(TASKS)}")
    return task.configuration, {**task.options, **overrides}

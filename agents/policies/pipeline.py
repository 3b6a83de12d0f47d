"""A file of robots in a pipeline: every other robot moves at once, each between static neighbours.

Turn taking (:class:`~agents.policies.caterpillar_multi.CaterpillarMulti`) moves a file
one robot at a time, leader first, then each follower in turn. The greedy parallel
policy (:class:`~agents.policies.greedy.GreedyParallelPolicy`) starts whoever the masks
allow, and on a file that fails twice: it starts a follower whose way is still blocked by
the robot ahead (its leg stalls), and it lets neighbours move together, so a mover can
lose the view that let it start before its leg ends, with no static camera left to find
it (on the bent file, ``caterpillar_multi_bend4``, every greedy episode lost track of a
robot).

:class:`FilePipelinePolicy` keeps turn taking's order and moves several robots at once
where the file allows it. A static robot not at its goal starts a leg when, besides the
action mask and the dwell (as for the greedy policy, farthest from its goal first, one
new mover per step):

* no neighbour moves: the robots it shares a motion view with (the configuration's
  ``motion_views``; in a file, the robot ahead and the robot behind) are static, so
  every mover is watched by a static camera behind it and watches a static board ahead
  for its whole leg, as under turn taking;
* the robot ahead has taken more legs than it since the episode began (or is at its
  goal): a follower moves up only into room the robot ahead has made;
* for the leader, the robot behind it has taken as many legs as the leader (or is at
  its goal): the leader runs at most one leg ahead of its follower's view, as under
  turn taking.

After the leader's first leg and its follower's, the file alternates between two sets
of movers, the robots at even places and those at odd places, so a file of four moves
two robots at a time. It reads what the greedy policy reads (observations, the
non-truth infos ``static`` and ``action_mask``) and at reset the rig's motion views, a
static fact of the configuration.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from agents.policies.base import ADVANCE, read_info
from agents.policies.greedy import GreedyParallelPolicy
from moma_env.env.parallel import MomaParallelEnv
from moma_env.scenarios import SCENARIO_SPECS, view_neighbours

__all__ = ["FilePipelinePolicy"]


class FilePipelinePolicy(GreedyParallelPolicy):
    """See the module docstring; the arguments are :class:`GreedyParallelPolicy`'s.

    Raises (at reset):
        ValueError: the env's UGVs share no motion views that form a file, ``ugv_0``
            first (each robot's neighbours are the robots just before and after it).
    """

    def reset(self, env: MomaParallelEnv, seed: int | None = None) -> None:
        """Read the file's order and every robot's neighbours; forget the last episode."""
        super().reset(env, seed)
        spec = SCENARIO_SPECS.get(env.scenario.name)
        world = env.scenario.world
        shared = view_neighbours(world, spec.motion_views(world) if spec is not None else {})
        file = self.ugvs
        for k, agent in enumerate(file):
            expected = {file[j] for j in (k - 1, k + 1) if 0 <= j < len(file)}
            if shared[agent] != expected:
                raise ValueError(
                    f"FilePipelinePolicy needs a file of robots sharing views with the robots just before and after "
                    f"them ({' - '.join(file)}); {agent!r} shares views with {sorted(shared[agent])} in "
                    f"{env.scenario.name!r}"
                )
        #: UGV -> the UGVs just before and after it in the file.
        self.neighbours = {agent: shared[agent] for agent in file}
        #: UGV -> legs it has started this episode.
        self.legs = {agent: 0 for agent in file}
        self._static = {agent: True for agent in file}

    def plan(
        self, observations: Mapping[str, np.ndarray], infos: Mapping[str, Mapping[str, Any]]
    ) -> tuple[dict[str, int], list[str]]:
        """:meth:`GreedyParallelPolicy.plan` with only the starts the pipeline allows (see the
        module docstring); :meth:`act` starts the first. Counts the legs started since the
        last call (call it, or :meth:`act`, once per step)."""
        self._count_legs(infos)
        actions, startable = super().plan(observations, infos)
        moving = {agent for agent, action in actions.items() if action == ADVANCE}
        return actions, [agent for agent in startable if self._may_start(agent, moving, observations)]

    def _count_legs(self, infos: Mapping[str, Mapping[str, Any]]) -> None:
        for agent in self.legs:
            static = read_info(infos, agent, "static")
            if static is None:
                continue
            if self._static[agent] and not static:
                self.legs[agent] += 1
            self._static[agent] = bool(static)

    def _may_start(self, agent: str, moving: set[str], observations: Mapping[str, np.ndarray]) -> bool:
        if self.neighbours[agent] & moving:
            return False
        file = self.ugvs
        k = file.index(agent)
        if k > 0:
            ahead = file[k - 1]
            return self.legs[agent] < self.legs[ahead] or self._done(ahead, observations)
        if len(file) > 1:
            behind = file[1]
            return self.legs[agent] <= self.legs[behind] or self._done(behind, observations)
        return True

    def _done(self, agent: str, observations: Mapping[str, np.ndarray]) -> bool:
        """Whether ``agent`` counts as at its goal (as estimated); a robot that left the episode does."""
        return agent not in observations or self.reader.at_goal(agent, observations)

"""A lookahead over the greedy policy's starts, with the simulator as its model.

:class:`~agents.policies.greedy.GreedyParallelPolicy` takes one decision per step that
a schedule could take differently: which static robot starts a leg when the rules let
one start (the farthest from its goal), or none. :class:`GreedyRolloutPolicy` tries
every choice the masks allow at such a step: for each it copies the env, applies the
choice, lets the greedy policy finish the episode in the copy, and keeps the choice
whose copy reached every goal soonest (the greedy's own on a tie). This is the rollout
algorithm of approximate dynamic programming with the greedy policy as its base (or
another :class:`~agents.policies.greedy.GreedyParallelPolicy`: with the file pipeline,
:class:`~agents.policies.pipeline.FilePipelinePolicy`, as ``base``, ``--policy
pipeline_rollout``, it tries the starts the pipeline allows and lets the pipeline finish;
with a greedy policy as ``candidates`` as well, ``--policy pipeline_rollout_masks``, it tries
every start the masks allow, neighbours of movers included, and lets the pipeline finish): the
copy carries the env's generators, so its future is the env's own for the same
actions, and the policy never reaches the goals later than the greedy policy on the
same seed (:meth:`GreedyRolloutPolicy.act` keeps a choice only when its copy is
faster than the best continuation already found).

It is a planner, not an agent: it reads the whole simulator (the future camera noise
included) through the env it is reset with, so it measures how much better the
schedule of starts can be on a layout, and can teach a learner; it is not a policy a
robot could run. Its cost is a rollout of the rest of the episode per choice and
decision step (seconds per episode on ``top_observer_team4``), less two savings that
change no decision:

* the greedy's choice is not rolled out again while the env follows the rollout of the
  choice taken at the last decision step (that choice, then the greedy's actions): the
  env is where that rollout was, and the greedy's choice now is its continuation, so
  its time is already known. Each rollout records, step by step, its copy's time, true
  and estimated poses and movers, and the time is reused only while the env's match
  them bit for bit (an env driven by other actions, a learner's, gets a fresh rollout);
* a rollout stops once its copy's time reaches the best time found so far with a goal
  still to reach: it can no longer win.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from agents.policies.greedy import GreedyParallelPolicy
from moma_env.env.parallel import MomaParallelEnv
from moma_env.sim import Frame

__all__ = ["GreedyRolloutPolicy", "state_signature"]


class GreedyRolloutPolicy:
    """See the module docstring.

    Args:
        wait: also try starting no robot at a step where one may start.
        reuse: take the greedy's choice's time from the rollout of the last choice taken
            while the env follows it (see the module docstring); False rolls it out
            again (the same decisions, one rollout more per decision step).
        base: the base policy, a :class:`GreedyParallelPolicy` (its :meth:`plan` gives the
            starts to try; default: a new greedy policy with the ``greedy`` settings), e.g. a
            :class:`~agents.policies.pipeline.FilePipelinePolicy` on a file of robots.
        candidates: None (the base's starts are tried), or another :class:`GreedyParallelPolicy`
            whose :meth:`~GreedyParallelPolicy.plan` gives the starts to try at each step (the
            base's own start, or none, is still tried first), e.g. a greedy policy beside the
            pipeline as base: every start the masks allow, with the pipeline finishing each
            rollout. It acts on the env only through this policy's choices.
        lengths: also try every leg length the env offers for each start (an env with
            ``EnvConfig.leg_lengths``; the base's own start, with its length, first), so
            that the lookahead chooses how far each leg goes as well as who starts.
        **greedy: settings of the default base :class:`GreedyParallelPolicy` (its stall watch).

    Attributes:
        lookaheads: rollouts run since :meth:`reset` (one per choice tried, but the
            reused ones).
        reused: decision steps whose greedy choice took its time from the last rollout.
        overrides: decision steps at which a choice other than the greedy's won.
        expected_time_s: the time to goal (s) of the choice taken at the last decision
            step, as its rollout found it (NaN before the first; ``inf`` if every
            rollout was truncated). Never grows over an episode: the greedy's choice at
            the next decision step continues that rollout.
    """

    env_options: Mapping[str, Any] = GreedyParallelPolicy.env_options

    def __init__(
        self,
        wait: bool = True,
        reuse: bool = True,
        base: GreedyParallelPolicy | None = None,
        candidates: GreedyParallelPolicy | None = None,
        lengths: bool = False,
        **greedy: float,
    ):
        for name, value in (("wait", wait), ("reuse", reuse), ("lengths", lengths)):
            if not isinstance(value, bool):
                raise TypeError(f"{name} must be a bool, got {type(value).__name__}")
        if base is not None and not isinstance(base, GreedyParallelPolicy):
            raise TypeError(f"base must be a GreedyParallelPolicy, got {type(base).__name__}")
        if candidates is not None and not isinstance(candidates, GreedyParallelPolicy):
            raise TypeError(f"candidates must be a GreedyParallelPolicy, got {type(candidates).__name__}")
        if candidates is not None and candidates is base:
            raise ValueError("candidates must be another policy than base (each keeps its own state)")
        if base is not None and greedy:
            raise ValueError(f"the greedy settings {sorted(greedy)} are for the default base; give them to the base policy")
        self.wait = wait
        self.reuse = reuse
        self.lengths = lengths
        self.base = GreedyParallelPolicy(**greedy) if base is None else base
        self.candidates = candidates
        self._env: MomaParallelEnv | None = None

    def reset(self, env: MomaParallelEnv, seed: int | None = None) -> None:
        """Reset the base policy on ``env`` (already reset) and keep ``env`` as the model."""
        self.base.reset(env, seed)
        if self.candidates is not None:
            self.candidates.reset(env, seed)
        self._env = env
        # the base's reset checked the switching mode: its advances are actions 1..n_advances
        self._start_actions = tuple(range(1, 1 + env.action_mode.n_advances)) if self.lengths else None
        self.lookaheads = 0
        self.reused = 0
        self.overrides = 0
        self.expected_time_s = math.nan
        self._ahead: dict[int, tuple] = {}  # step -> the taken choice's rollout's state signature

    def act(self, observations: Mapping[str, np.ndarray], infos: Mapping[str, Mapping[str, Any]]) -> dict[str, int]:
        """The greedy's actions, with the start that reaches the goals soonest in a copy of the env."""
        if self._env is None:
            raise RuntimeError("call reset(env) before act()")
        actions, base_starts = self.base.plan(observations, infos)
        start = self.base.start_action
        own = actions | {base_starts[0]: start} if base_starts else actions  # the base's act()
        startable = base_starts if self.candidates is None else self.candidates.plan(observations, infos)[1]
        if not startable:
            return own
        # The base's choice first (a tie keeps it, and the reuse below continues its rollout).
        tried = (start,) if self._start_actions is None else self._start_actions
        choices = [own] + [choice for choice in (actions | {agent: a} for agent in startable for a in tried) if choice != own]
        if self.wait and base_starts:  # waiting is not already the base's choice
            choices.append(actions)
        if len(choices) == 1:
            return choices[0]  # nothing to choose: no lookahead (expected_time_s stays)
        frame = self._env.frame
        if self.reuse and self._ahead.get(frame.steps) == state_signature(frame):
            self.reused += 1
            best, best_time, ahead = choices[0], self.expected_time_s, self._ahead
        else:
            best, (best_time, ahead) = choices[0], self._rollout(choices[0])
        for choice in choices[1:]:
            time, signatures = self._rollout(choice, limit=best_time)
            if time < best_time:
                best, best_time, ahead = choice, time, signatures
        if best is not choices[0]:
            self.overrides += 1
        self.expected_time_s = best_time
        self._ahead = ahead
        return best

    def time_to_goal(self, actions: Mapping[str, int]) -> float:
        """Simulated time (s) at which every goal is reached if this step's ``actions`` are
        taken and the greedy policy acts from the next step on, in a copy of the env and of
        the base policy (the env itself is not touched); ``inf`` if the episode is
        truncated first."""
        return self._rollout(actions)[0]

    def _rollout(self, actions: Mapping[str, int], limit: float = math.inf) -> tuple[float, dict[int, tuple]]:
        """:meth:`time_to_goal` and the copy's :func:`state_signature` after each of its steps, by
        step; ``inf`` and no signatures as soon as the copy's time reaches ``limit`` (s) with a
        goal still to reach (it cannot beat a choice reaching them all at ``limit``)."""
        if self._env is None:
            raise RuntimeError("call reset(env) before time_to_goal()")
        self.lookaheads += 1
        env = copy.deepcopy(self._env)
        base = copy.deepcopy(self.base)
        signatures = {}
        observations, _, terminations, _, infos = env.step(dict(actions))
        while env.agents:
            if env.frame.time >= limit:
                return math.inf, {}
            signatures[env.frame.steps] = state_signature(env.frame)
            observations, _, terminations, _, infos = env.step(base.act(observations, infos))
        return (float(env.frame.time) if any(terminations.values()) else math.inf), signatures


def state_signature(frame: Frame) -> tuple:
    """What tells two envs of one episode apart after a step: the simulated time (s), every
    device's true and estimated planar pose (m, rad) and the devices declared mobile."""
    return frame.time, tuple(frame.truth.values()), tuple(frame.estimated.values()), frame.mobile

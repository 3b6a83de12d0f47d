"""Caterpillars of UGVs in a file: leader first, then each follower in turn."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from agents.policies.base import ADVANCE
from agents.policies.turns import Move, TurnTakingPolicy
from moma_env.env.parallel import MomaParallelEnv

__all__ = ["CaterpillarMulti", "CaterpillarTwo"]


class CaterpillarMulti(TurnTakingPolicy):
    """N robots in a file (``ugv_0`` leads): they advance in file order, one at a time.

    Every other robot is static while one advances, so the mover is always seen
    from (or sees) a static neighbour; robots already at their goal are skipped.
    """

    min_robots = 2
    max_robots: int | None = None

    def reset(self, env: MomaParallelEnv, seed: int | None = None) -> None:
        super().reset(env, seed)
        n = len(self.ugvs)
        if n < self.min_robots or (self.max_robots is not None and n > self.max_robots):
            raise ValueError(f"{type(self).__name__} needs {self.min_robots}..{self.max_robots or 'N'} robots, the env has {n}")

    def _next_moves(self, observations: Mapping[str, np.ndarray]) -> Sequence[Move]:
        n = len(self.ugvs)
        start = 0 if self.last_move is None else (self.ugvs.index(self.last_move.agent) + 1) % n
        order = [self.ugvs[(start + k) % n] for k in range(n)]
        return [Move(a, ADVANCE, a) for a in order if a in observations and not self.at_goal(a, observations)]


class CaterpillarTwo(CaterpillarMulti):
    """The paper's two-robot caterpillar: leader advances, dwell, follower advances, repeat.

    The follower's built-in advance goes towards its own goal, which is offset
    from the leader's like the starts, so the stand-off is kept.
    """

    max_robots = 2

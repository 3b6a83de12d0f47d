"""Single-robot caterpillar: the robot advances while its sled is static, then reels it in."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from agents.policies.base import ADVANCE, REEL
from agents.policies.turns import Move, TurnTakingPolicy
from moma_env.env.parallel import MomaParallelEnv

__all__ = ["CaterpillarSled"]


class CaterpillarSled(TurnTakingPolicy):
    """Advance (sled static, the robot's camera sees the sled's board), then reel (robot
    static, the sled is measured while it comes in); repeat until the robot's goal."""

    def reset(self, env: MomaParallelEnv, seed: int | None = None) -> None:
        super().reset(env, seed)
        if not self.tows:
            raise ValueError(f"{type(self).__name__} needs a robot towing a sled; the env has none")

    def _next_moves(self, observations: Mapping[str, np.ndarray]) -> Sequence[Move]:
        moves = []
        for robot, sled in self.tows.items():
            if robot not in observations or self.at_goal(robot, observations):
                continue
            advance, reel = Move(robot, ADVANCE, robot), Move(robot, REEL, sled)
            pair = [reel, advance] if self.last_move == advance else [advance, reel]
            moves += pair
        return moves

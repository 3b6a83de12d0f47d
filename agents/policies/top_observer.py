"""Top observer: N UGVs leapfrog towards their goals under the UAV's camera."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from agents.policies.base import ADVANCE
from agents.policies.turns import Move, TurnTakingPolicy

__all__ = ["TopObserverLeapfrog"]


class TopObserverLeapfrog(TurnTakingPolicy):
    """One mover at a time, each leg the env's built-in advance, then hold and pass the turn.

    The next mover is the robot farthest behind (largest estimated goal
    distance) among those not at their goal; the robot that just moved goes last
    when another one is left, so turns go round. Moving the laggard keeps the
    formation compact, and the UAV's tracking controller (which flies higher
    with the spread) keeps everyone in view.
    """

    def _next_moves(self, observations: Mapping[str, np.ndarray]) -> Sequence[Move]:
        distance = {a: self.goal_distance(a, observations) for a in self.ugvs if a in observations and not self.at_goal(a, observations)}
        last = None if self.last_move is None else self.last_move.agent
        order = sorted(distance, key=lambda a: (a == last, -distance[a], self.ugvs.index(a)))
        return [Move(a, ADVANCE, a) for a in order]

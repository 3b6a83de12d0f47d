"""Scripted baseline policies of every MOMA configuration (switching action mode).

Every policy follows :class:`~agents.policies.base.Policy`: ``reset(env, seed)``
after ``env.reset``, then ``act(observations, infos)`` every step. They act on
estimates only (observation vectors and the non-truth ``infos`` keys).

>>> env = parallel_env("caterpillar")                       # doctest: +SKIP
>>> policy = scripted_policy("caterpillar")                  # doctest: +SKIP
>>> observations, infos = env.reset(seed=0); policy.reset(env, seed=0)   # doctest: +SKIP
>>> while env.agents:                                        # doctest: +SKIP
...     observations, rewards, terms, truncs, infos = env.step(policy.act(observations, infos))
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType

from agents.policies.base import ADVANCE, ALLOWED_INFO_KEYS, FORBIDDEN_INFO_KEYS, HOLD, REEL, Policy
from agents.policies.caterpillar_multi import CaterpillarMulti, CaterpillarTwo
from agents.policies.caterpillar_servo import CaterpillarServo
from agents.policies.caterpillar_sled import CaterpillarSled
from agents.policies.greedy import GreedyParallelPolicy
from agents.policies.pipeline import FilePipelinePolicy
from agents.policies.planned import PlannedPolicy
from agents.policies.random_policy import RandomPolicy
from agents.policies.rollout import GreedyRolloutPolicy
from agents.policies.top_observer import TopObserverLeapfrog
from agents.policies.turns import Move, TurnTakingPolicy
from moma_env.scenarios import SPECS

__all__ = [
    "Policy",
    "RandomPolicy",
    "TopObserverLeapfrog",
    "CaterpillarTwo",
    "CaterpillarSled",
    "CaterpillarMulti",
    "CaterpillarServo",
    "GreedyParallelPolicy",
    "FilePipelinePolicy",
    "GreedyRolloutPolicy",
    "PlannedPolicy",
    "TurnTakingPolicy",
    "Move",
    "scripted_policy",
    "SCRIPTED_POLICIES",
    "ALLOWED_INFO_KEYS",
    "FORBIDDEN_INFO_KEYS",
    "HOLD",
    "ADVANCE",
    "REEL",
]

#: Configuration name -> scripted policy class (read-only): each registered
#: configuration's ``ScenarioSpec.scripted_policy``.
SCRIPTED_POLICIES: Mapping[str, type[TurnTakingPolicy]] = MappingProxyType(
    {spec.name: spec.load_scripted_policy() for spec in SPECS if spec.scripted_policy is not None}
)


def scripted_policy(configuration: str) -> TurnTakingPolicy:
    """A new scripted baseline for ``configuration`` (one of :data:`SCRIPTED_POLICIES`)."""
    try:
        cls = SCRIPTED_POLICIES[configuration]
    except KeyError:
        raise ValueError(f"no scripted policy for configuration {configuration!r}; known: {sorted(SCRIPTED_POLICIES)}") from None
    return cls()

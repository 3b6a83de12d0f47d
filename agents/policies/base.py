"""The policy protocol and what every scripted policy reads from an episode.

A policy acts on ESTIMATED state only: the observation vectors (decoded through
``env.layout.features``) and the non-truth keys of ``infos`` listed in
:data:`ALLOWED_INFO_KEYS`. At ``reset`` it may read the static facts a robot
knows beforehand: its agents, action spaces, feature layouts, goals, the arena
normalisation and the switching parameters (leg length, dwell, goal tolerance).
"""

from __future__ import annotations

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

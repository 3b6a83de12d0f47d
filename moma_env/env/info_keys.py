"""The keys of the agents' infos, and the choice of them (``EnvConfig.info_keys``).

``MomaParallelEnv.step`` and ``reset`` return per agent an info dict. A UGV's carries,
in this order, the keys of :data:`UGV_INFO_KEYS` (the sled's two only for a robot that
tows one, ``"action_mask"`` only with ``EnvConfig.action_masks``); an observer's, the
keys of :data:`OBSERVER_INFO_KEYS`. ``EnvConfig.info_keys`` keeps some of them: each
agent's info then holds those of the chosen keys it has, in the same order, and the env
does not build the others (a caller that reads two keys does not pay for twelve).
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["INFO_KEYS", "InfoChoice", "OBSERVER_INFO_KEYS", "UGV_INFO_KEYS"]

#: A UGV agent's info keys, in their order.
UGV_INFO_KEYS = (
    "truth", "estimate", "covariance", "localisation_error", "status", "static", "events", "refused", "reached_goal",
    "collisions", "switches_total", "reward_terms", "sled_truth", "sled_localisation_error", "action_mask",
)
#: An observer agent's info keys, in their order.
OBSERVER_INFO_KEYS = ("truth", "status", "covariance", "localisation_error", "events", "reward_terms")
#: Every key an agent's info may carry.
INFO_KEYS = UGV_INFO_KEYS
#: The UGV keys given without building a UGV's whole info.
_CHEAP_UGV_KEYS = frozenset({"static", "action_mask"})


@dataclass(frozen=True, slots=True)
class InfoChoice:
    """What a choice of info keys needs built, worked out once per choice.

    Attributes:
        keys: the choice (``EnvConfig.info_keys``).
        keep: its keys as a set.
        observer_keys: an observer's keys among them, in their order.
        whole_ugv: whether a UGV's whole info is built (a key other than ``"static"``
            and ``"action_mask"`` is chosen), to keep the chosen keys of it.
        static: whether ``"static"`` is chosen.
        masks: whether ``"action_mask"`` is chosen.
    """

    keys: tuple[str, ...]
    keep: frozenset[str]
    observer_keys: tuple[str, ...]
    whole_ugv: bool
    static: bool
    masks: bool

    @classmethod
    def of(cls, keys: tuple[str, ...]) -> InfoChoice:
        keep = frozenset(keys)
        return cls(
            keys, keep, tuple(k for k in OBSERVER_INFO_KEYS if k in keep), not keep <= _CHEAP_UGV_KEYS, "static" in keep,
            "action_mask" in keep,
        )

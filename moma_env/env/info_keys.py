"""The keys of the agents' infos, and the choice of them (``EnvConfig.info_keys``).

``MomaParallelEnv.step`` and ``reset`` return per agent an info dict. A UGV's carries,
in this order, the keys of :data:`UGV_INFO_KEYS` (the sled's two only for a robot that
tows one, ``"action_mask"`` only with ``EnvConfig.action_masks``); an observer's, the
keys of :data:`OBSERVER_INFO_KEYS`. ``EnvConfig.info_keys`` keeps some of them: each
agent's info then holds those of the chosen keys it has, in the same order, and the env
does not build the others (a caller that reads two keys does not pay for twelve).
"""

from __future__ import annotations

__all__ = ["INFO_KEYS", "OBSERVER_INFO_KEYS", "UGV_INFO_KEYS"]

#: A UGV agent's info keys, in their order.
UGV_INFO_KEYS = (
    "truth", "estimate", "covariance", "localisation_error", "status", "static", "events", "refused", "reached_goal",
    "collisions", "switches_total", "reward_terms", "sled_truth", "sled_localisation_error", "action_mask",
)
#: An observer agent's info keys, in their order.
OBSERVER_INFO_KEYS = ("truth", "status", "covariance", "localisation_error", "events", "reward_terms")
#: Every key an agent's info may carry.
INFO_KEYS = UGV_INFO_KEYS

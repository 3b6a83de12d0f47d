"""Names of the env's agents: the UGVs carry their robots' names, the observers these.

One observer is the agent ``observer``; several (``TopObserverConfig.observer`` a
tuple of kinds) are ``observer_0``, ``observer_1``, ..., in the order of the
world's UAVs (``WorldConfig.uavs``). A robot is never named like an observer
(robots are ``ugv_<i>`` in every registered configuration).
"""

from __future__ import annotations

__all__ = ["OBSERVER", "observer_agent_names", "is_observer_agent"]

#: Name of the observer agent when there is one observer; the prefix of each name when there are several.
OBSERVER = "observer"


def observer_agent_names(n_observers: int) -> tuple[str, ...]:
    """The observer agents' names for ``n_observers`` observers, in the world's UAV order."""
    if n_observers == 1:
        return (OBSERVER,)
    return tuple(f"{OBSERVER}_{k}" for k in range(n_observers))


def is_observer_agent(agent: str) -> bool:
    """Whether ``agent`` names an observer (``observer`` or ``observer_<k>``), not a robot."""
    if agent == OBSERVER:
        return True
    prefix = OBSERVER + "_"
    return agent.startswith(prefix) and agent[len(prefix):].isdigit()

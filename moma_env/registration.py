"""Registration with Gymnasium and PettingZoo (called once by ``import moma_env``).

Every configuration of :data:`moma_env.scenarios.SPECS` is registered under the ids
its :class:`~moma_env.scenarios.ScenarioSpec` names:

* Gymnasium, the whole team as one agent: ``gymnasium.make("moma_env/TopObserver-v0")``,
  ``moma_env/Caterpillar-v0``, ``moma_env/CaterpillarSled-v0``, ``moma_env/CaterpillarMulti-v0``;
  ``gymnasium.make_vec(id, num_envs=K)`` builds the batched
  :class:`moma_env.vector.team.TeamVectorEnv` (the ``vector_entry_point``), and
  ``vectorization_mode="sync"`` / ``"async"`` Gymnasium's own vector envs of ``make``'s;
  every task of :data:`moma_env.tasks.TASKS` likewise (``moma_env/TopObserverTeam4-v0``).
* PettingZoo (where the installed version has ``pettingzoo.register``):
  ``pettingzoo.make("parallel", "moma_env/top_observer-v0")`` and ``"aec"``, for
  every configuration, from its versioned module (``moma_env.top_observer_v0``).
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType

from moma_env.scenarios.registry import SPECS
from moma_env.tasks import TASKS

__all__ = ["GYMNASIUM_IDS", "TASK_GYMNASIUM_IDS", "register_envs"]

#: Gymnasium id -> configuration name (read-only; from the registered specs).
GYMNASIUM_IDS: Mapping[str, str] = MappingProxyType({spec.gymnasium_id: spec.name for spec in SPECS})
#: Gymnasium id -> task name (read-only; :data:`moma_env.tasks.TASKS`).
TASK_GYMNASIUM_IDS: Mapping[str, str] = MappingProxyType({task.gymnasium_id: task.name for task in TASKS.values()})


def register_envs() -> None:
    """Register every environment; ids already registered are left alone."""
    import gymnasium
    import pettingzoo

    for env_id, name in {**GYMNASIUM_IDS, **TASK_GYMNASIUM_IDS}.items():
        if env_id not in gymnasium.registry:
            gymnasium.register(
                id=env_id,
                entry_point="moma_env.env.factory:centralised_env",
                vector_entry_point="moma_env.vector.team:TeamVectorEnv",
                kwargs={"configuration": name},
            )
    register = getattr(pettingzoo, "register", None)
    if register is None:
        return
    for spec in SPECS:
        for kind, attr in (("parallel", "parallel_env"), ("aec", "env")):
            if spec.pettingzoo_id in (getattr(pettingzoo, f"{kind}_registry", None) or {}):
                continue
            register(kind, spec.pettingzoo_id, entry_point=f"moma_env.{spec.pettingzoo_module}:{attr}")

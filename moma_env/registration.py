"""Registration with Gymnasium and PettingZoo (called once by ``import moma_env``).

Every configuration is registered under the ids its
:class:`~moma_env.scenarios.ScenarioSpec` names:

* Gymnasium, the whole team as one agent: ``gymnasium.make("moma_env/TopObserver-v0")``,
  ``moma_env/Caterpillar-v0``, ``moma_env/CaterpillarSled-v0``, ``moma_env/CaterpillarMulti-v0``;
  ``gymnasium.make_vec(id, num_envs=K)`` builds the batched
  :class:`moma_env.vector.team.TeamVectorEnv` (the ``vector_entry_point``), and
  ``vectorization_mode="sync"`` / ``"async"`` Gymnasium's own vector envs of ``make``'s;
  every task of :data:`moma_env.tasks.TASKS` likewise (``moma_env/TopObserverTeam4-v0``).
* PettingZoo (where the installed version has ``pettingzoo.register``):
  ``pettingzoo.make("parallel", "moma_env/top_observer-v0")`` and ``"aec"``, for
  every configuration, from its versioned module (``moma_env.top_observer_v0``).

The ids are listed here by name only (:data:`REGISTERED`), so that ``import moma_env``
(and everything that only needs the names, such as the ``moma-env`` command line's
``--help``) does not import the scenarios, the simulator, pymunk or OpenCV; the
envs are built from entry-point strings when they are made.
``tests/test_cli_light.py`` checks that :data:`REGISTERED` names exactly the
configurations of :data:`moma_env.scenarios.SPECS`, with the same ids.

Gymnasium wraps a made env (``OrderEnforcing``, ``PassiveEnvChecker``), and since
Gymnasium 1.0 its wrappers no longer forward unknown attributes: reach the team's
action masks with ``env.get_wrapper_attr("action_masks")()`` (what sb3-contrib's
``MaskablePPO`` does through its ``VecEnv``) or ``env.unwrapped.action_masks()``.
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType
from typing import NamedTuple

from moma_env.tasks import TASKS

__all__ = ["RegisteredConfiguration", "REGISTERED", "CONFIGURATION_NAMES", "GYMNASIUM_IDS", "TASK_GYMNASIUM_IDS", "register_envs"]


class RegisteredConfiguration(NamedTuple):
    """The names of one configuration, without importing it.

    Attributes:
        name: the configuration's name (``ScenarioSpec.name``).
        gymnasium_id: its Gymnasium id (``ScenarioSpec.gymnasium_id``).
        pettingzoo_module: its versioned module in ``moma_env`` (``ScenarioSpec.pettingzoo_module``).
        pettingzoo_id: its PettingZoo id (``ScenarioSpec.pettingzoo_id``).
    """

    name: str
    gymnasium_id: str
    pettingzoo_module: str
    pettingzoo_id: str


#: Every configuration of :data:`moma_env.scenarios.SPECS`, in the same order, by name only.
REGISTERED: tuple[RegisteredConfiguration, ...] = (
    RegisteredConfiguration("top_observer", "moma_env/TopObserver-v0", "top_observer_v0", "moma_env/top_observer-v0"),
    RegisteredConfiguration("caterpillar", "moma_env/Caterpillar-v0", "caterpillar_v0", "moma_env/caterpillar-v0"),
    RegisteredConfiguration("caterpillar_sled", "moma_env/CaterpillarSled-v0", "caterpillar_sled_v0", "moma_env/caterpillar_sled-v0"),
    RegisteredConfiguration(
        "caterpillar_multi", "moma_env/CaterpillarMulti-v0", "caterpillar_multi_v0", "moma_env/caterpillar_multi-v0"
    ),
)

#: The configurations' names, in the registry's order.
CONFIGURATION_NAMES: tuple[str, ...] = tuple(entry.name for entry in REGISTERED)
#: Gymnasium id -> configuration name (read-only).
GYMNASIUM_IDS: Mapping[str, str] = MappingProxyType({entry.gymnasium_id: entry.name for entry in REGISTERED})
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
    for entry in REGISTERED:
        for kind, attr in (("parallel", "parallel_env"), ("aec", "env")):
            if entry.pettingzoo_id in (getattr(pettingzoo, f"{kind}_registry", None) or {}):
                continue
            register(kind, entry.pettingzoo_id, entry_point=f"moma_env.{entry.pettingzoo_module}:{attr}")

"""Registration with Gymnasium and PettingZoo (called once by ``import moma_env``).

* Gymnasium, the whole team as one agent: ``gymnasium.make("moma_env/TopObserver-v0")``,
  ``moma_env/Caterpillar-v0``, ``moma_env/CaterpillarSled-v0``, ``moma_env/CaterpillarMulti-v0``.
* PettingZoo (where the installed version has ``pettingzoo.register``):
  ``pettingzoo.make("parallel", "moma_env/top_observer-v0")`` and ``"aec"``, for
  every configuration.
"""

from __future__ import annotations

__all__ = ["GYMNASIUM_IDS", "register_envs"]

#: Gymnasium id -> configuration name.
GYMNASIUM_IDS = {
    "moma_env/TopObserver-v0": "top_observer",
    "moma_env/Caterpillar-v0": "caterpillar",
    "moma_env/CaterpillarSled-v0": "caterpillar_sled",
    "moma_env/CaterpillarMulti-v0": "caterpillar_multi",
}


def register_envs() -> None:
    """Register every environment; ids already registered are left alone."""
    import gymnasium
    import pettingzoo

    for env_id, configuration in GYMNASIUM_IDS.items():
        if env_id not in gymnasium.registry:
            gymnasium.register(
                id=env_id,
                entry_point="moma_env.env.factory:centralised_env",
                kwargs={"configuration": configuration},
            )
    register = getattr(pettingzoo, "register", None)
    if register is None:
        return
    for configuration in GYMNASIUM_IDS.values():
        for kind, attr in (("parallel", "parallel_env"), ("aec", "env")):
            env_id = f"moma_env/{configuration}-v0"
            if env_id in (getattr(pettingzoo, f"{kind}_registry", None) or {}):
                continue
            register(kind, env_id, entry_point=f"moma_env.{configuration}_v0:{attr}")

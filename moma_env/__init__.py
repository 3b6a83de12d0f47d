"""moma_env: MOMA visual mobile marker odometry as a multi-agent learning environment.

Layers, with imports flowing one way (see docs/design.md):
world (pymunk truth) -> camera (detections) -> estimator (MOMA estimates)
-> env (PettingZoo / Gymnasium). The estimator imports nothing from the simulator.

Environments: ``from moma_env import top_observer_v0; top_observer_v0.parallel_env()``
(also ``caterpillar_v0``, ``caterpillar_sled_v0``, ``caterpillar_multi_v0``);
importing ``moma_env`` registers ``gymnasium.make("moma_env/TopObserver-v0")`` and the
PettingZoo ids (see :mod:`moma_env.registration`).
"""

from pathlib import Path

from moma_env.kernel_cache import clear_if_sources_changed

# Before any kernel loads: numba's caches of kernels that call kernels of other modules
# go stale when only the callee's file changes (see moma_env.kernel_cache).
clear_if_sources_changed(Path(__file__).resolve().parent)

from moma_env.registration import register_envs  # noqa: E402

__version__ = "0.1.0"

#: Version of what a learned policy depends on: the observations, actions and rewards of
#: the envs. Bump it (a new string) with any change to them; training manifests and
#: published policies (``policies/``) record it, and a policy of another version is refused.
ENV_VERSION = "2"  # 2: the tasks commit legs (EnvConfig.commit_legs)

register_envs()

"""moma_env on RLlib's new API stack (the ``ray`` extra).

Importing this module and calling :func:`register_envs` registers every configuration
and task with ``ray.tune.register_env`` under :func:`env_name` (``"moma_env/top_observer"``).
The registered creator takes the ``env_config`` of ``PPOConfig().environment(...)``:
keyword options of :func:`moma_env.env.factory.parallel_env` (``action_mode``,
``observer_agent``, ``max_cycles``, ``random_scenarios``, configuration fields) and
``masks`` (default True), and returns RLlib's own PettingZoo wrapper,
``ParallelPettingZooEnv``, around the parallel env, so RLlib sees the env as any
PettingZoo user would.

* **Policy mapping** (:func:`policy_mapping_fn`): every UGV agent maps to one shared
  policy :data:`UGV_POLICY`; the UAV observer, when it is an agent, to :data:`OBSERVER_POLICY`.
* **Action masks** (switching mode, ``masks=True``): :class:`MaskedObservations` makes a
  UGV's observation ``{"observations": obs, "action_mask": mask}`` (the mask of
  :meth:`MomaParallelEnv.action_masks`, float32 0/1, what the motion rules would grant
  at the next step) and the UGV policy is
  :class:`moma_env.integrations.rllib_masking.MaskedPPOTorchRLModule`.
* **Routes** (:data:`ROUTES`): ``"pettingzoo"``, RLlib's env runner vectorising copies
  of the registered env one by one; ``"vector"``, the batched env
  (:mod:`moma_env.integrations.rllib_vector`: every copy's cameras measured in one call).
  Both give RLlib the same agents, spaces and episodes.

:func:`ppo_config` builds the PPO configuration of a route. Units and frames are the
env's (observations: :mod:`moma_env.env.observations`; rewards per step).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ray.rllib.algorithms.ppo import PPOConfig
from ray.rllib.core.rl_module.multi_rl_module import MultiRLModuleSpec
from ray.rllib.core.rl_module.rl_module import RLModuleSpec
from ray.rllib.env.wrappers.pettingzoo_env import ParallelPettingZooEnv
from ray.tune.registry import register_env

from moma_env.config import ConfigError, check_count
from moma_env.env.agent_names import is_observer_agent
from moma_env.integrations.rllib_env import MaskedObservations, masked_parallel_env
from moma_env.integrations.rllib_masking import MaskedPPOTorchRLModule
from moma_env.scenarios import CONFIGURATIONS
from moma_env.tasks import TASKS

__all__ = [
    "ROUTES",
    "UGV_POLICY",
    "OBSERVER_POLICY",
    "MaskedObservations",
    "EnvCreator",
    "env_name",
    "register_envs",
    "make_multi_agent_env",
    "policy_mapping_fn",
    "policies_of",
    "module_specs",
    "ppo_config",
]

ROUTES = ("pettingzoo", "vector")
UGV_POLICY = "ugv"
OBSERVER_POLICY = "observer"


def env_name(configuration: str) -> str:
    """The ``register_env`` name of a configuration or task."""
    return f"moma_env/{configuration}"


def make_multi_agent_env(configuration: str, env_config: Mapping[str, Any] | None = None) -> ParallelPettingZooEnv:
    """RLlib's ``ParallelPettingZooEnv`` around the configuration's parallel env (see the module)."""
    return ParallelPettingZooEnv(masked_parallel_env(configuration, env_config or {}))


class EnvCreator:
    """The ``register_env`` creator of one configuration: ``creator(env_config)`` (picklable, no lambda)."""

    def __init__(self, configuration: str):
        if configuration not in CONFIGURATIONS and configuration not in TASKS:
            raise ConfigError("configuration", f"unknown configuration or task {configuration!r}")
        self.configuration = configuration

    def __call__(self, env_config: Mapping[str, Any] | None = None) -> ParallelPettingZooEnv:
        return make_multi_agent_env(self.configuration, env_config)


def register_envs() -> list[str]:
    """Register every configuration and task with ``ray.tune.register_env``; their names."""
    names = []
    for configuration in [*CONFIGURATIONS, *TASKS]:
        register_env(env_name(configuration), EnvCreator(configuration))
        names.append(env_name(configuration))
    return names


def policy_mapping_fn(agent_id: str, episode: Any = None, **kwargs: Any) -> str:
    """The UAV observers to :data:`OBSERVER_POLICY`, every UGV to the shared :data:`UGV_POLICY`."""
    return OBSERVER_POLICY if is_observer_agent(agent_id) else UGV_POLICY


def policies_of(agents: list[str]) -> set[str]:
    """The policies the agents map to."""
    return {policy_mapping_fn(a) for a in agents}


def module_specs(policies: set[str], masked: bool, hidden: tuple[int, ...] = (64, 64)) -> MultiRLModuleSpec:
    """The PPO modules: the UGV policy masked when ``masked``, layers ``hidden`` (tanh)."""
    model_config = {"fcnet_hiddens": list(hidden), "fcnet_activation": "tanh", "vf_share_layers": False}
    specs = {}
    for policy in sorted(policies):
        if policy == UGV_POLICY and masked:
            specs[policy] = RLModuleSpec(module_class=MaskedPPOTorchRLModule, model_config=model_config)
        else:
            specs[policy] = RLModuleSpec(model_config=model_config)
    return MultiRLModuleSpec(rl_module_specs=specs)


def ppo_config(
    configuration: str,
    env_config: Mapping[str, Any] | None = None,
    *,
    route: str = "pettingzoo",
    num_env_runners: int = 0,
    num_envs_per_env_runner: int = 1,
    rollout_fragment_length: int = 128,
    train_batch_size: int = 512,
    minibatch_size: int = 128,
    num_epochs: int = 4,
    lr: float = 3e-4,
    gamma: float = 0.995,
    entropy_coeff: float = 0.01,
    hidden: tuple[int, ...] = (64, 64),
    seed: int = 0,
) -> PPOConfig:
    """PPO on the new API stack for ``configuration`` through ``route``.

    Args:
        configuration: a configuration or task name.
        env_config: the registered creator's options (see the module); the env's agents
            decide the policies (an observer agent gets its own).
        route: ``"pettingzoo"`` or ``"vector"``.
        num_env_runners: remote env runners (0: sample in the driver).
        num_envs_per_env_runner: env copies per runner.
        rollout_fragment_length: env steps per copy per sample call.
        train_batch_size: agent steps per update (per learner).
        minibatch_size: agent steps per minibatch.
        num_epochs: passes over each batch.
        lr, gamma, entropy_coeff: PPO's learning rate, discount and entropy bonus.
        hidden: hidden layer sizes of the policy and value networks.
        seed: RLlib's seed (env runners and modules).

    Raises:
        ConfigError: naming the bad argument.
    """
    if route not in ROUTES:
        raise ConfigError("route", f"must be one of {ROUTES}, got {route!r}")
    check_count("num_env_runners", num_env_runners, 0)
    check_count("num_envs_per_env_runner", num_envs_per_env_runner, 1)
    env_config = {"configuration": configuration, **dict(env_config or {})}
    probe = masked_parallel_env(configuration, env_config)
    masked = isinstance(probe, MaskedObservations)
    policies = policies_of(list(probe.possible_agents))
    probe.close()
    register_env(env_name(configuration), EnvCreator(configuration))
    config = (
        PPOConfig()
        .framework("torch")
        .environment(env_name(configuration), env_config=env_config, disable_env_checking=True)
        .env_runners(
            num_env_runners=num_env_runners,
            num_envs_per_env_runner=num_envs_per_env_runner,
            rollout_fragment_length=rollout_fragment_length,
            num_cpus_per_env_runner=1,
        )
        .multi_agent(policies=policies, policy_mapping_fn=policy_mapping_fn)
        .rl_module(rl_module_spec=module_specs(policies, masked, hidden))
        .training(
            train_batch_size_per_learner=train_batch_size,
            minibatch_size=minibatch_size,
            num_epochs=num_epochs,
            lr=lr,
            gamma=gamma,
            entropy_coeff=entropy_coeff,
        )
        .debugging(seed=seed)
    )
    if route == "vector":
        from moma_env.integrations.rllib_vector import MomaVectorEnvRunner

        config = config.env_runners(env_runner_cls=MomaVectorEnvRunner)
    return config

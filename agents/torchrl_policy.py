"""A policy trained by ``moma-env train --backend torchrl`` (MAPPO or IPPO) as an evaluation harness policy.

The networks are TorchRL's ``MultiAgentMLP`` (tanh, parameters shared by the UGVs):

* the actor (:func:`actor_network`): each UGV's own observation -> its action logits,
  masked by the motion rules (``MaskedCategorical``) in training and here alike;
* the critic (:func:`critic_network`): each UGV's value, from the whole team's
  observations (``centralised``, MAPPO) or from its own (``independent``, IPPO). Only
  training uses it.

The run's folder holds ``manifest.json`` (``"backend": "torchrl"``, written last, so it
always names a complete checkpoint) and the checkpoint it names, a ``torch.save`` of
plain state dicts and shapes (loaded with ``weights_only=True``). :meth:`TorchRLPolicy.from_dir`
rebuilds the actor from it. Each UGV's observation is one row of the actor's team
input; its actions are among what the env's action masks allow
(:meth:`MomaParallelEnv.action_masks`, as in training). Actions: the most likely by
default; with ``deterministic=False`` a sample, torch's generator seeded per step from
the policy's numpy generator, itself seeded by ``reset(env, seed)`` (the same seed, the
same episode; torch's global generator is left as it was). The policy reads the
observations and the masks, never the infos.

torch and TorchRL (the ``torchrl`` extra) are imported only when networks are built;
:func:`is_torchrl_run` reads the manifest only.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from agents.learned import TrainingDirError, torch_threads
from agents.run_manifest import is_backend_run, read_backend_manifest
from agents.ugv_policy import TrainedUgvPolicy
from moma_env.env.parallel import MomaParallelEnv

__all__ = [
    "TorchRLPolicy",
    "actor_network",
    "critic_network",
    "is_torchrl_run",
    "read_torchrl_manifest",
    "load_checkpoint",
    "BACKEND",
]

#: The manifest's ``backend`` of a TorchRL run.
BACKEND = "torchrl"
#: The keys of a checkpoint file (besides the optimiser's and the value normaliser's state).
CHECKPOINT_KEYS = ("actor", "critic", "n_agents", "obs_dim", "n_actions", "net_arch", "critic_kind")


def _mlp(n_inputs: int, n_outputs: int, n_agents: int, centralised: bool, net_arch: Sequence[int]):
    import torch

    import moma_env.vector.torchrl  # noqa: F401  (torchrl imported first there, multiprocessing's start method kept)
    from torchrl.modules import MultiAgentMLP

    return MultiAgentMLP(
        n_agent_inputs=n_inputs, n_agent_outputs=n_outputs, n_agents=n_agents, centralized=centralised, share_params=True,
        num_cells=list(net_arch), activation_class=torch.nn.Tanh,
    )


def actor_network(n_agents: int, obs_dim: int, n_actions: int, net_arch: Sequence[int]):
    """The shared actor: ``(..., n_agents, obs_dim)`` observations -> ``(..., n_agents, n_actions)`` logits."""
    return _mlp(obs_dim, n_actions, n_agents, False, net_arch)


def critic_network(n_agents: int, obs_dim: int, net_arch: Sequence[int], critic_kind: str):
    """The critic: ``(..., n_agents, obs_dim)`` -> ``(..., n_agents, 1)`` values; ``critic_kind``
    ``"centralised"`` reads every agent's observation for each value, ``"independent"`` its own."""
    return _mlp(obs_dim, 1, n_agents, critic_kind == "centralised", net_arch)


def is_torchrl_run(directory: str | Path) -> bool:
    """Whether ``directory`` holds a manifest of a TorchRL run (False for any other or none)."""
    return is_backend_run(directory, BACKEND)


def read_torchrl_manifest(directory: str | Path) -> dict[str, Any]:
    """The manifest of a TorchRL run, checked: backend, keys, env version, the checkpoint it names.

    Raises:
        TrainingDirError: no folder or manifest, another backend, a missing key or
            checkpoint file, another env version.
    """
    directory = Path(directory)
    path, manifest = read_backend_manifest(directory, BACKEND, "a TorchRL")
    if not (directory / manifest["checkpoint"]).is_file():
        raise TrainingDirError(f"{str(path)!r} names checkpoint {manifest['checkpoint']!r}, which is not a file in {str(directory)!r}")
    return manifest


def load_checkpoint(path: str | Path) -> dict[str, Any]:
    """The checkpoint file ``path`` (tensors and plain data only), its keys checked.

    Raises:
        TrainingDirError: the file cannot be read as a checkpoint or lacks a key.
    """
    import torch

    try:
        state = torch.load(str(path), map_location="cpu", weights_only=True)
    except Exception as err:  # a damaged file fails anywhere in torch's unpickler or zip reader
        first = str(err).strip().splitlines()
        raise TrainingDirError(f"cannot load the checkpoint {str(path)!r}: {type(err).__name__}: {first[0] if first else ''}") from None
    if not isinstance(state, dict):
        raise TrainingDirError(f"{str(path)!r} is not a checkpoint of moma-env train --backend torchrl")
    for key in CHECKPOINT_KEYS:
        if key not in state:
            raise TrainingDirError(f"the checkpoint {str(path)!r} lacks the key {key!r}")
    return state


class TorchRLPolicy(TrainedUgvPolicy):
    """The shared actor acting for every UGV agent (see the module docstring).

    Args:
        actor: the actor network (:func:`actor_network`).
        n_agents: the UGVs it was built for.
        obs_dim: one UGV's observation length.
        configuration: the configuration or task it was trained on, if known.
        deterministic: act with the most likely action (True) or sample (False).
        torch_threads: torch's intra-op threads while acting.
    """

    #: The env action mode the actor acts in.
    action_mode = "switching"

    def __init__(self, actor: Any, n_agents: int, obs_dim: int, configuration: str | None = None, deterministic: bool = True,
                 torch_threads: int = 1):
        if not isinstance(deterministic, bool):
            raise ValueError(f"deterministic must be a bool, got {deterministic!r}")
        self.actor = actor
        self.n_agents = int(n_agents)
        self.obs_dim = int(obs_dim)
        self.configuration = configuration
        self.deterministic = deterministic
        self.torch_threads = int(torch_threads)
        self._sampler = np.random.default_rng(0)
        self._env: MomaParallelEnv | None = None
        self._agents: list[str] = []

    @classmethod
    def from_dir(cls, directory: str | Path, configuration: str | None = None, deterministic: bool = True) -> "TorchRLPolicy":
        """Rebuild the actor of the checkpoint ``directory``'s manifest names.

        Raises:
            TrainingDirError: see :func:`read_torchrl_manifest` and :func:`load_checkpoint`;
                a configuration mismatch; TorchRL missing; weights that do not fit.
        """
        directory = Path(directory)
        manifest = read_torchrl_manifest(directory)
        config = manifest["config"]
        if configuration is not None and config.get("scenario") != configuration:
            raise TrainingDirError(f"{str(directory)!r} was trained on {config.get('scenario')!r}, not {configuration!r}")
        try:
            import moma_env.vector.torchrl  # noqa: F401  (imports torchrl keeping multiprocessing's start method)
        except ImportError as err:
            raise TrainingDirError(f"loading a TorchRL policy needs the 'torchrl' extra: {err}") from None
        state = load_checkpoint(directory / manifest["checkpoint"])
        actor = actor_network(state["n_agents"], state["obs_dim"], state["n_actions"], state["net_arch"])
        try:
            actor.load_state_dict(state["actor"])
        except RuntimeError as err:
            first = str(err).strip().splitlines()
            raise TrainingDirError(f"the actor weights of {str(directory)!r} do not fit its shapes: {first[0] if first else ''}") from None
        actor.eval()
        return cls(actor, state["n_agents"], state["obs_dim"], config.get("scenario"), deterministic=deterministic,
                   torch_threads=int(config.get("torch_threads", 1)))

    def reset(self, env: MomaParallelEnv, seed: int | None = None) -> None:
        """Check that ``env`` fits the actor (switching mode, no observer agent, the
        UGV count and observation length); seed the action sampler with ``seed`` (0 if
        None). Call after ``env.reset``."""
        self._begin_episode(env, seed)
        agents = list(env.possible_agents)
        if len(agents) != self.n_agents:
            raise ValueError(f"the policy was trained for {self.n_agents} UGVs; this env has {len(agents)}")
        got = env.observation_space(agents[0]).shape
        if got != (self.obs_dim,):
            raise ValueError(f"the policy expects observations of shape ({self.obs_dim},); this env gives {got}")
        self._env = env
        self._agents = agents

    def act(self, observations: Mapping[str, np.ndarray], infos: Mapping[str, Mapping[str, Any]]) -> dict[str, int]:
        """Every agent's action among those its mask allows (infos read for the masks only)."""
        import torch

        if not observations:
            return {}
        if self._env is None:
            raise RuntimeError("call reset(env) before act()")
        masks = self._env_masks(self._env, self._agents, infos)
        obs = torch.as_tensor(np.stack([np.asarray(observations[a], dtype=np.float32) for a in self._agents]))
        allowed = torch.as_tensor(np.stack([masks[a] for a in self._agents]).astype(bool))
        with torch_threads(self.torch_threads), torch.no_grad():
            logits = self.actor(obs).masked_fill(~allowed, float("-inf"))
            if self.deterministic:
                actions = logits.argmax(dim=-1)
            else:
                generator = torch.Generator().manual_seed(int(self._sampler.integers(2**63)))
                actions = torch.multinomial(torch.softmax(logits, dim=-1), 1, generator=generator).squeeze(-1)
        return {a: int(actions[k]) for k, a in enumerate(self._agents) if a in observations}

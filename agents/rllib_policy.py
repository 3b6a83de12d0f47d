"""A policy trained by ``moma-env train --backend rllib`` as an evaluation harness policy.

The run's folder holds ``manifest.json`` (``"backend": "rllib"``, written last, so it
always names a complete checkpoint) and RLlib's own checkpoint folder it names.
:meth:`RllibPolicy.from_dir` loads only the shared UGV module from it
(``<checkpoint>/learner_group/learner/rl_module/ugv``, RLlib's ``RLModule.from_checkpoint``),
not the algorithm: no Ray cluster is needed to evaluate. Each UGV's observation is one
row of a batch; in switching mode the rows carry the env's action masks
(:meth:`MomaParallelEnv.action_masks`, what the motion rules would grant), as in
training. Actions: the mode of the action distribution by default; with
``deterministic=False`` a sample, torch's generator seeded per step from the policy's
numpy generator, itself seeded by ``reset(env, seed)`` (the same seed, the same episode).
The policy reads the observations only, never the infos.

RLlib (the ``ray`` extra) is imported only when a policy is loaded;
:func:`is_rllib_run` reads the manifest only.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from agents.learned import TrainingDirError
from agents.run_manifest import is_backend_run, read_backend_manifest
from agents.ugv_policy import TrainedUgvPolicy
from moma_env.env.parallel import MomaParallelEnv

__all__ = ["RllibPolicy", "is_rllib_run", "read_rllib_manifest", "BACKEND", "UGV_MODULE_PATH"]

#: The manifest's ``backend`` of an RLlib run.
BACKEND = "rllib"
#: Where the UGV policy's module lives inside an RLlib algorithm checkpoint.
UGV_MODULE_PATH = ("learner_group", "learner", "rl_module", "ugv")


def is_rllib_run(directory: str | Path) -> bool:
    """Whether ``directory`` holds a manifest of an RLlib run (False for any other or none)."""
    return is_backend_run(directory, BACKEND)


def read_rllib_manifest(directory: str | Path) -> dict[str, Any]:
    """The manifest of an RLlib run, checked: backend, keys, env version, the checkpoint it names.

    Raises:
        TrainingDirError: no folder or manifest, another backend, a missing key or
            checkpoint, another env version.
    """
    directory = Path(directory)
    path, manifest = read_backend_manifest(directory, BACKEND, "an RLlib")
    module = directory / manifest["checkpoint"] / Path(*UGV_MODULE_PATH)
    if not module.is_dir():
        raise TrainingDirError(f"{str(path)!r} names checkpoint {manifest['checkpoint']!r}, which holds no UGV module ({str(module)!r})")
    return manifest


class RllibPolicy(TrainedUgvPolicy):
    """An RLlib module acting for every UGV agent (see the module docstring).

    Args:
        module: the UGV policy's RLlib ``RLModule`` (torch).
        action_mode: the env action mode it was trained in.
        configuration: the configuration it was trained on, if known.
        deterministic: act with the distribution's mode (True) or sample (False).
    """

    def __init__(self, module: Any, action_mode: str, configuration: str | None = None, deterministic: bool = True):
        if not isinstance(deterministic, bool):
            raise ValueError(f"deterministic must be a bool, got {deterministic!r}")
        self.module = module
        self.action_mode = action_mode
        self.configuration = configuration
        self.deterministic = deterministic
        self._masked = action_mode == "switching"
        self._sampler = np.random.default_rng(0)
        self._env: MomaParallelEnv | None = None
        self._agents: list[str] = []

    @classmethod
    def from_dir(cls, directory: str | Path, configuration: str | None = None, deterministic: bool = True) -> "RllibPolicy":
        """Load the UGV module of the checkpoint ``directory``'s manifest names.

        Raises:
            TrainingDirError: see :func:`read_rllib_manifest`; a configuration mismatch;
                RLlib missing; a module that cannot be loaded.
        """
        directory = Path(directory)
        manifest = read_rllib_manifest(directory)
        config = manifest["config"]
        if configuration is not None and config.get("scenario") != configuration:
            raise TrainingDirError(f"{str(directory)!r} was trained on {config.get('scenario')!r}, not {configuration!r}")
        try:
            from ray.rllib.core.rl_module.rl_module import RLModule
        except ImportError as err:
            raise TrainingDirError(f"loading an RLlib policy needs the 'ray' extra: {err}") from None
        path = directory / manifest["checkpoint"] / Path(*UGV_MODULE_PATH)
        try:
            module = RLModule.from_checkpoint(str(path))
        except Exception as err:  # a damaged checkpoint fails anywhere in RLlib, pickle or torch
            first = str(err).strip().splitlines()
            raise TrainingDirError(f"cannot load the RLlib module {str(path)!r}: {type(err).__name__}: {first[0] if first else ''}") from None
        return cls(module, config["action_mode"], config.get("scenario"), deterministic=deterministic)

    def reset(self, env: MomaParallelEnv, seed: int | None = None) -> None:
        """Check that ``env`` fits the module (mode, no observer agent, observation shape);
        seed the action sampler with ``seed`` (0 if None). Call after ``env.reset``."""
        self._begin_episode(env, seed)
        self._env = env
        self._agents = list(env.possible_agents)
        space = self.module.observation_space
        expected = (space["observations"] if self._masked else space).shape
        got = env.observation_space(self._agents[0]).shape
        if got != expected:
            raise ValueError(f"the module expects observations of shape {expected}; this env gives {got}")

    def act(self, observations: Mapping[str, np.ndarray], infos: Mapping[str, Mapping[str, Any]]) -> dict[str, Any]:
        """The module's action of every agent in ``observations`` (infos read for the action masks only)."""
        import torch
        from ray.rllib.core.columns import Columns

        if not observations:
            return {}
        assert self._env is not None, "call reset(env) first"
        agents = [a for a in self._agents if a in observations]
        obs = torch.as_tensor(np.stack([np.asarray(observations[a], dtype=np.float32) for a in agents]))
        if self._masked:
            every = self._env_masks(self._env, agents, infos)
            mask = torch.as_tensor(np.stack([every[a] for a in agents]).astype(np.float32))
            batch = {Columns.OBS: {"observations": obs, "action_mask": mask}}
        else:
            batch = {Columns.OBS: obs}
        with torch.no_grad():
            out = self.module.forward_inference(batch)
            dist = self.module.get_inference_action_dist_cls().from_logits(out[Columns.ACTION_DIST_INPUTS])
            if self.deterministic:
                actions = dist.to_deterministic().sample()
            else:
                with torch.random.fork_rng(devices=[]):
                    torch.manual_seed(int(self._sampler.integers(2**63)))
                    actions = dist.sample()
        actions = actions.numpy()
        if self._masked:
            return {a: int(actions[k]) for k, a in enumerate(agents)}
        space = self._env.action_space(agents[0])
        return {a: np.clip(actions[k], space.low, space.high).astype(np.float32) for k, a in enumerate(agents)}

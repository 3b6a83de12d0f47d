"""A run that starts from another run's weights (``moma-env train --init-from RUN``).

Reinforcement learning from a cloned policy (``--pretrain``) repeats the teacher's
demonstrations every time, which for the lookahead teachers is half an hour of both
cores here. ``TrainConfig.init_from`` names a finished run instead: its last
checkpoint's policy and value networks and its ``VecNormalize`` statistics become the
new run's start, and the new run learns ``steps`` timesteps from there with its own
optimiser (fresh Adam state at its own learning rate), seed, rewards, discount and
evaluation settings.

What the two runs must share is what makes the weights mean the same thing:
:data:`SHARED_FIELDS` (the task, the algorithm, the action mode, the route, the network
and its sizes, the team action, the observations' timer, the normalisation). The
source is read like any trained policy (:func:`agents.learned.read_manifest`: files
present, the same env version), and the run records which checkpoint it started from
(:data:`INITIALISATION`, with the model's SHA-256) beside its manifest.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from stable_baselines3.common.base_class import BaseAlgorithm

from agents.learned import TrainingDirError, file_sha256, read_manifest, sb3_class
from moma_env.config import ConfigError
from training.train.config import TrainConfig

__all__ = ["INITIALISATION", "SHARED_FIELDS", "InitialWeights", "read_initial_weights"]

#: The record of where a run's weights started (``--init-from``), in its folder.
INITIALISATION = "init_from.json"

#: TrainConfig fields a run started from another must share with it: what its policy
#: observes and does, and the shapes of its networks.
SHARED_FIELDS = ("scenario", "algo", "action_mode", "route", "network", "net_arch", "team_action", "switch_horizon_s", "normalize")


@dataclass(frozen=True)
class InitialWeights:
    """The finished run a new run starts from.

    Attributes:
        folder: the source run's folder (a ``moma-env train --out`` folder or a published policy's).
        manifest: its checked manifest.
    """

    folder: Path
    manifest: dict[str, Any]

    @property
    def statistics(self) -> Path | None:
        """The source's ``VecNormalize`` statistics file (None if it did not normalise)."""
        name = self.manifest.get("vecnormalize")
        return self.folder / name if name else None

    def load_into(self, model: BaseAlgorithm) -> dict[str, Any]:
        """Copy the source's policy and value networks into ``model`` (built for the new
        run, on the CPU); return the record of :data:`INITIALISATION`.

        Raises:
            ConfigError (``init_from``): the source's model file cannot be loaded, or its
                spaces or network shapes are not ``model``'s.
        """
        path = self.folder / self.manifest["model"]
        try:
            source = sb3_class(self.manifest["sb3_class"]).load(path, device="cpu")
        except Exception as err:  # a damaged zip fails anywhere in SB3, zipfile or torch
            raise ConfigError("init_from", f"cannot load the model {str(path)!r}: {type(err).__name__}: {err}") from None
        for name in ("observation_space", "action_space"):
            theirs, ours = getattr(source, name), getattr(model, name)
            if theirs != ours:
                raise ConfigError("init_from", f"{str(path)!r} has {name} {theirs}, this run's is {ours}")
        try:
            model.policy.load_state_dict(source.policy.state_dict())
        except RuntimeError as err:  # torch names the missing, unexpected or mis-shaped weights
            raise ConfigError("init_from", f"{str(path)!r} has networks of other shapes than this run's: {str(err).splitlines()[0]}") from None
        return {
            "run": str(self.folder),
            "model": self.manifest["model"],
            "model_sha256": file_sha256(path),
            "vecnormalize": self.manifest.get("vecnormalize"),
            "num_timesteps": self.manifest["num_timesteps"],
            "git": self.manifest.get("git"),
        }


def read_initial_weights(config: TrainConfig) -> InitialWeights:
    """The run ``config.init_from`` names, checked against ``config``.

    Raises:
        ConfigError (``init_from``): no loadable run there (no folder, no manifest,
            another env version, a missing file), or one whose :data:`SHARED_FIELDS`
            differ from ``config``'s (naming the first).
    """
    if config.init_from is None:
        raise ValueError("the run starts from scratch: config.init_from is None")
    folder = Path(config.init_from)
    try:
        manifest = read_manifest(folder)
    except TrainingDirError as err:
        raise ConfigError("init_from", str(err)) from None
    try:
        stored = TrainConfig.from_dict(manifest["config"]).to_dict()
    except ConfigError as err:
        raise ConfigError("init_from", f"{str(folder)!r}: its manifest's configuration does not load here ({err})") from None
    ours = config.to_dict()
    for name in SHARED_FIELDS:
        if stored[name] != ours[name]:
            raise ConfigError("init_from", f"{str(folder)!r} was trained with {name}={stored[name]!r}, this run has {ours[name]!r}: "
                                           "a run starts from weights of its own task, algorithm, actions and network")
    return InitialWeights(folder, manifest)

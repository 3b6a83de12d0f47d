"""A trained Stable-Baselines3 policy as an :class:`agents.policies.base.Policy`.

``LearnedPolicy.from_dir("runs/train/top")`` loads what ``moma-env train``
wrote: ``manifest.json`` (written last, so it always names a complete
checkpoint) names the model zip and, if the run normalised observations, the
``VecNormalize`` statistics. The policy acts deterministically (the mode of the
action distribution) on the observations only; it never reads ``infos``, so it
honours the truth guard trivially.

Two routes (see ``training.train.config``):

* ``shared``: one network for every UGV; each robot's observation is one row
  of a batch, each row's action is that robot's.
* ``centralised``: the team as one agent; the observations are concatenated and
  the team action split back into the agents' actions exactly as the Gymnasium
  wrapper does (:class:`moma_env.env.centralised.CentralisedTeamEnv`).

The UAV observer was flown by its tracking controller during training
(``observer_agent=False``): :attr:`LearnedPolicy.env_options` says how to build
an env the policy fits, and ``reset`` refuses one it does not fit.

Stable-Baselines3 (the ``train`` extra) is imported only when a model is loaded.

Published policies: ``load_published("NAME")`` loads ``policies/NAME/`` (written by
``python -m training.train.publish RUN_DIR NAME``; the root is the repository's
``policies/`` folder, else ``$MOMA_POLICIES_DIR``, else a ``root`` argument, see
:func:`policies_root`). Its manifest is a training manifest (same keys, files
``model.zip`` and ``vecnormalize.pkl``) plus ``published`` (provenance) and the
files' SHA-256. A manifest whose ``env_version`` differs from
:data:`moma_env.ENV_VERSION` (observations, actions or rewards changed since it
was trained) is refused, for published policies and training folders alike.
Actions: by default the mode of the action distribution
(``deterministic=True``, what SB3's evaluation does). With
``deterministic=False`` the policy samples from the distribution it was
trained with; every sample comes from the policy's own numpy generator,
seeded by ``reset(env, seed)`` with the episode's seed (each call seeds a
forked torch RNG from it, so torch's global RNG is left as it was): the same
seed gives the same episode. A policy whose deterministic mode stalls (a state
that repeats and whose most likely action is to hold) keeps moving when
sampling.

A model that takes action masks (sb3-contrib's ``MaskablePPO``, ``moma-env
train --algo maskable_ppo``) acts only among the actions the motion rules would
grant at the next step, read from the env given to ``reset``
(``MomaParallelEnv.action_mask``, as in training); it still reads no ``infos``.

The network runs on ``torch_threads`` threads (default 1, as in training):
a 64x64 network on a batch of a few robots gains nothing from more, and on a
busy machine torch's default two threads made ``moma-env evaluate`` about 5x
slower (206 s against 40 s for 20 episodes).
"""

from __future__ import annotations

import hashlib
import io
import os
import pickle
import re
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
from gymnasium import spaces

from moma_env import ENV_VERSION
from moma_env.env.centralised import CentralisedTeamEnv
from agents.policy_mode import discrete_actions
from agents.ugv_policy import TrainedUgvPolicy
from moma_env.env.parallel import MomaParallelEnv
from moma_env.io import read_json_in

__all__ = [
    "LearnedPolicy",
    "ObservationScaling",
    "trained_env_fields",
    "TrainingDirError",
    "read_manifest",
    "sb3_class",
    "MANIFEST",
    "MANIFEST_FORMAT",
    "POLICIES_ENV",
    "PUBLISHED_NAME",
    "policies_root",
    "published_dir",
    "published_names",
    "read_published",
    "load_published",
    "file_sha256",
]

def trained_env_fields(config: Mapping[str, Any]) -> dict[str, Any]:
    """The env settings a run's policy must act in, from its ``TrainConfig`` as plain data
    (a manifest's ``config``, or ``TrainConfig.to_dict()``): :class:`LearnedPolicy`'s
    ``switch_horizon_s`` and ``team_action`` keywords (the defaults where a run, older
    than the field, does not name it)."""
    return {"switch_horizon_s": config.get("switch_horizon_s"), "team_action": config.get("team_action", "per_agent")}


#: Name of the manifest in a training output folder.
MANIFEST = "manifest.json"
#: Version of the manifest's layout.
MANIFEST_FORMAT = 1
#: Routes a manifest may name.
_ROUTES = ("centralised", "shared")
#: Environment variable naming the folder of published policies (instead of the repository's ``policies/``).
POLICIES_ENV = "MOMA_POLICIES_DIR"
#: The repository's folder of published policies (the default root).
_REPOSITORY_POLICIES = Path(__file__).resolve().parents[1] / "policies"
#: What a published policy's name may be: letters, digits, ``_`` and ``-``, starting with a letter or digit.
PUBLISHED_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_-]{0,63}$")

ObservationNormaliser = Callable[[np.ndarray], np.ndarray]


class ObservationScaling:
    """The observation transform of Stable-Baselines3's ``VecNormalize``, its statistics
    frozen: ``clip((obs - mean) / sqrt(var + epsilon), -clip, clip)`` as float32, the
    same numbers as ``VecNormalize.normalize_obs`` bit for bit. Unlike a ``VecNormalize``
    loaded from a run (which pickles only with its envs' attributes) it pickles, so a
    policy can act in a worker process.

    Args:
        mean: per-feature running mean of the raw observations (float64).
        var: per-feature running variance of the raw observations (float64).
        clip: bound of the scaled observations.
        epsilon: added to the variance.
    """

    def __init__(self, mean: np.ndarray, var: np.ndarray, clip: float, epsilon: float):
        self.mean = np.array(mean, dtype=np.float64)
        self.var = np.array(var, dtype=np.float64)
        self.clip = float(clip)
        self.epsilon = float(epsilon)

    @classmethod
    def from_vec_normalize(cls, statistics: Any) -> "ObservationScaling | None":
        """The transform of a ``VecNormalize`` (live or loaded), None if it leaves observations alone.

        Raises:
            ValueError: statistics per key of a dict observation (the envs here have one array).
        """
        if not statistics.norm_obs:
            return None
        rms = statistics.obs_rms
        if isinstance(rms, dict):
            raise ValueError("VecNormalize statistics per observation key are not supported: the observations are one array")
        return cls(rms.mean, rms.var, statistics.clip_obs, statistics.epsilon)

    def __call__(self, observations: np.ndarray) -> np.ndarray:
        scaled = np.clip((observations - self.mean) / np.sqrt(self.var + self.epsilon), -self.clip, self.clip)
        return scaled.astype(np.float32)


class TrainingDirError(ValueError):
    """A training output folder that holds no loadable run (one-line message)."""


def read_manifest(directory: str | Path) -> dict[str, Any]:
    """The manifest of a training folder, checked: format, route, and every file it names exists.

    A manifest that records an ``env_version`` must record :data:`moma_env.ENV_VERSION`
    (manifests written before the version existed record none and are not checked).

    Raises:
        TrainingDirError: no folder, no manifest, unreadable or inconsistent manifest,
            another env version.
    """
    directory = Path(directory)
    path, manifest = read_json_in(
        directory, MANIFEST, TrainingDirError, "a folder of a training run", "not a finished checkpoint of moma-env train"
    )
    if not isinstance(manifest, dict) or manifest.get("format") != MANIFEST_FORMAT:
        raise TrainingDirError(f"{str(path)!r} is not a version-{MANIFEST_FORMAT} training manifest")
    for key in ("sb3_class", "route", "model", "num_timesteps", "config"):
        if key not in manifest:
            raise TrainingDirError(f"{str(path)!r} lacks the key {key!r}")
    _check_manifest_types(path, manifest)
    if manifest["route"] not in _ROUTES:
        raise TrainingDirError(f"{str(path)!r} names an unknown route {manifest['route']!r}")
    version = manifest.get("env_version")
    if version is not None and version != ENV_VERSION:
        raise TrainingDirError(
            f"{str(path)!r} was trained on env version {version!r}, this code's is {ENV_VERSION!r} "
            "(observations, actions or rewards changed): retrain it, or run it at the commit its manifest names"
        )
    for key in ("model", "vecnormalize", "replay_buffer"):
        name = manifest.get(key)
        if name is not None and not (directory / name).is_file():
            raise TrainingDirError(f"{str(path)!r} names {key} file {name!r}, which is missing")
    return manifest


def _check_manifest_types(path: Path, manifest: dict[str, Any]) -> None:
    """TrainingDirError naming ``path`` and the key whose value has the wrong type."""

    def wrong(key: str, expected: str) -> TrainingDirError:
        value = manifest[key]
        return TrainingDirError(f"{str(path)!r}: {key!r} must be {expected}, got {type(value).__name__} {value!r:.60}")

    for key in ("sb3_class", "route"):
        if not isinstance(manifest[key], str):
            raise wrong(key, "a str")
    for key in ("model", "vecnormalize", "replay_buffer"):
        name = manifest.get(key)
        if key in manifest and not (name is None and key != "model") and (
            not isinstance(name, str) or not name or Path(name).name != name
        ):
            raise wrong(key, "a file name in the run's folder" + ("" if key == "model" else " or null"))
    steps = manifest["num_timesteps"]
    if isinstance(steps, bool) or not isinstance(steps, int) or steps < 0:
        raise wrong("num_timesteps", "an integer >= 0")
    if "wall_time_s" in manifest and (isinstance(manifest["wall_time_s"], bool) or not isinstance(manifest["wall_time_s"], (int, float))):
        raise wrong("wall_time_s", "a number of seconds")
    if "env_version" in manifest and not isinstance(manifest["env_version"], (str, type(None))):
        raise wrong("env_version", "a str")
    config = manifest["config"]
    if not isinstance(config, dict):
        raise wrong("config", "a mapping of the run's TrainConfig")
    for key in ("scenario", "action_mode"):
        if not isinstance(config.get(key), str):
            value = config.get(key)
            raise TrainingDirError(f"{str(path)!r}: 'config.{key}' must be a str, got {type(value).__name__} {value!r:.60}")


def _first_line(err: BaseException) -> str:
    text = str(err).strip().splitlines()
    return f"{type(err).__name__}: {text[0]}" if text else type(err).__name__


def file_sha256(path: str | Path) -> str:
    """Hex SHA-256 of a file's bytes."""
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def policies_root(root: str | Path | None = None) -> Path:
    """The folder of published policies: ``root`` if given, else ``$MOMA_POLICIES_DIR`` if set
    (and not empty), else the repository's ``policies/``."""
    if root is not None:
        return Path(root)
    from_env = os.environ.get(POLICIES_ENV)
    return Path(from_env) if from_env else _REPOSITORY_POLICIES


def published_dir(name: str, root: str | Path | None = None) -> Path:
    """The folder of published policy ``name`` under :func:`policies_root` (it may not exist).

    Raises:
        TrainingDirError: ``name`` is not a valid name (:data:`PUBLISHED_NAME`: no path separator).
    """
    if not isinstance(name, str) or not PUBLISHED_NAME.match(name):
        raise TrainingDirError(
            f"{name!r} is not a published policy name (letters, digits, '_' and '-', at most 64, no path separator)"
        )
    return policies_root(root) / name


def published_names(root: str | Path | None = None) -> list[str]:
    """The names of the policies published under :func:`policies_root` (folders with a manifest), sorted."""
    folder = policies_root(root)
    if not folder.is_dir():
        return []
    return sorted(p.name for p in folder.iterdir() if PUBLISHED_NAME.match(p.name) and (p / MANIFEST).is_file())


def read_published(name: str, root: str | Path | None = None) -> dict[str, Any]:
    """The checked manifest of published policy ``name``: a training manifest (:func:`read_manifest`:
    files present, same env version) that records its env version, its provenance
    (``published``) and the SHA-256 of every file, which must match the files.

    Raises:
        TrainingDirError: an invalid or unknown name (listing the published ones), a
            manifest without env version or checksums, another env version, a file
            whose bytes differ from its checksum (truncated or changed).
    """
    folder = published_dir(name, root)
    if not (folder / MANIFEST).is_file():
        known = published_names(root)
        raise TrainingDirError(
            f"no published policy {name!r} in {str(policies_root(root))!r} (published: {', '.join(known) if known else 'none'})"
        )
    manifest = read_manifest(folder)
    where = str(folder / MANIFEST)
    if "env_version" not in manifest:
        raise TrainingDirError(f"{where!r} records no env_version: republish the policy from a run of this code")
    checksums = manifest.get("sha256")
    if not isinstance(checksums, dict) or manifest["model"] not in checksums:
        raise TrainingDirError(f"{where!r} records no sha256 of its files: republish it with python -m training.train.publish")
    for file_name, expected in checksums.items():
        path = folder / file_name
        if not path.is_file():
            raise TrainingDirError(f"{where!r} names file {file_name!r}, which is missing")
        if file_sha256(path) != expected:
            raise TrainingDirError(f"{str(path)!r} differs from the sha256 its manifest records (truncated or changed): republish it")
    return manifest


def load_published(
    name: str, configuration: str | None = None, deterministic: bool = True, root: str | Path | None = None
) -> "LearnedPolicy":
    """The published policy ``name`` (``policies/<name>/``), ready for the evaluation harness::

        policy = agents.learned.load_published("top4_maskable")

    Args:
        name: its name (see :data:`PUBLISHED_NAME`).
        configuration: if given, must be the configuration or task it was trained on.
        deterministic: see :class:`LearnedPolicy`.
        root: the folder of published policies (default :func:`policies_root`).

    Raises:
        TrainingDirError: see :func:`read_published`; a configuration mismatch; a
            model that cannot be loaded.
    """
    read_published(name, root)
    return LearnedPolicy.from_dir(published_dir(name, root), configuration, deterministic=deterministic)


def sb3_class(name: str):
    """The algorithm class named ``name`` (``"PPO"``, ``"MaskablePPO"``, ...) in
    Stable-Baselines3, else in sb3-contrib.

    Raises:
        TrainingDirError: neither package has it (or Stable-Baselines3 is missing).
    """
    try:
        import stable_baselines3
    except ImportError as err:  # pragma: no cover - the train extra is installed in CI
        raise TrainingDirError(f"loading a trained policy needs stable-baselines3 (the 'train' extra): {err}") from None
    cls = getattr(stable_baselines3, name, None)
    if cls is None:
        try:
            import sb3_contrib
        except ImportError:  # pragma: no cover - the train extra is installed in CI
            sb3_contrib = None
        cls = getattr(sb3_contrib, name, None)
    if cls is None:
        raise TrainingDirError(f"neither stable-baselines3 nor sb3-contrib has an algorithm {name!r}")
    return cls


def _uses_action_masks(model: Any) -> bool:
    """Whether ``model.predict`` takes ``action_masks`` (sb3-contrib's MaskablePPO)."""
    import inspect

    return "action_masks" in inspect.signature(model.predict).parameters


@contextmanager
def torch_threads(n: int) -> Iterator[None]:
    """Run the block with torch's intra-op thread count set to ``n``, restored after."""
    import torch

    previous = torch.get_num_threads()
    torch.set_num_threads(n)
    try:
        yield
    finally:
        torch.set_num_threads(previous)


class LearnedPolicy(TrainedUgvPolicy):
    """A trained model acting for every UGV agent (see the module docstring).

    Args:
        model: a Stable-Baselines3 model (``predict(obs, deterministic=True)``;
            with an ``action_masks`` argument, masks are given).
        route: ``"shared"`` or ``"centralised"``.
        action_mode: the env action mode it was trained in.
        normalise: maps a batch of raw observations to the model's inputs
            (an :class:`ObservationScaling`, or ``VecNormalize.normalize_obs``), or None.
        configuration: the configuration name it was trained on, if known.
        torch_threads: torch's thread count while the network runs (>= 1).
        deterministic: act with the mode of the action distribution (True) or
            sample from it (False; seeded by :meth:`reset`).
        switch_horizon_s: the ``EnvConfig.switch_horizon_s`` it was trained with, None
            for the env's default; :meth:`reset` refuses an env with another.
        team_action: the ``EnvConfig.team_action`` of a centralised model (``"per_agent"``
            or ``"one_start"``); :meth:`reset` refuses an env with another.
    """

    def __init__(
        self,
        model: Any,
        route: str,
        action_mode: str,
        normalise: ObservationNormaliser | None = None,
        configuration: str | None = None,
        torch_threads: int = 1,
        deterministic: bool = True,
        switch_horizon_s: float | None = None,
        team_action: str = "per_agent",
    ):
        if route not in _ROUTES:
            raise ValueError(f"route must be one of {_ROUTES}, got {route!r}")
        if team_action != "per_agent" and route != "centralised":
            raise ValueError(f"team_action {team_action!r} is the centralised route's; this model is {route!r}")
        self.model = model
        self.route = route
        self.action_mode = action_mode
        self.configuration = configuration
        self.normalise = normalise
        self._agents: list[str] = []
        self._team: CentralisedTeamEnv | None = None
        self._discrete = isinstance(model.action_space, spaces.Discrete)
        if isinstance(torch_threads, bool) or not isinstance(torch_threads, int) or torch_threads < 1:
            raise ValueError(f"torch_threads must be an int >= 1, got {torch_threads!r}")
        self.torch_threads = torch_threads
        if not isinstance(deterministic, bool):
            raise ValueError(f"deterministic must be a bool, got {deterministic!r}")
        self.deterministic = deterministic
        self.switch_horizon_s = switch_horizon_s
        self.team_action = team_action
        self._sampler = np.random.default_rng(0)
        self._masked = _uses_action_masks(model)
        self._env: MomaParallelEnv | None = None

    @classmethod
    def from_dir(cls, directory: str | Path, configuration: str | None = None, deterministic: bool = True) -> "LearnedPolicy":
        """Load the checkpoint named by ``directory``'s manifest.

        Args:
            directory: a ``moma-env train --out`` folder.
            configuration: if given, must be the configuration the run trained on.
            deterministic: see the class.

        Raises:
            TrainingDirError: see :func:`read_manifest`; a configuration mismatch; a model
                zip or statistics file that cannot be loaded (damaged, truncated).
        """
        directory = Path(directory)
        manifest = read_manifest(directory)
        config = manifest["config"]
        trained_on = config.get("scenario")
        if configuration is not None and trained_on != configuration:
            raise TrainingDirError(f"{str(directory)!r} was trained on {trained_on!r}, not {configuration!r}")
        algorithm = sb3_class(manifest["sb3_class"])
        try:
            model = algorithm.load(directory / manifest["model"], device="cpu")
        except Exception as err:  # a truncated or foreign zip fails anywhere in SB3, zipfile or torch
            raise TrainingDirError(f"cannot load the model {str(directory / manifest['model'])!r} (damaged or not an SB3 zip): "
                                   f"{_first_line(err)}") from None
        normalise = None
        if manifest.get("vecnormalize"):
            try:
                with open(directory / manifest["vecnormalize"], "rb") as f:
                    stats = pickle.load(f)
            except Exception as err:  # truncated pickles raise EOFError, UnpicklingError, ...
                raise TrainingDirError(f"cannot load the normalisation statistics {str(directory / manifest['vecnormalize'])!r}: "
                                       f"{_first_line(err)}") from None
            if not callable(getattr(stats, "normalize_obs", None)):
                raise TrainingDirError(f"cannot load the normalisation statistics {str(directory / manifest['vecnormalize'])!r}: "
                                       f"a pickled {type(stats).__name__}, not SB3 VecNormalize statistics")
            try:
                normalise = ObservationScaling.from_vec_normalize(stats)
            except (AttributeError, ValueError) as err:
                raise TrainingDirError(f"cannot use the normalisation statistics {str(directory / manifest['vecnormalize'])!r}: "
                                       f"{_first_line(err)}") from None
        return cls(model, manifest["route"], config["action_mode"], normalise, trained_on, deterministic=deterministic,
                   **trained_env_fields(config))

    def __reduce__(self) -> tuple[Any, ...]:
        """Pickle as the model's Stable-Baselines3 zip (``save``: its weights and settings,
        not its env) and the constructor's arguments, so that a policy can act in another
        process even while its model trains on envs of this one (an evaluation split over
        workers). The copy acts bit for bit like this policy: the same weights, the same
        torch threads; an ``ObservationScaling`` or no normalisation (another normaliser
        must pickle on its own)."""
        saved = io.BytesIO()
        self.model.save(saved)
        arguments = {
            "route": self.route, "action_mode": self.action_mode, "normalise": self.normalise, "configuration": self.configuration,
            "torch_threads": self.torch_threads, "deterministic": self.deterministic, "switch_horizon_s": self.switch_horizon_s,
            "team_action": self.team_action,
        }
        return _learned_policy_from_zip, (type(self.model), saved.getvalue(), arguments)

    def reset(self, env: MomaParallelEnv, seed: int | None = None) -> None:
        """Check that ``env`` fits the model; read its agents (call after ``env.reset``);
        seed the action sampler with ``seed`` (0 if None)."""
        self._begin_episode(env, seed)
        self._agents = list(env.possible_agents)
        self._env = env
        expected = self.model.observation_space.shape
        if self.route == "centralised":
            if env.config.team_action != self.team_action:
                raise ValueError(f"the policy was trained with team_action={self.team_action!r}; the env has {env.config.team_action!r}")
            self._team = CentralisedTeamEnv(env)
            got = self._team.observation_space.shape
        else:
            got = env.observation_space(self._agents[0]).shape
        if got != expected:
            raise ValueError(f"the model expects observations of shape {expected}; this env gives {got}")

    def _predict(self, batch: np.ndarray, masks: np.ndarray | None = None) -> np.ndarray:
        if self.normalise is not None:
            batch = self.normalise(batch)
        extra = {} if masks is None else {"action_masks": masks}
        with torch_threads(self.torch_threads):
            if self.deterministic:
                actions = discrete_actions(self.model.policy, batch, masks)  # predict's actions, bit for bit, where it knows the policy
                if actions is None:
                    actions, _ = self.model.predict(batch, deterministic=True, **extra)
                return actions
            import torch

            with torch.random.fork_rng(devices=[]):
                torch.manual_seed(int(self._sampler.integers(2**63)))
                actions = discrete_actions(self.model.policy, batch, masks, deterministic=False)
                if actions is None:
                    actions, _ = self.model.predict(batch, deterministic=False, **extra)
        return actions

    def act(self, observations: Mapping[str, np.ndarray], infos: Mapping[str, Mapping[str, Any]]) -> dict[str, Any]:
        """The model's action of every agent in ``observations`` (``infos`` read only for
        the action masks the env puts there and by a one-start team action, for which
        robots move): the distribution's mode, or a sample (see the class)."""
        if not observations:
            return {}
        if self.route == "centralised":
            assert self._team is not None, "call reset(env) first"
            layout = self._team.layout
            team = layout.observation(observations)[None, :]
            masks = layout.masks(self._env_masks(self._env, layout.agents, infos), infos)[None, :] if self._masked else None
            return layout.agent_actions(self._predict(team, masks)[0], infos)
        agents = [a for a in self._agents if a in observations]
        batch = np.stack([np.asarray(observations[a], dtype=np.float32) for a in agents])
        masks = None
        if self._masked:
            assert self._env is not None, "call reset(env) first"
            every = self._env_masks(self._env, agents, infos)
            masks = np.stack([every[a] for a in agents]).astype(bool)
        actions = self._predict(batch, masks)
        if self._discrete:
            return {a: int(actions[k]) for k, a in enumerate(agents)}
        return {a: np.asarray(actions[k], dtype=np.float32) for k, a in enumerate(agents)}


def _learned_policy_from_zip(algorithm: type, saved: bytes, arguments: Mapping[str, Any]) -> LearnedPolicy:
    """A :class:`LearnedPolicy` unpickled (:meth:`LearnedPolicy.__reduce__`): the model
    loaded from its saved zip on the CPU. Loading seeds Python's, NumPy's and torch's
    global generators with the model's seed (Stable-Baselines3's ``set_random_seed``);
    their states are put back, so unpickling leaves the process's randomness as it was."""
    import random

    import torch

    python_state, numpy_state = random.getstate(), np.random.get_state()
    with torch.random.fork_rng(devices=[]):
        try:
            model = algorithm.load(io.BytesIO(saved), device="cpu")
        finally:
            random.setstate(python_state)
            np.random.set_state(numpy_state)
    return LearnedPolicy(model, **arguments)

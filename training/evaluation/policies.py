"""Which policy the harness runs: the protocol it needs and :func:`load_policy`.

A policy sees what an agent may see: the observations and the infos the env
hands it. Only the harness reads the ground truth for its metrics.

Specs understood by :func:`load_policy`:

* ``"scripted"``: ``agents.policies.scripted_policy(configuration)``;
* ``"greedy"``: ``agents.policies.GreedyParallelPolicy()`` (as many movers as the
  rules allow; it needs the env's action masks, which its ``env_options`` ask for);
  ``"greedy@L"`` starts every leg with ``L`` m, one of the env's ``leg_lengths``
  (``GreedyParallelPolicy(leg_m=L)``, e.g. ``greedy@1.5`` on ``top_observer_team4_legs``);
  ``"rollout@L"`` the lookahead over its starts and every leg length, ``greedy@L`` finishing
  (``GreedyRolloutPolicy(base=GreedyParallelPolicy(leg_m=L), lengths=True)``);
  ``"rollout_nowait@L"`` the same without waiting (``wait=False``: where a robot may
  start, one does);
* ``"pipeline"``: ``agents.policies.FilePipelinePolicy()`` (a file of robots, every
  other robot moving at once between static neighbours; caterpillar files only);
* ``"rollout"``: ``agents.policies.GreedyRolloutPolicy()`` (the greedy policy with a
  lookahead over its starts in copies of the env: a planner that reads the simulator);
* ``"rollout_nowait"``: the same lookahead without the choice of starting no robot where
  one may start (``GreedyRolloutPolicy(wait=False)``);
* ``"pipeline_rollout"``: the same lookahead over the file pipeline's starts
  (``GreedyRolloutPolicy(base=FilePipelinePolicy())``);
* ``"pipeline_rollout_masks"``: the lookahead over every start the masks allow, the
  pipeline finishing each rollout
  (``GreedyRolloutPolicy(base=FilePipelinePolicy(), candidates=GreedyParallelPolicy())``);
* ``"random"``: ``agents.policies.RandomPolicy(seed)``;
* a path: the output folder of ``moma-env train``
  (:class:`agents.learned.LearnedPolicy`, or with ``--backend rllib`` / ``torchrl``
  :class:`agents.rllib_policy.RllibPolicy` / :class:`agents.torchrl_policy.TorchRLPolicy`;
  each names the env options it fits in ``env_options``);
* a name without a path separator that is published under ``policies/`` (or
  ``$MOMA_POLICIES_DIR``): :func:`agents.learned.load_published` (a policy of
  another env version is refused). A name that is both a published policy and a
  folder in the working directory is refused as ambiguous (write ``./NAME`` for the folder).

``agents.policies`` is imported lazily, when a policy is loaded.
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

from moma_env.config import ConfigError

from training.policy_specs import BUILTIN_POLICIES, POLICY_ACTION_MODES, builtin_name, leg_spec

__all__ = [
    "Policy", "PolicyLoadError", "PolicyEnvError", "overrides_beside_policy", "BUILTIN_POLICIES", "POLICY_ACTION_MODES", "builtin_name", "load_policy", "policy_label",
]

#: Built-in policies that are an ``agents.policies`` class made without arguments.
_CLASS_POLICIES = {"greedy": "GreedyParallelPolicy", "pipeline": "FilePipelinePolicy", "rollout": "GreedyRolloutPolicy", "planned": "PlannedPolicy"}


class PolicyLoadError(ValueError):
    """A policy spec that names no policy the harness can load (one-line message)."""


class PolicyEnvError(PolicyLoadError):
    """A loaded policy that refuses the env it is given at ``reset`` (another configuration,
    action mode or team: e.g. the file pipeline under a top observer); one-line message."""


@runtime_checkable
class Policy(Protocol):
    """What the harness drives: reset once per episode, then one action dict per step."""

    def reset(self, env: Any, seed: int | None = None) -> None: ...

    def act(self, observations: dict, infos: dict) -> dict: ...


def overrides_beside_policy(spec: str, env_options: Mapping[str, Any], overrides: Mapping[str, Any]) -> dict[str, Any]:
    """``overrides`` (configuration fields and env options) less the env options the policy
    ``spec`` fixes (``env_options``, a trained policy's own), which an override may repeat
    but not change.

    Raises:
        ConfigError: naming ``overrides.<name>`` where an override would change one.
    """
    kept = dict(overrides)
    for name in overrides.keys() & env_options.keys():
        if overrides[name] != env_options[name]:
            raise ConfigError(f"overrides.{name}", f"the policy {spec!r} was trained with {name}={env_options[name]!r}")
        del kept[name]
    return kept


def policy_label(spec: str) -> str:
    """A short name of a policy spec for folders and tables (a path gives its stem)."""
    if builtin_name(spec) is not None:
        return spec
    return Path(spec).stem or "policy"


def _agents_policies():
    try:
        return importlib.import_module("agents.policies")
    except ImportError as err:
        raise PolicyLoadError(f"the built-in policies need the package agents.policies, which cannot be imported: {err}") from None


def _learned():
    try:
        return importlib.import_module("agents.learned")
    except ImportError as err:
        raise PolicyLoadError(f"trained policies need the module agents.learned, which cannot be imported: {err}") from None


def _load_trained_policy(path: Path, configuration: str, sample_actions: bool = False) -> Policy:
    """A policy trained by ``moma-env train`` in folder ``path`` (:class:`agents.learned.LearnedPolicy`),
    sampling its actions if ``sample_actions``."""
    learned = _learned()
    for module, is_run, policy_class in (("agents.rllib_policy", "is_rllib_run", "RllibPolicy"),  # moma-env train --backend rllib
                                         ("agents.torchrl_policy", "is_torchrl_run", "TorchRLPolicy")):  # --backend torchrl
        backend = importlib.import_module(module)
        if getattr(backend, is_run)(path):
            try:
                return getattr(backend, policy_class).from_dir(path, configuration, deterministic=not sample_actions)
            except learned.TrainingDirError as err:
                raise PolicyLoadError(str(err)) from None
    try:
        return learned.LearnedPolicy.from_dir(path, configuration, deterministic=not sample_actions)
    except learned.TrainingDirError as err:
        raise PolicyLoadError(str(err)) from None


def _published_folder(spec: str) -> Path | None:
    """The folder of published policy ``spec`` if ``spec`` is a bare name (no path separator)
    with a folder under the policies root, else None."""
    learned = _learned()
    if not learned.PUBLISHED_NAME.match(spec):
        return None
    folder = learned.published_dir(spec)
    return folder if folder.is_dir() else None


def _published_names() -> list[str]:
    return _learned().published_names()


def _load_published_policy(name: str, configuration: str, sample_actions: bool = False) -> Policy:
    """The published policy ``name`` (:func:`agents.learned.load_published`), sampling if ``sample_actions``."""
    learned = _learned()
    try:
        return learned.load_published(name, configuration, deterministic=not sample_actions)
    except learned.TrainingDirError as err:
        raise PolicyLoadError(str(err)) from None


def load_policy(spec: str, configuration: str, seed: int | None = None, sample_actions: bool = False) -> Policy:
    """The policy named by ``spec`` for configuration ``configuration``.

    Args:
        spec: ``"scripted"`` (switching mode), ``"greedy"`` (switching mode, several
            movers at once), ``"pipeline"`` (a file of robots, every other one moving
            at once), ``"rollout"`` / ``"pipeline_rollout"`` (the greedy / the pipeline
            with a lookahead over its starts, a planner reading the simulator;
            ``"rollout_nowait"``: never starting none where a start is allowed),
            ``"pipeline_rollout_masks"`` (the pipeline with a lookahead over every start the
            masks allow), ``"planned"`` (follows the MOMA
            navigation planner's plan, velocity mode), ``"servo"`` (the
            caterpillar follower servoing to its stand-off, velocity mode),
            ``"random"``, the path
            of a trained policy, or the name of a published one (``policies/<name>``).
        configuration: the configuration's or task's name (``"top_observer"``,
            ``"top_observer_team4"``, ...); a built-in policy is its configuration's.
        seed: the random policy's seed (ignored by the others).
        sample_actions: a trained policy samples its actions (seeded per
            episode) instead of taking the distribution's mode; only for trained
            policies.

    Raises:
        PolicyLoadError: an unknown spec, a path that does not exist or is not
            supported yet, a published policy that cannot be loaded (another env
            version, damaged files), or ``agents.policies`` missing or lacking the policy.
    """
    tasks = importlib.import_module("moma_env.tasks").TASKS
    if configuration in tasks:  # a built-in policy is that of the task's configuration
        builtin_configuration = tasks[configuration].configuration
    else:
        builtin_configuration = configuration
    if not isinstance(spec, str) or not spec:
        raise PolicyLoadError(f"policy must be 'scripted', 'random' or a path, got {spec!r}")
    if sample_actions and builtin_name(spec) is not None:
        raise PolicyLoadError(f"sampling actions applies to a trained policy (a path), not {spec!r}")
    try:
        leg = leg_spec(spec)
    except ValueError as err:
        raise PolicyLoadError(str(err)) from None
    if leg is not None:
        module = _agents_policies()
        name, leg_m = leg
        if name == "greedy":
            policy = module.GreedyParallelPolicy(leg_m=leg_m)
        else:  # rollout, rollout_nowait
            policy = module.GreedyRolloutPolicy(base=module.GreedyParallelPolicy(leg_m=leg_m), lengths=True, wait=name == "rollout")
    elif spec == "scripted":
        module = _agents_policies()
        factory = getattr(module, "scripted_policy", None)
        if factory is None:
            raise PolicyLoadError("agents.policies has no scripted_policy(configuration)")
        try:
            policy = factory(builtin_configuration)
        except (KeyError, ValueError) as err:
            raise PolicyLoadError(f"no scripted policy for configuration {configuration!r}: {err}") from None
    elif spec in _CLASS_POLICIES:
        class_name = _CLASS_POLICIES[spec]
        cls = getattr(_agents_policies(), class_name, None)
        if cls is None:
            raise PolicyLoadError(f"agents.policies has no {class_name}()")
        policy = cls()
    elif spec == "rollout_nowait":
        policy = _agents_policies().GreedyRolloutPolicy(wait=False)
    elif spec == "pipeline_rollout":
        module = _agents_policies()
        policy = module.GreedyRolloutPolicy(base=module.FilePipelinePolicy())
    elif spec == "pipeline_rollout_masks":
        module = _agents_policies()
        policy = module.GreedyRolloutPolicy(base=module.FilePipelinePolicy(), candidates=module.GreedyParallelPolicy())
    elif spec == "servo":
        if builtin_configuration != "caterpillar":
            raise PolicyLoadError(f"the servo policy is for the caterpillar configuration, not {configuration!r}")
        module = _agents_policies()
        cls = getattr(module, "CaterpillarServo", None)
        if cls is None:
            raise PolicyLoadError("agents.policies has no CaterpillarServo()")
        policy = cls()
    elif spec == "random":
        module = _agents_policies()
        cls = getattr(module, "RandomPolicy", None)
        if cls is None:
            raise PolicyLoadError("agents.policies has no RandomPolicy(seed)")
        policy = cls(seed)
    else:
        path = Path(spec)
        published = _published_folder(spec)
        if published is not None:
            if path.exists():
                raise PolicyLoadError(
                    f"policy {spec!r} is both a published policy ({str(published)!r}) and a folder here: write ./{spec} for the folder"
                )
            policy = _load_published_policy(spec, configuration, sample_actions)
        elif not path.exists():
            raise PolicyLoadError(
                f"unknown policy {spec!r}: expected one of {', '.join(repr(p) for p in BUILTIN_POLICIES)}, the folder of a trained "
                f"policy or a published policy's name (published: {', '.join(_published_names()) or 'none'})"
            )
        else:
            policy = _load_trained_policy(path, configuration, sample_actions)
    if not isinstance(policy, Policy):
        raise PolicyLoadError(f"policy {spec!r} lacks reset(env, seed) or act(observations, infos)")
    return policy

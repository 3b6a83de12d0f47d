"""Constructors of the environments by configuration name (what the versioned modules call).

``parallel_env("top_observer", action_mode="velocity", n_ugvs=3)`` builds a
:class:`MomaParallelEnv`; every keyword that is not an environment option is a
field of the configuration's dataclass (``moma_env.scenarios``), validated by it.
A task name (:data:`moma_env.tasks.TASKS`) stands for its configuration with the
task's options, which keywords override.
``random_scenarios=True`` draws a new random layout of the same robots at every
reset from the env's seeded generator (:class:`RandomScenarios`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import fields, replace
from typing import Any

import numpy as np
from pettingzoo.utils.conversions import parallel_to_aec

from moma_env.camera import CameraConfig, FloorConfig, RenderConfig
from moma_env.config import ConfigError, from_mapping
from moma_env.control import TrackingControllerConfig
from moma_env.env.centralised import CentralisedTeamEnv
from moma_env.env.config import DEFAULT_SWITCH_HORIZON_S, SWITCHING_ONLY_OPTIONS, EnvConfig, RewardConfig
from moma_env.env.parallel import MomaParallelEnv
from moma_env.scenarios import SCENARIO_SPECS, Scenario, ScenarioConfig, ScenarioSpec
from moma_env.tasks import TASKS, task_options

__all__ = [
    "parallel_env",
    "configuration_env",
    "aec_env",
    "centralised_env",
    "scenario_factory",
    "RandomScenarios",
    "checked_overrides",
    "env_config",
    "SETTABLE_ENV_OPTIONS",
    "BATCH_ONLY_OPTIONS",
    "versioned_constructors",
]

#: The env options (:class:`EnvConfig` fields) an override may set beside the
#: configuration's fields (:func:`checked_overrides`): all but the action mode and the
#: episode length, which the commands take as options of their own.
SETTABLE_ENV_OPTIONS = tuple(f.name for f in fields(EnvConfig) if f.name not in ("action_mode", "max_cycles"))
#: Every env option :func:`configuration_env` hands to :func:`env_config`.
_ENV_OPTIONS = tuple(f.name for f in fields(EnvConfig))


def _task_options(task: str, overrides: Mapping[str, Any]) -> tuple[str, dict[str, Any]]:
    """:func:`~moma_env.tasks.task_options` of ``task`` with ``overrides``, refusing in one
    error an action mode the task's own switching-only options (:data:`SWITCHING_ONLY_OPTIONS`)
    do not allow, so that a caller learns every option to turn off at once.

    Raises:
        ConfigError: naming ``action_mode``.
    """
    configuration, options = task_options(task, **overrides)
    mode = options.get("action_mode", EnvConfig.action_mode)
    if mode != "switching":
        kept = [key for key in SWITCHING_ONLY_OPTIONS if key not in overrides and options.get(key) not in (None, False)]
        if kept:
            off = ", ".join(f"{key}={'False' if isinstance(options[key], bool) else 'None'}" for key in kept)
            raise ConfigError(
                "action_mode",
                f"task {task!r} sets {', '.join(kept)}, which exist only in action_mode='switching'; "
                f"for action_mode={mode!r} pass {off} as well",
            )
    return configuration, options


def _spec(configuration: str) -> ScenarioSpec:
    """The registered spec of ``configuration``; ConfigError naming ``configuration`` otherwise."""
    spec = SCENARIO_SPECS.get(configuration) if isinstance(configuration, str) else None
    if spec is None:
        raise ConfigError("configuration", f"unknown configuration {configuration!r}; known: {sorted(SCENARIO_SPECS)}")
    return spec


class RandomScenarios:
    """A scenario factory ``f(rng) -> Scenario``: a new random layout of one team per call.

    ``f(None)`` is the base configuration's scenario (the env's first layout);
    ``f(rng)`` a random configuration drawn from ``rng`` (the configuration's
    ``random``) that keeps the base configuration's team fields (``TEAM_FIELDS``,
    e.g. ``n_ugvs``), so every layout has the same agents, and the rig's settings
    among the overrides (``SETTING_FIELDS``: the estimator, ``leg_length``,
    ``dwell_s``, the goal tolerances, ``max_cycles``; and with a ``camera`` override,
    its pose solver's and noise model's settings, ``CameraConfig.SETTING_FIELDS``, put
    into each drawn camera), so every layout is run alike. The other overrides (what
    ``random`` draws: formation, goals, the camera's intrinsics and noise, obstacles,
    ...) shape the base layout only. Instances pickle as their arguments.

    Args:
        configuration: a registered configuration name, e.g. ``"top_observer"``.
        overrides: fields of the configuration's dataclass for the base
            configuration (nested dataclasses may be mappings of their fields).

    Raises:
        ConfigError: naming the field, for an unknown configuration, a bad
            override, or a team random layouts cannot keep (e.g.
            ``"top_observer.n_ugvs"`` with its allowed range), or several
            observers (random layouts draw one), at construction; at a call, a
            camera setting that a drawn camera does not admit (e.g.
            ``camera.pnp_warm_max_rms_px`` below the drawn ``noise_px``).
    """

    def __init__(self, configuration: str, overrides: Mapping[str, Any] | None = None) -> None:
        spec = _spec(configuration)
        self._configuration = configuration
        self._overrides = dict(overrides or {})
        self._base = from_mapping(spec.config_type, self._overrides, name=configuration)
        self._team = spec.config_type.check_team({name: getattr(self._base, name) for name in spec.team_fields})
        self._settings = {name: getattr(self._base, name) for name in spec.config_type.SETTING_FIELDS if name in self._overrides}
        camera = self._base.camera
        self._camera_settings = {name: getattr(camera, name) for name in CameraConfig.SETTING_FIELDS} if "camera" in self._overrides else {}
        self._base_scenario = self._base.scenario()
        if len(self._base_scenario.world.uavs) > 1:
            raise ConfigError(
                f"{configuration}.observer",
                "random layouts draw one observer; several observers need random_scenarios=False",
            )

    @property
    def configuration(self) -> str:
        """The configuration's name."""
        return self._configuration

    @property
    def overrides(self) -> dict[str, Any]:
        """A copy of the base configuration's overrides."""
        return dict(self._overrides)

    @property
    def base(self) -> ScenarioConfig:
        """The base configuration (the layout of ``f(None)``)."""
        return self._base

    @property
    def team(self) -> dict[str, int]:
        """The team fields every random layout keeps, e.g. ``{"n_ugvs": 2}``."""
        return dict(self._team)

    @property
    def settings(self) -> dict[str, Any]:
        """The rig's settings every random layout keeps (those among the overrides), e.g. ``{"leg_length": 1.5}``."""
        return dict(self._settings)

    @property
    def camera_settings(self) -> dict[str, Any]:
        """The camera's settings every random layout keeps (all of ``CameraConfig.SETTING_FIELDS``
        when the overrides give a ``camera``, else none), e.g. ``{"pnp_method": "SQPNP", ...}``."""
        return dict(self._camera_settings)

    def __call__(self, rng: np.random.Generator | None) -> Scenario:
        """The base scenario for ``rng=None``, else a random one drawn from ``rng``."""
        if rng is None:
            return self._base_scenario
        config = _spec(self._configuration).random(rng, **self._team)
        changes = dict(self._settings)
        if self._camera_settings:
            changes["camera"] = replace(config.camera, **self._camera_settings)
        if changes:
            config = replace(config, **changes)
        return config.scenario()

    def __reduce__(self) -> tuple[type[RandomScenarios], tuple[str, dict[str, Any]]]:
        return (type(self), (self._configuration, self._overrides))

    def __repr__(self) -> str:
        return f"RandomScenarios({self._configuration!r}, {self._overrides!r})"


def scenario_factory(configuration: str, random_scenarios: bool = False, **overrides: Any) -> Scenario | RandomScenarios:
    """The fixed :class:`Scenario` of a configuration with ``overrides``, or with
    ``random_scenarios`` a :class:`RandomScenarios` keeping its robots."""
    if random_scenarios:
        return RandomScenarios(configuration, overrides)
    spec = _spec(configuration)
    return from_mapping(spec.config_type, overrides, name=configuration).scenario()


def checked_overrides(name: str, overrides: Mapping[str, Any]) -> dict[str, Any]:
    """``overrides`` for configuration or task ``name``, checked: each a field of the
    configuration's dataclass (e.g. ``{"leg_length": 1.5}``) or one of
    :data:`SETTABLE_ENV_OPTIONS` (e.g. ``{"tracking": {"fill": 0.5}}``), and the
    configuration and the env's settings, with the task's own, valid with them.

    Raises:
        ConfigError: naming the configuration's field or the env option (an unknown
            name, a bad value), or ``configuration`` (an unknown name).
    """
    configuration, options = task_options(name) if isinstance(name, str) and name in TASKS else (name, {})
    config_type = _spec(configuration).config_type
    known = [f.name for f in fields(config_type)]
    for key in overrides:
        if key not in known and key not in SETTABLE_ENV_OPTIONS:
            raise ConfigError(f"{configuration}.{key}", f"no such field of the {configuration} configuration, nor an env option; "
                              f"known: {known}; env options: {list(SETTABLE_ENV_OPTIONS)}")
    own = {key: value for key, value in options.items() if key in known}
    from_mapping(config_type, {**own, **{k: v for k, v in overrides.items() if k in known}}, name=configuration)
    if any(key in SETTABLE_ENV_OPTIONS for key in overrides):  # the env's settings, the task's with these
        env_config(**{key: value for key, value in {**options, **overrides}.items() if key in SETTABLE_ENV_OPTIONS})
    return dict(overrides)


def env_config(
    *,
    max_cycles: int | None = None,
    action_mode: str = "switching",
    observer_agent: bool | None = None,
    rewards: RewardConfig | Mapping[str, float] | None = None,
    camera_backend: str = "geometric",
    render: RenderConfig | Mapping[str, Any] | None = None,
    floor: FloorConfig | Mapping[str, Any] | None = None,
    observer_image: tuple[int, int] | None = None,
    action_masks: bool = False,
    commit_legs: bool = False,
    leg_lengths: tuple[float, ...] | None = None,
    follower_hold_m: float | None = None,
    info_keys: Sequence[str] | None = None,
    pad_observations: bool = False,
    localiser: Any = None,
    switch_horizon_s: float = DEFAULT_SWITCH_HORIZON_S,
    team_action: str = "per_agent",
    tracking: TrackingControllerConfig | Mapping[str, Any] | None = None,
) -> EnvConfig:
    """The :class:`EnvConfig` of these options, ``rewards``, ``render``, ``floor`` and
    ``tracking`` given as mappings of their fields or as their dataclasses (``rewards``
    and ``tracking`` None: their defaults).

    Raises:
        ConfigError: naming the bad field (``env.<name>``, ``tracking.<name>``, ...).
    """
    if rewards is None:
        rewards = RewardConfig()
    elif isinstance(rewards, Mapping):
        rewards = from_mapping(RewardConfig, rewards, name="rewards")
    if isinstance(render, Mapping):
        render = from_mapping(RenderConfig, render, name="render")
    if isinstance(floor, Mapping):
        floor = from_mapping(FloorConfig, floor, name="floor")
    if tracking is None:
        tracking = TrackingControllerConfig()
    elif isinstance(tracking, Mapping):
        tracking = from_mapping(TrackingControllerConfig, tracking, name="tracking")
    return EnvConfig(
        action_mode=action_mode,
        observer_agent=observer_agent,
        max_cycles=max_cycles,
        rewards=rewards,
        camera_backend=camera_backend,
        render=render,
        floor=floor,
        observer_image=observer_image,
        action_masks=action_masks,
        commit_legs=commit_legs,
        leg_lengths=leg_lengths,
        follower_hold_m=follower_hold_m,
        info_keys=info_keys,
        pad_observations=pad_observations,
        localiser=localiser,
        switch_horizon_s=switch_horizon_s,
        team_action=team_action,
        tracking=tracking,
    )


def parallel_env(configuration: str, **options: Any) -> MomaParallelEnv:
    """The PettingZoo parallel env of a configuration or of a task (:mod:`moma_env.tasks`,
    whose options ``options`` override); the options are :func:`configuration_env`'s."""
    if isinstance(configuration, str) and configuration in TASKS:
        configuration, options = _task_options(configuration, options)
    return configuration_env(configuration, **options)


def configuration_env(
    configuration: str,
    *,
    render_mode: str | None = None,
    random_scenarios: bool = False,
    **options: Any,
) -> MomaParallelEnv:
    """The PettingZoo parallel env of ``configuration`` (see the module docstring).

    Args:
        configuration: a name of :data:`moma_env.scenarios.CONFIGURATIONS`.
        render_mode: ``None``, ``"human"`` or ``"rgb_array"``.
        random_scenarios: a new random layout at every reset (:class:`RandomScenarios`).
        **options: the env's options, the :class:`EnvConfig` fields (``action_mode``,
            ``max_cycles``, ``rewards``, ``camera_backend``, ``render``, ``floor``,
            ``observer_image``, ``action_masks``, ``commit_legs``, ``leg_lengths``,
            ``follower_hold_m``, ``info_keys``, ``pad_observations``, ``localiser``, ``switch_horizon_s``, ``team_action``,
            ``tracking``, ``observer_agent``: :func:`env_config`, where ``rewards``,
            ``render``, ``floor`` and ``tracking`` may be mappings of their fields), and
            any other keyword a field of the configuration's dataclass.
    """
    config = env_config(**{name: options.pop(name) for name in _ENV_OPTIONS if name in options})
    overrides = options
    scenarios = scenario_factory(configuration, random_scenarios, **overrides)
    return MomaParallelEnv(
        scenarios,
        config,
        render_mode=render_mode,
        name=_spec(configuration).pettingzoo_module,
    )


def aec_env(configuration: str, **kwargs: Any):
    """The AEC version, through PettingZoo's converter (order enforced)."""
    return parallel_to_aec(parallel_env(configuration, **kwargs))


#: Keywords of the batched Gymnasium env (:class:`moma_env.vector.team.TeamVectorEnv`, what
#: ``gymnasium.make_vec`` builds by default) that one env does not take, and what to use in
#: their place with Gymnasium's own vector envs (``vectorization_mode="sync"`` or ``"async"``,
#: which make each copy with ``gymnasium.make``).
BATCH_ONLY_OPTIONS = {
    "autoreset_mode": "pass vector_kwargs={'autoreset_mode': ...} to gymnasium.make_vec",
    "workers": "use vectorization_mode='async' (a process per copy)",
}


def centralised_env(configuration: str, **kwargs: Any) -> CentralisedTeamEnv:
    """The whole team as one Gymnasium agent (what ``gymnasium.make`` builds).

    Raises:
        ConfigError: naming a keyword of the batched env only (:data:`BATCH_ONLY_OPTIONS`),
            as ``gymnasium.make_vec(..., vectorization_mode="sync")`` hands its keywords
            to every copy; else as :func:`parallel_env`.
    """
    for key, instead in BATCH_ONLY_OPTIONS.items():
        if key in kwargs:
            raise ConfigError(
                key, f"is an option of the batched env gymnasium.make_vec builds by default (vectorization_mode="
                     f"'vector_entry_point'), not of one env; with Gymnasium's own vector envs, {instead}"
            )
    return CentralisedTeamEnv(parallel_env(configuration, **kwargs))


def versioned_constructors(configuration: str):
    """``(parallel_env, env)`` of a versioned module such as ``moma_env.top_observer_v0``."""

    def make_parallel(**kwargs: Any) -> MomaParallelEnv:
        return parallel_env(configuration, **kwargs)

    def make_aec(**kwargs: Any):
        return aec_env(configuration, **kwargs)

    make_parallel.__doc__ = f"PettingZoo parallel env of the {configuration} configuration; kwargs as moma_env.env.factory.parallel_env."
    make_aec.__doc__ = f"PettingZoo AEC env of the {configuration} configuration; kwargs as moma_env.env.factory.parallel_env."
    return make_parallel, make_aec

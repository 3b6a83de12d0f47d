"""Configuration of the PettingZoo environment: action mode, agents, rewards.

The scenario (world, cameras, goals) comes from a configuration of
:mod:`moma_env.scenarios`; this module holds what is about the learning problem,
in the spirit of highway-env's ``default_config()``: the action type is chosen by
config, the reward is a weighted sum of named terms.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, fields
from typing import Any


from moma_env.camera.factory import CAMERA_BACKENDS
from moma_env.camera.floor import FloorConfig
from moma_env.camera.render_config import RenderConfig
from moma_env.config import (
    ConfigError,
    check_bool,
    check_choice,
    check_count,
    check_finite,
    check_non_negative,
    check_numbers,
    check_positive,
)
from moma_env.control import TrackingControllerConfig
from moma_env.env.actions import LEG_POSITION_TOLERANCE_M
from moma_env.env.info_keys import INFO_KEYS
from moma_env.estimator.registry import check_estimator_name, resolve_localiser

__all__ = ["ACTION_MODES", "SWITCHING_ONLY_OPTIONS", "TEAM_ACTIONS", "RewardConfig", "EnvConfig", "checked_info_keys", "checked_max_cycles"]


def checked_info_keys(name: str, value: object) -> tuple[str, ...]:
    """``value`` as a choice of info keys: a sequence (not a string) of distinct keys of
    :data:`~moma_env.env.info_keys.INFO_KEYS`, as a tuple; ConfigError naming ``name`` otherwise."""
    if isinstance(value, (str, bytes)) or not isinstance(value, Sequence):
        raise ConfigError(name, f"must be None (every key) or a sequence of info keys, got {value!r}")
    keys = tuple(value)
    for key in keys:
        if key not in INFO_KEYS:
            raise ConfigError(name, f"unknown info key {key!r}; known: {list(INFO_KEYS)}")
    if len(set(keys)) != len(keys):
        raise ConfigError(name, f"must be distinct, got {list(keys)}")
    return keys


def checked_max_cycles(name: str, value: object) -> int:
    """``value`` as an episode length in steps: an integer >= 1 (Python or numpy, not a bool);
    ConfigError naming ``name`` otherwise."""
    check_count(name, value)
    return int(value)


#: ``velocity``: continuous body velocities plus a requested static/mobile state;
#: ``switching``: discrete hold / advance per UGV, built-in controllers drive.
ACTION_MODES = ("velocity", "switching")
#: The ``EnvConfig`` fields that only ``switching`` mode takes (off: False or None); in
#: ``velocity`` mode ``EnvConfig`` refuses each one set.
SWITCHING_ONLY_OPTIONS = ("action_masks", "commit_legs", "leg_lengths", "follower_hold_m")
#: What the centralised team's action is (``EnvConfig.team_action``).
TEAM_ACTIONS = ("per_agent", "one_start")


@dataclass(frozen=True)
class RewardConfig:
    """Weights of the team reward's terms (every agent gets the same team reward).

    Attributes:
        progress: per metre the UGVs got closer to their goals this step (truth).
        localisation_error: per metre of the mean position error of the UGVs'
            MOMA estimates this step (truth vs estimate; a lost robot counts
            ``lost_error_m``).
        switch: per granted static/mobile switch.
        refused: per refused request to become mobile.
        collision: per new collision pair involving a robot.
        lost: per step and per robot whose estimate is LOST.
        goal_bonus: once per UGV reaching its goal.
        time: per step (a negative value rewards finishing early).
        final_error: per metre of the mean position error of the UGVs' estimates
            (as ``localisation_error`` counts it) at the step the team reaches its
            last goal; 0 at every other step.
        lost_error_m: error (m) charged for a robot without a usable estimate.
    """

    progress: float = 1.0
    localisation_error: float = -0.5
    switch: float = -0.01
    refused: float = -0.05
    collision: float = -0.2
    lost: float = -0.05
    goal_bonus: float = 5.0
    time: float = -0.005
    final_error: float = 0.0
    lost_error_m: float = 1.0

    def __post_init__(self) -> None:
        for f in fields(self):
            check_finite(f"rewards.{f.name}", getattr(self, f.name))
        check_non_negative("rewards.lost_error_m", self.lost_error_m)


#: The env's default ``EnvConfig.switch_horizon_s`` (s).
DEFAULT_SWITCH_HORIZON_S = 5.0


@dataclass(frozen=True)
class EnvConfig:
    """How the environment exposes a scenario to learning agents.

    Attributes:
        action_mode: one of :data:`ACTION_MODES`.
        observer_agent: whether the UAV observer is an agent. ``None`` means yes
            in ``velocity`` mode and no in ``switching`` mode (its built-in
            tracking controller flies it).
        max_cycles: episode length in steps; ``None`` takes the scenario's.
        rewards: reward weights.
        camera_backend: ``"geometric"`` (projected corners; fast, the default)
            or ``"rendered"`` (synthetic images through the ArUco detector).
        render: image formation of the rendered backend (its defaults if None).
        floor: floor texture of the rendered backend; None textures the whole
            arena plus a 1 m margin with :class:`FloorConfig`'s defaults.
        observer_image: ``(width, height)`` (px) of the observer's camera image
            added to its observation, or None (the default: vector only). The
            observer's observation is then a ``Dict`` with ``"features"`` (the
            usual vector) and ``"image"`` (``Box(0, 255, (height, width, 1),
            uint8)``, the latest rendered frame downscaled). Needs the rendered
            backend and the observer as an agent.
        action_masks: in ``switching`` mode, add ``"action_mask"`` to every UGV
            agent's ``infos`` (see :meth:`MomaParallelEnv.action_mask`). Off by
            default: it costs a motion-rules check per UGV and step.
        commit_legs: in ``switching`` mode, a leg once started runs to its end:
            ``hold`` from a UGV driving a leg on a localised estimate is ignored
            and masked (see :class:`moma_env.env.actions.SwitchingActions`). Off
            by default.
        leg_lengths: in ``switching`` mode, the lengths (m, positive, distinct) a UGV
            chooses its legs from: action ``k`` (1 to K) advances ``leg_lengths[k - 1]``
            m, 0 holds (see :class:`moma_env.env.actions.SwitchingActions`). None (the
            default): one advance, of the scenario's ``leg_length``.
        follower_hold_m: in ``switching`` mode, once a robot's estimate has come within
            the leg's position tolerance (2 cm) of the leg's end, the position stays
            reached while the estimate stays within this distance (m, at least 0.02),
            so the robot turns in place to the leg's heading instead of driving back
            whenever its estimate's noise leaves the tolerance (see
            :class:`moma_env.env.actions.SwitchingActions`). None (the default): only
            within the tolerance, the authors' follower.
        info_keys: the keys every agent's ``infos`` entry keeps, of
            :data:`moma_env.env.info_keys.INFO_KEYS` (each agent gets those of them it
            has, in their usual order, and the env builds no other), or None (the
            default): every key. ``("static", "action_mask")`` is what the training
            adapters read (:mod:`training.train.team_slots`).
        pad_observations: pad every agent's vector observation with zeros to
            the longest one, and give every agent one observation space (the
            union of their bounds), so that parameter-sharing wrappers (SuperSuit's
            vector envs) take the observer beside the UGVs in ``velocity`` mode.
            Off by default.
        switch_horizon_s: the time since the last switch (s) at which the agents'
            ``time_since_switch`` feature reaches 1; it stays 1 after (clipped). 5 s by
            default. A team that holds every robot for longer sees the same
            observation at every step, so a deterministic policy that holds once
            holds to the end of the episode; a horizon as long as an episode keeps
            the feature changing (docs/learning.md, "A timer that keeps moving").
        team_action: the action of the whole team as one agent (the centralised
            views: :class:`moma_env.env.centralised.CentralisedTeamEnv`,
            ``gymnasium.make``, :class:`moma_env.vector.team.TeamVectorEnv` and the
            centralised training route; the PettingZoo env's agents keep their own
            actions). ``"per_agent"`` (the default): every agent's action side by
            side (a ``MultiDiscrete`` in switching mode). ``"one_start"``: one
            ``Discrete`` choice a step, no robot starts (0) or one static robot
            takes one of its advance actions, every other robot keeping its state
            (a mobile one advances, a static one holds); needs
            switching mode with ``commit_legs`` (so that a robot driving a leg
            goes on whatever the team chooses) and the observer flown by its
            controller (see :class:`moma_env.env.centralised.TeamLayout`).
        tracking: gains and targets of the UAV's board-tracking controller, which flies
            every UAV that is not an agent (:class:`moma_env.control.TrackingControllerConfig`:
            how much of the image the boards' spread fills, so how high the UAV climbs, up to
            ``max_depth``; its defaults unless given).
        localiser: builds each episode's localiser from the scenario's
            ``EstimatorConfig`` (a :class:`moma_env.sim.Localiser`), or the name
            of one of :data:`moma_env.estimator.registry.ESTIMATORS` (``"moma"``,
            ``"fused"``, ``"ekf"``, ``"graph"``); None: the MOMA estimator. Pass a class or a module-level function so that the
            env stays picklable.
    """

    action_mode: str = "switching"
    observer_agent: bool | None = None
    max_cycles: int | None = None
    rewards: RewardConfig = field(default_factory=RewardConfig)
    camera_backend: str = "geometric"
    render: RenderConfig | None = None
    floor: FloorConfig | None = None
    observer_image: tuple[int, int] | None = None
    action_masks: bool = False
    commit_legs: bool = False
    leg_lengths: tuple[float, ...] | None = None
    follower_hold_m: float | None = None
    info_keys: tuple[str, ...] | None = None
    pad_observations: bool = False
    localiser: Callable[[Any], Any] | None = None
    switch_horizon_s: float = DEFAULT_SWITCH_HORIZON_S
    tracking: TrackingControllerConfig = field(default_factory=TrackingControllerConfig)
    team_action: str = "per_agent"

    def __post_init__(self) -> None:
        check_choice("env.action_mode", self.action_mode, ACTION_MODES)
        if self.observer_agent is not None:
            check_bool("env.observer_agent", self.observer_agent)
        if self.max_cycles is not None:
            object.__setattr__(self, "max_cycles", checked_max_cycles("env.max_cycles", self.max_cycles))
        if not isinstance(self.rewards, RewardConfig):
            raise ConfigError("env.rewards", f"must be a RewardConfig, got {type(self.rewards).__name__}")
        if not isinstance(self.tracking, TrackingControllerConfig):
            raise ConfigError("env.tracking", f"must be a TrackingControllerConfig, got {type(self.tracking).__name__}")
        check_choice("env.camera_backend", self.camera_backend, CAMERA_BACKENDS)
        rendered = self.camera_backend == "rendered"
        for name, cls in (("render", RenderConfig), ("floor", FloorConfig)):
            value = getattr(self, name)
            if value is None:
                continue
            if not isinstance(value, cls):
                raise ConfigError(f"env.{name}", f"must be a {cls.__name__} or None, got {type(value).__name__}")
            if not rendered:
                raise ConfigError(f"env.{name}", "is used only by camera_backend='rendered'")
        if self.observer_image is not None:
            check_numbers("env.observer_image", self.observer_image, ("width", "height"), positive=True)
            size = tuple(self.observer_image)
            check_count("env.observer_image.width", size[0])
            check_count("env.observer_image.height", size[1])
            object.__setattr__(self, "observer_image", (int(size[0]), int(size[1])))
            if not rendered:
                raise ConfigError("env.observer_image", "needs camera_backend='rendered' (the geometric camera has no image)")
            if not self.observer_is_agent:
                raise ConfigError("env.observer_image", "needs the observer to be an agent (observer_agent=True)")

        check_bool("env.pad_observations", self.pad_observations)
        check_positive("env.switch_horizon_s", self.switch_horizon_s)
        object.__setattr__(self, "switch_horizon_s", float(self.switch_horizon_s))
        if isinstance(self.localiser, str):
            check_estimator_name("env.localiser", self.localiser)
        elif self.localiser is not None and not callable(self.localiser):
            raise ConfigError(
                "env.localiser", f"must be an estimator name, a callable EstimatorConfig -> Localiser or None, got {self.localiser!r}"
            )
        check_bool("env.action_masks", self.action_masks)
        if self.action_masks and self.action_mode != "switching":
            raise ConfigError("env.action_masks", "exist only for the discrete actions of action_mode='switching'")
        check_bool("env.commit_legs", self.commit_legs)
        if self.commit_legs and self.action_mode != "switching":
            raise ConfigError("env.commit_legs", "exists only for the legs of action_mode='switching'")
        if self.leg_lengths is not None:
            if self.action_mode != "switching":
                raise ConfigError("env.leg_lengths", "exist only for the legs of action_mode='switching'")
            if isinstance(self.leg_lengths, (str, bytes)) or not isinstance(self.leg_lengths, Sequence) or not self.leg_lengths:
                raise ConfigError("env.leg_lengths", f"must be a non-empty sequence of lengths (m), got {self.leg_lengths!r}")
            for k, length in enumerate(self.leg_lengths):
                check_positive(f"env.leg_lengths[{k}]", length)
            lengths = tuple(float(length) for length in self.leg_lengths)
            if len(set(lengths)) != len(lengths):
                raise ConfigError("env.leg_lengths", f"must be distinct, got {list(lengths)}")
            object.__setattr__(self, "leg_lengths", lengths)
        if self.follower_hold_m is not None:
            if self.action_mode != "switching":
                raise ConfigError("env.follower_hold_m", "exists only for the legs of action_mode='switching'")
            check_positive("env.follower_hold_m", self.follower_hold_m)
            if self.follower_hold_m < LEG_POSITION_TOLERANCE_M:
                raise ConfigError(
                    "env.follower_hold_m",
                    f"must be at least the legs' position tolerance ({LEG_POSITION_TOLERANCE_M} m), got {self.follower_hold_m}",
                )
            object.__setattr__(self, "follower_hold_m", float(self.follower_hold_m))
        if self.info_keys is not None:
            object.__setattr__(self, "info_keys", checked_info_keys("env.info_keys", self.info_keys))
        check_choice("env.team_action", self.team_action, TEAM_ACTIONS)
        if self.team_action == "one_start":
            if not self.commit_legs:
                raise ConfigError("env.team_action", "'one_start' needs commit_legs=True (a robot driving a leg must go on while another starts)")
            if self.observer_is_agent:
                raise ConfigError("env.team_action", "'one_start' needs the observer flown by its controller (observer_agent=False)")

    @property
    def localiser_factory(self) -> Callable[[Any], Any] | None:
        """The localiser factory :attr:`localiser` names or is (None: the MOMA estimator)."""
        return None if self.localiser is None else resolve_localiser(self.localiser)

    @property
    def observer_is_agent(self) -> bool:
        """The resolved ``observer_agent``."""
        return self.action_mode == "velocity" if self.observer_agent is None else self.observer_agent

"""What a training run is: :class:`TrainConfig`, validated at the boundary.

A run trains one Stable-Baselines3 algorithm on one configuration of
:mod:`moma_env.scenarios` through one of two routes:

* ``centralised``: the whole team as one Gymnasium agent
  (:class:`moma_env.env.centralised.CentralisedTeamEnv`), K copies through
  :class:`training.train.shared_vec_env.TeamVecEnv` (one slot per copy); one
  timestep is one env step.
* ``shared``: one policy shared by every UGV agent, through
  :class:`training.train.shared_vec_env.SharedPolicyVecEnv` (each UGV of each of
  the K copies is one slot); one timestep is one agent step, so an env step of
  a team of N robots counts N timesteps.

The UAV observer is never a learning agent here: its tracking controller flies
it in both action modes (``observer_agent=False``), so the learned problem is
the UGVs' coordination. Every layout is a new random scenario of the
configuration (``random_scenarios=True``) drawn from the env's seeded generator.

Nothing in this module imports Stable-Baselines3, and the env's modules (the
camera, the simulator) are imported only when a configuration is checked, so that
``moma-env train --help`` stays light (``tests/test_cli_light.py``).
"""

from __future__ import annotations

import dataclasses
import difflib
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from moma_env.config import ConfigError, check_bool, check_choice, check_count, check_non_negative, check_positive, check_range, from_mapping
from moma_env.registration import CONFIGURATION_NAMES
from moma_env.tasks import TASKS
from training.policy_specs import builtin_name, leg_spec

if TYPE_CHECKING:
    from moma_env.env.config import RewardConfig

__all__ = [
    "ALGORITHMS", "ROUTES", "DISCRETE_ONLY", "MASKED", "BOX_ONLY", "PRETRAINABLE", "TEACHERS", "check_teacher", "NETWORKS", "TrainConfig", "reward_overrides",
    "run_env_options", "config_to_dict", "config_from_dict", "BackendTrainConfig", "check_learning_fields", "check_workers",
    "MIN_COPIES_PER_WORKER", "auto_workers", "eval_jobs", "usable_cores", "PPO_MINIBATCHES", "DEFAULT_BATCH_SIZE", "backend_batch_size",
    "ROLLOUT_UPDATES", "update_threads", "recorded_update_threads",
]

#: Algorithms by CLI name -> Stable-Baselines3 (or sb3-contrib) class name.
ALGORITHMS = {"ppo": "PPO", "a2c": "A2C", "dqn": "DQN", "sac": "SAC", "td3": "TD3", "maskable_ppo": "MaskablePPO"}
#: Algorithms that need a single ``Discrete`` action (switching mode, shared route).
DISCRETE_ONLY = frozenset({"dqn"})
#: Algorithms that act through the env's action masks (switching mode, either route):
#: PPO whose invalid actions (requests the motion rules would refuse, see
#: ``MomaParallelEnv.action_mask``) get zero probability.
MASKED = frozenset({"maskable_ppo"})
#: Algorithms that need a ``Box`` action (velocity mode).
BOX_ONLY = frozenset({"sac", "td3"})
#: Algorithms whose model a scripted teacher can initialise (``pretrain``): an actor and a critic.
PRETRAINABLE = frozenset({"ppo", "maskable_ppo"})
#: On-policy algorithms whose gradient updates run after each rollout, while every env copy
#: waits for the new policy: ``update_threads`` applies to them. (The off-policy ones update
#: between env steps, on ``torch_threads``.)
ROLLOUT_UPDATES = frozenset({"ppo", "a2c", "maskable_ppo"})
#: Minibatches per epoch of PPO's and MaskablePPO's updates when ``batch_size`` is None: each
#: rollout (``n_steps`` x the slots) in this many, as MAPPO does, so that the learner's cost per
#: sample falls as the batched env's copies grow.
PPO_MINIBATCHES = 4
#: Minibatch size (rows) of behaviour cloning, DAgger and the off-policy algorithms when
#: ``batch_size`` is None, and the RLlib and TorchRL backends' default ``--batch-size``.
DEFAULT_BATCH_SIZE = 256
#: Policy networks (``network``): SB3's MLP, or the team network of :mod:`agents.team_network`.
NETWORKS = ("mlp", "team")
#: Scripted teachers a run may be cloned from (``pretrain``, ``dagger_teacher``): built-in
#: switching-mode policies of :func:`training.evaluation.policies.load_policy` (``rollout``
#: and ``rollout_nowait`` read the simulator: planners with a perfect model, seconds per episode).
TEACHERS = ("greedy", "pipeline", "scripted", "rollout", "rollout_nowait")


def check_teacher(name: str, teacher: object) -> str:
    """``teacher`` if it is a teacher: one of :data:`TEACHERS`, or ``greedy@L`` /
    ``rollout@L`` / ``rollout_nowait@L`` (the greedy policy starting legs of ``L`` m on an
    env with ``leg_lengths``, or the lookahead over its starts and lengths, with or without
    waiting); ConfigError naming ``name``."""
    if isinstance(teacher, str):
        try:
            leg_spec(teacher)
        except ValueError as err:
            raise ConfigError(name, str(err)) from None
        if builtin_name(teacher) in TEACHERS:
            return teacher
    close = difflib.get_close_matches(teacher, TEACHERS, n=1, cutoff=0.6) if isinstance(teacher, str) else []
    hint = f" (did you mean {close[0]!r}?)" if close else ""
    raise ConfigError(name, f"must be one of {list(TEACHERS)}, greedy@L, rollout@L or rollout_nowait@L (L m legs), got {teacher!r}{hint}")


def check_learning_fields(config: Any) -> None:
    """ConfigError naming the first bad one of the fields every training configuration has
    (:class:`TrainConfig`, :class:`BackendTrainConfig`): ``max_cycles``,
    ``eval_max_cycles``, ``rewards``, ``net_arch``, ``n_steps``, ``learning_rate``,
    ``gamma``, ``ent_coef``, ``checkpoint_every`` and the evaluation fields."""
    from moma_env.env.config import RewardConfig

    for name in ("max_cycles", "eval_max_cycles"):
        if getattr(config, name) is not None:
            check_count(name, getattr(config, name), 1)
    if config.rewards is not None and not isinstance(config.rewards, RewardConfig):
        raise ConfigError("rewards", f"must be a RewardConfig or None, got {type(config.rewards).__name__}")
    if not isinstance(config.net_arch, tuple) or not config.net_arch:
        raise ConfigError("net_arch", f"must be a non-empty tuple of layer sizes, got {config.net_arch!r}")
    for k, size in enumerate(config.net_arch):
        check_count(f"net_arch[{k}]", size, 1)
    check_count("n_steps", config.n_steps, 1)
    check_positive("learning_rate", config.learning_rate)
    check_range("gamma", config.gamma, 0.0, 1.0)
    check_non_negative("ent_coef", config.ent_coef)
    check_count("checkpoint_every", config.checkpoint_every, 1)
    check_count("eval_every", config.eval_every, 0)
    check_count("eval_episodes", config.eval_episodes, 1)
    check_count("eval_seed", config.eval_seed, 0)
    check_bool("eval_sample_actions", config.eval_sample_actions)


def check_workers(workers: object, envs: int) -> None:
    """ConfigError naming ``workers`` unless it is None or an integer in ``[1, envs]``."""
    if workers is None:
        return
    check_count("workers", workers, 1)
    if workers > envs:  # type: ignore[operator]
        raise ConfigError("workers", f"must be at most the number of env copies ({envs}), got {workers}")


#: The fewest env copies a worker process steps under ``moma-env train --workers auto``:
#: a batch step waits for its slowest shard and a pipe round trip, so a shard of a
#: few copies gains little (docs/training.md: 1.2x with 4 copies a process, 1.5x with 16,
#: on 2 cores).
MIN_COPIES_PER_WORKER = 4


def usable_cores() -> int:
    """The CPU cores this process may run on (its affinity where the platform tells it)."""
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def eval_jobs(config: "TrainConfig") -> int:
    """The worker processes of ``config``'s evaluations: ``config.eval_jobs``, or where it
    is None one per usable core; at most one per episode (1: in this process)."""
    jobs = config.eval_jobs if config.eval_jobs is not None else usable_cores()
    return min(jobs, config.eval_episodes)


def update_threads(config: Any) -> int:
    """torch's intra-op threads for the gradient updates of ``config`` (a :class:`TrainConfig`
    or a TorchRL run's): its ``update_threads``, or where that is None one per usable core
    (nothing else runs during an on-policy update)."""
    return config.update_threads if config.update_threads is not None else usable_cores()


def recorded_update_threads(data: Mapping[str, Any]) -> dict[str, Any]:
    """A recorded configuration ``data`` with ``update_threads`` as its run had it: a run
    recorded before the field existed updated on its ``torch_threads``."""
    if "update_threads" in data:
        return dict(data)
    return {**data, "update_threads": data.get("torch_threads", 1)}


def auto_workers(envs: int, cores: int) -> int | None:
    """The worker processes ``--workers auto`` splits ``envs`` copies over on ``cores`` cores:
    one per core, each stepping at least :data:`MIN_COPIES_PER_WORKER` copies; None (every
    copy in this process) when that leaves one. The rollouts are the same either way."""
    count = min(cores, envs // MIN_COPIES_PER_WORKER)
    return count if count >= 2 else None


#: Training routes (see the module docstring).
ROUTES = ("centralised", "shared")


def backend_batch_size(batch_size: int | None) -> int:
    """A minibatch size given or not: as given, else :data:`DEFAULT_BATCH_SIZE` (``--batch-size``
    of ``moma-env train --backend rllib | torchrl``, and :meth:`TrainConfig.minibatch_size`
    without a rollout)."""
    return DEFAULT_BATCH_SIZE if batch_size is None else batch_size


@dataclass(frozen=True)
class TrainConfig:
    """One training run.

    Attributes:
        scenario: configuration or task name (``"top_observer"``,
            ``"top_observer_team4"``, ...; :mod:`moma_env.tasks`).
        algo: a key of :data:`ALGORITHMS` (``maskable_ppo``: sb3-contrib's
            MaskablePPO, the switching mode's actions masked by the motion rules).
        steps: total SB3 timesteps (env steps on the centralised route, agent
            steps on the shared route); 0 with ``pretrain`` or ``dagger_teacher``: the
            cloned or DAgger-fitted policy as it is.
        envs: number of env copies K.
        subproc: run the K copies in worker processes, one each.
        workers: None, or split the K copies of the run's batched env over this
            many processes, this one included (:func:`moma_env.vector.make`): the
            same rollouts, faster with a free core per process and enough copies.
        seed: seed of the model and of the envs (copy k resets first with a seed
            derived from it; later layouts come from each env's own generator).
        action_mode: ``"switching"`` or ``"velocity"``.
        route: ``"centralised"`` or ``"shared"``.
        max_cycles: episode length limit in steps (None: the scenario's).
        switch_horizon_s: the envs' ``EnvConfig.switch_horizon_s`` (s): the time since
            the last switch at which the observations' timer reaches 1; None: the
            env's default (5 s).
        team_action: the centralised team's action (``EnvConfig.team_action``):
            ``"per_agent"`` (every robot's action side by side, the default) or
            ``"one_start"`` (one choice a step: which static robot starts which leg,
            if any); ``"one_start"`` on the centralised route with the ``mlp`` network,
            on a task with committed legs.
        rewards: reward weights; None: the scenario's (a task's objective, else
            :class:`RewardConfig`'s defaults).
        normalize: wrap the envs in ``VecNormalize`` (observations and rewards).
        net_arch: hidden layer sizes of the policy and value networks.
        n_steps: rollout length per slot (on-policy algorithms).
        batch_size: minibatch size (rows); None: PPO and MaskablePPO update in
            :data:`PPO_MINIBATCHES` minibatches of each rollout, behaviour cloning, DAgger
            and the off-policy algorithms in minibatches of :data:`DEFAULT_BATCH_SIZE`
            (:meth:`minibatch_size`). Runs before 2026-12-06 had 256 as the default.
        learning_rate: optimiser step size.
        gamma: discount factor per step.
        buffer_size: replay buffer capacity in transitions (off-policy algorithms).
        ent_coef: entropy bonus of the loss (PPO, A2C): keeps exploring.
        checkpoint_every: timesteps between checkpoints (the last one is always saved).
        eval_every: timesteps between evaluations on held-out scenarios (0: never).
        eval_episodes: episodes per evaluation.
        eval_seed: seed of the first held-out evaluation episode.
        eval_max_cycles: episode length limit of the evaluations (None: the scenario's).
        eval_sample_actions: the evaluations sample the policy's actions (seeded per
            episode) instead of taking the most likely one.
        eval_jobs: worker processes an evaluation's episodes are split over, kept for
            the run (1: in this process; None: :func:`eval_jobs`, one per usable core).
            The evaluations are the same for any value.
        progress_bar: show SB3's progress bar.
        torch_threads: torch's intra-op threads while training (1: the networks
            are tiny, more threads only contend with the envs for the cores); the
            on-policy algorithms' updates run on ``update_threads`` instead.
        update_threads: torch's intra-op threads during the gradient updates of PPO,
            MaskablePPO and A2C (:data:`ROLLOUT_UPDATES`), which run after each rollout
            while every env copy waits (None: one per usable core, :func:`update_threads`;
            the rollouts keep ``torch_threads``). Only the on-policy algorithms take it.
        network: ``"mlp"`` (SB3's MLP over the observation) or ``"team"`` (on the
            centralised route in switching mode: one encoder and one action head
            shared by every robot, with max and mean pooling over the team,
            :mod:`agents.team_network`); ``net_arch`` gives its hidden sizes.
        pretrain: a scripted teacher to clone before learning (:func:`check_teacher`: ``"greedy"``,
            ``"pipeline"`` (files of robots), ``"scripted"``, ``"rollout"``, or ``greedy@L`` /
            ``rollout@L``; :mod:`training.train.pretrain`; None: start from scratch).
            PPO-like algorithms in switching mode only.
        pretrain_rows: teacher demonstration rows to record (UGV slot steps on the
            shared route, env steps on the centralised one).
        pretrain_epochs: passes of behaviour cloning over them.
        dagger_rounds: DAgger rounds after that cloning: each records ``dagger_rows``
            rows of the states the cloned policy reaches, labelled with the teacher's
            actions, and clones all the rows so far for ``dagger_epochs`` passes.
        dagger_rows: rows per DAgger round.
        dagger_epochs: cloning passes per DAgger round.
        dagger_teacher: the teacher that labels the DAgger rounds' states (None: ``pretrain``),
            e.g. ``"rollout@1.5"`` after cloning ``"greedy@1.5"``: a teacher too slow to
            demonstrate ``pretrain_rows`` rows, which then corrects the clone where it acts.
            Its labels disagree with the first teacher's on the choices it is there to
            change, so each round then clones its rows alone (every round's so far).
            With ``init_from`` instead of ``pretrain``: DAgger from that run's policy,
            ``dagger_rounds`` rounds of its states labelled by this teacher, each fitting
            every round's rows so far (:func:`training.train.pretrain.dagger_model`).
        init_from: the folder of a finished run (``moma-env train --out``, or a published
            policy's) whose last checkpoint's networks and normalisation statistics this
            run starts from, instead of random weights or a teacher's clone
            (:mod:`training.train.init_from`; the two runs share its ``SHARED_FIELDS``).
            None: start from scratch or from ``pretrain``.
        kl_to_start: BETA of a penalty ``BETA * KL(policy || start policy)`` (nats, mean
            over each minibatch's observations) in PPO's loss, the start policy being the
            one this run starts from (``init_from``'s or ``pretrain``'s, frozen;
            :mod:`training.train.kl_to_start`); 0: no penalty.
        demonstrations: the folder of a run cloned from the same teacher whose kept
            demonstrations (:mod:`training.train.demonstrations`) the cloning fits
            instead of collecting them; they must be the rows this run would collect (same
            teacher, rows, seed, copies, route, task, env options and env version). None:
            collect them. With ``init_from`` and ``dagger_teacher`` instead of ``pretrain``:
            rows of ``dagger_teacher``'s (on the same route, task, env options and env
            version) that every DAgger round fits beside its own rows; None: the rounds'
            rows alone.
    """

    scenario: str
    algo: str = "ppo"
    steps: int = 100_000
    envs: int = 2
    subproc: bool = False
    workers: int | None = None
    seed: int = 0
    action_mode: str = "switching"
    route: str = "shared"
    max_cycles: int | None = None
    switch_horizon_s: float | None = None
    team_action: str = "per_agent"
    rewards: RewardConfig | None = None
    normalize: bool = True
    net_arch: tuple[int, ...] = (64, 64)
    n_steps: int = 256
    batch_size: int | None = None
    learning_rate: float = 3e-4
    gamma: float = 0.995
    buffer_size: int = 100_000
    ent_coef: float = 0.01
    checkpoint_every: int = 20_000
    eval_every: int = 0
    eval_episodes: int = 5
    eval_seed: int = 10_000
    eval_max_cycles: int | None = None
    eval_sample_actions: bool = False
    eval_jobs: int | None = None
    progress_bar: bool = False
    torch_threads: int = 1
    update_threads: int | None = None
    network: str = "mlp"
    pretrain: str | None = None
    pretrain_rows: int = 256_000
    pretrain_epochs: int = 30
    dagger_rounds: int = 3
    dagger_rows: int = 32_000
    dagger_epochs: int = 8
    dagger_teacher: str | None = None
    init_from: str | None = None
    kl_to_start: float = 0.0
    demonstrations: str | None = None

    def __post_init__(self) -> None:
        from moma_env.env.config import ACTION_MODES, TEAM_ACTIONS

        check_choice("scenario", self.scenario, sorted(CONFIGURATION_NAMES) + sorted(TASKS))
        check_choice("algo", self.algo, sorted(ALGORITHMS))
        # a cloned or DAgger-fitted policy may be trained no further
        check_count("steps", self.steps, 0 if self.pretrain is not None or self.dagger_teacher is not None else 1)
        check_count("envs", self.envs, 1)
        check_bool("subproc", self.subproc)
        check_count("seed", self.seed, 0)
        check_choice("action_mode", self.action_mode, ACTION_MODES)
        check_choice("route", self.route, ROUTES)
        check_workers(self.workers, self.envs)
        if self.workers is not None and self.subproc:
            raise ConfigError("workers", "subproc runs a process per copy; workers splits the batch over processes: give one")
        check_learning_fields(self)
        if self.switch_horizon_s is not None:
            check_positive("switch_horizon_s", self.switch_horizon_s)
            object.__setattr__(self, "switch_horizon_s", float(self.switch_horizon_s))
        check_choice("team_action", self.team_action, TEAM_ACTIONS)
        if self.team_action != "per_agent":
            committed = [name for name, task in sorted(TASKS.items()) if task.options.get("commit_legs")]
            if self.route != "centralised" or self.network != "mlp":
                raise ConfigError("team_action", f"{self.team_action!r} is the centralised team's action: use --route centralised with --network mlp")
            if self.scenario not in committed:
                raise ConfigError("team_action", f"{self.team_action!r} needs a task with committed legs, one of {committed}; got {self.scenario!r}")
        check_bool("normalize", self.normalize)
        if self.batch_size is not None:
            check_count("batch_size", self.batch_size, 1)
        check_count("buffer_size", self.buffer_size, 1)
        check_bool("progress_bar", self.progress_bar)
        if self.eval_jobs is not None:
            check_count("eval_jobs", self.eval_jobs, 1)
        check_count("torch_threads", self.torch_threads, 1)
        if self.update_threads is not None:
            check_count("update_threads", self.update_threads, 1)
            if self.algo not in ROLLOUT_UPDATES:
                raise ConfigError("update_threads", f"{self.algo} updates between env steps, on torch_threads; update_threads is for "
                                  f"the algorithms that update after each rollout: {', '.join(sorted(ROLLOUT_UPDATES))}")
        check_choice("network", self.network, NETWORKS)
        if self.network == "team" and (self.route != "centralised" or self.action_mode != "switching" or self.algo not in PRETRAINABLE):
            raise ConfigError("network", "the team network gives each robot of the centralised team its switching action: "
                              "use --route centralised --action-mode switching with --algo ppo or maskable_ppo")
        if self.pretrain is not None:
            check_teacher("pretrain", self.pretrain)
            if self.algo not in PRETRAINABLE:
                raise ConfigError("pretrain", f"behaviour cloning initialises PPO's actor and critic: use --algo {' or '.join(sorted(PRETRAINABLE))}")
            if self.action_mode != "switching":
                raise ConfigError("pretrain", f"the {self.pretrain} teacher acts in the switching action mode: use --action-mode switching")
        for name in ("pretrain_rows", "pretrain_epochs", "dagger_rows", "dagger_epochs"):
            check_count(name, getattr(self, name), 1)
        check_count("dagger_rounds", self.dagger_rounds, 0)
        if self.dagger_teacher is not None:
            check_teacher("dagger_teacher", self.dagger_teacher)
            if (self.pretrain is None and self.init_from is None) or self.dagger_rounds == 0:
                raise ConfigError(
                    "dagger_teacher", "labels the DAgger rounds after a cloning or from a run's weights: give --pretrain or "
                    "--init-from, and --dagger-rounds of 1 or more"
                )
            if self.pretrain is None:  # DAgger from init_from's policy: the checks of a cloning
                if self.algo not in PRETRAINABLE:
                    raise ConfigError("dagger_teacher", f"DAgger fits PPO's actor and critic: use --algo {' or '.join(sorted(PRETRAINABLE))}")
                if self.action_mode != "switching":
                    raise ConfigError("dagger_teacher", f"the {self.dagger_teacher} teacher acts in the switching action mode: use --action-mode switching")
        if self.demonstrations is not None:
            if not isinstance(self.demonstrations, str) or not self.demonstrations:
                raise ConfigError("demonstrations", f"must be the folder of a cloned training run, got {self.demonstrations!r}")
            if self.pretrain is None and (self.init_from is None or self.dagger_teacher is None):
                raise ConfigError(
                    "demonstrations", "are a teacher's rows for a cloning, or for DAgger from a run's weights: give --pretrain, "
                    "or --init-from with --dagger-teacher"
                )
        if self.init_from is not None:
            if not isinstance(self.init_from, str) or not self.init_from:
                raise ConfigError("init_from", f"must be the folder of a finished training run, got {self.init_from!r}")
            if self.pretrain is not None:
                raise ConfigError("init_from", "starts from a run's weights, pretrain from a teacher's clone: give one")
        check_non_negative("kl_to_start", self.kl_to_start)
        object.__setattr__(self, "kl_to_start", float(self.kl_to_start))
        if self.kl_to_start > 0:
            if self.algo not in PRETRAINABLE:
                raise ConfigError("kl_to_start", f"is a penalty in PPO's loss: use --algo {' or '.join(sorted(PRETRAINABLE))}")
            if self.init_from is None and self.pretrain is None:
                raise ConfigError("kl_to_start", "measures the divergence from the policy the run starts from: give --init-from or --pretrain")
        if self.algo in DISCRETE_ONLY and (self.action_mode != "switching" or self.route != "shared"):
            raise ConfigError(
                "algo", f"{self.algo} needs one discrete action per slot: use --action-mode switching --route shared"
            )
        if self.algo in MASKED and self.action_mode != "switching":
            raise ConfigError("algo", f"{self.algo} masks discrete actions: use --action-mode switching")
        if self.algo in BOX_ONLY and self.action_mode != "velocity":
            raise ConfigError("algo", f"{self.algo} needs continuous actions: use --action-mode velocity")

    @property
    def env_options(self) -> dict[str, Any]:
        """Keyword options of :func:`moma_env.env.factory.parallel_env` for this run (a
        task's own options apply beneath them)."""
        return run_env_options(self.action_mode, self.max_cycles, self.rewards, self.switch_horizon_s, self.team_action)

    def minibatch_size(self, rollout: int | None = None) -> int:
        """The rows of a gradient step: ``batch_size`` if given, else a :data:`PPO_MINIBATCHES`-th
        of ``rollout`` (PPO's rows per update: ``n_steps`` x the slots; at least 1) or, without
        one (behaviour cloning, DAgger, the off-policy algorithms), :data:`DEFAULT_BATCH_SIZE`."""
        if self.batch_size is None and rollout is not None:
            return max(1, rollout // PPO_MINIBATCHES)
        return backend_batch_size(self.batch_size)

    def to_dict(self) -> dict[str, Any]:
        """Plain data for the manifest (tuples as lists)."""
        return config_to_dict(self)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> "TrainConfig":
        """Inverse of :meth:`to_dict`; unknown keys raise ConfigError. A run recorded before
        ``update_threads`` existed updated on its ``torch_threads``, which it gets."""
        if data.get("algo", "ppo") in ROLLOUT_UPDATES:
            data = recorded_update_threads(data)
        return config_from_dict(cls, data)


def run_env_options(
    action_mode: str,
    max_cycles: int | None,
    rewards: RewardConfig | None,
    switch_horizon_s: float | None = None,
    team_action: str = "per_agent",
) -> dict[str, Any]:
    """Keyword options of ``parallel_env`` for a training run's envs: random layouts, the
    observer flown by its controller, ``rewards`` (None: the scenario's),
    ``switch_horizon_s`` (None: the env's default) and ``team_action`` (given only
    when it is not the default, ``"per_agent"``)."""
    options: dict[str, Any] = {"action_mode": action_mode, "observer_agent": False, "max_cycles": max_cycles, "random_scenarios": True}
    if rewards is not None:
        options["rewards"] = dataclasses.asdict(rewards)
    if switch_horizon_s is not None:
        options["switch_horizon_s"] = switch_horizon_s
    if team_action != "per_agent":
        options["team_action"] = team_action
    return options


@dataclass(frozen=True)
class BackendTrainConfig:
    """The fields every run of ``moma-env train --backend rllib | torchrl`` has
    (:class:`training.train.rllib_config.RllibTrainConfig`,
    :class:`training.train.torchrl_config.TorchRLTrainConfig` add their own), validated
    at construction (ConfigError names the first bad field).

    Attributes:
        scenario: configuration or task name.
        steps: total env steps to collect.
        envs: env copies (per env runner on RLlib).
        seed: the run's seed.
        max_cycles: training episode length in steps (None: the scenario's).
        rewards: reward weights (None: the scenario's).
        net_arch: hidden layer sizes of the policy and value networks.
        n_steps: env steps per copy collected between updates (RLlib: the rollout fragment).
        minibatch_size: minibatch size.
        num_epochs: passes over each batch.
        learning_rate, gamma, ent_coef: PPO's step size, discount, entropy bonus.
        checkpoint_every: env steps between checkpoints (the last is always saved).
        eval_every: env steps between held-out evaluations (0: never), also run at the end.
        eval_episodes: episodes per evaluation.
        eval_seed: seed of the first held-out episode.
        eval_max_cycles: episode length of the evaluations (None: the scenario's).
        eval_sample_actions: the evaluations sample actions instead of taking the mode.
    """

    scenario: str
    steps: int = 100_000
    envs: int = 2
    seed: int = 0
    max_cycles: int | None = None
    rewards: RewardConfig | None = None
    net_arch: tuple[int, ...] = (64, 64)
    n_steps: int = 256
    minibatch_size: int = 256
    num_epochs: int = 4
    learning_rate: float = 3e-4
    gamma: float = 0.995
    ent_coef: float = 0.01
    checkpoint_every: int = 20_000
    eval_every: int = 0
    eval_episodes: int = 5
    eval_seed: int = 10_000
    eval_max_cycles: int | None = None
    eval_sample_actions: bool = False

    def __post_init__(self) -> None:
        check_choice("scenario", self.scenario, sorted(CONFIGURATION_NAMES) + sorted(TASKS))
        check_count("steps", self.steps, 1)
        check_count("envs", self.envs, 1)
        check_count("seed", self.seed, 0)
        check_learning_fields(self)
        check_count("minibatch_size", self.minibatch_size, 1)
        check_count("num_epochs", self.num_epochs, 1)

    def to_dict(self) -> dict[str, Any]:
        """Plain data for the manifest (tuples as lists)."""
        return config_to_dict(self)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Any:
        """Inverse of :meth:`to_dict`; unknown keys raise ConfigError."""
        return config_from_dict(cls, data)


def config_to_dict(config: Any) -> dict[str, Any]:
    """A run configuration (a dataclass with ``net_arch``) as plain data for its manifest."""
    out = dataclasses.asdict(config)
    out["net_arch"] = list(config.net_arch)
    return out


def config_from_dict(cls: type, data: Mapping[str, Any]) -> Any:
    """Inverse of :func:`config_to_dict` for ``cls`` (``rewards`` from its weights by name);
    unknown keys raise ConfigError."""
    from moma_env.env.config import RewardConfig

    data = dict(data)
    if isinstance(data.get("net_arch"), list):
        data["net_arch"] = tuple(data["net_arch"])
    if isinstance(data.get("rewards"), Mapping):
        data["rewards"] = from_mapping(RewardConfig, data["rewards"], name="train.rewards")
    return from_mapping(cls, data, name="train")


def reward_overrides(pairs: list[str] | tuple[str, ...], base: Mapping[str, float] | None = None) -> RewardConfig:
    """``["progress=2", "time=-0.01"]`` -> a :class:`RewardConfig` with those weights
    changed from ``base`` (weights by name, e.g. a task's; None: the defaults).

    Raises:
        ConfigError: a pair without ``=``, a value that is not a number, or an
            unknown weight (named ``rewards.<name>``).
    """
    from moma_env.env.config import RewardConfig

    values: dict[str, float] = dict(base or {})
    for pair in pairs:
        name, sep, text = pair.partition("=")
        if not sep or not name:
            raise ConfigError("rewards", f"expected NAME=VALUE, got {pair!r}")
        try:
            values[name.strip()] = float(text)
        except ValueError:
            raise ConfigError(f"rewards.{name.strip()}", f"must be a number, got {text!r}") from None
    return from_mapping(RewardConfig, values, name="rewards")

"""Behaviour cloning from a scripted teacher before reinforcement learning.

A policy trained from scratch on the coordination tasks rarely sees a goal
reached in a million timesteps; the greedy parallel teacher
(:class:`agents.policies.GreedyParallelPolicy`) reaches every goal. So a run may
start from the teacher (``moma-env train --pretrain greedy``):

1. :func:`collect_demonstrations` drives the run's own batched env
   (:class:`moma_env.vector.MomaVectorEnv`, the copies the shared route trains
   on) with one teacher per copy for a number of UGV slot steps, and records
   every slot's observation, the teacher's action, the motion rules' action mask
   and the team's reward, copy by copy in the order the slots are laid out.
2. :func:`seed_normalisation` feeds those observations and the running
   discounted returns of those rewards to the run's ``VecNormalize``, exactly the
   statistics the wrapper would have gathered had it stepped through the same
   transitions.
3. :func:`behaviour_clone` fits the policy to the teacher's actions (the
   negative log-likelihood of the masked action distribution) and the value
   network to the normalised discounted return of the rest of each episode, so
   that the first PPO updates start from a critic that knows the teacher's
   returns rather than undo the cloned policy.

A run that starts from another run's weights (``--init-from``) may correct that policy
by DAgger alone (``--dagger-teacher``, :func:`dagger_model`): the rows of the states the
policy reaches, labelled by the teacher, and, given a cloned run's kept demonstrations of
that teacher (``--demonstrations``), those rows too.

Everything is seeded: the envs from the run's seed (copy ``k`` resets first with
``seed + k * N``, as :class:`~training.train.shared_vec_env.SharedPolicyVecEnv`
seeds it), the minibatch order from a generator of the run's seed, the network
from the model's own seeding; the same seed and thread count give the same weights.
With ``workers`` (the run's ``--workers``) the copies are driven by that many
processes side by side, each with its own teachers, and the rows joined in copy
order: the rows, and so the weights, of one process, in less wall time when the
teacher is slow (the lookahead teachers spend seconds of one core per episode).
"""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch
from gymnasium import spaces
from sb3_contrib.common.maskable.policies import MaskableActorCriticPolicy
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.vec_env import VecEnv, VecNormalize

from agents.learned import ObservationScaling
from agents.policy_mode import discrete_actions, knows
from moma_env.vector import MomaVectorEnv
from moma_env.vector.parent_watch import worker_pool
from moma_env.vector.sharded import shard_sizes
from training.evaluation.policies import load_policy
from training.train.config import TrainConfig, check_teacher
from training.train.demonstrations import Demonstrations, save_demonstrations
from training.train.envs import env_spec
from training.train.team_slots import SLOT_LAYOUTS, EnvSpec

__all__ = ["ModelRowPolicy", "choice_agents", "choice_agreement", "choice_rows", "collect_demonstrations", "seed_normalisation", "behaviour_clone", "discounted_returns", "dagger_model", "pretrain_model"]



#: A policy acting on demonstration rows: ``(observations (R, D), masks (R, M)) -> actions`` of the rows' shape.
RowPolicy = Callable[[np.ndarray, np.ndarray], np.ndarray]


def collect_demonstrations(
    spec: EnvSpec,
    teacher: str,
    n_copies: int,
    rows: int,
    seed: int,
    route: str = "shared",
    learner: RowPolicy | None = None,
    workers: int = 1,
    report: Callable[[str], None] | None = None,
) -> Demonstrations:
    """Drive ``n_copies`` copies of ``spec`` with ``teacher`` until at least ``rows`` rows are recorded.

    Args:
        spec: the run's env (its options are the training env's; the teacher's own
            env options, e.g. ``action_masks=True``, are added, which change no
            observation, action or reward).
        teacher: one of :data:`TEACHERS`, or ``greedy@L`` (:func:`~training.train.config.check_teacher`).
        n_copies: copies stepped together.
        rows: rows to record at least (whole env steps of every copy).
        seed: copy ``k`` resets first with ``seed + k * N`` (``shared``, ``N`` UGVs) or
            ``seed + k`` (``centralised``), the seeds the run's own envs start from.
        route: ``"shared"``: a row per UGV slot (its own observation and action);
            ``"centralised"``: a row per copy (the team's concatenated observation,
            the agents' actions side by side, their masks concatenated).
        learner: None: the teacher acts. Else the learner acts and the teacher only
            labels every row with what it would have done (DAgger: the states are
            the learner's, the actions the teacher's).
        workers: processes driving the copies, this one included: the copies are
            split into ``workers`` contiguous groups (:func:`~moma_env.vector.sharded.shard_sizes`)
            driven side by side, each with its own teachers, and their rows are joined
            in copy order. Every copy's episodes are its own, so the rows are those of
            one process bit for bit, as long as ``learner`` acts on a row whatever rows
            come with it (:class:`ModelRowPolicy` does); with ``workers > 1`` the learner
            must pickle and runs with this process's torch threads.
        report: called with a line of progress after each tenth of the env steps of the
            copies driven in this process (the other groups step as many times, each
            at its own pace), or None (silent).

    Raises:
        ValueError: an unknown teacher or route, a teacher for another action mode,
            an env whose UGVs cannot share one policy, or ``workers`` outside ``[1, n_copies]``.
    """
    check_teacher("teacher", teacher)
    if route not in ("shared", "centralised"):
        raise ValueError(f"route must be 'shared' or 'centralised', got {route!r}")
    if spec.options.get("action_mode", "switching") != "switching":
        raise ValueError(f"the {teacher} teacher acts in the switching action mode, the run trains in {spec.options['action_mode']!r}")
    if isinstance(workers, bool) or not isinstance(workers, int) or not 1 <= workers <= n_copies:
        raise ValueError(f"workers must be an integer in [1, n_copies={n_copies}], got {workers!r}")
    groups: list[tuple[int, int]] = []
    first = 0
    for size in shard_sizes(n_copies, workers):
        groups.append((first, size))
        first += size
    drive = functools.partial(_drive_copies, spec, teacher, n_copies, rows, seed, route, learner, torch.get_num_threads())
    if workers == 1:
        return drive(*groups[0], report)
    with worker_pool(workers - 1) as pool:
        others = [pool.submit(drive, *group, None) for group in groups[1:]]  # the first group is driven here meanwhile
        parts = [drive(*groups[0], report)] + [future.result() for future in others]
    return _interleave(parts)


def _drive_copies(
    spec: EnvSpec, teacher: str, n_copies: int, rows: int, seed: int, route: str, learner: RowPolicy | None,
    torch_threads: int, first: int, size: int, report: Callable[[str], None] | None,
) -> Demonstrations:
    """Copies ``first .. first + size - 1`` of :func:`collect_demonstrations`' ``n_copies``,
    for as many env steps as all of them need for ``rows`` rows: their rows, in copy order
    (``report``: see :func:`collect_demonstrations`)."""
    torch.set_num_threads(torch_threads)  # a worker process starts with torch's default
    policies = [load_policy(teacher, spec.configuration) for _ in range(size)]
    options = dict(spec.options) | dict(getattr(policies[0], "env_options", {}))
    vector = MomaVectorEnv(spec.configuration, size, **options)
    try:
        shared = route == "shared"
        layout = SLOT_LAYOUTS["ugv" if shared else "team"](vector.envs[0])  # a row per slot of the run's VecEnv
        agents = layout.agents
        seeds = [seed + k * layout.per_copy for k in range(first, first + size)]
        observations, infos = vector.reset(seed=seeds)
        for k, policy in enumerate(policies):
            policy.reset(vector.envs[k], seed=seeds[k])
        stride = size * layout.per_copy  # rows per env step of these copies
        steps = math.ceil(rows / (n_copies * layout.per_copy))  # env steps of every copy
        total = steps * stride
        obs_out = np.empty((total, *layout.observation_space.shape), dtype=np.float32)
        act_out = np.empty((total, *layout.action_space.shape), dtype=np.int64)  # (T,) a robot's or a one-start team's, (T, N) the team's
        mask_out = np.empty((total, layout.mask_rows(vector.action_masks(), infos).shape[1]), dtype=bool)
        reward_out = np.empty(total, dtype=np.float64)
        end_out = np.zeros(total, dtype=bool)
        episodes = successes = 0
        started = time.perf_counter()
        tenths = {math.ceil(steps * k / 10): k for k in range(1, 10)}  # step count -> tenth
        for t in range(steps):
            if report is not None and t in tenths:
                report(
                    f"{tenths[t] * 10} % of {steps} env steps, copies {first}..{first + size - 1}: "
                    f"{episodes} episodes ended, {time.perf_counter() - started:.0f} s"
                )
            masks = vector.action_masks()
            actions = {a: np.empty(size, dtype=np.int64) for a in agents}
            for k, policy in enumerate(policies):
                chosen = policy.act({a: observations[a][k] for a in agents}, infos[k])
                for a in agents:
                    actions[a][k] = int(chosen[a])
            block = slice(t * stride, (t + 1) * stride)
            obs_out[block] = layout.rows(observations)
            act_out[block] = layout.slot_actions(actions, infos)
            mask_out[block] = layout.mask_rows(masks, infos)
            if learner is not None:
                acted = np.asarray(learner(obs_out[block], mask_out[block]), dtype=np.int64)
                actions = {a: np.array(column, dtype=np.int64) for a, column in layout.agent_actions(acted, infos).items()}
            observations, rewards, terminations, truncations, infos = vector.step(actions)
            ended = np.zeros(size, dtype=bool)
            for a in agents:
                ended |= np.asarray(terminations[a], dtype=bool) | np.asarray(truncations[a], dtype=bool)
            reward_out[block] = np.repeat(np.asarray(rewards[agents[0]], dtype=np.float32), layout.per_copy)  # SB3's reward precision
            end_out[block] = np.repeat(ended, layout.per_copy)
            for k in np.flatnonzero(ended):
                episodes += 1
                final = infos[k]["final_info"]
                successes += int(all(bool(final[a].get("reached_goal", False)) for a in agents))
                policies[k].reset(vector.envs[k], seed=None)
        return Demonstrations(obs_out, act_out, mask_out, reward_out, end_out, _ended_later(end_out, stride), stride, episodes, successes)
    finally:
        vector.close()


def _interleave(parts: Sequence[Demonstrations]) -> Demonstrations:
    """The rows of groups of copies driven apart for the same env steps, joined step by
    step in copy order (each step's block: the first group's rows, then the next's)."""
    steps = len(parts[0]) // parts[0].stride

    def join(field: str) -> np.ndarray:
        blocks = [getattr(p, field).reshape(steps, p.stride, *getattr(p, field).shape[1:]) for p in parts]
        joined = np.concatenate(blocks, axis=1)
        return joined.reshape(steps * joined.shape[1], *joined.shape[2:])

    ends = join("episode_ends")
    stride = sum(p.stride for p in parts)
    return Demonstrations(
        join("observations"), join("actions"), join("masks"), join("rewards"), ends, _ended_later(ends, stride), stride,
        sum(p.episodes for p in parts), sum(p.successes for p in parts),
    )


def seed_normalisation(venv: VecNormalize, demonstrations: Demonstrations) -> None:
    """Give ``venv`` the statistics it would have gathered stepping through the
    demonstrations' transitions: the observations, block by block in their float32
    as the wrapper sees them, and each row's running discounted return
    (``returns = returns * gamma + reward``, restarted at an episode's end)."""
    n = demonstrations.stride
    returns = np.zeros(n)
    for t in range(len(demonstrations) // n):
        block = slice(t * n, (t + 1) * n)
        if venv.norm_obs:
            venv.obs_rms.update(demonstrations.observations[block])
        if venv.norm_reward:
            returns = returns * venv.gamma + demonstrations.rewards[block]
            venv.ret_rms.update(returns)
            returns[demonstrations.episode_ends[block]] = 0.0


def discounted_returns(rewards: np.ndarray, episode_ends: np.ndarray, n_slots: int, gamma: float) -> np.ndarray:
    """Each row's discounted return of the rest of its episode (zero past an episode's end;
    an episode still running when the collection stopped is cut there)."""
    out = np.empty_like(rewards, dtype=np.float64)
    running = np.zeros(n_slots)
    for t in range(len(rewards) // n_slots - 1, -1, -1):
        block = slice(t * n_slots, (t + 1) * n_slots)
        running = rewards[block] + gamma * running * ~episode_ends[block]
        out[block] = running
    return out


def behaviour_clone(
    model: BaseAlgorithm,
    demonstrations: Demonstrations,
    normalise_obs: Callable[[np.ndarray], np.ndarray] | None,
    normalise_reward: Callable[[np.ndarray], np.ndarray] | None,
    epochs: int,
    batch_size: int,
    seed: int,
) -> list[dict[str, float]]:
    """Fit ``model``'s policy to the teacher's actions and its value network to the returns.

    Args:
        model: a PPO-like model (``PPO`` or sb3-contrib's ``MaskablePPO``; the masks are
            given to a model that takes them).
        demonstrations: what the teacher did.
        normalise_obs / normalise_reward: the run's ``VecNormalize`` transforms (None: identity).
        epochs: passes over the demonstrations.
        batch_size: rows per gradient step.
        seed: seed of the minibatch order.

    Returns:
        one record per epoch: mean ``policy_loss`` (negative log-likelihood of the
        teacher's action), ``value_loss`` (mean squared error, normalised returns)
        ``accuracy`` (share of rows whose most likely action is the teacher's) and
        ``choice_accuracy`` (the same over the rows where the masks left a choice;
        elsewhere the action is forced and the policy cannot err).
    """
    observations = demonstrations.observations
    if normalise_obs is not None:
        observations = normalise_obs(observations)
    rewards = demonstrations.rewards if normalise_reward is None else normalise_reward(demonstrations.rewards).astype(np.float64)
    returns = discounted_returns(rewards, demonstrations.episode_ends, demonstrations.stride, float(model.gamma))
    policy = model.policy
    masked = isinstance(policy, MaskableActorCriticPolicy)
    obs_t = torch.as_tensor(np.asarray(observations, dtype=np.float32))
    act_t = torch.as_tensor(demonstrations.actions)
    mask_t = torch.as_tensor(demonstrations.masks)
    ret_t = torch.as_tensor(returns, dtype=torch.float32)
    choice_t = torch.as_tensor(choice_rows(demonstrations))
    value_rows = torch.as_tensor(demonstrations.complete, dtype=torch.float32)
    rng = np.random.default_rng(seed)
    records: list[dict[str, float]] = []
    policy.set_training_mode(True)
    for _ in range(epochs):
        order = torch.as_tensor(rng.permutation(len(demonstrations)))
        sums = {"policy_loss": 0.0, "value_loss": 0.0, "accuracy": 0.0, "choice_accuracy": 0.0}
        n_choice = 0
        for start in range(0, len(order), batch_size):
            rows = order[start:start + batch_size]
            if masked:
                values, log_prob, _ = policy.evaluate_actions(obs_t[rows], act_t[rows], action_masks=mask_t[rows])
            else:
                values, log_prob, _ = policy.evaluate_actions(obs_t[rows], act_t[rows])
            keep = value_rows[rows]
            value_loss = ((values.flatten() - ret_t[rows]) ** 2 * keep).sum() / keep.sum().clamp(min=1)
            policy_loss = -log_prob.mean()
            loss = policy_loss + model.vf_coef * value_loss
            policy.optimizer.zero_grad()
            loss.backward()
            torch.nn.utils.clip_grad_norm_(policy.parameters(), model.max_grad_norm)
            policy.optimizer.step()
            with torch.no_grad():
                distribution = policy.get_distribution(obs_t[rows], action_masks=mask_t[rows]) if masked else policy.get_distribution(obs_t[rows])
                agree = (distribution.mode().reshape(act_t[rows].shape) == act_t[rows]).reshape(len(rows), -1).all(dim=1)
                choice = choice_t[rows]
            sums["policy_loss"] += float(policy_loss.detach()) * len(rows)
            sums["value_loss"] += float(value_loss.detach()) * len(rows)
            sums["accuracy"] += float(agree.float().sum())
            sums["choice_accuracy"] += float(agree[choice].float().sum())
            n_choice += int(choice.sum())
        record = {k: sums[k] / len(order) for k in ("policy_loss", "value_loss", "accuracy")}
        record["choice_accuracy"] = sums["choice_accuracy"] / n_choice if n_choice else math.nan
        records.append(record)
    policy.set_training_mode(False)
    return records


def _ended_later(episode_ends: np.ndarray, n_slots: int) -> np.ndarray:
    """``(T,)`` bool: the row's slot ends an episode at this row or a later one."""
    out = np.empty_like(episode_ends)
    seen = np.zeros(n_slots, dtype=bool)
    for t in range(len(episode_ends) // n_slots - 1, -1, -1):
        block = slice(t * n_slots, (t + 1) * n_slots)
        seen |= episode_ends[block]
        out[block] = seen
    return out


def choice_agents(demonstrations: Demonstrations) -> np.ndarray:
    """``(T, N)`` bool: agent ``n`` of the row had more than one action allowed (``N`` is 1
    on the shared route, the team's agents on the centralised one)."""
    n_agents = 1 if demonstrations.actions.ndim == 1 else demonstrations.actions.shape[1]
    return demonstrations.masks.reshape(len(demonstrations), n_agents, -1).sum(axis=2) > 1


def choice_rows(demonstrations: Demonstrations) -> np.ndarray:
    """``(T,)`` bool: some agent of the row had more than one action allowed."""
    return choice_agents(demonstrations).any(axis=1)


def choice_agreement(demonstrations: Demonstrations, actions: np.ndarray, rows: np.ndarray | None = None) -> float:
    """The share of the rows where the masks left a choice on which ``actions`` (a
    policy's, one per row as ``demonstrations.actions`` holds them) are the rows' own
    (every agent's, on the centralised route), of those rows only where ``rows`` (``(T,)``
    bool) is true if given; NaN without such rows."""
    choice = choice_rows(demonstrations)
    if rows is not None:
        choice = choice & np.asarray(rows, dtype=bool)
    if not choice.any():
        return math.nan
    same = (np.asarray(actions).reshape(demonstrations.actions.shape) == demonstrations.actions).reshape(len(demonstrations), -1).all(axis=1)
    return float(same[choice].mean())


def _silent(line: str) -> None:
    """A progress report that reports nothing."""


def _collected(demonstrations: Demonstrations, start: float) -> str:
    """A progress line: what a collection gathered, at the pretraining's wall time since ``start``."""
    return (
        f"{len(demonstrations)} rows, {demonstrations.episodes} episodes ended, {demonstrations.successes} reaching every goal; "
        f"{time.perf_counter() - start:.0f} s"
    )


def _cloned(epochs: Sequence[Mapping[str, float]], start: float) -> str:
    """A progress line: the last epoch of a fit, at the pretraining's wall time since ``start``."""
    last = epochs[-1]
    return (
        f"cloned in {len(epochs)} epochs: accuracy {last['accuracy']:.1%}, on the rows with a choice "
        f"{last['choice_accuracy']:.1%}; {time.perf_counter() - start:.0f} s"
    )


def pretrain_model(
    model: BaseAlgorithm,
    venv: VecEnv,
    config: TrainConfig,
    report: Callable[[str], None] | None = None,
    demonstrations: Demonstrations | None = None,
    keep: Path | None = None,
) -> dict[str, Any]:
    """Clone ``config.pretrain`` into a new run's ``model`` (and its ``venv``'s normalisation).

    The teacher's demonstrations come from ``config.envs`` copies of the run's env
    seeded as the run's own envs are (``config.seed``), ``config.pretrain_rows`` rows
    of them, on the run's route, cloned for ``config.pretrain_epochs`` passes of
    minibatches of ``config.minibatch_size()``. Then each of ``config.dagger_rounds`` DAgger
    rounds adds ``config.dagger_rows`` rows of the states the cloned policy reaches
    (from seeds after the teacher's), labelled with the teacher's actions, and clones
    every row so far for ``config.dagger_epochs`` passes. With ``config.dagger_teacher``
    another teacher labels those states, and the rounds clone its rows alone. The
    copies are driven by ``config.workers`` processes (:func:`collect_demonstrations`).
    ``demonstrations``, when given, are the teacher's rows already collected for this run
    (``config.demonstrations``'s, :func:`~training.train.demonstrations.read_demonstrations`)
    and are fitted instead; rows it collects are written to the run folder ``keep`` (None:
    not kept) for another run to reuse. ``report`` (None: silent) is called with a line of
    progress at each stage and each tenth of a collection.

    Returns:
        the record of ``pretrain.json``: the teacher, where its rows came from
        (``demonstrations``: None, collected, or the run folder they were kept in), its episodes and successes,
        wall time (s), and per round the rows, the per-epoch losses and accuracies
        and, for the states of the next DAgger round, the cloned policy's episodes and
        successes and ``learner_choice_agreement``: the share of the rows where the masks
        left a choice on which the policy's most likely action was the labeller's (before
        the round's fit).
    """
    say = report if report is not None else _silent
    start = time.perf_counter()
    spec = env_spec(config)
    workers = 1 if config.workers is None else config.workers  # the processes that step the run's copies drive the teachers'
    if demonstrations is None:
        say(f"pretraining: {config.pretrain_rows} rows of {config.pretrain} on {config.envs} copies in {workers} process(es)")
        demonstrations = collect_demonstrations(
            spec, config.pretrain, config.envs, config.pretrain_rows, config.seed, config.route, workers=workers, report=report
        )
        say(_collected(demonstrations, start))
        if keep is not None:
            save_demonstrations(keep, demonstrations, config)
    else:
        say(f"pretraining: the {len(demonstrations)} rows of {config.pretrain} kept in {config.demonstrations}")
    if isinstance(venv, VecNormalize):
        seed_normalisation(venv, demonstrations)
    normalise_obs, normalise_reward = _normalisers(venv)
    teacher = {"episodes": demonstrations.episodes, "successes": demonstrations.successes}
    epochs = behaviour_clone(model, demonstrations, normalise_obs, normalise_reward, config.pretrain_epochs, config.minibatch_size(), config.seed)
    say(_cloned(epochs, start))
    rounds: list[dict[str, Any]] = [{"rows": len(demonstrations), "epochs": epochs}]
    labeller = config.pretrain if config.dagger_teacher is None else config.dagger_teacher
    # Another teacher's labels are cloned alone: the first's disagree where it corrects them.
    _dagger_rounds(model, venv, config, labeller, demonstrations if labeller == config.pretrain else None, rounds, start, say, report)
    return {
        "teacher": config.pretrain,
        "demonstrations": config.demonstrations,
        "dagger_teacher": labeller,
        "teacher_episodes": teacher["episodes"],
        "teacher_successes": teacher["successes"],
        "wall_time_s": time.perf_counter() - start,
        "rounds": rounds,
    }


def dagger_model(
    model: BaseAlgorithm,
    venv: VecEnv,
    config: TrainConfig,
    report: Callable[[str], None] | None = None,
    demonstrations: Demonstrations | None = None,
) -> dict[str, Any]:
    """DAgger from the policy a run starts with (``config.init_from``'s weights and
    statistics, already in ``model`` and ``venv``): ``config.dagger_rounds`` rounds in which
    the policy acts (its most likely action) for ``config.dagger_rows`` rows,
    ``config.dagger_teacher`` labels every state it reaches, and the policy is fitted to
    ``demonstrations`` (the teacher's own rows, ``config.demonstrations``'s; None: none)
    and every round's rows so far for ``config.dagger_epochs`` passes. The rows are
    normalised with the run's statistics, left as they are.

    Returns:
        the record of ``pretrain.json``: ``teacher`` None, ``dagger_teacher``, the folder of
        the ``demonstrations`` (None without them), wall time (s) and the rounds as
        :func:`pretrain_model` records them, the first standing for the starting policy
        (the demonstrations' rows, not fitted before the first round).
    """
    say = report if report is not None else _silent
    start = time.perf_counter()
    rounds: list[dict[str, Any]] = [{"rows": 0 if demonstrations is None else len(demonstrations), "epochs": []}]
    if demonstrations is not None:
        say(f"DAgger: the {len(demonstrations)} rows of {config.dagger_teacher} kept in {config.demonstrations} fitted in every round")
    _dagger_rounds(model, venv, config, config.dagger_teacher, demonstrations, rounds, start, say, report)
    return {
        "teacher": None,
        "demonstrations": config.demonstrations,
        "dagger_teacher": config.dagger_teacher,
        "wall_time_s": time.perf_counter() - start,
        "rounds": rounds,
    }


def _normalisers(venv: VecEnv) -> tuple[Callable[[np.ndarray], np.ndarray] | None, Callable[[np.ndarray], np.ndarray] | None]:
    """The run's observation and reward normalisation (``VecNormalize``'s, None where it has none)."""
    if not isinstance(venv, VecNormalize):
        return None, None
    return (venv.normalize_obs if venv.norm_obs else None), (venv.normalize_reward if venv.norm_reward else None)


def _dagger_rounds(
    model: BaseAlgorithm,
    venv: VecEnv,
    config: TrainConfig,
    labeller: str,
    cloned: Demonstrations | None,
    rounds: list[dict[str, Any]],
    start: float,
    say: Callable[[str], None],
    report: Callable[[str], None] | None,
) -> None:
    """``config.dagger_rounds`` DAgger rounds on ``model``, labelled by ``labeller``, each fitting
    ``cloned`` (the rows fitted so far; None: none) and every round's rows so far; each round
    adds its learner's record to ``rounds[-1]`` and appends the record of its fit."""
    normalise_obs, normalise_reward = _normalisers(venv)
    spec = env_spec(config)
    workers = 1 if config.workers is None else config.workers
    for k in range(1, config.dagger_rounds + 1):
        # DAgger: the states the cloned policy reaches (other layouts than the teacher's), labelled by the teacher
        seed = config.seed + config.pretrain_rows + (k - 1) * config.dagger_rows
        learner = ModelRowPolicy(model.policy, None if normalise_obs is None else ObservationScaling.from_vec_normalize(venv))
        say(f"DAgger round {k} of {config.dagger_rounds}: {config.dagger_rows} rows of the cloned policy's states, labelled by {labeller}")
        visited = collect_demonstrations(spec, labeller, config.envs, config.dagger_rows, seed, config.route, learner, workers, report=report)
        say(_collected(visited, start))
        agreement = choice_agreement(visited, learner(visited.observations, visited.masks))
        rounds[-1]["learner_episodes"], rounds[-1]["learner_successes"] = visited.episodes, visited.successes
        rounds[-1]["learner_choice_agreement"] = agreement
        say(f"the cloned policy chose as {labeller} on {agreement:.1%} of the rows with a choice")
        cloned = visited if cloned is None else cloned + visited
        epochs = behaviour_clone(model, cloned, normalise_obs, normalise_reward, config.dagger_epochs, config.minibatch_size(), config.seed + k)
        say(_cloned(epochs, start))
        rounds.append({"rows": len(cloned), "epochs": epochs})


class ModelRowPolicy:
    """A PPO-like policy's most likely actions on demonstration rows (among the allowed
    ones, for a masked policy), row by row: a :data:`RowPolicy` that pickles, to act in a
    worker process.

    Args:
        policy: the model's ``policy`` (SB3 ``ActorCriticPolicy`` or sb3-contrib's maskable one).
        normalise: maps the rows to the policy's inputs, or None (the rows as they are);
            with workers it must pickle (:class:`~agents.learned.ObservationScaling` does).
    """

    def __init__(self, policy: torch.nn.Module, normalise: Callable[[np.ndarray], np.ndarray] | None):
        if not isinstance(getattr(policy, "action_space", None), (spaces.Discrete, spaces.MultiDiscrete)):
            raise TypeError(f"ModelRowPolicy acts in the switching mode's discrete actions, got a policy of {getattr(policy, 'action_space', None)!r}")
        self.policy = policy
        self.normalise = normalise

    def __call__(self, observations: np.ndarray, masks: np.ndarray) -> np.ndarray:
        """The most likely allowed action of every row, each row's computed alone: torch's
        matrix products may give a row other last bits in a batch of another size, and so,
        near a tie, another action; row by row, a row's action is its own whichever rows
        come with it (a group of copies of any size, a round's rows all at once)."""
        obs = observations if self.normalise is None else self.normalise(observations)
        policy = self.policy
        masked = isinstance(policy, MaskableActorCriticPolicy)
        policy.set_training_mode(False)
        actions = np.empty((len(obs), *policy.action_space.shape), dtype=np.int64)
        if knows(policy):  # what policy.predict(row, deterministic=True[, action_masks=mask]) gives, without its checks
            for i in range(len(obs)):
                actions[i] = discrete_actions(policy, obs[i : i + 1], masks[i : i + 1] if masked else None)[0]
            return actions
        rows, _ = policy.obs_to_tensor(obs)  # another policy class (the team network): its own distribution per row
        with torch.no_grad():
            for i in range(len(obs)):
                if masked:
                    distribution = policy.get_distribution(rows[i : i + 1], masks[i : i + 1])
                else:
                    distribution = policy.get_distribution(rows[i : i + 1])
                actions[i] = distribution.get_actions(deterministic=True).cpu().numpy().reshape(policy.action_space.shape)
        return actions

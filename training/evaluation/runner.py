"""The episodes of one evaluation, in this process or split over worker processes.

:func:`run_episodes` runs a contiguous range of an evaluation's episodes in one env
(episode ``k`` reset with ``seed + k``); :func:`run_episodes_split` cuts the
evaluation into such ranges and runs them in a process pool, each range in a worker of
its own env and its own copy of the policy, and returns the episodes in order. An
episode depends only on its seed and the policy (every policy is reseeded at each
episode's ``reset``), so both give the same episodes, bit for bit
(``tests/test_evaluation_jobs.py``).

What goes to a worker: the env's options, the policy object, pickled once for every
range (every built-in policy pickles; a :class:`agents.learned.LearnedPolicy` pickles
its model as Stable-Baselines3's saved zip), and a range; what comes back: the episodes
and, when asked, their detection logs.
"""

from __future__ import annotations

import pickle
from collections.abc import Callable, Mapping
from concurrent.futures import FIRST_COMPLETED, Executor, wait
from dataclasses import dataclass
from typing import Any

from moma_env.env.factory import parallel_env
from moma_env.estimator import RecordingFactory
from moma_env.estimator.registry import resolve_localiser
from training.evaluation.episode import EpisodeResult, FrameSink, robot_agents, run_episode
from training.evaluation.policies import Policy

__all__ = ["EpisodeRange", "RangeResult", "PolicyNotPortableError", "run_episodes", "run_episodes_split", "episode_ranges", "RANGES_PER_JOB"]

#: Called after every episode (progress bars).
ProgressCallback = Callable[[EpisodeResult], None]

#: Ranges an evaluation is cut into per worker process: episodes differ in length (a
#: success ends early, a failure runs to the limit), so several ranges a worker keep
#: the workers busy to the end; each range costs a worker an env and a policy copy.
RANGES_PER_JOB = 4


class PolicyNotPortableError(ValueError):
    """A policy object that cannot be sent to a worker process (it does not pickle)."""


@dataclass(frozen=True)
class EpisodeRange:
    """Episodes ``first .. first + count - 1`` of an evaluation whose episode 0 is seeded ``seed``."""

    first: int
    count: int


@dataclass(frozen=True)
class RangeResult:
    """Episodes in order, the scored robots (env order) and the episodes' detection logs
    (texts, :mod:`moma_env.estimator.log`) when recorded."""

    robots: tuple[str, ...]
    episodes: tuple[EpisodeResult, ...]
    detection_logs: tuple[str, ...] | None


def episode_ranges(episodes: int, jobs: int) -> list[EpisodeRange]:
    """``episodes`` cut into contiguous ranges, :data:`RANGES_PER_JOB` per job at most,
    of sizes differing by one at most, in order."""
    count = max(1, min(episodes, RANGES_PER_JOB * jobs))
    size, extra = divmod(episodes, count)
    ranges, first = [], 0
    for k in range(count):
        n = size + (1 if k < extra else 0)
        ranges.append(EpisodeRange(first, n))
        first += n
    return ranges


def run_episodes(
    configuration: str,
    policy: Policy,
    episodes: EpisodeRange,
    seed: int,
    env_options: Mapping[str, Any],
    *,
    frame_sink: FrameSink | None = None,
    progress: ProgressCallback | None = None,
    detection_logs: bool = False,
) -> RangeResult:
    """Run the range ``episodes`` of ``policy`` in one env made with ``env_options``.

    Args:
        configuration: the configuration's or task's name.
        policy: the policy (reset at every episode with its seed).
        episodes: which episodes; episode ``k`` resets with ``seed + k``.
        seed: the seed of the evaluation's episode 0.
        env_options: everything :func:`moma_env.env.factory.parallel_env` takes but the
            configuration and the render mode.
        frame_sink: receives the rendered frames of the range's first episode.
        progress: called with every finished episode.
        detection_logs: keep each episode's detection log (:mod:`moma_env.estimator.log`).
    """
    recording = None
    options = dict(env_options)
    if detection_logs:
        recording = RecordingFactory(resolve_localiser(options.get("localiser")))
        options["localiser"] = recording
    env = parallel_env(configuration, render_mode="rgb_array" if frame_sink is not None else None, **options)
    results: list[EpisodeResult] = []
    logs: list[str] = []
    try:
        robots = tuple(robot_agents(env))
        for k in range(episodes.first, episodes.first + episodes.count):
            ep = run_episode(env, policy, k, seed + k, frame_sink if k == episodes.first else None)
            results.append(ep)
            if recording is not None:
                logs.append(recording.made[-1].text())
                recording.made.clear()  # one episode's log in memory at a time
            if progress is not None:
                progress(ep)
    finally:
        env.close()
    return RangeResult(robots, tuple(results), tuple(logs) if detection_logs else None)


def _run_range_in_worker(
    configuration: str, policy: bytes, episodes: EpisodeRange, seed: int, env_options: Mapping[str, Any], detection_logs: bool
) -> RangeResult:
    """A worker's task: the policy unpickled, then :func:`run_episodes`."""
    return run_episodes(configuration, pickle.loads(policy), episodes, seed, env_options, detection_logs=detection_logs)


def _portable(policy: Policy) -> bytes:
    """The policy as a worker receives it, pickled.

    Raises:
        PolicyNotPortableError: the policy does not pickle.
    """
    try:
        return pickle.dumps(policy, protocol=pickle.HIGHEST_PROTOCOL)
    except Exception as err:  # pickling fails with TypeError, AttributeError, PicklingError, ...
        raise PolicyNotPortableError(f"{type(policy).__name__} cannot be sent to worker processes (it does not pickle: {err}); "
                         f"evaluate with jobs=1") from None


def run_episodes_split(
    executor: Executor,
    jobs: int,
    configuration: str,
    policy: Policy,
    episodes: int,
    seed: int,
    env_options: Mapping[str, Any],
    *,
    progress: ProgressCallback | None = None,
    detection_logs: bool = False,
) -> RangeResult:
    """Episodes ``0 .. episodes - 1`` of ``policy``, cut by :func:`episode_ranges` for
    ``jobs`` workers and run in ``executor``; the same result as :func:`run_episodes`
    over the whole evaluation.

    Args:
        executor: a process pool (:func:`moma_env.vector.parent_watch.worker_pool`).
        jobs: its worker count (how finely to cut the evaluation).
        configuration, seed, env_options: see :func:`run_episodes`.
        policy: a policy that pickles.
        episodes: how many (>= 1).
        progress: called in this process with every episode of a range as the range finishes.
        detection_logs: keep each episode's detection log.

    Raises:
        PolicyNotPortableError: the policy does not pickle.
    """
    payload = _portable(policy)
    ranges = episode_ranges(episodes, jobs)
    pending = {
        executor.submit(_run_range_in_worker, configuration, payload, r, seed, dict(env_options), detection_logs): k
        for k, r in enumerate(ranges)
    }
    finished: list[RangeResult | None] = [None] * len(ranges)
    while pending:
        done, _ = wait(pending, return_when=FIRST_COMPLETED)
        for future in done:
            k = pending.pop(future)
            finished[k] = future.result()
            if progress is not None:
                for ep in finished[k].episodes:
                    progress(ep)
    logs = tuple(log for part in finished for log in part.detection_logs) if detection_logs else None
    return RangeResult(finished[0].robots, tuple(ep for part in finished for ep in part.episodes), logs)


"""The evaluation core: run N episodes of one policy and aggregate them.

``evaluate("top_observer", "scripted", episodes=10, seed=0)`` builds the env
(``moma_env.env.factory.parallel_env``), resets episode k with ``seed + k`` (a
new random layout per episode with ``random_scenarios``), and returns an
:class:`EvaluationResult`: the episodes and their summary (means and standard
deviations over episodes). Nothing here prints or writes files; see
:mod:`training.evaluation.report`. Distances in m, angles in deg, times in s.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from concurrent.futures import Executor
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from moma_env.metrics import aggregate
from moma_env.scenarios import CONFIGURATIONS
from moma_env.tasks import TASKS
from moma_env.config import ConfigError
from moma_env.vector.parent_watch import worker_pool
from training.evaluation.episode import EpisodeResult, FrameSink
from training.evaluation.policies import Policy, load_policy, policy_label
from training.evaluation.runner import EpisodeRange, ProgressCallback, run_episodes, run_episodes_split

__all__ = ["EvaluationResult", "evaluate", "summarise", "mean_std"]

@dataclass(frozen=True, eq=False)
class EvaluationResult:
    """N episodes of one policy on one configuration.

    Attributes:
        configuration: configuration name (``"top_observer"``, ...).
        policy: the policy spec's label (``"scripted"``, ``"random"``, a file stem).
        seed: seed of episode 0 (episode k used ``seed + k``).
        random_scenarios: whether every episode drew a random layout.
        action_mode: the env's action mode.
        max_cycles: the episode length limit given (None: the scenario's).
        robots: the scored robots, in env order.
        episodes: the episodes in order.
        summary: see :func:`summarise`.
        options: the other env options and configuration fields given (``**overrides``
            of :func:`evaluate`, e.g. ``{"leg_length": 1.5}``).
    """

    configuration: str
    policy: str
    seed: int
    random_scenarios: bool
    action_mode: str
    max_cycles: int | None
    robots: tuple[str, ...]
    episodes: tuple[EpisodeResult, ...]
    summary: Mapping[str, Any] = field(repr=False)
    options: Mapping[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """Everything for ``summary.json`` (NaN kept as float; the JSON writer makes it null)."""
        return {
            "scenario": self.configuration,
            "policy": self.policy,
            "seed": self.seed,
            "n_episodes": len(self.episodes),
            "random_scenarios": self.random_scenarios,
            "action_mode": self.action_mode,
            "max_cycles": self.max_cycles,
            "options": dict(self.options),
            "robots": list(self.robots),
            "summary": dict(self.summary),
            "episodes": [episode_dict(ep) for ep in self.episodes],
        }


def episode_dict(ep: EpisodeResult) -> dict[str, Any]:
    """One episode as nested plain data (the per-robot metrics in full)."""
    return {
        "episode": ep.index,
        "seed": ep.seed,
        "success": ep.success,
        "truncated": ep.truncated,
        "steps": ep.steps,
        "duration_s": ep.duration_s,
        "time_to_goal_s": ep.time_to_goal_s,
        "total_reward": ep.total_reward,
        "n_switches": ep.n_switches,
        "n_refused": ep.n_refused,
        "lost_track": ep.lost_track,
        "waiting_s": ep.waiting_s,
        "still_s": ep.still_s,
        "bound_s": ep.bound_s,
        "waves": ep.waves,
        "fewest_waves": ep.fewest_waves,
        "fewest_waves_time_s": ep.fewest_waves_time_s,
        "goals": {name: list(goal) for name, goal in ep.goals.items()},
        "robots": {
            name: {
                "distance_m": r.distance_m,
                "n_switches": r.n_switches,
                "n_refused": r.n_refused,
                "lost": r.lost,
                "goal_time_s": r.goal_time_s,
                "switch_times": list(r.switch_times),
                "metrics": r.metrics.to_dict(),
            }
            for name, r in ep.robots.items()
        },
    }


def mean_std(values: Sequence[float] | np.ndarray, ddof: int = 1) -> dict[str, float | int]:
    """``{"mean", "std", "n"}`` over the finite ``values`` (NaN when too few)."""
    a = np.asarray(values, dtype=float)
    a = a[np.isfinite(a)]
    n = int(a.shape[0])
    return {
        "mean": float(a.mean()) if n else math.nan,
        "std": float(a.std(ddof=ddof)) if n > ddof else math.nan,
        "n": n,
    }


def summarise(episodes: Sequence[EpisodeResult], robots: Sequence[str]) -> dict[str, Any]:
    """Aggregate episodes: rates, means and standard deviations (sample std, ddof 1).

    Keys: ``n_episodes``, ``success_rate``, ``lost_track_rate``,
    ``time_to_goal_s`` (over successful episodes), ``duration_s``,
    ``total_reward``, ``n_switches``, ``n_refused``, ``waiting_s`` and ``still_s``
    (over successful episodes; :func:`training.evaluation.episode.schedule_split`),
    ``bound_s`` (over successful episodes; :func:`training.evaluation.episode.schedule_bound`),
    ``waves``, ``fewest_waves`` and ``fewest_waves_time_s`` (over successful episodes;
    :func:`training.evaluation.episode.start_waves`, :func:`~training.evaluation.episode.fewest_waves`)
    (each ``{"mean", "std", "n"}``), and ``robots``: per robot ``distance_m``, ``n_switches``,
    ``mean_heading_error_deg``, ``final_heading_error_deg`` (mean/std) and
    ``moma``: :func:`moma_env.metrics.aggregate` of its runs (ME_f, its std,
    ME, % of path, best and worst, failures; m and %).

    Raises:
        ValueError: no episodes.
    """
    if not episodes:
        raise ValueError("summarise needs at least one episode")
    n = len(episodes)
    out: dict[str, Any] = {
        "n_episodes": n,
        "success_rate": sum(ep.success for ep in episodes) / n,
        "lost_track_rate": sum(ep.lost_track for ep in episodes) / n,
        "time_to_goal_s": mean_std([ep.time_to_goal_s for ep in episodes]),
        "duration_s": mean_std([ep.duration_s for ep in episodes]),
        "total_reward": mean_std([ep.total_reward for ep in episodes]),
        "n_switches": mean_std([ep.n_switches for ep in episodes]),
        "n_refused": mean_std([ep.n_refused for ep in episodes]),
        "waiting_s": mean_std([ep.waiting_s for ep in episodes]),
        "still_s": mean_std([ep.still_s for ep in episodes]),
        "bound_s": mean_std([ep.bound_s for ep in episodes]),
        "waves": mean_std([ep.waves for ep in episodes]),
        "fewest_waves": mean_std([ep.fewest_waves for ep in episodes]),
        "fewest_waves_time_s": mean_std([ep.fewest_waves_time_s for ep in episodes]),
    }
    per_robot = {}
    for name in robots:
        runs = [ep.robots[name] for ep in episodes]
        per_robot[name] = {
            "distance_m": mean_std([r.distance_m for r in runs]),
            "n_switches": mean_std([r.n_switches for r in runs]),
            "lost_rate": sum(r.lost for r in runs) / n,
            "mean_heading_error_deg": mean_std([r.metrics.mean_heading_error_deg for r in runs]),
            "final_heading_error_deg": mean_std([r.metrics.final_heading_error_deg for r in runs]),
            "moma": aggregate([r.metrics for r in runs]).to_dict(),
        }
    out["robots"] = per_robot
    return out


def evaluate(
    configuration: str,
    policy_spec: str | Policy,
    episodes: int,
    seed: int = 0,
    *,
    random_scenarios: bool = True,
    action_mode: str = "switching",
    max_cycles: int | None = None,
    frame_sink: FrameSink | None = None,
    progress: ProgressCallback | None = None,
    detection_logs: list[str] | None = None,
    jobs: int = 1,
    executor: Executor | None = None,
    **overrides: Any,
) -> EvaluationResult:
    """Run ``episodes`` episodes of a policy on ``configuration`` and summarise them.

    Args:
        configuration: a name of :data:`moma_env.scenarios.CONFIGURATIONS` or of
            :data:`moma_env.tasks.TASKS` (built-in policies are those of its configuration).
        policy_spec: ``"scripted"``, ``"random"``, a path (see
            :func:`training.evaluation.policies.load_policy`) or a policy object.
        episodes: number of episodes (>= 1); episode k resets with ``seed + k``.
        seed: seed of the first episode (>= 0).
        random_scenarios: a random layout per episode (else the default one).
        action_mode: the env's action mode (``"switching"`` or ``"velocity"``).
        max_cycles: episode length limit in steps (None: the scenario's).
        frame_sink: receives the rendered frames of the first episode.
        progress: called with every finished episode.
        detection_logs: when given, each episode's detection log (the file's text,
            :mod:`moma_env.estimator.log`: every call its estimator took) is appended to
            it, in episode order; the episodes are the same.
        jobs: worker processes the episodes are split over
            (:mod:`training.evaluation.runner`; 1: every episode in this process). The
            episodes are the same for any value; the policy must pickle (every built-in one does), and
            ``frame_sink`` needs ``jobs=1``.
        executor: a process pool of ``jobs`` workers to run in (a training run's,
            kept between its evaluations) instead of one started for this call.
        **overrides: fields of the configuration's dataclass, or env options
            (``localiser``, ...).

    Raises:
        ConfigError: unknown configuration, bad option or override.
        PolicyLoadError: the policy spec names no loadable policy.
        ValueError: ``episodes`` < 1, ``seed`` < 0, ``jobs`` < 1, ``jobs`` > 1 with a
            ``frame_sink``.
        PolicyNotPortableError: a policy object for ``jobs`` > 1 that does not pickle.
    """
    if configuration not in CONFIGURATIONS and configuration not in TASKS:
        raise ConfigError("scenario", f"unknown configuration or task {configuration!r}; known: {sorted(CONFIGURATIONS) + sorted(TASKS)}")
    if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 1:
        raise ValueError(f"episodes must be an integer >= 1, got {episodes!r}")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
    if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
        raise ValueError(f"jobs must be an integer >= 1, got {jobs!r}")
    if jobs > 1 and frame_sink is not None:
        raise ValueError("recording frames runs the first episode in this process: evaluate with jobs=1")
    jobs = min(jobs, episodes)
    if isinstance(policy_spec, str):
        label = policy_label(policy_spec)
        policy = load_policy(policy_spec, configuration, seed)
    else:
        label = type(policy_spec).__name__
        policy = policy_spec
    env_options = {"random_scenarios": random_scenarios, "action_mode": action_mode, "max_cycles": max_cycles, **overrides}
    logs = detection_logs is not None
    if jobs == 1:
        whole = run_episodes(configuration, policy, EpisodeRange(0, episodes), seed, env_options, frame_sink=frame_sink,
                             progress=progress, detection_logs=logs)
    else:
        if executor is not None:
            whole = run_episodes_split(executor, jobs, configuration, policy, episodes, seed, env_options, progress=progress, detection_logs=logs)
        else:
            with worker_pool(jobs) as pool:
                whole = run_episodes_split(pool, jobs, configuration, policy, episodes, seed, env_options, progress=progress, detection_logs=logs)
    if logs:
        detection_logs.extend(whole.detection_logs)
    results, robots = list(whole.episodes), whole.robots
    return EvaluationResult(
        configuration=configuration,
        policy=label,
        seed=seed,
        random_scenarios=random_scenarios,
        action_mode=action_mode,
        max_cycles=max_cycles,
        robots=robots,
        episodes=tuple(results),
        summary=summarise(results, robots),
        options=dict(overrides),
    )

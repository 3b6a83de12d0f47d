"""Evaluation of a policy during and after training, through the evaluation harness.

:func:`evaluate_model` runs the current model (the most likely actions, or
sampled ones with ``eval_sample_actions``; the run's observation
normalisation) on held-out random scenarios with
:func:`training.evaluation.harness.evaluate`, the same harness as the scripted
baselines, and :func:`headline` reduces a summary to the numbers of the
issue's table: success rate, time to goal (s), switches and refused requests
per episode, ME and E_f (m, mean over episodes and robots of each robot's mean
and final position error of its MOMA estimate).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from concurrent.futures import Executor
from typing import Any

from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.vec_env import VecNormalize

from agents.learned import LearnedPolicy, ObservationScaling, trained_env_fields
from training.evaluation.harness import EvaluationResult, evaluate
from training.train.config import TrainConfig

__all__ = ["headline", "live_policy", "evaluate_model"]


def _float(value: float | None) -> float:
    """A summary number; None (NaN as read back from JSON) is NaN."""
    return math.nan if value is None else float(value)


def _mean(values: list[float | None]) -> float:
    finite = [v for v in map(_float, values) if math.isfinite(v)]
    return sum(finite) / len(finite) if finite else math.nan


def headline(summary: Mapping[str, Any]) -> dict[str, float]:
    """The table's numbers from :func:`training.evaluation.harness.summarise`'s summary
    (in memory, or read back from ``summary.json`` where NaN is null)."""
    robots = summary["robots"].values()
    return {
        "success_rate": _float(summary["success_rate"]),
        "time_to_goal_s": _float(summary["time_to_goal_s"]["mean"]),
        "time_to_goal_std_s": _float(summary["time_to_goal_s"]["std"]),
        "n_switches": _float(summary["n_switches"]["mean"]),
        "n_refused": _float(summary["n_refused"]["mean"]),
        "me_m": _mean([r["moma"]["mean_mean_error"] for r in robots]),
        "e_f_m": _mean([r["moma"]["mean_final_error"] for r in robots]),
        "total_reward": _float(summary["total_reward"]["mean"]),
    }


def live_policy(model: BaseAlgorithm, config: TrainConfig) -> LearnedPolicy:
    """The model as a policy, normalising observations with the training env's statistics
    as they are now (:class:`~agents.learned.ObservationScaling`: a copy, which pickles, so
    the policy can act in worker processes), on envs like the run's (its observations'
    timer and team action)."""
    venv = model.get_env()
    normalise = ObservationScaling.from_vec_normalize(venv) if isinstance(venv, VecNormalize) else None
    return LearnedPolicy(
        model, config.route, config.action_mode, normalise, config.scenario,
        torch_threads=config.torch_threads, deterministic=not config.eval_sample_actions,
        **trained_env_fields(config.to_dict()),
    )


def evaluate_model(model: BaseAlgorithm, config: TrainConfig, jobs: int = 1, executor: Executor | None = None) -> EvaluationResult:
    """``config.eval_episodes`` held-out episodes of the model from ``config.eval_seed``,
    in this process or split over ``jobs`` worker processes (in ``executor`` when given:
    :func:`training.evaluation.harness.evaluate`); the same episodes either way."""
    policy = live_policy(model, config)
    return evaluate(
        config.scenario,
        policy,
        config.eval_episodes,
        config.eval_seed,
        random_scenarios=True,
        action_mode=config.action_mode,
        max_cycles=config.eval_max_cycles,
        jobs=jobs,
        executor=executor,
        **{k: v for k, v in policy.env_options.items() if k != "action_mode"},
    )

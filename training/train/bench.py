"""PPO training frames per second on the switching task (a benchmark, never a test).

``training_fps`` trains PPO (the run's default hyperparameters, 64x64 networks,
``VecNormalize``, one torch thread) on ``top_observer`` in ``switching`` mode
with the geometric camera, through a route, and reports the wall time of
``learn`` only (envs and model built beforehand): SB3 timesteps per second
(agent steps on the shared route, env steps on the centralised one) and joint
env steps per second (each env step moves the whole team one control step).
"""

from __future__ import annotations

import time

from agents.learned import torch_threads
from training.train.config import TrainConfig
from training.train.envs import make_vec_env, wrap_normalisation
from training.train.models import build_model, training_logger

__all__ = ["training_fps", "bench_training"]


def training_fps(steps: int, envs: int, route: str = "shared", subproc: bool = False, scenario: str = "top_observer") -> dict:
    """One PPO training measurement (see the module docstring)."""
    config = TrainConfig(scenario=scenario, steps=steps, envs=envs, route=route, subproc=subproc, checkpoint_every=10**9)
    with torch_threads(config.torch_threads):
        venv = wrap_normalisation(make_vec_env(config, config.seed), config)
        try:
            model = build_model(config, venv)
            model.set_logger(training_logger(None))
            start = time.perf_counter()
            model.learn(steps)
            elapsed = time.perf_counter() - start
            slots_per_env_step = venv.num_envs // envs
            timesteps = int(model.num_timesteps)
        finally:
            venv.close()
    return {
        "scenario": scenario, "route": route, "envs": envs, "subproc": subproc, "timesteps": timesteps, "seconds": elapsed,
        "timesteps_per_s": timesteps / elapsed, "env_steps_per_s": timesteps / slots_per_env_step / elapsed,
    }


def bench_training(steps: int) -> list[dict]:
    """PPO frames per second through the shared route (in-process and 2 workers) and the centralised route."""
    return [
        training_fps(steps, envs=2, route="shared"),
        training_fps(steps, envs=2, route="shared", subproc=True),
        training_fps(steps, envs=2, route="centralised"),
    ]


def format_training(rows: list[dict]) -> list[str]:
    """Lines of the training rows of the benchmark table."""
    lines = [f"\nPPO training on top_observer (switching, geometric camera): {rows[0]['timesteps']} timesteps per row",
             f"{'route':<14}{'envs':>6}{'workers':>9}{'timesteps/s':>13}{'env steps/s':>13}", "-" * 55]
    for r in rows:
        lines.append(f"{r['route']:<14}{r['envs']:>6}{(r['envs'] if r['subproc'] else 0):>9}{r['timesteps_per_s']:>13.0f}{r['env_steps_per_s']:>13.0f}")
    return lines

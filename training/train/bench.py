"""PPO training frames per second on the switching task (a benchmark, never a test).

``training_fps`` trains PPO or MaskablePPO (the run's default hyperparameters, 64x64
networks, ``VecNormalize``, one torch thread) on a configuration or task in
``switching`` mode with the geometric camera, through a route, and reports the wall
time of ``learn`` only (envs and model built beforehand): SB3 timesteps per second
(agent steps on the shared route, env steps on the centralised one) and joint env
steps per second (each env step moves the whole team one control step). Rows:
``top_observer`` (2 UGVs) through each route, and the coordination task
``top_observer_team4`` (4 UGVs, :mod:`moma_env.tasks`) with MaskablePPO on 8 copies.
"""

from __future__ import annotations

import time

from agents.learned import torch_threads
from training.train.config import TrainConfig
from training.train.envs import make_vec_env, wrap_normalisation
from training.train.models import build_model, training_logger

__all__ = ["training_fps", "bench_training"]


def training_fps(
    steps: int, envs: int, route: str = "shared", subproc: bool = False, scenario: str = "top_observer", algo: str = "ppo"
) -> dict:
    """One training measurement (see the module docstring)."""
    config = TrainConfig(scenario=scenario, algo=algo, steps=steps, envs=envs, route=route, subproc=subproc, checkpoint_every=10**9)
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
        "scenario": scenario, "algo": algo, "route": route, "envs": envs, "subproc": subproc, "timesteps": timesteps, "seconds": elapsed,
        "timesteps_per_s": timesteps / elapsed, "env_steps_per_s": timesteps / slots_per_env_step / elapsed,
    }


def bench_training(steps: int) -> list[dict]:
    """PPO frames per second through the shared route (in-process and 2 workers) and the centralised route."""
    return [
        training_fps(steps, envs=2, route="shared"),
        training_fps(steps, envs=2, route="shared", subproc=True),
        training_fps(steps, envs=2, route="centralised"),
        training_fps(steps, envs=8, route="shared", scenario="top_observer_team4", algo="maskable_ppo"),
    ]


def format_training(rows: list[dict]) -> list[str]:
    """Lines of the training rows of the benchmark table."""
    lines = [f"\ntraining (switching, geometric camera): about {rows[0]['timesteps']} timesteps per row",
             f"{'scenario':<20}{'algo':<14}{'route':<13}{'envs':>5}{'workers':>8}{'timesteps/s':>13}{'env steps/s':>13}", "-" * 86]
    for r in rows:
        workers = r["envs"] if r["subproc"] else 0
        lines.append(
            f"{r['scenario']:<20}{r.get('algo', 'ppo'):<14}{r['route']:<13}{r['envs']:>5}{workers:>8}{r['timesteps_per_s']:>13.0f}{r['env_steps_per_s']:>13.0f}"
        )
    return lines

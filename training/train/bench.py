"""PPO training frames per second on the switching task (a benchmark, never a test).

``training_fps`` trains PPO or MaskablePPO (the run's default hyperparameters, 64x64
networks, ``VecNormalize``, one torch thread while collecting and one per core for the
updates, as ``moma-env train``) on a configuration or task in
``switching`` mode with the geometric camera, through a route, and reports the wall
time of ``learn`` only (envs and model built beforehand): SB3 timesteps per second
(agent steps on the shared route, env steps on the centralised one) and joint env
steps per second (each env step moves the whole team one control step). Rows:
``top_observer`` (2 UGVs) through each route, and the coordination task
``top_observer_team4`` (4 UGVs, :mod:`moma_env.tasks`) with MaskablePPO on 8 copies and,
when the ``torchrl`` extra is installed, with TorchRL's MAPPO on 8 copies of the batched env
(``torchrl_training_fps``: the run's collecting and learning time, from its manifest; its
timesteps are agent steps, as on the shared route). ``python -m training.train.bench``
times those two on the four-UGV task in interleaved rounds and prints their ratio
(:func:`compare_backends`); with ``--target`` it times ``moma-env train`` on the four-UGV
task with its defaults and with the fastest settings measured (:data:`FASTEST_TEAM4`),
interleaved, and judges each against :data:`TARGET_ENV_STEPS_PER_S` (:func:`throughput_target`).

Each row also says where the time went: ``env_s`` (the SB3 rows: the vectorised env's
``step_wait``, the copies stepping), ``collect_s`` (gathering the rollout: the env, the
policy's forward passes, masks, normalisation and the buffer) and ``learn_s`` (the
gradient updates), and ``learner_bound_env_steps_per_s``: the env steps per second the
run would reach with an env that cost nothing, its env steps over ``learn_s`` plus the
collection's time outside the env (on the TorchRL rows, whose manifests do not split the
collection, over ``learn_s`` alone: an upper bound).
"""

from __future__ import annotations

import time
from typing import Any

from agents.learned import torch_threads
from training.bench_common import time_calls
from training.train.callbacks import update_threads_callback
from training.train.config import TrainConfig
from training.train.envs import make_vec_env, wrap_normalisation
from training.train.models import build_model, training_logger

__all__ = [
    "training_fps",
    "torchrl_training_fps",
    "bench_training",
    "compare_backends",
    "compare_batch_sizes",
    "TARGET_ENV_STEPS_PER_S",
    "FASTEST_TEAM4",
    "throughput_target",
    "target_lines",
    "main",
]

#: What training is built towards: env steps per second, learner included, on this
#: machine's 2 cores, for the four-UGV task (docs/training.md, "Where a training run's time goes").
TARGET_ENV_STEPS_PER_S = 10_000

#: The fastest ``moma-env train`` settings measured on ``top_observer_team4``: MaskablePPO,
#: 32 copies split over 2 worker processes, rollouts of 64 steps per slot
#: (``--algo maskable_ppo --num-envs 32 --workers 2 --n-steps 64``).
FASTEST_TEAM4 = {"algo": "maskable_ppo", "envs": 32, "workers": 2, "n_steps": 64}


def training_fps(
    steps: int, envs: int, route: str = "shared", subproc: bool = False, scenario: str = "top_observer", algo: str = "ppo",
    workers: int | None = None, **learning: Any,
) -> dict:
    """One training measurement (see the module docstring); ``workers``: the batched env split
    over that many processes (``moma-env train --workers``); ``learning``: other
    :class:`~training.train.config.TrainConfig` fields (``batch_size``, ``n_steps``, ...),
    recorded in the row."""
    config = TrainConfig(
        scenario=scenario, algo=algo, steps=steps, envs=envs, route=route, subproc=subproc, workers=workers, checkpoint_every=10**9,
        **learning,
    )
    with torch_threads(config.torch_threads):
        venv = wrap_normalisation(make_vec_env(config, config.seed), config)
        try:
            model = build_model(config, venv)
            model.set_logger(training_logger(None))
            clocks = {"env": 0.0, "collect": 0.0, "learn": 0.0}
            time_calls(venv.unwrapped, "step_wait", clocks, "env")  # under VecNormalize and the other wrappers
            time_calls(model, "collect_rollouts", clocks, "collect")
            time_calls(model, "train", clocks, "learn")
            start = time.perf_counter()
            model.learn(steps, callback=update_threads_callback(config))
            elapsed = time.perf_counter() - start
            slots_per_env_step = venv.num_envs // envs
            timesteps = int(model.num_timesteps)
        finally:
            venv.close()
    env_steps = timesteps / slots_per_env_step
    return {
        "scenario": scenario, "algo": algo, "route": route, "envs": envs, "subproc": subproc, "workers": workers,
        "timesteps": timesteps, "seconds": elapsed,
        "timesteps_per_s": timesteps / elapsed, "env_steps_per_s": env_steps / elapsed,
        "env_s": clocks["env"], "collect_s": clocks["collect"], "learn_s": clocks["learn"],
        "learner_bound_env_steps_per_s": env_steps / (clocks["collect"] - clocks["env"] + clocks["learn"]),
        **learning,
    }


def torchrl_training_fps(
    steps: int, envs: int, scenario: str = "top_observer_team4", critic: str = "centralised", workers: int | None = None
) -> dict:
    """One TorchRL measurement: ``moma-env train --backend torchrl`` for at least ``steps``
    agent steps (whole batches of ``256 x envs`` env steps) in a temporary folder, timed
    by the run's own collecting and learning clocks (the set-up and the save left out)."""
    import tempfile
    from pathlib import Path

    from moma_env.env.factory import parallel_env
    from training.train.torchrl_config import TorchRLTrainConfig
    from training.train.torchrl_run import manifest_algorithm, train_torchrl

    n_ugvs = len(parallel_env(scenario, observer_agent=False).possible_agents)
    batch = 256 * envs
    env_steps = max(1, -(-steps // (n_ugvs * batch))) * batch
    config = TorchRLTrainConfig(
        scenario=scenario, steps=env_steps, envs=envs, critic=critic, minibatch_size=64, checkpoint_every=10**9, workers=workers
    )
    with tempfile.TemporaryDirectory() as folder:
        manifest = train_torchrl(config, Path(folder) / "run")
    elapsed = manifest["collect_s"] + manifest["learn_s"]
    timesteps = int(manifest["num_timesteps"]) * n_ugvs
    return {
        "scenario": scenario, "algo": f"{manifest_algorithm(config).lower()} (torchrl)", "route": "shared", "envs": envs, "subproc": False,
        "workers": workers, "timesteps": timesteps, "seconds": elapsed, "timesteps_per_s": timesteps / elapsed,
        "env_steps_per_s": manifest["num_timesteps"] / elapsed,
        "env_s": None, "collect_s": manifest["collect_s"], "learn_s": manifest["learn_s"],
        "learner_bound_env_steps_per_s": manifest["num_timesteps"] / manifest["learn_s"],
    }


def bench_training(steps: int) -> list[dict]:
    """PPO frames per second through the shared route (in-process and 2 workers) and the centralised route,
    MaskablePPO on the four-UGV task, and TorchRL's MAPPO on it when TorchRL is installed."""
    rows = [
        training_fps(steps, envs=2, route="shared"),
        training_fps(steps, envs=2, route="shared", subproc=True),
        training_fps(steps, envs=2, route="centralised"),
        training_fps(steps, envs=8, route="shared", scenario="top_observer_team4", algo="maskable_ppo"),
    ]
    try:
        import moma_env.vector.torchrl  # noqa: F401  (imports torchrl keeping multiprocessing's start method)
    except ImportError:
        return rows
    return [*rows, torchrl_training_fps(steps, envs=8)]


def format_training(rows: list[dict]) -> list[str]:
    """Lines of the training rows of the benchmark table (with a minibatch column, ``batch``,
    when a row gives its ``batch_size``: ``-`` for the run's default)."""
    batches = any("batch_size" in r for r in rows)
    batch_head = f"{'batch':>7}" if batches else ""
    lines = [f"\ntraining (switching, geometric camera): about {rows[0]['timesteps']} timesteps per row; env %: the "
             "share of the time in the env's step; learner bound: env steps/s with an env that cost nothing",
             f"{'scenario':<20}{'algo':<18}{'route':<13}{'envs':>5}{'workers':>8}{batch_head}{'timesteps/s':>13}{'env steps/s':>13}"
             f"{'env %':>7}{'learner bound':>15}", "-" * (112 + len(batch_head))]
    for r in rows:
        workers = r["envs"] if r["subproc"] else (r.get("workers") or 0)
        env_share = "-" if r.get("env_s") is None else f"{100 * r['env_s'] / r['seconds']:.0f}"
        bound = r.get("learner_bound_env_steps_per_s")
        batch = f"{r.get('batch_size') or '-':>7}" if batches else ""
        lines.append(
            f"{r['scenario']:<20}{r.get('algo', 'ppo'):<18}{r['route']:<13}{r['envs']:>5}{workers:>8}{batch}{r['timesteps_per_s']:>13.0f}"
            f"{r['env_steps_per_s']:>13.0f}{env_share:>7}{'-' if bound is None else f'{bound:.0f}':>15}"
        )
    return lines


def compare_backends(
    steps: int, rounds: int, envs: int = 8, scenario: str = "top_observer_team4", workers: int | None = None
) -> list[dict]:
    """Interleaved rounds of MaskablePPO (SB3, shared route) and TorchRL's MAPPO on ``scenario``
    with ``envs`` copies, at least ``steps`` agent steps each: one row per round and backend,
    with ``round`` and, on the TorchRL rows, ``x_sb3`` (its env steps per second over the SB3
    row's of the same round). With ``workers``, each backend also runs with its batched env
    split over that many processes, and those rows carry ``x_in_process`` (over the same
    backend's in-process row of the round)."""
    rows = []
    for k in range(rounds):
        sb3 = training_fps(steps, envs=envs, route="shared", scenario=scenario, algo="maskable_ppo") | {"round": k}
        mappo = torchrl_training_fps(steps, envs=envs, scenario=scenario) | {"round": k}
        mappo["x_sb3"] = mappo["env_steps_per_s"] / sb3["env_steps_per_s"]
        rows += [sb3, mappo]
        if workers is not None:
            sb3_w = training_fps(steps, envs=envs, route="shared", scenario=scenario, algo="maskable_ppo", workers=workers)
            mappo_w = torchrl_training_fps(steps, envs=envs, scenario=scenario, workers=workers)
            for row, reference in ((sb3_w, sb3), (mappo_w, mappo)):
                rows.append(row | {"round": k, "x_in_process": row["env_steps_per_s"] / reference["env_steps_per_s"]})
    return rows


def compare_batch_sizes(
    steps: int, rounds: int, batch_sizes: list[int], envs: int = 32, scenario: str = "top_observer_team4", workers: int | None = None,
    n_steps: int | None = None,
) -> list[dict]:
    """Interleaved rounds of SB3 MaskablePPO (shared route) on ``scenario`` with each of
    ``batch_sizes`` as its minibatch size (``--batch-size``), ``envs`` copies split over
    ``workers`` processes and ``n_steps`` (None: the default) per rollout: one row per
    round and size, each with ``round`` and ``x_first`` (its env steps per second over the
    first size's row of the same round)."""
    rows = []
    learning = {} if n_steps is None else {"n_steps": n_steps}
    for k in range(rounds):
        first = None
        for size in batch_sizes:
            row = training_fps(steps, envs=envs, route="shared", scenario=scenario, algo="maskable_ppo", workers=workers,
                               batch_size=size, **learning) | {"round": k}
            first = first or row
            row["x_first"] = row["env_steps_per_s"] / first["env_steps_per_s"]
            rows.append(row)
    return rows


def throughput_target(steps: int, rounds: int, scenario: str = "top_observer_team4") -> list[dict]:
    """Interleaved rounds of ``moma-env train --scenario SCENARIO`` with its defaults
    (``setting`` "default": PPO, 2 copies in this process) and with :data:`FASTEST_TEAM4`
    (``setting`` "fastest"), at least ``steps`` SB3 timesteps each: one row per round and setting."""
    default = TrainConfig(scenario=scenario)
    rows = []
    for k in range(rounds):
        rows.append(training_fps(steps, envs=default.envs, scenario=scenario, algo=default.algo) | {"round": k, "setting": "default"})
        fastest = dict(FASTEST_TEAM4)
        rows.append(training_fps(steps, envs=fastest.pop("envs"), scenario=scenario, **fastest) | {"round": k, "setting": "fastest"})
    return rows


def target_lines(rows: list[dict]) -> list[str]:
    """Each setting of :func:`throughput_target`'s ``rows``: its best and median env steps per
    second over the rounds, against :data:`TARGET_ENV_STEPS_PER_S`, met or missed on the best."""
    import statistics

    lines = []
    for setting in dict.fromkeys(r["setting"] for r in rows):
        rates = [r["env_steps_per_s"] for r in rows if r["setting"] == setting]
        best = max(rates)
        lines.append(
            f"target >= {TARGET_ENV_STEPS_PER_S} env steps/s, learner included, {setting} settings: best {best:.0f}, "
            f"median {statistics.median(rates):.0f} over {len(rates)} rounds: {best / TARGET_ENV_STEPS_PER_S:.0%} of it "
            f"({'met' if best >= TARGET_ENV_STEPS_PER_S else 'missed'})"
        )
    return lines


def main(argv: list[str] | None = None) -> int:
    """``python -m training.train.bench [--steps N] [--rounds R]``: SB3 MaskablePPO against TorchRL
    MAPPO on the four-UGV task, interleaved; prints each round and the best and median ratio.
    With ``--batch-sizes A,B,...``: SB3 MaskablePPO with each minibatch size instead, interleaved,
    and each size's best and median ratio to the first. With ``--target``: the four-UGV task's
    default and fastest training settings instead, interleaved, each against the throughput target."""
    import argparse
    import statistics

    from training.cli_args import int_at_least, int_list

    parser = argparse.ArgumentParser(prog="python -m training.train.bench", description=main.__doc__)
    parser.add_argument("--steps", type=int_at_least(1, "step count"), default=32768, help="agent steps per row (default %(default)s)")
    parser.add_argument("--rounds", type=int_at_least(1, "round count"), default=3, help="interleaved rounds (default %(default)s)")
    parser.add_argument("--num-envs", type=int_at_least(1, "env count"), default=8, help="env copies (default %(default)s)")
    parser.add_argument("--workers", type=int_at_least(1, "worker count"), default=None,
                        help="also time both backends with the copies split over this many processes (default: not)")
    parser.add_argument("--batch-sizes", type=int_list("batch size", 2), default=None,
                        help="comma-separated minibatch sizes: time SB3 MaskablePPO with each instead of the two backends (default: not)")
    parser.add_argument("--n-steps", type=int_at_least(1, "rollout length"), default=None,
                        help="with --batch-sizes: rollout length per slot (default: moma-env train's)")
    parser.add_argument("--target", action="store_true",
                        help="time moma-env train on top_observer_team4 with its defaults and its fastest settings "
                             f"instead, each judged against {TARGET_ENV_STEPS_PER_S} env steps/s")
    args = parser.parse_args(argv)
    if args.target and args.batch_sizes is not None:
        parser.error("--target and --batch-sizes time different things: give one")
    if args.target:
        rows = throughput_target(args.steps, args.rounds)
        for line in format_training(rows):
            print(line)
        for line in target_lines(rows):
            print(line)
        return 0
    if args.workers is not None and args.workers > args.num_envs:
        parser.error(f"--workers must be at most --num-envs ({args.num_envs})")
    if args.batch_sizes is not None:
        rows = compare_batch_sizes(args.steps, args.rounds, args.batch_sizes, envs=args.num_envs, workers=args.workers, n_steps=args.n_steps)
        for line in format_training(rows):
            print(line)
        for size in args.batch_sizes[1:]:
            ratios = [r["x_first"] for r in rows if r["batch_size"] == size]
            print(f"--batch-size {size} / {args.batch_sizes[0]} env steps per second: best {max(ratios):.2f}, "
                  f"median {statistics.median(ratios):.2f} over {len(ratios)} rounds")
        return 0
    rows = compare_backends(args.steps, args.rounds, envs=args.num_envs, workers=args.workers)
    for line in format_training(rows):
        print(line)
    ratios = [r["x_sb3"] for r in rows if "x_sb3" in r]
    print(f"TorchRL MAPPO / SB3 MaskablePPO env steps per second: best {max(ratios):.2f}, median {statistics.median(ratios):.2f} "
          f"over {len(ratios)} rounds")
    for algo in sorted({r["algo"] for r in rows if "x_in_process" in r}):
        split = [r["x_in_process"] for r in rows if r.get("algo") == algo and "x_in_process" in r]
        print(f"{algo} with {args.workers} workers / in this process: best {max(split):.2f}, median {statistics.median(split):.2f} "
              f"over {len(split)} rounds")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

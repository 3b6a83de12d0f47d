"""Wall time of a teacher's demonstrations in one process against several.

``python -m training.bench_demonstrations [--teacher rollout@1.5] [--scenario top_observer_team4_legs]
[--copies 8] [--rows 1600] [--workers 2] [--rounds 2] [--learner RUN]`` drives ``--copies``
copies of the scenario with the teacher for ``--rows`` rows on the centralised route
(:func:`training.train.pretrain.collect_demonstrations`, what ``moma-env train
--pretrain`` does first), once in this process and once split over ``--workers``
processes, in interleaved rounds of one run, and prints each one's rows per second
(best and median of the rounds) and the ratio of the split collection to the one
process. With ``--learner``, a centralised ``moma-env train`` run folder, that run's
policy acts (its most likely actions) and the teacher labels its states, as in a
DAgger round. Both collections' rows are compared: they must be the same, bit for bit.
A measurement, not an assertion of a speed: the machine's other load shows in it.
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Sequence

import numpy as np
import torch

from agents.learned import LearnedPolicy
from training.cli_args import int_at_least
from training.train.config import TrainConfig, check_teacher
from training.train.envs import env_spec
from training.train.demonstrations import Demonstrations
from training.train.pretrain import ModelRowPolicy, collect_demonstrations
from training.train.team_slots import EnvSpec

__all__ = ["main", "run_learner", "time_collection"]

FIELDS = ("observations", "actions", "masks", "rewards", "episode_ends", "complete")


def time_collection(
    spec: EnvSpec, teacher: str, copies: int, rows: int, workers: int, learner: ModelRowPolicy | None = None, seed: int = 0
) -> tuple[float, Demonstrations]:
    """Wall time (s) of one centralised collection of ``rows`` rows on envs built from ``spec``
    (copy ``k`` first reset with ``seed + k``) and the collection itself."""
    start = time.perf_counter()
    demonstrations = collect_demonstrations(spec, teacher, copies, rows, seed=seed, route="centralised", learner=learner, workers=workers)
    return time.perf_counter() - start, demonstrations


def run_learner(directory: str, scenario: str) -> ModelRowPolicy:
    """The most likely actions of the centralised policy in the run folder ``directory``
    (ValueError: not a run, another scenario, or another route)."""
    policy = LearnedPolicy.from_dir(directory, scenario)
    if policy.route != "centralised":
        raise ValueError(f"{directory!r} trained on the {policy.route} route; the demonstrations here are centralised")
    return ModelRowPolicy(policy.model.policy, policy.normalise)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="A teacher's demonstrations in one process against several.")
    parser.add_argument("--scenario", default="top_observer_team4_legs", help="a registered scenario (default top_observer_team4_legs)")
    parser.add_argument("--teacher", default="rollout@1.5", help="a pretraining teacher (default rollout@1.5)")
    parser.add_argument("--copies", type=int_at_least(1, "copy count"), default=8, help="env copies (default 8)")
    parser.add_argument("--rows", type=int_at_least(1, "row count"), default=1600, help="rows per collection (default 1600)")
    parser.add_argument("--workers", type=int_at_least(2, "worker count"), default=2, help="processes of the split collection (default 2)")
    parser.add_argument("--rounds", type=int_at_least(1, "round count"), default=2, help="interleaved rounds (default 2)")
    parser.add_argument("--learner", default=None, metavar="RUN", help="a centralised training run whose policy acts, the teacher labelling (default: the teacher acts)")
    args = parser.parse_args(argv)
    try:
        check_teacher("teacher", args.teacher)
        spec = env_spec(TrainConfig(scenario=args.scenario, algo="maskable_ppo", route="centralised", envs=args.copies, pretrain=args.teacher, steps=0))
        learner = None if args.learner is None else run_learner(args.learner, args.scenario)
    except ValueError as error:  # ConfigError names the field; TrainingDirError the run
        parser.error(str(error))
    if args.workers > args.copies:
        parser.error(f"--workers must be at most --copies ({args.copies}), got {args.workers}")
    torch.set_num_threads(1)
    rates: dict[int, list[float]] = {1: [], args.workers: []}
    for _ in range(args.rounds):
        collected = {}
        for workers in rates:
            seconds, collected[workers] = time_collection(spec, args.teacher, args.copies, args.rows, workers, learner)
            rates[workers].append(len(collected[workers]) / seconds)
        one, split = collected[1], collected[args.workers]
        if not all(np.array_equal(getattr(one, f), getattr(split, f)) for f in FIELDS):
            print("the split collection's rows differ from one process's")
            return 1
    acting = "" if args.learner is None else f", labelling the states of {args.learner}"
    print(f"{args.teacher} on {args.scenario}{acting}, {args.copies} copies, {len(one)} rows, {args.rounds} rounds")
    print("| processes | best rows/s | median rows/s |")
    print("|---|---|---|")
    for workers, measured in rates.items():
        print(f"| {workers} | {max(measured):.1f} | {statistics.median(measured):.1f} |")
    ratios = [s / o for o, s in zip(rates[1], rates[args.workers])]
    print(f"{args.workers} processes / 1, per round: best {max(ratios):.2f}x, median {statistics.median(ratios):.2f}x")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Wall time of an evaluation in one process against its episodes split over workers.

``python -m training.bench_evaluation [--scenario top_observer_team4] [--policy
top_observer_team4_mppo] [--episodes 10] [--seed 100000] [--jobs 2] [--rounds 3]
[--max-cycles N]`` runs the same evaluation (:func:`training.evaluation.harness.evaluate`)
three ways in interleaved rounds of one run: in this process; split over ``--jobs``
worker processes started for the call (``moma-env evaluate --jobs``); and in a pool of
``--jobs`` workers started, and used once, before the rounds (a training run's
evaluations after its first, ``--eval-jobs``); this process runs one evaluation
before the rounds too. It prints each one's seconds (best and
median of the rounds) and the ratios to one process, and checks that the three give the
same episodes. A measurement, not an assertion of a speed: the machine's other load
shows in it.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from collections.abc import Callable, Sequence

import torch

from moma_env.vector.parent_watch import worker_pool
from training.cli_args import SCENARIO_NAMES, choice, int_at_least
from training.evaluation.harness import EvaluationResult, episode_dict, evaluate
from training.evaluation.policies import PolicyLoadError, load_policy

__all__ = ["main", "timed"]

#: The three ways, in the order of a round.
WAYS = ("one process", "workers started per call", "workers kept")


def timed(run: Callable[[], EvaluationResult]) -> tuple[float, EvaluationResult]:
    """Wall time (s) of ``run()`` and its result."""
    start = time.perf_counter()
    result = run()
    return time.perf_counter() - start, result


def _episodes(result: EvaluationResult) -> str:
    return json.dumps([episode_dict(ep) for ep in result.episodes], sort_keys=True, default=repr)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="An evaluation in one process against its episodes split over workers.")
    parser.add_argument("--scenario", default="top_observer_team4", type=choice(SCENARIO_NAMES, "scenario"),
                        help="configuration or task (default top_observer_team4)")
    parser.add_argument("--policy", default="top_observer_team4_mppo", help="a policy spec of moma-env evaluate (default top_observer_team4_mppo)")
    parser.add_argument("--episodes", type=int_at_least(1, "episode count"), default=10, help="episodes per evaluation (default 10)")
    parser.add_argument("--seed", type=int_at_least(0, "seed"), default=100_000, help="seed of the first episode (default 100000)")
    parser.add_argument("--jobs", type=int_at_least(2, "job count"), default=2, help="worker processes of the split evaluations (default 2)")
    parser.add_argument("--rounds", type=int_at_least(1, "round count"), default=3, help="interleaved rounds (default 3)")
    parser.add_argument("--max-cycles", type=int_at_least(1, "step count"), default=None, help="episode length limit (default: the scenario's)")
    args = parser.parse_args(argv)
    try:
        policy = load_policy(args.policy, args.scenario, args.seed)
    except PolicyLoadError as error:
        parser.error(str(error))
    options = dict(getattr(policy, "env_options", {}))
    options["max_cycles"] = args.max_cycles
    torch.set_num_threads(1)

    def run(**split) -> EvaluationResult:
        return evaluate(args.scenario, policy, args.episodes, args.seed, **options, **split)

    seconds: dict[str, list[float]] = {way: [] for way in WAYS}
    with worker_pool(args.jobs) as kept:
        run()  # this process compiles and caches what an episode needs once, before the timing
        run(jobs=args.jobs, executor=kept)  # the workers start and import once, as at a run's first evaluation
        for _ in range(args.rounds):
            results = {}
            for way, split in zip(WAYS, ({}, {"jobs": args.jobs}, {"jobs": args.jobs, "executor": kept})):
                seconds[way].append(0.0)
                seconds[way][-1], results[way] = timed(lambda: run(**split))
            if len({_episodes(result) for result in results.values()}) != 1:
                print("the split evaluations' episodes differ from one process's")
                return 1
    print(f"{args.policy} on {args.scenario}, {args.episodes} episodes from seed {args.seed}, {args.jobs} workers, {args.rounds} rounds")
    print("| evaluation | best s | median s | one process / it, best | median |")
    print("|---|---|---|---|---|")
    for way, measured in seconds.items():
        ratios = [one / it for one, it in zip(seconds[WAYS[0]], measured)]
        print(f"| {way} | {min(measured):.1f} | {statistics.median(measured):.1f} | {max(ratios):.2f}x | {statistics.median(ratios):.2f}x |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

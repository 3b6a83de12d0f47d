"""How often a cloned policy chooses as its teacher does, on the teacher's own states of new layouts.

``python -m training.clone_agreement RUN [--teacher T] [--copies 8] [--rows 8000]
[--seed 2000000] [--workers 2]`` drives ``--copies`` copies of the run's own env (its
scenario with the options it trained with) with the
teacher (default: the one the run was cloned from, its ``--pretrain``) for ``--rows``
rows on the centralised route, copy ``k`` first reset with seed ``--seed + k`` (layouts no
training run nor held-out sweep here starts from by default), and compares the run's most
likely actions with the teacher's on the rows where the masks left a choice: on all of
them, on those where the teacher started a robot, and on those where it started none;
and on how many of the teacher's starts the policy started no robot.
The fit's own accuracy (``pretrain.json``) is measured on the rows it was fitted to; this
is the same measure away from them.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence

import numpy as np
import torch

from agents.learned import read_manifest
from training.bench_demonstrations import run_learner, time_collection
from training.cli_args import int_at_least
from training.train.config import TrainConfig, check_teacher
from training.train.envs import env_spec
from training.train.demonstrations import Demonstrations
from training.train.pretrain import choice_agents, choice_agreement, choice_rows

__all__ = ["main", "start_rows"]


def start_rows(demonstrations: Demonstrations, actions: np.ndarray | None = None) -> np.ndarray:
    """``(T,)`` bool: some agent with more than one action allowed takes one other than 0
    (hold) in ``actions`` (one per row as ``demonstrations.actions`` holds them; default:
    the demonstrations' own): on a switching task, a robot is started."""
    free = choice_agents(demonstrations)
    own = demonstrations.actions if actions is None else np.asarray(actions)
    return (free & (own.reshape(free.shape) != 0)).any(axis=1)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="A cloned policy's agreement with its teacher on the teacher's states of new layouts.")
    parser.add_argument("run", metavar="RUN", help="a centralised moma-env train folder (its policy's most likely actions are compared)")
    parser.add_argument("--teacher", default=None, help="the teacher (default: the run's --pretrain, else its --dagger-teacher)")
    parser.add_argument("--copies", type=int_at_least(1, "copy count"), default=8, help="env copies (default 8)")
    parser.add_argument("--rows", type=int_at_least(1, "row count"), default=8000, help="rows to record (default 8000)")
    parser.add_argument("--seed", type=int_at_least(0, "seed"), default=2_000_000, help="seed of copy 0's first layout (default 2000000)")
    parser.add_argument("--workers", type=int_at_least(1, "worker count"), default=2, help="processes driving the copies (default 2)")
    args = parser.parse_args(argv)
    try:
        config = read_manifest(args.run)["config"]
        scenario = config["scenario"]
        spec = env_spec(TrainConfig.from_dict(config))  # the run's own envs: its observations' timer, rewards, episode length
        teacher = check_teacher("teacher", args.teacher if args.teacher is not None else config.get("pretrain") or config.get("dagger_teacher"))
        policy = run_learner(args.run, scenario)
    except ValueError as error:  # TrainingDirError names the run, ConfigError the teacher
        parser.error(str(error))
    if args.workers > args.copies:
        parser.error(f"--workers must be at most --copies ({args.copies}), got {args.workers}")
    torch.set_num_threads(1)
    seconds, demonstrations = time_collection(spec, teacher, args.copies, args.rows, args.workers, seed=args.seed)
    actions = policy(demonstrations.observations, demonstrations.masks)
    choice = choice_rows(demonstrations)
    starts = start_rows(demonstrations) & choice
    print(f"{teacher} on {scenario}, {args.copies} copies from seed {args.seed}: {len(demonstrations)} rows, "
          f"{demonstrations.episodes} episodes ended, {seconds:.0f} s")
    print(f"| rows with a choice | rows | {args.run}'s most likely actions = {teacher}'s |")
    print("|---|---|---|")
    for label, rows in (("all", choice), ("the teacher starts a robot", starts), ("the teacher starts none", choice & ~starts)):
        share = choice_agreement(demonstrations, actions, rows)
        print(f"| {label} | {int(rows.sum())} | {'-' if np.isnan(share) else f'{100 * share:.1f} %'} |")
    held = int((starts & ~start_rows(demonstrations, actions)).sum())
    print(f"On {held} of the {int(starts.sum())} rows where the teacher starts a robot, the policy starts none.")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""The ``moma-env`` command line.

Subcommands:
    experiment square   the paper's 1 m square: table, figure, TUM files, JSON.
    bench               environment steps per second against MPE2, memory over a long run.
    evaluate            run a policy for N episodes: success, errors, switches; JSON, CSV, TUM, figure.
    train               train a coordination policy with Stable-Baselines3 (training/train/).

Every subcommand validates its arguments at the boundary and exits with status 2
and a one-line message on bad input.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from moma_env.config import ConfigError

__all__ = ["main", "build_parser"]


def _int_at_least(minimum: int, what: str):
    """An argparse type: an integer >= ``minimum``."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer {what}, got {text!r}") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"{what} must be >= {minimum}, got {value}")
        return value

    return parse


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``moma-env``."""
    parser = argparse.ArgumentParser(prog="moma-env", description="MOMA visual mobile marker odometry environment.")
    sub = parser.add_subparsers(dest="command", required=True)

    exp = sub.add_parser("experiment", help="run one of the paper's experiments")
    exp_sub = exp.add_subparsers(dest="experiment", required=True)
    sq = exp_sub.add_parser("square", help="two UGVs leapfrog around a 1 m square under a UAV observer")
    sq.add_argument("--runs", type=_int_at_least(1, "count"), default=10, help="number of runs (default 10, as in the paper)")
    sq.add_argument("--seed", type=_int_at_least(0, "seed"), default=0, help="seed of the first run; run k uses seed+k (default 0)")
    sq.add_argument("--out", type=Path, default=Path("runs/square"), help="output folder (default runs/square)")
    sq.add_argument("--observer", choices=("quadcopter", "handheld"), default="quadcopter", help="the observer carrying the camera")
    sq.add_argument("--noise-px", type=float, default=None, help="corner noise std in pixels (default: the camera config's)")
    sq.add_argument(
        "--full-6dof", action="store_true", help="estimate the UGVs' full 3D pose instead of constraining them upright on the floor"
    )
    sq.add_argument("--json", action="store_true", help="print the results as JSON instead of the table")
    sq.set_defaults(handler=_run_square)

    bench = sub.add_parser("bench", help="steps per second of every environment against MPE2, and memory over a long run")
    bench.add_argument("--steps", type=_int_at_least(100, "step count"), default=5000, help="random-action steps per row (default 5000)")
    bench.add_argument(
        "--memory-steps", type=_int_at_least(0, "step count"), default=100_000, help="steps of the memory run (default 100000; 0 skips it)"
    )
    bench.add_argument(
        "--train-steps", type=_int_at_least(0, "step count"), default=16_384, help="PPO timesteps per training row (default 16384; 0 skips them)"
    )
    bench.add_argument("--json", action="store_true", help="print the results as JSON")
    bench.set_defaults(handler=_run_bench)

    ev = sub.add_parser("evaluate", help="run a policy for N episodes and report success, errors and switches")
    ev.add_argument("--scenario", required=True, help="configuration name (top_observer, caterpillar, caterpillar_sled, caterpillar_multi)")
    ev.add_argument("--policy", default="scripted", help="'scripted', 'planned' (follows the MOMA navigation planner), 'servo' (caterpillar stand-off servo), 'random' or the path of a trained policy (default scripted)")
    ev.add_argument("--episodes", type=_int_at_least(1, "episode count"), default=10, help="number of episodes (default 10)")
    ev.add_argument("--seed", type=_int_at_least(0, "seed"), default=0, help="seed of the first episode; episode k uses seed+k (default 0)")
    layouts = ev.add_mutually_exclusive_group()
    layouts.add_argument(
        "--random-scenarios", dest="random_scenarios", action="store_true", default=True, help="a random layout per episode (default)"
    )
    layouts.add_argument("--fixed", dest="random_scenarios", action="store_false", help="the configuration's default layout every episode")
    ev.add_argument("--out", type=Path, default=None, help="output folder (default runs/evaluate/<scenario>_<policy>)")
    ev.add_argument("--json", action="store_true", help="print the summary as JSON instead of the table")
    ev.add_argument("--video", action="store_true", help="write an animated GIF of the first episode")
    ev.add_argument(
        "--action-mode",
        choices=("switching", "velocity"),
        default=None,
        help="the env's action mode (default: the policy's own, velocity for 'planned', else switching)",
    )
    ev.add_argument("--max-cycles", type=_int_at_least(1, "step count"), default=None, help="episode length limit in steps (default: the scenario's)")
    ev.set_defaults(handler=_run_evaluate)

    from training.train.command import add_train_parser

    add_train_parser(sub, _int_at_least)
    return parser


def _run_evaluate(args: argparse.Namespace) -> int:
    from moma_env.io import to_jsonable
    from moma_env.scenarios import CONFIGURATIONS
    from training.evaluation import PolicyLoadError, evaluate, load_policy, policy_label
    from training.evaluation.policies import POLICY_ACTION_MODES
    from training.evaluation.progress import EpisodeProgress
    from training.evaluation.report import format_table, write_outputs
    from training.evaluation.video import GifRecorder

    if args.scenario not in CONFIGURATIONS:
        print(f"moma-env evaluate: unknown scenario {args.scenario!r}; known: {', '.join(sorted(CONFIGURATIONS))}", file=sys.stderr)
        return 2
    try:
        policy = load_policy(args.policy, args.scenario, args.seed)
    except PolicyLoadError as err:
        print(f"moma-env evaluate: {err}", file=sys.stderr)
        return 2
    label = policy_label(args.policy)
    env_options = dict(getattr(policy, "env_options", {}))  # a trained policy says which env it fits
    if args.action_mode is not None and env_options.get("action_mode", args.action_mode) != args.action_mode:
        print(f"moma-env evaluate: the policy was trained in {env_options['action_mode']!r} mode, not {args.action_mode!r}", file=sys.stderr)
        return 2
    out = args.out if args.out is not None else Path("runs/evaluate") / f"{args.scenario}_{label}"
    recorder = None
    if args.video:
        from moma_env.scenarios import make_scenario

        recorder = GifRecorder(fps=make_scenario(args.scenario).world.control_hz)
    start = time.perf_counter()
    with EpisodeProgress(args.episodes, f"{args.scenario}/{label}") as bar:
        result = evaluate(
            args.scenario,
            policy,
            args.episodes,
            args.seed,
            random_scenarios=args.random_scenarios,
            action_mode=args.action_mode or env_options.pop("action_mode", None) or POLICY_ACTION_MODES.get(args.policy, "switching"),
            max_cycles=args.max_cycles,
            frame_sink=recorder,
            progress=lambda _episode: bar.update(),
            **env_options,
        )
    result = dataclasses.replace(result, policy=label)
    paths = write_outputs(result, out)
    if recorder is not None:
        paths["video"] = out / f"{args.scenario}_episode_000.gif"
        recorder.write(paths["video"])
    wall = time.perf_counter() - start
    if args.json:
        print(json.dumps(to_jsonable(dict(result.summary) | {"scenario": args.scenario, "policy": label, "seed": args.seed,
                                                              "files": paths, "wall_time_s": wall}), indent=2, sort_keys=True))
    else:
        print(format_table(result))
        print("\n" + "\n".join(f"{kind}: {path}" for kind, path in paths.items()) + f"\nwall time: {wall:.1f} s")
    return 0


def _run_bench(args: argparse.Namespace) -> int:
    from training.bench import format_bench, run_bench

    result = run_bench(args.steps, args.memory_steps, args.train_steps)
    print(json.dumps(result, indent=2) if args.json else format_bench(result))
    return 0


def _run_square(args: argparse.Namespace) -> int:
    from training.experiments.square import SquareConfig, run_square, summarise
    from moma_env.io import to_jsonable
    from training.experiments.square_report import format_table, results_dict, write_outputs

    config = SquareConfig(observer=args.observer, planar_ugvs=not args.full_6dof)
    if args.noise_px is not None:
        config = dataclasses.replace(config, camera=dataclasses.replace(config.camera, noise_px=args.noise_px))
    runs = []
    start = time.perf_counter()
    for k in range(args.runs):
        run = run_square(config, args.seed + k)
        runs.append(run)
        m = run.metrics["moma"]
        print(
            f"run {k + 1}/{args.runs} seed {run.seed}: {'done' if run.completed else 'NOT COMPLETED'} in {run.duration_s:.1f} s sim, "
            f"MOMA E_f {100 * m.final_error:.2f} cm, wheel E_f {100 * run.metrics['wheel'].final_error:.2f} cm",
            file=sys.stderr,
        )
    summary = summarise(runs)
    paths = write_outputs(runs, summary, config, args.out)
    wall = time.perf_counter() - start
    if args.json:
        print(json.dumps(to_jsonable(results_dict(runs, summary, config) | {"wall_time_s": wall}), indent=2, sort_keys=True))
    else:
        print(format_table(summary, config, sum(r.completed for r in runs), len(runs)))
        print(f"\nfigure: {paths['figure']}\nsummary: {paths['summary']}\nTUM trajectories: {paths['tum']}/run_XX/\nwall time: {wall:.1f} s")
    return 0 if all(r.completed for r in runs) else 1


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``moma-env`` console script."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.handler(args)
    except ConfigError as err:
        print(f"moma-env: invalid configuration: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())

"""The ``moma-env`` command line.

Subcommands:
    experiment square   the paper's 1 m square: table, figure, TUM files, JSON, CSV.
    experiment line     the paper's 4.6 m line, forward-back-forward: keypoint table, figures, JSON, CSV.
    experiment flips    how often a nearly face-on board's pose comes out flipped, per pose rule.
    experiment consistency  Monte Carlo NEES of MOMA's covariance (square, line; planar, 6-DoF): table, figures, JSON, CSV.
    experiment compare  the estimators (moma, fused, ekf, graph) on the same runs: ME_f, ME, % of path, ANEES, time per update.
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
    _add_experiment_arguments(sq, default_runs=10, default_out=Path("runs/square"))
    sq.add_argument("--side", type=_positive_float("side (m)"), default=1.0, help="side of the square in m (default 1, the paper's)")
    sq.add_argument("--leg", type=_positive_float("leg (m)"), default=0.5, help="length of the main robot's legs in m (default 0.5)")
    sq.set_defaults(handler=_run_experiment)

    ln = exp_sub.add_parser("line", help="the 4.6 m line driven forward, back and forward, 6 switches per pass")
    _add_experiment_arguments(ln, default_runs=5, default_out=Path("runs/line"))
    ln.add_argument("--length", type=_positive_float("length (m)"), default=4.595, help="length of the line in m (default 4.595: 13.785 m in 3 passes)")
    ln.add_argument("--passes", type=_int_at_least(1, "pass count"), default=3, help="passes, alternately forward and back (default 3)")
    ln.add_argument("--switches-per-pass", type=_int_at_least(1, "switch count"), default=6, help="keypoints per pass (default 6)")
    ln.set_defaults(handler=_run_experiment)

    fl = exp_sub.add_parser("flips", help="flip rate of a board at 3 m with 1 px noise, per pose rule and tilt (docs/pnp.md)")
    fl.add_argument("--views", type=_int_at_least(1, "view count"), default=1000, help="random views per tilt (default 1000)")
    fl.add_argument("--seed", type=_int_at_least(0, "seed"), default=0, help="seed of the views and the noise (default 0)")
    fl.add_argument("--json", action="store_true", help="print the results as JSON instead of the table")
    fl.add_argument(
        "--envs",
        type=_int_at_least(1, "episode count"),
        default=None,
        metavar="EPISODES",
        help="also measure the detected normals' errors in every configuration over EPISODES scripted episodes",
    )
    fl.set_defaults(handler=_run_flips)

    cons = exp_sub.add_parser(
        "consistency", help="Monte Carlo NEES of MOMA's covariance on the square and the line (planar and 6-DoF UGVs)"
    )
    cons.add_argument("--runs", type=_int_at_least(1, "count"), default=20, help="runs of each geometric-camera case (default 20)")
    cons.add_argument(
        "--rendered-runs", type=_int_at_least(0, "count"), default=2, help="runs of each rendered-camera case (default 2; 0 skips them)"
    )
    cons.add_argument("--seed", type=_int_at_least(0, "seed"), default=0, help="seed of the first run of each case; run k uses seed+k (default 0)")
    cons.add_argument(
        "--jobs", type=_int_at_least(1, "job count"), default=1, help="worker processes for the runs (default 1; same results for any value)"
    )
    cons.add_argument("--experiments", nargs="+", choices=("square", "line"), default=["square", "line"], help="experiments to run (default both)")
    cons.add_argument(
        "--max-time", type=_positive_float("time limit (s)"), default=None, help="simulated time limit of a run in s (default: the experiment's)"
    )
    cons.add_argument("--out", type=Path, default=Path("runs/consistency"), help="output folder (default runs/consistency)")
    cons.add_argument("--json", action="store_true", help="print the results as JSON instead of the table")
    cons.set_defaults(handler=_run_consistency)
    from training.experiments.compare import add_compare_parser

    add_compare_parser(exp_sub)

    bench = sub.add_parser("bench", help="steps per second of every environment against MPE2, and memory over a long run")
    bench.add_argument("--steps", type=_int_at_least(100, "step count"), default=5000, help="random-action steps per row (default 5000)")
    bench.add_argument(
        "--memory-steps", type=_int_at_least(0, "step count"), default=100_000, help="steps of the memory run (default 100000; 0 skips it)"
    )
    bench.add_argument(
        "--rendered-steps", type=_int_at_least(0, "step count"), default=1000,
        help="steps of each rendered-camera row (top_observer, 720x576 with noise; default 1000; 0 skips it)",
    )
    bench.add_argument("--rendered-only", action="store_true", help="run only the rendered-camera rows")
    bench.add_argument(
        "--train-steps", type=_int_at_least(0, "step count"), default=16_384, help="PPO timesteps per training row (default 16384; 0 skips them)"
    )
    bench.add_argument(
        "--rounds", type=_int_at_least(1, "round count"), default=3,
        help="interleaved rounds of the step-rate rows; each row reports its best round (default 3)",
    )
    bench.add_argument(
        "--vector", action="store_true",
        help="instead: env-steps per second of the batched env (moma_env.vector) against MPE2 and VMAS (training.bench_vector)",
    )
    bench.add_argument(
        "--num-envs", type=_int_at_least(1, "batch size"), nargs="+", default=[1, 64, 256, 1024],
        help="with --vector: the batch sizes (default 1 64 256 1024)",
    )
    bench.add_argument("--json", action="store_true", help="print the results as JSON")
    bench.set_defaults(handler=_run_bench)

    ev = sub.add_parser("evaluate", help="run a policy for N episodes and report success, errors and switches")
    ev.add_argument("--scenario", required=True, help="configuration (top_observer, caterpillar, caterpillar_sled, caterpillar_multi) or task (top_observer_team4, top_observer_team6) name")
    ev.add_argument("--policy", default="scripted", help="'scripted' (one mover at a time), 'greedy' (as many movers as the rules allow), 'planned' (follows the MOMA navigation planner), 'servo' (caterpillar stand-off servo), 'random', the path of a trained policy, or the name of a policy published under policies/ ($MOMA_POLICIES_DIR; python -m training.train.publish) (default scripted)")
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
    ev.add_argument(
        "--sample-actions", action="store_true",
        help="a trained policy samples its actions (seeded by the episode's seed) instead of taking the most likely one",
    )
    ev.set_defaults(handler=_run_evaluate)

    from training.train.command import add_train_parser

    add_train_parser(sub, _int_at_least)
    return parser


def _run_evaluate(args: argparse.Namespace) -> int:
    from moma_env.io import to_jsonable
    from moma_env.scenarios import CONFIGURATIONS
    from moma_env.tasks import TASKS
    from training.evaluation import PolicyLoadError, evaluate, load_policy, policy_label
    from training.evaluation.policies import POLICY_ACTION_MODES
    from training.evaluation.progress import EpisodeProgress
    from training.evaluation.report import format_table, write_outputs
    from training.evaluation.video import GifRecorder

    if args.scenario not in CONFIGURATIONS and args.scenario not in TASKS:
        known = ", ".join(sorted(CONFIGURATIONS) + sorted(TASKS))
        print(f"moma-env evaluate: unknown scenario {args.scenario!r}; known: {known}", file=sys.stderr)
        return 2
    rig = TASKS[args.scenario].configuration if args.scenario in TASKS else args.scenario
    try:
        policy = load_policy(args.policy, args.scenario, args.seed, sample_actions=args.sample_actions)
    except PolicyLoadError as err:
        print(f"moma-env evaluate: {err}", file=sys.stderr)
        return 2
    label = policy_label(args.policy) + ("_sampled" if args.sample_actions else "")
    env_options = dict(getattr(policy, "env_options", {}))  # a trained policy says which env it fits
    if args.action_mode is not None and env_options.get("action_mode", args.action_mode) != args.action_mode:
        print(f"moma-env evaluate: the policy was trained in {env_options['action_mode']!r} mode, not {args.action_mode!r}", file=sys.stderr)
        return 2
    out = args.out if args.out is not None else Path("runs/evaluate") / f"{args.scenario}_{label}"
    recorder = None
    if args.video:
        from moma_env.scenarios import make_scenario

        recorder = GifRecorder(fps=make_scenario(rig).world.control_hz)
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


def _run_flips(args: argparse.Namespace) -> int:
    from training.experiments.flip_rate import FlipConfig, flip_rates, format_flip_table

    start = time.perf_counter()
    result = flip_rates(FlipConfig(views=args.views, seed=args.seed))
    if args.envs is not None:
        from moma_env.scenarios import CONFIGURATIONS
        from training.experiments.board_normals import format_normal_table, normal_errors

        result["environments"] = [normal_errors(name, args.envs, args.seed) for name in CONFIGURATIONS]
    wall = time.perf_counter() - start
    if args.json:
        print(json.dumps(result | {"wall_time_s": wall}, indent=2))
    else:
        tables = [format_flip_table(result)]
        if args.envs is not None:
            tables.append(format_normal_table(result["environments"]))
        print("\n\n".join(tables) + f"\n\nwall time: {wall:.1f} s")
    return 0


def _run_bench(args: argparse.Namespace) -> int:
    if args.vector:
        from training.bench_vector import format_vector_bench, run_vector_bench

        result = run_vector_bench(args.num_envs, args.rounds, min_env_steps=args.steps)
        print(json.dumps(result, indent=2) if args.json else format_vector_bench(result))
        return 0
    from training.bench import format_bench, run_bench

    result = run_bench(args.steps, args.memory_steps, args.rendered_steps, args.rendered_only, args.train_steps, args.rounds)
    print(json.dumps(result, indent=2) if args.json else format_bench(result))
    return 0


def _add_experiment_arguments(parser: argparse.ArgumentParser, default_runs: int, default_out: Path) -> None:
    """The arguments every leapfrog experiment takes."""
    from moma_env.camera import CAMERA_BACKENDS
    from training.experiments.presets import PRESETS

    parser.add_argument("--runs", type=_int_at_least(1, "count"), default=default_runs, help=f"number of runs (default {default_runs})")
    parser.add_argument("--seed", type=_int_at_least(0, "seed"), default=0, help="seed of the first run; run k uses seed+k (default 0)")
    parser.add_argument(
        "--jobs", type=_int_at_least(1, "job count"), default=1, help="worker processes for the runs (default 1; same results for any value)"
    )
    parser.add_argument("--out", type=Path, default=default_out, help=f"output folder (default {default_out})")
    parser.add_argument(
        "--observer",
        choices=("quadcopter", "handheld", "both"),
        default="quadcopter",
        help="the observer carrying the camera; 'both' runs each and compares them (outputs in OUT/<observer>/, OUT/observers.png)",
    )
    parser.add_argument("--preset", choices=sorted(PRESETS), default="default", help="sensing settings (camera, altitude, board; default 'default')")
    parser.add_argument(
        "--camera", choices=CAMERA_BACKENDS, default=None, help="camera backend (default: the preset's; 'rendered' adds the visual odometry baseline)"
    )
    parser.add_argument("--noise-px", type=float, default=None, help="corner noise std in pixels of the geometric camera (default: the preset's)")
    parser.add_argument(
        "--full-6dof", action="store_true", help="estimate the UGVs' full 3D pose instead of constraining them upright on the floor"
    )
    parser.add_argument(
        "--plain-floor",
        action="store_true",
        help="a perfectly plain floor (one gray level) outside the textured regions, instead of the preset's floor grain",
    )
    parser.add_argument(
        "--max-time", type=_positive_float("time limit (s)"), default=None, help="simulated time limit of a run in s; a run stopped by it is flagged (default: the experiment's)"
    )
    parser.add_argument("--json", action="store_true", help="print the results as JSON instead of the table")
    from training.experiments.compare import add_estimator_argument

    add_estimator_argument(parser)


def _positive_float(what: str):
    """An argparse type: a finite number > 0."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a number for the {what}, got {text!r}") from None
        if not value > 0.0 or value == float("inf"):
            raise argparse.ArgumentTypeError(f"the {what} must be a finite number > 0, got {text}")
        return value

    return parse


def _experiment_config(args: argparse.Namespace, observer: str):
    """The experiment's configuration from the arguments: defaults, then the preset, then the flags."""
    from training.experiments.line import LineConfig
    from training.experiments.presets import get_preset
    from training.experiments.square import SquareConfig

    if args.experiment == "square":
        config = SquareConfig(observer=observer, side=args.side, leg=args.leg)
    else:
        config = LineConfig(observer=observer, length=args.length, passes=args.passes, switches_per_pass=args.switches_per_pass)
    config = get_preset(args.preset).apply(config, camera_backend=args.camera)
    if args.full_6dof:
        config = dataclasses.replace(config, planar_ugvs=False)
    if args.noise_px is not None:
        config = dataclasses.replace(config, camera=dataclasses.replace(config.camera, noise_px=args.noise_px))
    if args.plain_floor:
        config = dataclasses.replace(config, floor=dataclasses.replace(config.floor, grain=None))
    if args.max_time is not None:
        config = dataclasses.replace(config, max_time_s=args.max_time)
    return dataclasses.replace(config, localiser=args.estimator)


def _run_experiment(args: argparse.Namespace) -> int:
    from moma_env.io import to_jsonable
    from training.experiments import line_report, square_report
    from training.experiments.line import summarise_line
    from training.experiments.leapfrog_run import summarise
    from training.experiments.report_common import plot_observer_errors
    from training.experiments.runner import run_many

    report, summarise_runs = (square_report, summarise) if args.experiment == "square" else (line_report, summarise_line)
    observers = ("quadcopter", "handheld") if args.observer == "both" else (args.observer,)
    configs = {observer: _experiment_config(args, observer) for observer in observers}  # all validated before any run
    start = time.perf_counter()
    results, tables, all_runs, files = {}, [], {}, {}
    for observer, config in configs.items():
        out = args.out / observer if len(observers) > 1 else args.out
        runs = run_many(config, args.runs, args.seed, log=lambda line, o=observer: print(f"[{o}] {line}", file=sys.stderr), jobs=args.jobs)
        summary = summarise_runs(runs)
        files[observer] = report.write_outputs(runs, summary, config, out)
        results[observer] = report.results_dict(runs, summary, config)
        tables.append(report.format_table(summary, config, sum(r.completed for r in runs), len(runs)))
        if args.experiment == "line":
            tables.append(line_report.format_keypoints(runs[0]))
        all_runs[observer] = runs
    if len(observers) > 1:
        files["observers_figure"] = args.out / "observers.png"
        plot_observer_errors(all_runs, files["observers_figure"])
    wall = time.perf_counter() - start
    completed = all(r.completed for runs in all_runs.values() for r in runs)
    if args.json:
        data = results[observers[0]] if len(observers) == 1 else {"observers": results}
        print(json.dumps(to_jsonable(data | {"wall_time_s": wall, "files": files}), indent=2, sort_keys=True))
    else:
        print("\n\n".join(tables))
        for name, paths in files.items():
            print("\n" + (f"{name}: {paths}" if isinstance(paths, Path) else "\n".join(f"{kind}: {path}" for kind, path in paths.items())))
        print(f"wall time: {wall:.1f} s")
    return 0 if completed else 1


def _run_consistency(args: argparse.Namespace) -> int:
    from moma_env.io import to_jsonable
    from training.experiments.consistency import consistency_cases, run_consistency
    from training.experiments.consistency_report import format_table, results_dict, write_outputs

    try:
        cases = consistency_cases(args.runs, args.rendered_runs, tuple(dict.fromkeys(args.experiments)), args.max_time)
    except ValueError as err:
        print(f"moma-env experiment consistency: {err}", file=sys.stderr)
        return 2
    start = time.perf_counter()
    results = run_consistency(cases, args.seed, jobs=args.jobs, log=lambda line: print(line, file=sys.stderr))
    files = write_outputs(results, args.seed, args.out)
    wall = time.perf_counter() - start
    if args.json:
        print(json.dumps(to_jsonable(results_dict(results, args.seed) | {"wall_time_s": wall, "files": files}), indent=2, sort_keys=True))
    else:
        print(format_table(results))
        print("\n" + "\n".join(f"{kind}: {path}" for kind, path in files.items()) + f"\nwall time: {wall:.1f} s")
    return 0 if all(r.n_completed == r.case.n_runs for r in results) else 1


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

"""The ``moma-env`` command line.

Subcommands:
    experiment square   the paper's 1 m square: table, figure, TUM files, JSON, CSV.
    experiment line     the paper's 4.6 m line, forward-back-forward: keypoint table, figures, JSON, CSV.
    experiment flips    how often a nearly face-on board's pose comes out flipped, per pose rule.
    experiment consistency  Monte Carlo NEES of MOMA's covariance (square, line; planar, 6-DoF): table, figures, JSON, CSV.
    experiment compare  the estimators (moma, fused, ekf, graph, graph_vision) on the same runs: ME_f, ME, % of path, ANEES, time per update.
    bench               environment steps per second against MPE2, memory over a long run; --cli: this command's start-up.
    evaluate            run a policy for N episodes: success, errors, switches; JSON, CSV, TUM, figure.
    localise            run an estimator on a detection log (recorded or real): TUM trajectories and covariances.
    train               train a coordination policy with Stable-Baselines3 (training/train/).
    warm-up             compile the kernels ahead of their first use (make setup runs it).

Every subcommand validates its arguments at the boundary and exits with status 2
and a one-line message on bad input (:data:`EXIT_STATUSES`, docs/cli.md). Building
the parser imports names only (:mod:`training.cli_args`); each subcommand imports
the envs, matplotlib, torch or Stable-Baselines3 when it runs, so ``--help`` is
quick. An output folder holds one run (:func:`moma_env.io.run_folder`): results are
written into a temporary sibling folder that replaces the folder whole at the end.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from moma_env.config import ConfigError
from moma_env.io import RunFolderError
from moma_env.registration import CONFIGURATION_NAMES
from training.cli_args import (
    ACTION_MODE_NAMES,
    CAMERA_BACKEND_NAMES,
    ESTIMATOR_NAMES,
    PRESET_NAMES,
    SCENARIO_NAMES,
    SET_HELP,
    choice,
    field_assignment,
    field_assignments,
    int_at_least,
    name_list,
    positive_float,
)

__all__ = ["main", "build_parser", "CommandParser", "leaf_commands", "EXIT_STATUSES"]

#: The exit statuses of ``moma-env`` (the epilog of every ``--help``; docs/cli.md).
EXIT_STATUSES = """exit status:
  0    done: every run completed and its outputs are written
  1    done, but not every run completed: an experiment run (square, line,
       consistency) stopped by its time limit before the end of its path; the
       outputs are written and flag those runs ("completed": false). E.g.
       'moma-env experiment square --max-time 1' returns 1: one simulated
       second stops every run long before the square is closed
  2    bad input, one line on stderr, nothing written: an option value, an
       unknown scenario or policy, a damaged policy folder (model zip,
       normalisation pickle, manifest), an output folder holding another kind of
       run or files that are not a moma-env run
  130  interrupted (Ctrl-C): the output folder keeps its previous results
"""


class CommandParser(argparse.ArgumentParser):
    """An ``ArgumentParser`` that answers which sub-commands it has (argparse keeps them
    only inside its actions): :attr:`subcommands`, name -> parser, and
    :func:`leaf_commands` for the whole tree."""

    def __init__(self, *args: Any, **kwargs: Any):
        super().__init__(*args, **kwargs)
        self._subparsers_action: Any = None

    def add_subparsers(self, **kwargs: Any) -> Any:
        """As ``ArgumentParser.add_subparsers``; the sub-parsers are ``CommandParser`` too."""
        kwargs.setdefault("parser_class", CommandParser)
        self._subparsers_action = super().add_subparsers(**kwargs)
        return self._subparsers_action

    @property
    def subcommands(self) -> dict[str, "CommandParser"]:
        """Sub-command name -> its parser, in the order they were added (empty for a leaf)."""
        return {} if self._subparsers_action is None else dict(self._subparsers_action.choices)


def leaf_commands(parser: CommandParser, prefix: str) -> list[tuple[str, str, CommandParser]]:
    """``(command line, description, parser)`` of every leaf command under ``parser``,
    depth first, each command line starting with ``prefix``."""
    leaves: list[tuple[str, str, CommandParser]] = []
    for name, sub in parser.subcommands.items():
        command = f"{prefix} {name}"
        leaves += leaf_commands(sub, command) or [(command, sub.description or "", sub)]
    return leaves


def build_parser() -> CommandParser:
    """The argument parser of ``moma-env``: one ``_add_<command>`` function per subcommand.

    Building it (and ``--help``) imports no env, camera, pymunk, OpenCV, matplotlib,
    torch or Stable-Baselines3: each subcommand imports what it needs when it runs.
    """
    parser = CommandParser(
        prog="moma-env",
        description="MOMA visual mobile marker odometry environment (docs/cli.md).",
        epilog=EXIT_STATUSES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    exp = add_subcommand(sub, "experiment", "run one of the paper's experiments or an estimator check")
    exp_sub = exp.add_subparsers(dest="experiment", required=True, metavar="EXPERIMENT")
    for add in (_add_square, _add_line, _add_flips, _add_consistency, _add_compare):
        add(exp_sub)
    for add in (_add_bench, _add_evaluate, _add_localise, _add_train, _add_warm_up):
        add(sub)
    from training.sweep.command import add_sweep_parser

    add_sweep_parser(sub, add_subcommand)
    return parser


def add_subcommand(sub, name: str, help_text: str) -> argparse.ArgumentParser:
    """A subcommand of ``sub`` whose ``--help`` shows ``help_text`` and the exit statuses."""
    return sub.add_parser(
        name,
        help=help_text,
        description=help_text[0].upper() + help_text[1:] + ".",
        epilog=EXIT_STATUSES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )


def _add_square(exp_sub) -> None:
    sq = add_subcommand(exp_sub, "square", "two UGVs leapfrog around a 1 m square under a UAV observer (docs/experiments.md)")
    _add_experiment_arguments(sq, default_runs=10, default_out=Path("runs/square"))
    sq.add_argument("--side", type=positive_float("side (m)"), default=1.0, help="side of the square in m (default 1, the paper's)")
    sq.add_argument("--leg", type=positive_float("leg (m)"), default=0.5, help="length of the main robot's legs in m (default 0.5)")
    sq.set_defaults(handler=_run_experiment)


def _add_line(exp_sub) -> None:
    ln = add_subcommand(exp_sub, "line", "the 4.6 m line driven forward, back and forward, 6 switches per pass (docs/experiments.md)")
    _add_experiment_arguments(ln, default_runs=5, default_out=Path("runs/line"))
    ln.add_argument("--length", type=positive_float("length (m)"), default=4.595, help="length of the line in m (default 4.595: 13.785 m in 3 passes)")
    ln.add_argument("--passes", type=int_at_least(1, "pass count"), default=3, help="passes, alternately forward and back (default 3)")
    ln.add_argument("--switches-per-pass", type=int_at_least(1, "switch count"), default=6, help="keypoints per pass (default 6)")
    ln.set_defaults(handler=_run_experiment)


def _add_experiment_arguments(parser: argparse.ArgumentParser, default_runs: int, default_out: Path) -> None:
    """The arguments every leapfrog experiment takes."""
    parser.add_argument("--runs", type=int_at_least(1, "count"), default=default_runs, help=f"number of runs (default {default_runs})")
    parser.add_argument("--seed", type=int_at_least(0, "seed"), default=0, help="seed of the first run; run k uses seed+k (default 0)")
    parser.add_argument(
        "--jobs", type=int_at_least(1, "job count"), default=1, help="worker processes for the runs (default 1; same results for any value)"
    )
    parser.add_argument("--out", type=Path, default=default_out, help=f"output folder, one run (default {default_out})")
    observers = ("quadcopter", "handheld", "both")
    parser.add_argument(
        "--observer",
        choices=observers,
        type=choice(observers, "observer"),
        default="quadcopter",
        help="the observer carrying the camera; 'both' runs each and compares them (outputs in OUT/<observer>/, OUT/observers.png) "
        "(default quadcopter)",
    )
    parser.add_argument(
        "--preset", choices=PRESET_NAMES, type=choice(PRESET_NAMES, "preset"), default="default",
        help="sensing settings (camera, altitude, board; default 'default')",
    )
    parser.add_argument(
        "--camera", choices=CAMERA_BACKEND_NAMES, type=choice(CAMERA_BACKEND_NAMES, "camera backend"), default=None,
        help="camera backend (default: the preset's; 'rendered' adds the visual odometry baseline)",
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
        "--max-time", type=positive_float("time limit (s)"), default=None,
        help="simulated time limit of a run in s; a run stopped by it is flagged and the exit status is 1 (default: the experiment's)",
    )
    parser.add_argument("--json", action="store_true", help="print the results as JSON instead of the table")
    parser.add_argument(
        "--estimator", choices=ESTIMATOR_NAMES, type=choice(ESTIMATOR_NAMES, "estimator"), default="moma",
        help="the estimator whose trajectories are the runs' 'moma' method (default moma, the paper's; docs/estimators.md)",
    )
    parser.add_argument(
        "--record-detections", action="store_true",
        help="also write each run's detection log, OUT/detections/run_XX.jsonl: every call its estimator took, "
        "for 'moma-env localise' (docs/estimator.md)",
    )


def _add_localise(sub) -> None:
    loc = add_subcommand(
        sub, "localise", "run an estimator on a detection log, recorded by an experiment or written from a real robot (docs/estimator.md)"
    )
    loc.add_argument("log", type=Path, help="the detection log (JSON Lines, format moma-detection-log)")
    loc.add_argument("--out", type=Path, required=True, help="output folder, one run: <robot>.tum, <robot>.cov.txt, summary.json")
    loc.add_argument(
        "--estimator", choices=ESTIMATOR_NAMES, type=choice(ESTIMATOR_NAMES, "estimator"), default="moma",
        help="the estimator, with the log's configuration (default moma, the paper's; docs/estimators.md)",
    )
    loc.add_argument(
        "--truth", type=Path, default=None,
        help="a folder of ground-truth TUM files, <robot>.tum or <robot>_truth.tum (an experiment's tum/run_XX, a motion "
        "capture's): also each robot's planar position errors ME, E_f, max, RMSE (default: none)",
    )
    loc.add_argument(
        "--max-dt", type=positive_float("time tolerance (s)"), default=1e-6,
        help="largest time (s) between a truth sample and the estimate matched to it (default 1e-6: the same instants)",
    )
    loc.add_argument("--json", action="store_true", help="print the summary as JSON instead of the table")
    loc.set_defaults(handler=_run_localise)


def _add_warm_up(sub) -> None:
    warm = add_subcommand(
        sub, "warm-up",
        "compile the package's kernels into numba's cache ahead of their first use: a short seeded run of each "
        "configuration in each action mode (make setup runs it; again after a change to the kernels' sources)",
    )
    warm.add_argument(
        "--configuration", action="append", default=None, type=choice(CONFIGURATION_NAMES, "configuration"),
        choices=CONFIGURATION_NAMES, metavar="NAME",
        help=f"a configuration to warm up (repeatable; default every one: {', '.join(CONFIGURATION_NAMES)})",
    )
    warm.set_defaults(handler=_run_warm_up)


def _add_flips(exp_sub) -> None:
    fl = add_subcommand(exp_sub, "flips", "flip rate of a board at 3 m with 1 px noise, per pose rule and tilt (docs/pnp.md)")
    fl.add_argument("--views", type=int_at_least(1, "view count"), default=1000, help="random views per tilt (default 1000)")
    fl.add_argument("--seed", type=int_at_least(0, "seed"), default=0, help="seed of the views and the noise (default 0)")
    fl.add_argument("--json", action="store_true", help="print the results as JSON instead of the table")
    fl.add_argument(
        "--env-episodes",
        type=int_at_least(1, "episode count"),
        default=None,
        metavar="EPISODES",
        help="also measure the detected normals' errors in every configuration over EPISODES scripted episodes (default: not measured)",
    )
    fl.set_defaults(handler=_run_flips)


def _add_consistency(exp_sub) -> None:
    cons = add_subcommand(
        exp_sub, "consistency", "Monte Carlo NEES of MOMA's covariance on the square and the line, planar and 6-DoF (docs/consistency.md)"
    )
    cons.add_argument("--runs", type=int_at_least(1, "count"), default=20, help="runs of each geometric-camera case (default 20)")
    cons.add_argument(
        "--rendered-runs", type=int_at_least(0, "count"), default=2, help="runs of each rendered-camera case (default 2; 0 skips them)"
    )
    cons.add_argument("--seed", type=int_at_least(0, "seed"), default=0, help="seed of the first run of each case; run k uses seed+k (default 0)")
    cons.add_argument(
        "--jobs", type=int_at_least(1, "job count"), default=1, help="worker processes for the runs (default 1; same results for any value)"
    )
    experiments = ("square", "line")
    cons.add_argument(
        "--experiments", nargs="+", choices=experiments, type=choice(experiments, "experiment"), default=list(experiments),
        help="experiments to run (default both)",
    )
    cons.add_argument(
        "--max-time", type=positive_float("time limit (s)"), default=None,
        help="simulated time limit of a run in s; a run stopped by it is flagged and the exit status is 1 (default: the experiment's)",
    )
    cons.add_argument("--out", type=Path, default=Path("runs/consistency"), help="output folder, one run (default runs/consistency)")
    cons.add_argument("--json", action="store_true", help="print the results as JSON instead of the table")
    cons.set_defaults(handler=_run_consistency)


def _add_compare(exp_sub) -> None:
    comp = add_subcommand(
        exp_sub, "compare", "the estimators (moma, fused, ekf, graph, graph_vision) on the same runs of the square and the line (docs/estimators.md)"
    )
    comp.add_argument(
        "--estimators", type=name_list("estimator", ESTIMATOR_NAMES), default=list(ESTIMATOR_NAMES),
        help=f"comma-separated estimators (default {','.join(ESTIMATOR_NAMES)})",
    )
    comp.add_argument("--runs", type=int_at_least(1, "count"), default=5, help="runs per experiment, camera and estimator (default 5)")
    comp.add_argument("--seed", type=int_at_least(0, "seed"), default=0, help="seed of the first run; run k uses seed+k (default 0)")
    comp.add_argument(
        "--experiments", type=name_list("experiment", ("square", "line")), default=["square", "line"],
        help="comma-separated experiments (default square,line)",
    )
    comp.add_argument(
        "--cameras", type=name_list("camera", CAMERA_BACKEND_NAMES), default=["geometric"],
        help="comma-separated observer cameras: geometric, rendered (slow) (default geometric)",
    )
    comp.add_argument(
        "--preset", choices=PRESET_NAMES, type=choice(PRESET_NAMES, "preset"), default="paper", help="sensing settings (default paper)"
    )
    comp.add_argument(
        "--max-time", type=positive_float("time limit (s)"), default=None,
        help="simulated time limit of a run in s; a run stopped by it makes the exit status 1 (default: the experiment's)",
    )
    comp.add_argument(
        "--observers", type=name_list("observer", ("quadcopter", "handheld"), repeats=True), default=None,
        help="comma-separated observer kinds (quadcopter, handheld) watching the pair at once, e.g. quadcopter,quadcopter: "
        "each alone, then all together (default: the experiment's one observer)",
    )
    comp.add_argument("--json", action="store_true", help="print the rows as JSON instead of the table")
    comp.set_defaults(handler=_run_compare)


def _run_compare(args: argparse.Namespace) -> int:
    from training.experiments.compare import run_compare_command

    return run_compare_command(args)


def _add_bench(sub) -> None:
    bench = add_subcommand(sub, "bench", "steps per second of every environment against MPE2, memory over a long run (docs/benchmarks.md)")
    bench.add_argument("--steps", type=int_at_least(100, "step count"), default=5000, help="random-action env steps per row (default 5000)")
    bench.add_argument(
        "--memory-steps", type=int_at_least(0, "step count"), default=100_000,
        help="env steps of the memory run (default 100000; 0 skips it); with --vector: env-steps of top_observer at the largest --num-envs",
    )
    bench.add_argument(
        "--rendered-steps", type=int_at_least(0, "step count"), default=1000,
        help="env steps of each rendered-camera row (top_observer, 720x576 with noise; default 1000; 0 skips it)",
    )
    bench.add_argument("--rendered-only", action="store_true", help="run only the rendered-camera rows")
    bench.add_argument(
        "--train-timesteps", type=int_at_least(0, "timestep count"), default=16_384,
        help="PPO training timesteps per training row (default 16384; 0 skips them)",
    )
    bench.add_argument(
        "--rounds", type=int_at_least(1, "round count"), default=3,
        help="interleaved rounds of the step-rate rows and of --cli; each row reports its best round (default 3)",
    )
    modes = bench.add_mutually_exclusive_group()
    modes.add_argument(
        "--vector", action="store_true",
        help="instead: env-steps per second of the batched env (moma_env.vector) against MPE2 and VMAS (training.bench_vector)",
    )
    modes.add_argument(
        "--cli", action="store_true",
        help="instead: wall time of 'moma-env --help' and of every subcommand's --help, each in a fresh process (training.bench_cli)",
    )
    bench.add_argument(
        "--num-envs", type=int_at_least(1, "env count"), nargs="+", default=[1, 64, 256, 1024],
        help="with --vector: the batch sizes, env copies stepped together (default 1 64 256 1024)",
    )
    bench.add_argument(
        "--workers", type=int_at_least(2, "worker count"), nargs="*", default=[2],
        help="with --vector: worker counts of the top_observer rows split over processes (default 2; --workers alone: none)",
    )
    bench.add_argument("--json", action="store_true", help="print the results as JSON")
    bench.set_defaults(handler=_run_bench)


def _add_evaluate(sub) -> None:
    ev = add_subcommand(sub, "evaluate", "run a policy for N episodes and report success, errors and switches (docs/baselines.md)")
    ev.add_argument(
        "--scenario", required=True, choices=SCENARIO_NAMES, type=choice(SCENARIO_NAMES, "scenario"), metavar="NAME",
        help=f"configuration or task: {', '.join(SCENARIO_NAMES)} (required)",
    )
    ev.add_argument(
        "--policy", default="scripted",
        help="'scripted' (one mover at a time), 'greedy' (as many movers as the rules allow; 'greedy@L' starts legs of L m on "
        "an env with leg_lengths), 'pipeline' (a file of "
        "robots: every other robot moves at once), 'rollout' (the greedy with a lookahead over its starts in copies of the "
        "env: a planner reading the simulator; 'rollout@L' over its starts and every leg length, greedy@L finishing), 'rollout_nowait' / 'rollout_nowait@L' (the same, "
        "never choosing to start no robot where one may start), 'pipeline_rollout' (the same over the pipeline's starts), "
        "'pipeline_rollout_masks' (the same over every start the masks allow, the pipeline finishing), 'planned' "
        "(follows the MOMA navigation planner), 'servo' (caterpillar stand-off servo), 'random', the path of a trained "
        "policy, or the name of a policy published under policies/ ($MOMA_POLICIES_DIR; python -m training.train.publish) "
        "(default scripted)",
    )
    ev.add_argument("--episodes", type=int_at_least(1, "episode count"), default=10, help="number of episodes (default 10)")
    ev.add_argument("--seed", type=int_at_least(0, "seed"), default=0, help="seed of the first episode; episode k uses seed+k (default 0)")
    layouts = ev.add_mutually_exclusive_group()
    layouts.add_argument(
        "--random-scenarios", dest="random_scenarios", action="store_true", default=True, help="a random layout per episode (default)"
    )
    layouts.add_argument("--fixed", dest="random_scenarios", action="store_false", help="the configuration's default layout every episode")
    ev.add_argument("--out", type=Path, default=None, help="output folder, one run (default runs/evaluate/<scenario>_<policy>)")
    ev.add_argument("--json", action="store_true", help="print the summary as JSON instead of the table")
    ev.add_argument("--video", action="store_true", help="write an animated GIF of the first episode (with --jobs 1)")
    ev.add_argument(
        "--jobs", type=int_at_least(1, "job count"), default=1,
        help="worker processes the episodes are split over (default 1: in this process; the same episodes for any value)",
    )
    ev.add_argument(
        "--record-detections", action="store_true",
        help="also write each episode's detection log, OUT/detections/ep_XXX.jsonl: every call its estimator took, "
        "for 'moma-env localise' (docs/estimator.md)",
    )
    ev.add_argument(
        "--action-mode", choices=ACTION_MODE_NAMES, type=choice(ACTION_MODE_NAMES, "action mode"), default=None,
        help="the env's action mode (default: the policy's own, velocity for 'planned', else switching)",
    )
    ev.add_argument("--max-cycles", type=int_at_least(1, "step count"), default=None, help="episode length limit in steps (default: the scenario's)")
    ev.add_argument(
        "--sample-actions", action="store_true",
        help="a trained policy samples its actions (seeded by the episode's seed) instead of taking the most likely one",
    )
    ev.add_argument(
        "--set", dest="overrides", action="append", type=field_assignment, metavar="FIELD=VALUE", default=None,
        help=SET_HELP,
    )
    ev.set_defaults(handler=_run_evaluate)


def _add_train(sub) -> None:
    from training.train.command import add_train_parser

    add_train_parser(sub, int_at_least)


def _run_evaluate(args: argparse.Namespace) -> int:
    from moma_env.config import ConfigError
    from moma_env.env.factory import checked_overrides
    from moma_env.io import run_folder, to_jsonable
    from moma_env.tasks import TASKS
    from training.evaluation import PolicyEnvError, PolicyLoadError, evaluate, load_policy, policy_label
    from training.evaluation.policies import POLICY_ACTION_MODES, builtin_name, overrides_beside_policy
    from training.evaluation.progress import EpisodeProgress
    from training.evaluation.runner import PolicyNotPortableError
    from training.evaluation.report import format_table, write_outputs
    from training.localise import write_detection_logs
    from training.evaluation.video import GifRecorder

    rig = TASKS[args.scenario].configuration if args.scenario in TASKS else args.scenario
    try:
        overrides = checked_overrides(args.scenario, field_assignments(args.overrides))
        if "max_cycles" in overrides:
            raise ConfigError("max_cycles", "set the episode length with --max-cycles, not --set")
        policy = load_policy(args.policy, args.scenario, args.seed, sample_actions=args.sample_actions)
    except (PolicyLoadError, ConfigError) as err:
        print(f"moma-env evaluate: {err}", file=sys.stderr)
        return 2
    if args.video and args.jobs > 1:
        print("moma-env evaluate: --video records the first episode in this process: give --jobs 1", file=sys.stderr)
        return 2
    label = policy_label(args.policy) + ("_sampled" if args.sample_actions else "")
    env_options = dict(getattr(policy, "env_options", {}))  # a trained policy says which env it fits
    try:
        overrides = overrides_beside_policy(args.policy, env_options, overrides)
    except ConfigError as err:
        print(f"moma-env evaluate: {err}", file=sys.stderr)
        return 2
    if args.action_mode is not None and env_options.get("action_mode", args.action_mode) != args.action_mode:
        print(f"moma-env evaluate: the policy was trained in {env_options['action_mode']!r} mode, not {args.action_mode!r}", file=sys.stderr)
        return 2
    out = args.out if args.out is not None else Path("runs/evaluate") / f"{args.scenario}_{label}"
    recorder = None
    if args.video:
        from moma_env.scenarios import make_scenario

        recorder = GifRecorder(fps=make_scenario(rig).world.control_hz)
    logs: list[str] | None = [] if args.record_detections else None
    start = time.perf_counter()
    try:
        with run_folder(out, "evaluate") as run:
            with EpisodeProgress(args.episodes, f"{args.scenario}/{label}") as bar:
                result = evaluate(
                    args.scenario,
                    policy,
                    args.episodes,
                    args.seed,
                    random_scenarios=args.random_scenarios,
                    action_mode=args.action_mode or env_options.pop("action_mode", None) or POLICY_ACTION_MODES.get(builtin_name(args.policy) or "", "switching"),
                    max_cycles=args.max_cycles,
                    frame_sink=recorder,
                    progress=lambda _episode: bar.update(),
                    detection_logs=logs,
                    jobs=args.jobs,
                    **env_options,
                    **overrides,
                )
            result = dataclasses.replace(result, policy=label)
            paths = write_outputs(result, run.path)
            if logs is not None:
                paths["detections"] = write_detection_logs(logs, run.path, "ep_%03d.jsonl")  # beside tum/ep_XXX
            if recorder is not None:
                paths["video"] = run.path / f"{args.scenario}_episode_000.gif"
                recorder.write(paths["video"])
            paths = run.final(paths)
    except (PolicyEnvError, PolicyNotPortableError) as err:  # refused the env at its first reset, or cannot go to --jobs: nothing written
        print(f"moma-env evaluate: {err}", file=sys.stderr)
        return 2
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
    if args.env_episodes is not None:
        from moma_env.scenarios import CONFIGURATIONS
        from training.experiments.board_normals import format_normal_table, normal_errors

        result["environments"] = [normal_errors(name, args.env_episodes, args.seed) for name in CONFIGURATIONS]
    wall = time.perf_counter() - start
    if args.json:
        print(json.dumps(result | {"wall_time_s": wall}, indent=2))
    else:
        tables = [format_flip_table(result)]
        if args.env_episodes is not None:
            tables.append(format_normal_table(result["environments"]))
        print("\n\n".join(tables) + f"\n\nwall time: {wall:.1f} s")
    return 0


def _run_bench(args: argparse.Namespace) -> int:
    if args.cli:
        from training.bench_cli import format_cli_bench, run_cli_bench

        result = run_cli_bench(args.rounds)
        print(json.dumps(result, indent=2) if args.json else format_cli_bench(result))
        return 0
    if args.vector:
        from training.bench_vector import format_vector_bench, memory_run, run_vector_bench

        largest = max(args.num_envs)
        if 0 < args.memory_steps < largest:
            print(f"moma-env bench: --memory-steps must be 0 or at least the largest --num-envs ({largest})", file=sys.stderr)
            return 2
        result = run_vector_bench(args.num_envs, args.rounds, min_env_steps=args.steps, workers=args.workers)
        if args.memory_steps:
            result["memory"] = memory_run(largest, args.memory_steps)
        print(json.dumps(result, indent=2) if args.json else format_vector_bench(result))
        return 0
    from training.bench import format_bench, run_bench

    result = run_bench(args.steps, args.memory_steps, args.rendered_steps, args.rendered_only, args.train_timesteps, args.rounds)
    print(json.dumps(result, indent=2) if args.json else format_bench(result))
    return 0


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
    from moma_env.io import run_folder, to_jsonable
    from training.experiments import line_report, square_report
    from training.experiments.line import summarise_line
    from training.experiments.leapfrog_run import summarise
    from training.experiments.report_common import plot_observer_errors
    from training.localise import write_detection_logs
    from training.experiments.runner import run_many

    report, summarise_runs = (square_report, summarise) if args.experiment == "square" else (line_report, summarise_line)
    observers = ("quadcopter", "handheld") if args.observer == "both" else (args.observer,)
    configs = {observer: _experiment_config(args, observer) for observer in observers}  # all validated before any run
    start = time.perf_counter()
    results, tables, all_runs, files = {}, [], {}, {}
    with run_folder(args.out, f"experiment {args.experiment}") as run:
        for observer, config in configs.items():
            out = run.path / observer if len(observers) > 1 else run.path
            logs: list[str] | None = [] if args.record_detections else None
            runs = run_many(
                config, args.runs, args.seed, log=lambda line, o=observer: print(f"[{o}] {line}", file=sys.stderr), jobs=args.jobs,
                detection_logs=logs,
            )
            summary = summarise_runs(runs)
            files[observer] = report.write_outputs(runs, summary, config, out)
            if logs is not None:
                files[observer]["detections"] = write_detection_logs(logs, out, "run_%02d.jsonl")  # beside tum/run_XX
            results[observer] = report.results_dict(runs, summary, config)
            tables.append(report.format_table(summary, config, sum(r.completed for r in runs), len(runs)))
            if args.experiment == "line":
                tables.append(line_report.format_keypoints(runs[0]))
            all_runs[observer] = runs
        if len(observers) > 1:
            files["observers_figure"] = run.path / "observers.png"
            plot_observer_errors(all_runs, files["observers_figure"])
        files = run.final(files)
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
    if not completed:
        print(f"moma-env experiment {args.experiment}: not every run completed (see 'completed' in the results); exit status 1",
              file=sys.stderr)
    return 0 if completed else 1


def _run_warm_up(args: argparse.Namespace) -> int:
    from moma_env.warm_up import warm_up

    start = time.perf_counter()
    for step in warm_up(args.configuration):
        print(f"{step.configuration} {step.action_mode}: {step.seconds:.1f} s")
    print(f"kernels compiled and cached in {time.perf_counter() - start:.1f} s")
    return 0


def _run_localise(args: argparse.Namespace) -> int:
    from training.localise import run_localise_command

    return run_localise_command(args.log, args.out, args.estimator, args.json, args.truth, args.max_dt)


def _run_consistency(args: argparse.Namespace) -> int:
    from moma_env.io import run_folder, to_jsonable
    from training.experiments.consistency import consistency_cases, run_consistency
    from training.experiments.consistency_report import format_table, results_dict, write_outputs

    try:
        cases = consistency_cases(args.runs, args.rendered_runs, tuple(dict.fromkeys(args.experiments)), args.max_time)
    except ValueError as err:
        print(f"moma-env experiment consistency: {err}", file=sys.stderr)
        return 2
    start = time.perf_counter()
    with run_folder(args.out, "experiment consistency") as run:
        results = run_consistency(cases, args.seed, jobs=args.jobs, log=lambda line: print(line, file=sys.stderr))
        files = run.final(write_outputs(results, args.seed, run.path))
    wall = time.perf_counter() - start
    if args.json:
        print(json.dumps(to_jsonable(results_dict(results, args.seed) | {"wall_time_s": wall, "files": files}), indent=2, sort_keys=True))
    else:
        print(format_table(results))
        print("\n" + "\n".join(f"{kind}: {path}" for kind, path in files.items()) + f"\nwall time: {wall:.1f} s")
    completed = all(r.n_completed == r.case.n_runs for r in results)
    if not completed:
        print("moma-env experiment consistency: not every run completed; exit status 1", file=sys.stderr)
    return 0 if completed else 1


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``moma-env`` console script; returns the exit status (:data:`EXIT_STATUSES`)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.handler(args)
    except ConfigError as err:
        print(f"moma-env: invalid configuration: {err}", file=sys.stderr)
        return 2
    except RunFolderError as err:
        print(f"moma-env: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("moma-env: interrupted; the output folder keeps its previous results", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())

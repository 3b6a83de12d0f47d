"""The ``moma-env train`` subcommand: arguments, validation, and the call into :func:`training.train.run.train`.

Stable-Baselines3 is imported only when the command runs, so ``moma-env``'s
other subcommands work without the ``train`` extra.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from collections.abc import Callable
from pathlib import Path
from types import MappingProxyType
from typing import TYPE_CHECKING

from moma_env.config import ConfigError
from moma_env.tasks import TASKS
from training.cli_args import ACTION_MODE_NAMES, SCENARIO_NAMES, TEAM_ACTION_NAMES, choice, int_at_least, int_at_least_or
from training.train.command_common import AUTO, report_training, resolved_workers, scenario_rewards
from training.train.config import ALGORITHMS, DEFAULT_BATCH_SIZE, NETWORKS, PPO_MINIBATCHES, ROUTES, TEACHERS, TrainConfig, check_teacher

if TYPE_CHECKING:
    from moma_env.env.config import RewardConfig

#: Exit statuses of ``moma-env train`` (its ``--help`` epilog).
TRAIN_EPILOG = """exit status:
  0    trained (or resumed) to --timesteps; the manifest names the final checkpoint
  2    bad input, one line on stderr: an option value, a configuration the algorithm
       cannot train, --out holding another run (or a training run without --resume),
       --resume without a loadable checkpoint, the 'train' extra missing
  130  interrupted (Ctrl-C): --out keeps the last checkpoint; --resume continues from it
"""

__all__ = ["add_train_parser", "run_train", "config_from_args", "train_command"]


def _teacher(field: str) -> Callable[[str], str]:
    """An argparse type: a teacher of the TrainConfig field ``field`` (:func:`training.train.config.check_teacher`)."""

    def parse(text: str) -> str:
        try:
            return check_teacher(field, text)
        except ConfigError as err:
            raise argparse.ArgumentTypeError(str(err)) from None

    return parse


def _layers(text: str) -> tuple[int, ...]:
    try:
        sizes = tuple(int(part) for part in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated layer sizes such as 64,64, got {text!r}") from None
    if not sizes or min(sizes) < 1:
        raise argparse.ArgumentTypeError(f"layer sizes must be integers >= 1, got {text!r}")
    return sizes


def add_train_parser(sub, int_at_least=int_at_least) -> argparse.ArgumentParser:
    """Add ``train`` to the subparsers ``sub``; ``int_at_least(minimum, what)`` is the CLI's integer type.

    Light: the parser needs names only (``moma-env train --help`` imports no env, torch or SB3).
    """
    defaults = {f.name: f.default for f in dataclasses.fields(TrainConfig) if f.default is not dataclasses.MISSING}
    tr = sub.add_parser("train", help="train a coordination policy with Stable-Baselines3",
                        description="Train a coordination policy with Stable-Baselines3 or sb3-contrib (docs/training.md).",
                        epilog=TRAIN_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    tr.add_argument("--scenario", required=True, choices=SCENARIO_NAMES, type=choice(SCENARIO_NAMES, "scenario"), metavar="NAME",
                    help=f"configuration or task: {', '.join(SCENARIO_NAMES)} (required)")
    algos = sorted(ALGORITHMS)
    tr.add_argument("--algo", choices=algos, type=choice(algos, "algorithm"), default=defaults["algo"],
                    help="algorithm (default %(default)s; dqn: switching + shared; maskable_ppo: switching, needs sb3-contrib; sac, td3: velocity)")
    tr.add_argument("--timesteps", type=int_at_least(0, "timestep count"), default=defaults["steps"], metavar="TIMESTEPS",
                    help="total training timesteps: env steps (centralised) or agent steps (shared) (default %(default)s)")
    tr.add_argument("--num-envs", type=int_at_least(1, "env count"), default=defaults["envs"], metavar="K",
                    help="env copies K stepped together (default %(default)s)")
    tr.add_argument("--subproc", action="store_true", help="run each env copy in its own worker process (default: in this process)")
    tr.add_argument("--workers", type=int_at_least_or(AUTO, 1, "worker count"), default=AUTO, metavar="W",
                    help="split the batched env's copies over W processes, this one and W - 1 workers: the same rollouts, faster "
                         "with a free core per process and enough copies (not with --subproc, nor --backend rllib); 1: every "
                         "copy in this process; auto (default): one per usable core, at most one per 4 copies (so in this "
                         "process below 8 copies, and with --subproc)")
    tr.add_argument("--seed", type=int_at_least(0, "seed"), default=defaults["seed"], help="seed of the model and the envs (default %(default)s)")
    tr.add_argument("--torch-threads", type=int_at_least(1, "thread count"), default=defaults["torch_threads"], metavar="N",
                    help="torch's intra-op threads while collecting rollouts (default %(default)s: the networks are small, more "
                         "threads contend with the envs for the cores; training is deterministic for a seed and its thread counts)")
    tr.add_argument("--update-threads", type=int_at_least_or(AUTO, 1, "thread count"), default=AUTO, metavar="N",
                    help="torch's intra-op threads for the gradient updates of ppo, a2c and maskable_ppo (and of --backend torchrl), which run after each "
                         "rollout while every env copy waits (default auto: one per usable core)")
    tr.add_argument("--out", type=Path, required=True,
                    help="output folder, one run: checkpoints, manifest.json, evaluations.json (required; a folder holding another run is refused)")
    tr.add_argument("--resume", action="store_true",
                    help="continue the run in --out from its last checkpoint (same settings; --timesteps is the new total) (default: a fresh run)")
    tr.add_argument("--action-mode", choices=ACTION_MODE_NAMES, type=choice(ACTION_MODE_NAMES, "action mode"), default=defaults["action_mode"],
                    help="env action mode (default %(default)s)")
    tr.add_argument("--route", choices=ROUTES, type=choice(ROUTES, "route"), default=defaults["route"],
                    help="shared policy over the UGV agents, or the centralised team as one agent (default %(default)s)")
    tr.add_argument("--max-cycles", type=int_at_least(1, "step count"), default=None, help="training episode length in steps (default: the scenario's)")
    tr.add_argument("--switch-horizon", dest="switch_horizon_s", type=float, default=None, metavar="S",
                    help="seconds since the last switch at which the observations' timer reaches 1 (EnvConfig.switch_horizon_s; "
                         "default: the env's, 5 s; sb3 backend only)")
    tr.add_argument("--team-action", dest="team_action", choices=TEAM_ACTION_NAMES, type=choice(TEAM_ACTION_NAMES, "team action"), default="per_agent",
                    help="the centralised team's action (EnvConfig.team_action): per_agent, every robot's side by side, or one_start, "
                         "one choice a step of which static robot starts which leg, if any (centralised route, tasks with committed legs; "
                         "sb3 backend only) (default %(default)s)")
    tr.add_argument("--reward", action="append", default=[], metavar="NAME=VALUE",
                    help="override a reward weight of RewardConfig (repeatable), e.g. --reward time=-0.01 (default: the scenario's weights)")
    tr.add_argument("--no-normalize", dest="normalize", action="store_false",
                    help="no VecNormalize of observations and rewards (default: normalise)")
    tr.add_argument("--net", type=_layers, default=defaults["net_arch"], metavar="SIZES",
                    help=f"hidden layer sizes, e.g. 64,64 (default {','.join(map(str, defaults['net_arch']))})")
    tr.add_argument("--n-steps", type=int_at_least(1, "step count"), default=defaults["n_steps"], help="rollout length per slot (default %(default)s)")
    tr.add_argument("--batch-size", type=int_at_least(2, "batch size"), default=defaults["batch_size"],
                    help=f"minibatch size (default: PPO and MaskablePPO split each rollout into {PPO_MINIBATCHES} minibatches; "
                         f"behaviour cloning, DAgger, the off-policy algorithms and --backend rllib|torchrl take {DEFAULT_BATCH_SIZE})")
    tr.add_argument("--learning-rate", type=float, default=defaults["learning_rate"], help="learning rate (default %(default)s)")
    tr.add_argument("--gamma", type=float, default=defaults["gamma"], help="discount factor (default %(default)s)")
    tr.add_argument("--ent-coef", type=float, default=defaults["ent_coef"], help="entropy bonus, PPO and A2C (default %(default)s)")
    tr.add_argument("--checkpoint-every", type=int_at_least(1, "timestep count"), default=defaults["checkpoint_every"],
                    help="timesteps between checkpoints (default %(default)s)")
    tr.add_argument("--eval-every", type=int_at_least(0, "timestep count"), default=defaults["eval_every"],
                    help="timesteps between held-out evaluations, also run at the end (default %(default)s: never)")
    tr.add_argument("--eval-episodes", type=int_at_least(1, "episode count"), default=defaults["eval_episodes"],
                    help="episodes per evaluation (default %(default)s)")
    tr.add_argument("--eval-seed", type=int_at_least(0, "seed"), default=defaults["eval_seed"],
                    help="seed of the first held-out evaluation episode (default %(default)s)")
    tr.add_argument("--eval-jobs", type=int_at_least_or(AUTO, 1, "job count"), default=AUTO, metavar="J",
                    help="worker processes an evaluation's episodes are split over, kept for the run; the same evaluations for "
                         "any value (sb3 backend only); auto (default): one per usable core, at most one per episode; 1: in this process")
    tr.add_argument("--eval-sample-actions", action="store_true",
                    help="the held-out evaluations sample the policy's actions (default: the most likely one)")
    tr.add_argument("--network", choices=NETWORKS, type=choice(NETWORKS, "network"), default=defaults["network"],
                    help="policy network: SB3's mlp, or team (centralised route: one encoder and head shared by every robot, "
                         "pooled over the team) (default %(default)s)")
    tr.add_argument("--pretrain", type=_teacher("pretrain"), default=None, metavar="{" + ",".join(TEACHERS) + ",greedy@L,rollout@L,rollout_nowait@L}",
                    help="clone this scripted policy into the network before learning (behaviour cloning; PPO-like, switching mode; "
                         "greedy@L: the greedy policy starting legs of L m, on a task with leg lengths to choose; rollout: a lookahead "
                         "reading the simulator, seconds per episode; rollout_nowait: the same, never choosing to start no robot) "
                         "(default: none, learning starts from random weights)")
    for flag, low, unit, text in (
        ("--pretrain-rows", 1, "row count", "demonstration rows: UGV slot steps (shared route) or env steps (centralised)"),
        ("--pretrain-epochs", 1, "epoch count", "behaviour cloning passes over the teacher's rows"),
        ("--dagger-rounds", 0, "round count", "DAgger rounds after the cloning: the cloned policy acts, the teacher labels"),
        ("--dagger-rows", 1, "row count", "rows recorded per DAgger round"),
        ("--dagger-epochs", 1, "epoch count", "cloning passes over all rows per DAgger round"),
    ):
        field = flag[2:].replace("-", "_")
        tr.add_argument(flag, type=int_at_least(low, unit), default=defaults[field], help=text + " (default %(default)s)")
    tr.add_argument("--dagger-teacher", type=_teacher("dagger_teacher"), default=None, metavar="TEACHER",
                    help="the teacher labelling the DAgger rounds, e.g. rollout@1.5 after --pretrain greedy@1.5; its rows "
                         "alone are then cloned; with --init-from, DAgger from that run's policy (default: the --pretrain teacher)")
    tr.add_argument("--init-from", dest="init_from", default=None, metavar="RUN",
                    help="start from the networks and normalisation statistics of this finished run's last checkpoint (a "
                         "moma-env train --out folder or policies/NAME; the same task, algorithm, action mode, route, network, "
                         "team action and timer), with a fresh optimiser; not with --pretrain (default: none, learning starts from "
                         "random weights or --pretrain's clone)")
    tr.add_argument("--demonstrations", default=None, metavar="RUN",
                    help="fit the teacher's demonstrations kept in this cloned run's folder instead of collecting them; they "
                         "must be the rows this run would collect (same --pretrain, --pretrain-rows, --seed, --num-envs, "
                         "route, task and env options); with --init-from and --dagger-teacher, rows of that teacher (same "
                         "route, task and env options) that every DAgger round fits beside its own (default: collect them; "
                         "DAgger from a run fits its rounds' rows alone)")
    tr.add_argument("--kl-to-start", dest="kl_to_start", type=float, default=defaults["kl_to_start"], metavar="BETA",
                    help="add BETA times the KL divergence of the policy from the one the run started from (--init-from's or "
                         "--pretrain's) to PPO's loss, keeping it near that policy (default %(default)s: no penalty)")
    tr.add_argument("--no-progress", dest="progress_bar", action="store_false", help="no progress bar (default: shown)")
    tr.add_argument("--json", action="store_true", help="print the final manifest as JSON (default: a summary)")
    from training.train.rllib_command import add_rllib_arguments

    add_rllib_arguments(tr)
    from training.train.torchrl_command import add_torchrl_arguments

    add_torchrl_arguments(tr)
    tr.set_defaults(handler=run_train)
    return tr


def config_from_args(args: argparse.Namespace) -> TrainConfig:
    """The :class:`TrainConfig` of parsed arguments (ConfigError names a bad field)."""
    return TrainConfig(
        scenario=args.scenario,
        algo=args.algo,
        steps=args.timesteps,
        envs=args.num_envs,
        subproc=args.subproc,
        workers=resolved_workers(args.workers, args.num_envs, splits=not args.subproc),
        torch_threads=args.torch_threads,
        update_threads=None if args.update_threads == AUTO else args.update_threads,
        seed=args.seed,
        action_mode=args.action_mode,
        route=args.route,
        max_cycles=args.max_cycles,
        switch_horizon_s=args.switch_horizon_s,
        team_action=args.team_action,
        rewards=scenario_rewards(args.scenario, args.reward),
        normalize=args.normalize,
        net_arch=tuple(args.net),
        n_steps=args.n_steps,
        batch_size=args.batch_size,
        learning_rate=args.learning_rate,
        gamma=args.gamma,
        ent_coef=args.ent_coef,
        checkpoint_every=args.checkpoint_every,
        eval_every=args.eval_every,
        eval_jobs=None if args.eval_jobs == AUTO else args.eval_jobs,
        eval_episodes=args.eval_episodes,
        eval_seed=args.eval_seed,
        eval_sample_actions=args.eval_sample_actions,
        progress_bar=args.progress_bar,
        network=args.network,
        pretrain=args.pretrain,
        pretrain_rows=args.pretrain_rows,
        pretrain_epochs=args.pretrain_epochs,
        dagger_rounds=args.dagger_rounds,
        dagger_rows=args.dagger_rows,
        dagger_epochs=args.dagger_epochs,
        dagger_teacher=args.dagger_teacher,
        init_from=args.init_from,
        demonstrations=args.demonstrations,
        kl_to_start=args.kl_to_start,
    )


#: TrainConfig fields -> their ``moma-env train`` option (value options; flags are handled apart).
_VALUE_OPTIONS = MappingProxyType({
    "algo": "--algo", "steps": "--timesteps", "envs": "--num-envs", "workers": "--workers", "torch_threads": "--torch-threads", "update_threads": "--update-threads", "seed": "--seed", "action_mode": "--action-mode",
    "route": "--route", "max_cycles": "--max-cycles", "switch_horizon_s": "--switch-horizon", "team_action": "--team-action", "n_steps": "--n-steps", "batch_size": "--batch-size",
    "learning_rate": "--learning-rate", "gamma": "--gamma", "ent_coef": "--ent-coef",
    "checkpoint_every": "--checkpoint-every", "eval_every": "--eval-every", "eval_episodes": "--eval-episodes",
    "eval_seed": "--eval-seed", "eval_jobs": "--eval-jobs", "network": "--network", "pretrain": "--pretrain", "pretrain_rows": "--pretrain-rows", "pretrain_epochs": "--pretrain-epochs",
    "dagger_rounds": "--dagger-rounds", "dagger_rows": "--dagger-rows", "dagger_epochs": "--dagger-epochs",
    "dagger_teacher": "--dagger-teacher", "init_from": "--init-from", "kl_to_start": "--kl-to-start",
    "demonstrations": "--demonstrations",
})
#: TrainConfig fields -> (the flag, the field's value when the flag is given; without it, the other).
_FLAGS = MappingProxyType({"subproc": ("--subproc", True), "normalize": ("--no-normalize", False),
                           "eval_sample_actions": ("--eval-sample-actions", True), "progress_bar": ("--no-progress", False)})


def train_command(config: TrainConfig, out: str | Path) -> tuple[list[str], list[str]]:
    """``(argv, fields)``: the ``moma-env train`` command line of ``config`` writing to ``out``
    (options at their defaults left out), and the fields that differ from the defaults but
    have no option (``buffer_size``, ``eval_max_cycles``: a run made from Python), which the
    command cannot reproduce."""
    defaults = TrainConfig(scenario=config.scenario)
    argv = ["moma-env", "train", "--scenario", config.scenario]
    for name, option in _VALUE_OPTIONS.items():
        value = getattr(config, name)
        if value != getattr(defaults, name) and value is not None:
            argv += [option, repr(value) if isinstance(value, float) else str(value)]
    if config.net_arch != defaults.net_arch:
        argv += ["--net", ",".join(map(str, config.net_arch))]
    if config.rewards is not None:
        from moma_env.env.config import RewardConfig

        task = TASKS.get(config.scenario)
        base = RewardConfig(**(task.options.get("rewards", {}) if task is not None else {}))
        for f in dataclasses.fields(RewardConfig):
            value = getattr(config.rewards, f.name)
            if value != getattr(base, f.name):
                argv += ["--reward", f"{f.name}={value!r}"]
    for name, (flag, when) in _FLAGS.items():
        if getattr(config, name) == when:  # the command line's default is the other value
            argv.append(flag)
    argv += ["--out", str(out)]
    known = set(_VALUE_OPTIONS) | set(_FLAGS) | {"scenario", "net_arch", "rewards"}
    missing = [f.name for f in dataclasses.fields(TrainConfig) if f.name not in known and getattr(config, f.name) != getattr(defaults, f.name)]
    return argv, missing


def run_train(args: argparse.Namespace) -> int:
    """Handler of ``moma-env train``: exit status 0, or 2 with a one-line message on bad input."""
    if getattr(args, "backend", "sb3") == "rllib":
        from training.train.rllib_command import run_rllib_train

        return run_rllib_train(args)
    if getattr(args, "backend", "sb3") == "torchrl":
        from training.train.torchrl_command import run_torchrl_train

        return run_torchrl_train(args)
    config = config_from_args(args)  # ConfigError -> the CLI's exit status 2
    try:
        from training.train.run import train
    except ImportError as err:
        print(f"moma-env train: needs the 'train' extra (stable-baselines3, torch): {err}", file=sys.stderr)
        return 2
    return report_training(
        args, lambda: train(config, args.out, resume=args.resume),
        lambda manifest: f"trained {config.algo} ({config.route}, {config.action_mode}) on {config.scenario}: "
                         f"{manifest['num_timesteps']} timesteps, {manifest['wall_time_s']:.1f} s of training wall time\n"
                         f"model: {Path(args.out) / manifest['model']}\nmanifest: {Path(args.out) / 'manifest.json'}",
    )

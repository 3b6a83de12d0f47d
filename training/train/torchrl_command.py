"""``moma-env train --backend torchrl``: the option it adds to ``train`` and its handler.

The other options of ``moma-env train`` keep their meaning where TorchRL's multi-agent
PPO has one: ``--timesteps`` (env steps), ``--num-envs`` (copies of the batched env),
``--seed``, ``--max-cycles``, ``--reward``, ``--net``, ``--n-steps`` (steps per copy
between updates; an update trains on ``n_steps x num_envs`` env steps), ``--batch-size``
(minibatch, env steps), ``--learning-rate``, ``--gamma``, ``--ent-coef``,
``--checkpoint-every``, ``--eval-*``, ``--resume``, ``--out``, ``--json``. ``--critic``
chooses MAPPO (centralised) or IPPO (independent). The actor is always one network
shared by the UGVs in switching mode with the action masks (``--algo ppo`` or
``maskable_ppo`` alike); ``--route centralised``, ``--subproc``, ``--network team``,
``--pretrain`` and ``--action-mode velocity`` are refused with one line. Observations
are not normalised.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from training.train.torchrl_config import CRITICS

if TYPE_CHECKING:
    from training.train.torchrl_config import TorchRLTrainConfig

__all__ = ["add_torchrl_arguments", "run_torchrl_train", "torchrl_config_from_args"]


def add_torchrl_arguments(parser: argparse.ArgumentParser) -> None:
    """``--critic`` on ``moma-env train``'s parser."""
    parser.add_argument("--critic", choices=CRITICS, default="centralised",
                        help="with --backend torchrl: centralised (MAPPO: each UGV's value from the whole team's observations) "
                             "or independent (IPPO: from its own) (default %(default)s)")


def torchrl_config_from_args(args: argparse.Namespace) -> "TorchRLTrainConfig":
    """The :class:`TorchRLTrainConfig` of ``moma-env train --backend torchrl`` (ConfigError names a bad option)."""
    from moma_env.config import ConfigError
    from training.train.command_common import AUTO, resolved_workers, scenario_rewards
    from training.train.config import backend_batch_size
    from training.train.torchrl_config import TORCHRL_ACTION_MODE, TorchRLTrainConfig

    if args.algo not in ("ppo", "maskable_ppo"):
        raise ConfigError("algo", f"--backend torchrl trains masked multi-agent PPO only (--algo ppo or maskable_ppo), got {args.algo!r}")
    if args.route != "shared":
        raise ConfigError("route", "--backend torchrl trains one actor shared by the UGVs: drop --route centralised (--critic chooses the critic)")
    if args.subproc:
        raise ConfigError("subproc", "--backend torchrl steps its copies in one batched env: drop --subproc (--workers W splits it over W processes)")
    if args.eval_jobs != AUTO:
        raise ConfigError("eval_jobs", "--backend torchrl evaluates in this process: drop --eval-jobs (the sb3 backend takes it)")
    if args.action_mode != TORCHRL_ACTION_MODE:
        raise ConfigError("action_mode", f"--backend torchrl trains in {TORCHRL_ACTION_MODE} mode only, got {args.action_mode!r}")
    if args.network != "mlp":
        raise ConfigError("network", "--backend torchrl builds TorchRL's multi-agent MLPs: drop --network")
    if args.pretrain is not None:
        raise ConfigError("pretrain", "--backend torchrl does not clone a teacher: drop --pretrain (the sb3 backend does)")
    if args.switch_horizon_s is not None:
        raise ConfigError("switch_horizon_s", "--backend torchrl trains on the env's default timer: drop --switch-horizon (the sb3 backend takes it)")
    if args.team_action != "per_agent":
        raise ConfigError("team_action", "--backend torchrl does not train the centralised team: drop --team-action (the sb3 backend takes it)")
    if args.init_from is not None:
        raise ConfigError("init_from", "--backend torchrl starts from its own checkpoints only: drop --init-from (the sb3 backend takes it)")
    if args.kl_to_start != 0:
        raise ConfigError("kl_to_start", "--backend torchrl has no penalty towards a start policy: drop --kl-to-start (the sb3 backend takes it)")
    if args.dagger_teacher is not None or args.demonstrations is not None:
        raise ConfigError("dagger_teacher" if args.dagger_teacher is not None else "demonstrations",
                          "--backend torchrl does not clone a teacher: drop --dagger-teacher and --demonstrations (the sb3 backend takes them)")
    return TorchRLTrainConfig(
        scenario=args.scenario, steps=args.timesteps, envs=args.num_envs, seed=args.seed, critic=args.critic,
        max_cycles=args.max_cycles, rewards=scenario_rewards(args.scenario, args.reward), net_arch=tuple(args.net),
        n_steps=args.n_steps, minibatch_size=min(backend_batch_size(args.batch_size), args.n_steps * args.num_envs), learning_rate=args.learning_rate,
        gamma=args.gamma, ent_coef=args.ent_coef, checkpoint_every=args.checkpoint_every, eval_every=args.eval_every,
        eval_episodes=args.eval_episodes, eval_seed=args.eval_seed, eval_sample_actions=args.eval_sample_actions,
        workers=resolved_workers(args.workers, args.num_envs, splits=True), torch_threads=args.torch_threads,
        update_threads=None if args.update_threads == AUTO else args.update_threads,
    )


def run_torchrl_train(args: argparse.Namespace) -> int:
    """Handler of ``moma-env train --backend torchrl``: exit status 0, or 2 with a one-line message."""
    config = torchrl_config_from_args(args)  # ConfigError -> the CLI's exit status 2
    try:
        import moma_env.vector.torchrl  # noqa: F401  (imports torchrl keeping multiprocessing's start method)

        from training.train.torchrl_run import manifest_algorithm, train_torchrl
    except ImportError as err:
        print(f"moma-env train: --backend torchrl needs the 'torchrl' extra (pip install -e '.[torchrl]'): {err}", file=sys.stderr)
        return 2
    from training.train.command_common import report_training

    def summary(manifest: dict) -> str:
        steps, collect, learn = manifest["num_timesteps"], manifest["collect_s"], manifest["learn_s"]
        return (f"trained TorchRL {manifest_algorithm(config)} on {config.scenario}: {steps} env steps, "
                f"{manifest['wall_time_s']:.1f} s of training wall time ({steps / max(collect + learn, 1e-9):.0f} env steps/s "
                f"with the learner, {steps / max(collect, 1e-9):.0f} collecting alone)\n"
                f"checkpoint: {Path(args.out) / manifest['checkpoint']}\nmanifest: {Path(args.out) / 'manifest.json'}")

    return report_training(args, lambda: train_torchrl(config, args.out, resume=args.resume), summary)

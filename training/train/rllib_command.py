"""``moma-env train --backend rllib``: the options it adds to ``train`` and its handler.

The other options of ``moma-env train`` keep their meaning where RLlib has one:
``--timesteps`` (env steps), ``--num-envs`` (copies per env runner), ``--seed``,
``--action-mode``, ``--max-cycles``, ``--reward``, ``--net``, ``--n-steps`` (rollout
fragment per copy; an update trains on ``n_steps x num_envs x max(1, runners)`` env steps),
``--batch-size`` (minibatch), ``--learning-rate``, ``--gamma``, ``--ent-coef``,
``--checkpoint-every``, ``--eval-*``, ``--resume``, ``--out``, ``--json``. The route is
always one shared UGV policy; ``--algo`` other than ppo, ``--route centralised`` and
``--subproc`` are refused with one line. RLlib does not normalise observations.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from training.cli_args import int_at_least

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from training.train.rllib_config import RllibTrainConfig

__all__ = ["add_rllib_arguments", "run_rllib_train", "rllib_config_from_args", "BACKENDS", "RLLIB_ENVS"]

#: ``--backend`` of ``moma-env train``.
BACKENDS = ("sb3", "rllib", "torchrl")
#: ``--rllib-env`` (:data:`training.train.rllib_config.RLLIB_ROUTES`; the parser imports no env module).
RLLIB_ENVS = ("pettingzoo", "vector")


def add_rllib_arguments(parser: argparse.ArgumentParser) -> None:
    """``--backend`` (every backend of ``moma-env train``), ``--num-env-runners``, ``--address``, ``--rllib-env`` on ``moma-env train``'s parser."""
    parser.add_argument("--backend", choices=BACKENDS, default="sb3", help="sb3 (Stable-Baselines3, default), rllib (PPO on Ray RLlib's new API stack) "
                             "or torchrl (MAPPO or IPPO on TorchRL with the batched env)")
    parser.add_argument("--num-env-runners", type=int_at_least(0, "runner count"), default=0, help="with --backend rllib: remote env runners (default 0: sample in the driver)")
    parser.add_argument("--address", default=None, help="with --backend rllib: an existing Ray cluster's address (default: a local Ray)")
    parser.add_argument("--rllib-env", choices=RLLIB_ENVS, default="pettingzoo",
                        help="with --backend rllib: pettingzoo (RLlib's PettingZoo wrapper, default) or vector (the batched env)")


def rllib_config_from_args(args: argparse.Namespace) -> "RllibTrainConfig":
    """The :class:`RllibTrainConfig` of ``moma-env train --backend rllib`` (ConfigError names a bad option)."""
    from moma_env.config import ConfigError
    from training.train.command_common import AUTO, scenario_rewards
    from training.train.config import backend_batch_size
    from training.train.rllib_config import RllibTrainConfig

    if args.algo != "ppo":
        raise ConfigError("algo", f"--backend rllib trains PPO only, got {args.algo!r}")
    if args.route != "shared":
        raise ConfigError("route", "--backend rllib trains one shared UGV policy: drop --route centralised")
    if args.subproc:
        raise ConfigError("subproc", "--backend rllib runs its envs in env runners: use --num-env-runners instead of --subproc")
    if args.workers != AUTO:
        raise ConfigError("workers", "--backend rllib runs its envs in env runners: use --num-env-runners instead of --workers")
    if args.eval_jobs != AUTO:
        raise ConfigError("eval_jobs", "--backend rllib evaluates in this process: drop --eval-jobs (the sb3 backend takes it)")
    if args.update_threads != AUTO:
        raise ConfigError("update_threads", "--backend rllib does not take --update-threads (the sb3 backend does): its learner sets its own threads")
    if args.torch_threads != 1:
        raise ConfigError("torch_threads", "--backend rllib does not take --torch-threads: its env runners and learner set their own threads")
    if args.switch_horizon_s is not None:
        raise ConfigError("switch_horizon_s", "--backend rllib trains on the env's default timer: drop --switch-horizon (the sb3 backend takes it)")
    if args.team_action != "per_agent":
        raise ConfigError("team_action", "--backend rllib does not train the centralised team: drop --team-action (the sb3 backend takes it)")
    if args.init_from is not None:
        raise ConfigError("init_from", "--backend rllib starts from its own checkpoints only: drop --init-from (the sb3 backend takes it)")
    if args.kl_to_start != 0:
        raise ConfigError("kl_to_start", "--backend rllib has no penalty towards a start policy: drop --kl-to-start (the sb3 backend takes it)")
    if args.pretrain is not None:
        raise ConfigError("pretrain", "--backend rllib does not clone a teacher: drop --pretrain (the sb3 backend does)")
    if args.dagger_teacher is not None or args.demonstrations is not None:
        raise ConfigError("dagger_teacher" if args.dagger_teacher is not None else "demonstrations",
                          "--backend rllib does not clone a teacher: drop --dagger-teacher and --demonstrations (the sb3 backend takes them)")
    train_batch = args.n_steps * args.num_envs * max(1, args.num_env_runners)
    return RllibTrainConfig(
        scenario=args.scenario, steps=args.timesteps, num_env_runners=args.num_env_runners, envs=args.num_envs, env_route=args.rllib_env,
        seed=args.seed, action_mode=args.action_mode, max_cycles=args.max_cycles, rewards=scenario_rewards(args.scenario, args.reward),
        net_arch=tuple(args.net), n_steps=args.n_steps, batch_size=train_batch, minibatch_size=min(backend_batch_size(args.batch_size), train_batch),
        learning_rate=args.learning_rate, gamma=args.gamma, ent_coef=args.ent_coef, checkpoint_every=args.checkpoint_every,
        eval_every=args.eval_every, eval_episodes=args.eval_episodes, eval_seed=args.eval_seed, eval_sample_actions=args.eval_sample_actions,
    )


def run_rllib_train(args: argparse.Namespace) -> int:
    """Handler of ``moma-env train --backend rllib``: exit status 0, or 2 with a one-line message."""
    config = rllib_config_from_args(args)  # ConfigError -> the CLI's exit status 2
    try:
        from training.train.rllib_run import train_rllib
        import ray.rllib  # noqa: F401
    except ImportError as err:
        print(f"moma-env train: --backend rllib needs the 'ray' extra (pip install -e '.[ray]'): {err}", file=sys.stderr)
        return 2
    from training.train.command_common import report_training

    return report_training(
        args, lambda: train_rllib(config, args.out, resume=args.resume, address=args.address),
        lambda manifest: f"trained RLlib PPO ({config.env_route}, {config.action_mode}) on {config.scenario}: {manifest['num_timesteps']} env steps, "
                         f"{manifest['wall_time_s']:.1f} s of training wall time\ncheckpoint: {Path(args.out) / manifest['checkpoint']}\n"
                         f"manifest: {Path(args.out) / 'manifest.json'}",
    )

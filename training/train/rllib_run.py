"""An RLlib PPO run from start to finish, or resumed from its last checkpoint (``moma-env train --backend rllib``).

The output folder has the Stable-Baselines3 route's layout: ``manifest.json`` (written
last, naming a complete checkpoint; ``"backend": "rllib"``), the checkpoint itself
(RLlib's own checkpoint folder, ``checkpoint_<steps>/``, written by
``Algorithm.save_to_path`` into a temporary folder and then renamed), and, with
``eval_every``, ``evaluations.json``, ``curves.csv`` and ``curves.png`` of the held-out
evaluations, run through the same harness and with the same headline numbers
(:func:`training.train.evaluation.headline`). Older checkpoints are deleted once the
new manifest is in place. ``moma-env evaluate --policy OUT`` loads the run
(:class:`agents.rllib_policy.RllibPolicy`).

``resume=True`` builds the same algorithm, restores it from the manifest's checkpoint
(weights, optimiser, RLlib's step counters) and samples until ``config.steps`` env
steps. Ray: the one already initialised in this process, else ``ray.init(address)``
(None: a local Ray on this machine's cores), shut down at the end if started here.
"""

from __future__ import annotations

import contextlib
import datetime
import re
import shutil
import uuid
from pathlib import Path
from typing import Any

from agents.learned import MANIFEST
from agents.rllib_policy import BACKEND, RllibPolicy, read_rllib_manifest
from moma_env import ENV_VERSION
from moma_env.io import write_json
from training.provenance import library_versions
from training.train.backend_run import RunProgress, start_run
from training.train.evaluation import headline
from training.train.rllib_config import RllibTrainConfig

__all__ = ["train_rllib", "RESUMABLE_CHANGES", "algorithm_config", "env_steps"]

#: Fields a resumed run may change; every other must match the run's.
RESUMABLE_CHANGES = frozenset({"steps", "num_env_runners", "checkpoint_every", "eval_every", "eval_episodes", "eval_seed",
                               "eval_max_cycles", "eval_sample_actions"})
_CHECKPOINT = re.compile(r"^checkpoint_\d{12}$")
_TEMPORARY = re.compile(r"^\.checkpoint_\d{12}\.[0-9a-f]{12}\.tmp$")


def algorithm_config(config: RllibTrainConfig):
    """The ``PPOConfig`` of the run (:func:`moma_env.integrations.rllib.ppo_config`)."""
    from moma_env.integrations.rllib import ppo_config

    return ppo_config(
        config.scenario,
        config.env_options,
        route=config.env_route,
        num_env_runners=config.num_env_runners,
        num_envs_per_env_runner=config.envs,
        rollout_fragment_length=config.n_steps,
        train_batch_size=config.batch_size,
        minibatch_size=config.minibatch_size,
        num_epochs=config.num_epochs,
        lr=config.learning_rate,
        gamma=config.gamma,
        entropy_coeff=config.ent_coef,
        hidden=config.net_arch,
        seed=config.seed,
    )


def env_steps(result: dict[str, Any]) -> int:
    """Env steps sampled over the run's lifetime, from an ``Algorithm.train()`` result."""
    return int(result["env_runners"]["num_env_steps_sampled_lifetime"])


def _checkpoints(out: Path) -> list[Path]:
    return sorted(p for p in out.iterdir() if p.is_dir() and _CHECKPOINT.match(p.name))


def _save(out: Path, algo: Any, config: RllibTrainConfig, steps: int, wall_time_s: float, extra: dict[str, Any]) -> dict[str, Any]:
    """Checkpoint ``algo`` at ``steps``, then the manifest naming it, then delete older checkpoints."""
    name = f"checkpoint_{steps:012d}"
    final = out / name
    if not final.is_dir():
        tmp = out / f".{name}.{uuid.uuid4().hex[:12]}.tmp"
        algo.save_to_path(str(tmp.resolve()))
        tmp.rename(final)
    manifest = {
        "format": 1,
        "backend": BACKEND,
        "env_version": ENV_VERSION,
        "num_timesteps": int(steps),
        "algorithm": "PPO",
        "route": config.env_route,
        "checkpoint": name,
        "iteration": int(algo.iteration),
        "config": config.to_dict(),
        "wall_time_s": float(wall_time_s),
        "saved_at": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "versions": library_versions(),
        **extra,
    }
    write_json(out / MANIFEST, manifest)
    for path in _checkpoints(out):
        if path.name != name:
            shutil.rmtree(path, ignore_errors=True)
    return manifest


def _evaluate(algo: Any, config: RllibTrainConfig) -> dict[str, Any]:
    """The held-out evaluation of the current UGV module through the harness; its headline numbers."""
    from moma_env.integrations.rllib import UGV_POLICY
    from training.evaluation.harness import evaluate

    policy = RllibPolicy(algo.get_module(UGV_POLICY), config.action_mode, config.scenario, deterministic=not config.eval_sample_actions)
    result = evaluate(config.scenario, policy, config.eval_episodes, config.eval_seed, random_scenarios=True,
                      action_mode=config.action_mode, max_cycles=config.eval_max_cycles,
                      **{k: v for k, v in policy.env_options.items() if k != "action_mode"})
    return headline(result.summary)


def train_rllib(config: RllibTrainConfig, out: str | Path, resume: bool = False, address: str | None = None) -> dict[str, Any]:
    """Train (or resume) the RLlib run ``config`` in folder ``out``; return the final manifest.

    Raises:
        moma_env.io.RunFolderError: ``out`` holds another kind of run or files that are not a run.
        ConfigError: ``out`` holds a run and ``resume`` is False; the configuration
            differs from the resumed run's (naming the field).
        agents.learned.TrainingDirError: ``resume`` without a loadable RLlib run in ``out``.
    """
    import ray

    from training.train.checkpoint import source_revision

    out = Path(out)
    start = start_run(out, resume, config, read_rllib_manifest, RESUMABLE_CHANGES, lambda folder: bool(_checkpoints(folder)))
    manifest, steps = start.manifest, start.steps
    for path in out.iterdir():  # temporaries of a killed save
        if _TEMPORARY.match(path.name):
            shutil.rmtree(path, ignore_errors=True)
    started = False
    if not ray.is_initialized():
        if address is None:
            ray.init(include_dashboard=False, log_to_driver=False)
        else:  # a cluster's own settings apply (a ray:// client accepts few options)
            ray.init(address=address)
        started = True
    algo = None
    try:
        algo = algorithm_config(config).build_algo()
        if manifest is not None:
            algo.restore_from_path(str((out / manifest["checkpoint"]).resolve()))
        extra = {"git": source_revision()}
        progress = RunProgress(out, config, start, f"{config.scenario}: RLlib PPO, {config.env_route}, seed {config.seed}")
        last_saved = last_eval = steps
        wall = progress.wall

        def evaluate_now() -> None:
            progress.evaluate(steps, lambda: _evaluate(algo, config))

        manifest_now = manifest
        while steps < config.steps:
            steps = env_steps(algo.train())
            if steps - last_saved >= config.checkpoint_every and steps < config.steps:
                manifest_now = _save(out, algo, config, steps, wall(), extra)
                last_saved = steps
            if config.eval_every > 0 and steps - last_eval >= config.eval_every and steps < config.steps:
                evaluate_now()
                last_eval = steps
        if config.eval_every > 0 and not progress.evaluated_at(steps):
            evaluate_now()
        if manifest_now is None or manifest_now["num_timesteps"] != steps:
            manifest_now = _save(out, algo, config, steps, wall(), extra)
        return manifest_now
    finally:
        if algo is not None:
            with contextlib.suppress(Exception):
                algo.stop()
        if started:
            ray.shutdown()

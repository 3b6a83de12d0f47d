"""Checkpoints of a training run: the output folder never holds a half-written model.

A checkpoint at ``S`` timesteps is the model zip ``model_<S>.zip`` (weights,
optimiser state, step counter), the ``VecNormalize`` statistics
``vecnormalize_<S>.pkl`` if the run normalises, the replay buffer
``replay_<S>.pkl`` of off-policy algorithms, and then, last, ``manifest.json``
naming them. Every file is written through :func:`moma_env.io.atomic_path`
(temporary file, fsync, rename), and the manifest is only replaced once its
files are complete, so the manifest always names a whole checkpoint; files of
older checkpoints are deleted after the new manifest is in place. A run killed
at any instant resumes from the checkpoint its manifest names
(:func:`agents.learned.read_manifest` checks it).
"""

from __future__ import annotations

import contextlib
import datetime
import re
import subprocess
from pathlib import Path
from typing import Any

from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm
from stable_baselines3.common.vec_env import VecNormalize

from agents.learned import MANIFEST, MANIFEST_FORMAT, read_manifest
from moma_env import ENV_VERSION
from moma_env.io import atomic_path, write_json
from training.provenance import library_versions
from training.train.config import ALGORITHMS, TrainConfig

__all__ = ["save_checkpoint", "read_manifest", "checkpoint_files", "remove_stale_temporaries", "source_revision"]

#: The repository holding this file (where ``git`` is asked for the commit).
_REPOSITORY = Path(__file__).resolve().parents[2]


def source_revision(repository: Path = _REPOSITORY) -> dict[str, Any]:
    """``{"commit": sha or None, "dirty": bool or None}`` of the code's git checkout
    (None where git or the repository is unavailable; ``dirty``: tracked files differ
    from the commit)."""

    def git(*args: str) -> str | None:
        try:
            done = subprocess.run(["git", "-C", str(repository), *args], capture_output=True, text=True, timeout=10, check=True)
        except (OSError, subprocess.SubprocessError):
            return None
        return done.stdout.strip()

    commit = git("rev-parse", "HEAD")
    status = git("status", "--porcelain", "--untracked-files=no") if commit else None
    return {"commit": commit or None, "dirty": None if status is None else bool(status)}

#: Files of checkpoints: ``<kind>_<timesteps>.<ext>``.
_CHECKPOINT_FILE = re.compile(r"^(model|vecnormalize|replay)_\d+\.(zip|pkl)$")


def checkpoint_files(out: Path) -> list[Path]:
    """Every checkpoint file in ``out`` (of any step)."""
    return sorted(p for p in Path(out).iterdir() if _CHECKPOINT_FILE.match(p.name))


def save_checkpoint(
    out: Path,
    model: BaseAlgorithm,
    config: TrainConfig,
    wall_time_s: float,
    extra: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Write a checkpoint of ``model`` at its current step into ``out``; return its manifest.

    Args:
        out: the run's folder (exists).
        model: the model; its env is the (possibly ``VecNormalize``-wrapped) training env.
        config: the run's configuration (stored in the manifest).
        wall_time_s: training wall time so far (s), over every session of the run.
        extra: more manifest entries (plain data), such as ``{"git": source_revision()}``.

    The manifest records :data:`moma_env.ENV_VERSION`, the version of the envs' observations,
    actions and rewards the model was trained on (a policy of another version is refused).
    """
    out = Path(out)
    steps = int(model.num_timesteps)
    names: dict[str, str | None] = {"model": f"model_{steps:012d}.zip", "vecnormalize": None, "replay_buffer": None}
    with atomic_path(out / names["model"]) as tmp:
        model.save(tmp)
    venv = model.get_env()
    if isinstance(venv, VecNormalize):
        names["vecnormalize"] = f"vecnormalize_{steps:012d}.pkl"
        with atomic_path(out / names["vecnormalize"]) as tmp:
            venv.save(str(tmp))
    if isinstance(model, OffPolicyAlgorithm) and model.replay_buffer is not None:
        names["replay_buffer"] = f"replay_{steps:012d}.pkl"
        with atomic_path(out / names["replay_buffer"]) as tmp:
            model.save_replay_buffer(tmp)
    manifest = {
        "format": MANIFEST_FORMAT,
        "env_version": ENV_VERSION,
        "num_timesteps": steps,
        "sb3_class": ALGORITHMS[config.algo],
        "route": config.route,
        **names,
        "config": config.to_dict(),
        "observation_shape": list(model.observation_space.shape),
        "action_space": repr(model.action_space),
        "wall_time_s": float(wall_time_s),
        "saved_at": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "versions": library_versions(),
        **(extra or {}),
    }
    write_json(out / MANIFEST, manifest)
    keep = {name for name in names.values() if name is not None}
    for path in checkpoint_files(out):
        if path.name not in keep:
            with contextlib.suppress(FileNotFoundError):
                path.unlink()
    return manifest


#: Temporaries of :func:`moma_env.io.atomic_path` left by a process killed mid-write.
_STALE_TEMPORARY = re.compile(r"^\.(model|vecnormalize|replay|manifest|evaluations|curves)_?[\w]*\.[0-9a-f]{12}\.tmp\.(zip|pkl|json|csv|png)$")


def remove_stale_temporaries(out: Path) -> list[Path]:
    """Delete half-written temporaries of a killed run in ``out``; return what was deleted."""
    removed = []
    for path in Path(out).iterdir():
        if _STALE_TEMPORARY.match(path.name):
            with contextlib.suppress(FileNotFoundError):
                path.unlink()
            removed.append(path)
    return removed

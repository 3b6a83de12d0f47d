"""Publish a trained run as a named policy: ``python -m training.train.publish RUN_DIR NAME``.

Copies the final checkpoint of the ``moma-env train`` folder ``RUN_DIR`` (the
model zip its manifest names and the ``VecNormalize`` statistics, if any; never
the replay buffer) into ``<policies root>/NAME/`` as ``model.zip`` and
``vecnormalize.pkl``, with a ``manifest.json``: the run's own manifest (configuration,
algorithm, route, timesteps, training wall time in s, env version, git commit of
the training code) with the new file names, their SHA-256, and ``published``:
the name, the time (UTC), the source folder (as given, like the command's ``--out``), the ``moma-env train`` command line
that remakes the run (and the settings it cannot express), the training seed,
timesteps and wall time, the git commit at publishing, and the last held-out
evaluation of ``evaluations.json``.

The root is the repository's ``policies/`` (``--root DIR`` or ``$MOMA_POLICIES_DIR``
to publish elsewhere; :func:`agents.learned.policies_root`). The folder appears
whole or not at all: it is assembled in a temporary folder beside it, loaded once
as a policy, and renamed into place. An existing policy of that name is refused
unless ``--replace``. A run of another env version, or older than env versions
(its manifest records none), is refused: its observations may not be this env's.

Loading: ``moma-env evaluate --policy NAME`` or ``agents.learned.load_published("NAME")``.
"""

from __future__ import annotations

import argparse
import contextlib
import datetime
import json
import os
import shlex
import shutil
import sys
import uuid
import zipfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from agents.learned import (
    MANIFEST,
    LearnedPolicy,
    TrainingDirError,
    file_sha256,
    policies_root,
    published_dir,
    read_manifest,
)
from moma_env import ENV_VERSION
from moma_env.config import ConfigError
from moma_env.io import write_json
from training.evaluation.policies import BUILTIN_POLICIES
from training.train.checkpoint import source_revision
from training.train.command import train_command
from training.train.config import TrainConfig
from training.train.curves import EVALUATIONS

__all__ = ["PublishError", "publish", "main", "MODEL_FILE", "STATS_FILE"]

#: File names in a published policy's folder.
MODEL_FILE = "model.zip"
STATS_FILE = "vecnormalize.pkl"


class PublishError(ValueError):
    """A run that cannot be published under that name (one-line message)."""


def _last_evaluation(run_dir: Path) -> dict[str, Any] | None:
    path = run_dir / EVALUATIONS
    try:
        records = json.loads(path.read_text(encoding="utf-8")).get("records") or []
    except (OSError, ValueError, AttributeError):
        return None
    return records[-1] if records else None


def _copy(source: Path, target: Path) -> str:
    """Copy ``source`` to ``target`` (flushed to disk); return its SHA-256."""
    shutil.copyfile(source, target)
    fd = os.open(target, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)
    return file_sha256(target)


def _published_manifest(run_dir: Path, name: str, manifest: dict[str, Any], checksums: dict[str, str]) -> dict[str, Any]:
    config = TrainConfig.from_dict(manifest["config"])
    argv, omitted = train_command(config, run_dir)
    out = dict(manifest)
    out |= {
        "model": MODEL_FILE,
        "vecnormalize": STATS_FILE if STATS_FILE in checksums else None,
        "replay_buffer": None,
        "sha256": checksums,
        "published": {
            "name": name,
            "published_at": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
            "source": run_dir.as_posix(),  # as given, like the command's --out: no path of the publisher's machine
            "source_model": manifest["model"],
            "command": shlex.join(argv),
            "command_omits": {field: manifest["config"][field] for field in omitted},
            "seed": config.seed,
            "num_timesteps": int(manifest["num_timesteps"]),
            "wall_time_s": float(manifest.get("wall_time_s", float("nan"))),
            "env_version": manifest["env_version"],
            "training_git": manifest.get("git"),
            "publishing_git": source_revision(),
            "last_evaluation": _last_evaluation(run_dir),
        },
    }
    return out


def publish(run_dir: str | Path, name: str, root: str | Path | None = None, replace: bool = False) -> Path:
    """Publish the final checkpoint of ``run_dir`` as policy ``name``; return its folder.

    Args:
        run_dir: a ``moma-env train --out`` folder.
        name: the policy's name (letters, digits, ``_``, ``-``; not a built-in policy's).
        root: the folder of published policies (default :func:`agents.learned.policies_root`).
        replace: replace a policy already published under ``name``.

    Raises:
        PublishError: a bad name, a missing root folder, a name already published
            (without ``replace``), a run without or of another env version, a model
            that does not load.
        agents.learned.TrainingDirError: ``run_dir`` holds no loadable run.
    """
    run_dir = Path(run_dir)
    try:
        target = published_dir(name, root)
    except TrainingDirError as err:
        raise PublishError(str(err)) from None
    if name in BUILTIN_POLICIES:
        raise PublishError(f"{name!r} is a built-in policy's name: choose another")
    folder = policies_root(root)
    if not folder.is_dir():
        raise PublishError(f"the folder of published policies {str(folder)!r} does not exist")
    if target.exists() and not replace:
        raise PublishError(f"a policy {name!r} is already published in {str(folder)!r}: pass --replace to replace it")
    manifest = read_manifest(run_dir)  # same env version, if it records one
    if manifest.get("env_version") is None:
        raise PublishError(f"{str(run_dir)!r} records no env_version (trained before env versions, env {ENV_VERSION!r} now): retrain it")
    model = run_dir / manifest["model"]
    if not zipfile.is_zipfile(model):
        raise PublishError(f"{str(model)!r} is not a whole zip (truncated?)")
    stage = folder / f".{name}.{uuid.uuid4().hex[:12]}.tmp"
    stage.mkdir()
    try:
        checksums = {MODEL_FILE: _copy(model, stage / MODEL_FILE)}
        if manifest.get("vecnormalize"):
            checksums[STATS_FILE] = _copy(run_dir / manifest["vecnormalize"], stage / STATS_FILE)
        write_json(stage / MANIFEST, _published_manifest(run_dir, name, manifest, checksums))
        try:
            LearnedPolicy.from_dir(stage)
        except TrainingDirError as err:
            raise PublishError(f"the run's model does not load: {err}") from None
        old = None
        if target.exists():
            old = folder / f".{name}.{uuid.uuid4().hex[:12]}.old"
            os.rename(target, old)
        os.rename(stage, target)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            shutil.rmtree(stage)
        raise
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)
    return target


def main(argv: Sequence[str] | None = None) -> int:
    """Command line (see the module docstring): exit 0, or 2 with one line on bad input."""
    parser = argparse.ArgumentParser(prog="python -m training.train.publish", description=__doc__.splitlines()[0])
    parser.add_argument("run", type=Path, help="folder of a moma-env train run")
    parser.add_argument("name", help="the policy's name (letters, digits, '_', '-'): policies/NAME/")
    parser.add_argument("--root", type=Path, default=None, help="folder of published policies (default $MOMA_POLICIES_DIR, else the repository's policies/)")
    parser.add_argument("--replace", action="store_true", help="replace a policy already published under NAME")
    args = parser.parse_args(argv)
    try:
        target = publish(args.run, args.name, args.root, args.replace)
    except (PublishError, TrainingDirError, ConfigError) as err:  # ConfigError: the manifest's configuration
        print(f"publish: {err}", file=sys.stderr)
        return 2
    manifest = json.loads((target / MANIFEST).read_text(encoding="utf-8"))
    print(f"published {args.name!r}: {target}\n"
          f"{manifest['config']['algo']} on {manifest['config']['scenario']}, {manifest['num_timesteps']} timesteps, "
          f"env version {manifest['env_version']}\nload: moma-env evaluate --policy {args.name} "
          f"(or agents.learned.load_published({args.name!r}))")
    return 0


if __name__ == "__main__":
    sys.exit(main())

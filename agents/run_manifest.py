"""The manifest of a training run made by another backend than Stable-Baselines3 (``--backend rllib | torchrl``).

Every backend writes ``manifest.json`` last, with its ``backend``, the ``checkpoint`` it
names, ``num_timesteps``, its ``config`` and the ``env_version`` it was trained on.
:func:`is_backend_run` tells which backend made a folder (reading the manifest only);
:func:`read_backend_manifest` reads and checks one, so that a run of another backend or
another env version is refused with one line.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from agents.learned import MANIFEST, TrainingDirError
from moma_env import ENV_VERSION
from moma_env.io import read_json_in

__all__ = ["is_backend_run", "read_backend_manifest", "MANIFEST_KEYS"]

#: The keys every backend's manifest has.
MANIFEST_KEYS = ("checkpoint", "num_timesteps", "config", "env_version")


def is_backend_run(directory: str | Path, backend: str) -> bool:
    """Whether ``directory`` holds a manifest of a ``backend`` run (False for any other or none)."""
    path = Path(directory) / MANIFEST
    try:
        manifest = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    return isinstance(manifest, dict) and manifest.get("backend") == backend


def read_backend_manifest(directory: str | Path, backend: str, label: str) -> tuple[Path, dict[str, Any]]:
    """``(path, manifest)`` of the ``backend`` run in ``directory`` (``label``: how messages name
    the backend, e.g. ``"an RLlib"``), checked: the backend, :data:`MANIFEST_KEYS`, the env version.
    The caller checks the checkpoint it names.

    Raises:
        TrainingDirError: no folder or manifest, another backend, a missing key, another env version.
    """
    path, manifest = read_json_in(Path(directory), MANIFEST, TrainingDirError, "a folder of a training run",
                                  f"not a finished checkpoint of moma-env train --backend {backend}")
    if not isinstance(manifest, dict) or manifest.get("backend") != backend:
        raise TrainingDirError(f"{str(path)!r} is not the manifest of {label} run")
    for key in MANIFEST_KEYS:
        if key not in manifest:
            raise TrainingDirError(f"{str(path)!r} lacks the key {key!r}")
    if manifest["env_version"] != ENV_VERSION:
        raise TrainingDirError(f"{str(path)!r} was trained on env version {manifest['env_version']!r}, this code's is {ENV_VERSION!r}: retrain it")
    return path, manifest

"""A teacher's demonstrations (:class:`Demonstrations`), and their file in a cloned run's
folder for another run to reuse.

Collecting a slow teacher's demonstrations (the lookahead's 100,000 rows: half an hour of
both cores) is most of a cloning's cost, and runs that differ only after it (their DAgger
rounds, epochs, or what follows) would collect the same rows again. A run cloned with
``--pretrain`` writes the rows its teacher demonstrated to :data:`DEMONSTRATIONS` in its
folder; ``moma-env train --demonstrations RUN`` fits those rows instead of collecting
them, when they are the rows the run would have collected: the same teacher, rows, seed,
copies, route, task and env options, and env version (:func:`collection_key`). The
result is the run that collects them, bit for bit.

DAgger from a finished run's weights (``--init-from`` with ``--dagger-teacher``) may fit
kept demonstrations of its labeller beside each round's rows (``--demonstrations`` too):
any such rows in the run's observation and action layout.

The file is a numpy ``.npz`` of the :class:`Demonstrations` arrays, its counts, and the
key as JSON, written whole or not at all.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from moma_env import ENV_VERSION
from moma_env.config import ConfigError
from moma_env.io import atomic_path
from training.train.config import TrainConfig

__all__ = ["DEMONSTRATIONS", "Demonstrations", "collection_key", "save_demonstrations", "read_demonstrations"]

#: The teacher's demonstrations of a cloned run, in its folder.
DEMONSTRATIONS = "demonstrations.npz"

#: The array fields of :class:`Demonstrations`, and its counts.
_ARRAYS = ("observations", "actions", "masks", "rewards", "episode_ends", "complete")
_COUNTS = ("stride", "episodes", "successes")


@dataclass(frozen=True)
class Demonstrations:
    """What a teacher did: ``stride`` rows per env step of every copy (on the shared
    route a row per UGV slot, a copy's robots in ``agents`` order, then the next
    copy's; on the centralised route a row per copy), then the next step's.

    Attributes:
        observations: ``(T, D)`` float32, the observation before the action (a robot's
            own, or the team's concatenated).
        actions: the teacher's switching actions as the slots' actions, int64: ``(T,)`` a
            robot's (shared route), ``(T, N)`` the team's side by side, or ``(T,)`` the
            one start that stands for them (``team_action="one_start"``).
        masks: ``(T, M)`` bool, the actions the motion rules would grant then (a robot's, the
            team's side by side, or the one-start team action's).
        rewards: ``(T,)`` float64, the team's reward of that step (rounded to float32, as the training envs give it).
        episode_ends: ``(T,)`` bool, the step ended the copy's episode (terminated or truncated).
        complete: ``(T,)`` bool, the row's episode ended within the collection (its
            discounted return is complete; the episodes still running at the end are cut).
        stride: rows per env step of every copy.
        episodes: episodes finished during the collection.
        successes: of those, the ones where every robot reached its goal.
    """

    observations: np.ndarray
    actions: np.ndarray
    masks: np.ndarray
    rewards: np.ndarray
    episode_ends: np.ndarray
    complete: np.ndarray
    stride: int
    episodes: int
    successes: int

    def __len__(self) -> int:
        return int(self.actions.shape[0])

    def __add__(self, other: "Demonstrations") -> "Demonstrations":
        """Both collections' rows, this one's first (same stride; each keeps its episodes)."""
        if other.stride != self.stride or other.observations.shape[1:] != self.observations.shape[1:]:
            raise ValueError(f"cannot join demonstrations of stride {self.stride} and {other.stride}")
        return Demonstrations(
            *(np.concatenate([getattr(self, f), getattr(other, f)]) for f in _ARRAYS),
            self.stride, self.episodes + other.episodes, self.successes + other.successes,
        )


#: The fields of :func:`collection_key` that DAgger from a run's weights requires of
#: kept demonstrations: rows of its labeller, of the same observations and actions.
_LAYOUT_FIELDS = ("teacher", "route", "scenario", "env_options", "env_version")


def collection_key(config: TrainConfig) -> dict[str, Any]:
    """What a run's teacher demonstrations depend on (JSON values)."""
    return {
        "teacher": config.pretrain,
        "rows": config.pretrain_rows,
        "seed": config.seed,
        "envs": config.envs,
        "route": config.route,
        "scenario": config.scenario,
        "env_options": json.loads(json.dumps(config.env_options)),
        "env_version": ENV_VERSION,
    }


def save_demonstrations(folder: Path, demonstrations: Demonstrations, config: TrainConfig) -> Path:
    """Write ``demonstrations`` (collected for ``config``) to ``folder``/:data:`DEMONSTRATIONS`, atomically."""
    path = Path(folder) / DEMONSTRATIONS
    arrays = {name: getattr(demonstrations, name) for name in _ARRAYS}
    counts = {name: np.int64(getattr(demonstrations, name)) for name in _COUNTS}
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:  # a file object: np.savez would add ".npz" to the temporary name
            np.savez(f, key=np.array(json.dumps(collection_key(config), sort_keys=True)), **arrays, **counts)
    return path


def read_demonstrations(config: TrainConfig) -> Demonstrations:
    """The demonstrations kept in ``config.demonstrations`` (a run folder) for a run of ``config``:
    for a cloning (``config.pretrain``) the rows it would collect; for DAgger from a run's
    weights rows of its ``dagger_teacher`` on the same route, task, env options and env
    version, however many and from whichever seed.

    Raises:
        ConfigError (field ``demonstrations``): the folder has no readable
            :data:`DEMONSTRATIONS`, or its rows were collected with other settings
            (naming the first that differs, the file's value and the run's).
    """
    path = Path(config.demonstrations) / DEMONSTRATIONS
    try:
        with np.load(path, allow_pickle=False) as data:
            key = json.loads(str(data["key"]))
            fields = {name: data[name] for name in _ARRAYS}
            counts = {name: int(data[name]) for name in _COUNTS}
    except (OSError, KeyError, ValueError) as error:
        raise ConfigError("demonstrations", f"cannot read a run's demonstrations from {str(path)!r}: {type(error).__name__}: {error}") from None
    wanted = collection_key(config)
    if config.pretrain is None:  # DAgger from a run's weights: any rows of its labeller, in the run's layout
        wanted = {name: wanted[name] for name in _LAYOUT_FIELDS} | {"teacher": config.dagger_teacher}
    for name, value in wanted.items():
        if key.get(name) != value:
            raise ConfigError(
                "demonstrations", f"{str(path)!r} holds rows collected with {name}={key.get(name)!r}; this run needs {name}={value!r}"
            )
    return Demonstrations(**fields, **counts)

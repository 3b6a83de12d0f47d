"""Whether two trained runs are the same policy, bit for bit; retraining a published one to check it.

::

    python -m training.train.reproduce RUN_A RUN_B
    python -m training.train.reproduce NAME --retrain --out DIR

``RUN_A`` and ``RUN_B`` are ``moma-env train`` folders or names of published policies
(``policies/NAME``, as ``moma-env evaluate --policy`` takes them). The comparison reads
each run's final checkpoint, the one its manifest names: every tensor of the policy's
state dict (SB3 zips keep it as ``policy.pth``) must be equal in shape, dtype and every
bit, and so must the ``VecNormalize`` statistics (the running means,
variances and counts of observations and returns, and the clipping settings). The
timesteps, the algorithm and the route must agree. Settings of the two manifests that
differ, and library versions both record that differ, are listed too (a setting that one
manifest lacks, added to ``TrainConfig`` after that run was made, counts as its default);
settings that cannot change the weights (the
progress bar, the worker processes, the checkpoint interval) are not.

``--retrain`` runs the ``moma-env train`` command of the settings a published policy's
manifest records (``config``; the command it records, ``published.command``, with every
setting spelt out that differs from today's defaults) with ``--out DIR`` instead of the
original folder and without the progress bar, then compares ``DIR`` with the policy. Training is
deterministic for a configuration, a torch thread count, a machine and the library
versions (docs/training.md, "Determinism"), so on the same kind of machine with the
versions the manifest records (``versions``) a difference means the code behaves
otherwise than at the commit the manifest names. A ``DIR`` that already holds the
finished run is compared without training again; one holding an interrupted run's checkpoint
is refused (resumed, its envs would restart at new layouts: not the uninterrupted run).

Exit status: 0 the same policy bit for bit, 1 a difference (each printed), 2 bad input
(one line: an unknown name or folder, a damaged checkpoint, a policy whose command
cannot remake it).
"""

from __future__ import annotations

import argparse
import dataclasses
import io
import pickle
import shlex
import sys
import zipfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from agents.learned import MANIFEST, TrainingDirError, published_dir, published_names, read_manifest, read_published
from training.provenance import differing_versions
from training.train.command import train_command
from training.train.config import TrainConfig

__all__ = ["Comparison", "compare_runs", "run_folder", "retrain_argv", "retrain_published", "main"]

#: TrainConfig fields that do not change what a run learns (not listed as differences).
RESULT_FREE_FIELDS = frozenset({"progress_bar", "workers", "subproc", "checkpoint_every"})

#: The SB3 zip member holding the policy's state dict.
POLICY_MEMBER = "policy.pth"


@dataclass
class Comparison:
    """What differs between two runs' final checkpoints.

    Attributes:
        tensors: how many tensors of the policy's state dict were compared.
        tensor_differences: ``(name, what)`` of every tensor that differs (missing on one
            side, another shape or dtype, or the largest absolute difference).
        statistics_differences: ``(name, what)`` of every normalisation statistic that
            differs (or ``"missing"`` when one run has statistics and the other none).
        run_differences: ``(key, a, b)``: timesteps, algorithm, route, a setting of the
            two manifests (settings in :data:`RESULT_FREE_FIELDS` left out) or a library
            version both record (``versions.numpy``, ...) that differs.
    """

    tensors: int = 0
    tensor_differences: list[tuple[str, str]] = field(default_factory=list)
    statistics_differences: list[tuple[str, str]] = field(default_factory=list)
    run_differences: list[tuple[str, Any, Any]] = field(default_factory=list)

    @property
    def identical(self) -> bool:
        """Whether the two runs are the same policy bit for bit (weights, statistics, timesteps, algorithm, route)."""
        weights_differ = self.tensor_differences or self.statistics_differences
        return not weights_differ and not any(key in ("num_timesteps", "sb3_class", "route") for key, _, _ in self.run_differences)

    def report(self, a: str, b: str) -> str:
        """A readable account of the comparison of run ``a`` with run ``b``."""
        lines = []
        if self.identical:
            lines.append(f"the same policy bit for bit: {a} and {b} ({self.tensors} tensors and the normalisation statistics equal)")
        else:
            lines.append(f"different policies: {a} and {b}")
        for name, what in self.tensor_differences:
            lines.append(f"  tensor {name}: {what}")
        for name, what in self.statistics_differences:
            lines.append(f"  normalisation {name}: {what}")
        for key, value_a, value_b in self.run_differences:
            lines.append(f"  {key}: {value_a!r} against {value_b!r}")
        return "\n".join(lines)


def run_folder(spec: str | Path) -> Path:
    """The folder of a run: a published policy's name (its checksums checked), else a training folder.

    Raises:
        TrainingDirError: neither (listing the published names), a name that is both
            a published policy and a folder here (write ``./NAME`` for the folder), a
            manifest that does not check out.
    """
    text = str(spec)
    path = Path(text)
    if "/" not in text and "\\" not in text:
        try:
            published = published_dir(text)
        except TrainingDirError:
            published = None
        if published is not None and (published / MANIFEST).is_file():
            if path.exists():
                raise TrainingDirError(
                    f"{text!r} is both a published policy ({str(published)!r}) and a folder here: write ./{text} for the folder"
                )
            read_published(text)
            return published
    if not path.is_dir():
        known = ", ".join(published_names()) or "none"
        raise TrainingDirError(f"{text!r} is neither a published policy (published: {known}) nor the folder of a training run")
    read_manifest(path)
    return path


def _policy_tensors(folder: Path, manifest: Mapping[str, Any]) -> dict[str, np.ndarray]:
    """The policy's state dict kept in the run's final model zip, each tensor as a numpy array."""
    import torch

    path = folder / manifest["model"]
    try:
        with zipfile.ZipFile(path) as archive:
            data = archive.read(POLICY_MEMBER)
        state = torch.load(io.BytesIO(data), map_location="cpu", weights_only=True)
    except Exception as err:  # a damaged zip fails in zipfile or torch, each with its own error
        raise TrainingDirError(f"cannot read the policy's weights in {str(path)!r} (damaged or not an SB3 zip): {err}") from None
    if not isinstance(state, dict) or not all(isinstance(t, torch.Tensor) for t in state.values()):
        raise TrainingDirError(f"{str(path)!r}: {POLICY_MEMBER} holds a {type(state).__name__}, not a state dict of tensors")
    return {name: tensor.detach().cpu().numpy() for name, tensor in state.items()}


def _statistics(folder: Path, manifest: Mapping[str, Any]) -> dict[str, np.ndarray] | None:
    """The run's ``VecNormalize`` statistics as arrays by name, None without normalisation."""
    name = manifest.get("vecnormalize")
    if not name:
        return None
    path = folder / name
    try:
        with open(path, "rb") as f:
            stats = pickle.load(f)
    except Exception as err:  # truncated pickles raise EOFError, UnpicklingError, ...
        raise TrainingDirError(f"cannot read the normalisation statistics {str(path)!r}: {err}") from None
    values: dict[str, np.ndarray] = {}
    for group in ("obs_rms", "ret_rms"):
        rms = getattr(stats, group, None)
        if rms is None:
            continue
        for part in ("mean", "var", "count"):
            values[f"{group}.{part}"] = np.asarray(getattr(rms, part))
    for setting in ("clip_obs", "clip_reward", "gamma", "epsilon", "norm_obs", "norm_reward"):
        if hasattr(stats, setting):
            values[setting] = np.asarray(getattr(stats, setting))
    if not values:
        raise TrainingDirError(f"{str(path)!r} holds a pickled {type(stats).__name__}, not SB3 VecNormalize statistics")
    return values


def _array_difference(a: np.ndarray, b: np.ndarray) -> str | None:
    """None if ``a`` and ``b`` are equal in shape, dtype and every bit, else what differs."""
    if a.shape != b.shape:
        return f"shape {a.shape} against {b.shape}"
    if a.dtype != b.dtype:
        return f"dtype {a.dtype} against {b.dtype}"
    if a.tobytes() == b.tobytes():
        return None
    if a.dtype.kind in "fc":
        largest = float(np.max(np.abs(a.astype(np.float64) - b.astype(np.float64))))
        return f"largest absolute difference {largest:.3g}"
    return "values differ"


def _differences(a: Mapping[str, np.ndarray], b: Mapping[str, np.ndarray]) -> list[tuple[str, str]]:
    """``(name, what)`` of every array of ``a`` or ``b`` missing on one side or differing (:func:`_array_difference`)."""
    found = []
    for name in sorted(set(a) | set(b)):
        if name not in a or name not in b:
            found.append((name, "missing in " + ("the first" if name not in a else "the second")))
        else:
            what = _array_difference(a[name], b[name])
            if what is not None:
                found.append((name, what))
    return found


def compare_runs(a: str | Path, b: str | Path) -> Comparison:
    """Compare the final checkpoints of runs ``a`` and ``b`` (folders or published names; see the module docstring).

    Raises:
        TrainingDirError: a run that cannot be found or read.
    """
    folders = [run_folder(a), run_folder(b)]
    manifests = [read_manifest(f) for f in folders]
    result = Comparison()
    for key in ("num_timesteps", "sb3_class", "route"):
        if manifests[0][key] != manifests[1][key]:
            result.run_differences.append((key, manifests[0][key], manifests[1][key]))
    # A setting added to TrainConfig after a run was made is missing from its manifest: it had the default.
    defaults = {f.name: f.default for f in dataclasses.fields(TrainConfig) if f.default is not dataclasses.MISSING}
    configs = [m["config"] for m in manifests]
    for key in sorted(set(configs[0]) | set(configs[1])):
        values = [config[key] if key in config else defaults.get(key) for config in configs]
        if key not in RESULT_FREE_FIELDS and values[0] != values[1]:
            result.run_differences.append((f"config.{key}", values[0], values[1]))

    for key, value_a, value_b in differing_versions(manifests[0].get("versions"), manifests[1].get("versions")):
        result.run_differences.append((f"versions.{key}", value_a, value_b))  # an older manifest records fewer

    tensors = [_policy_tensors(f, m) for f, m in zip(folders, manifests)]
    result.tensors = len(set(tensors[0]) & set(tensors[1]))
    result.tensor_differences = _differences(*tensors)
    statistics = [_statistics(f, m) for f, m in zip(folders, manifests)]
    if (statistics[0] is None) != (statistics[1] is None):
        result.statistics_differences.append(("statistics", "missing in " + ("the first" if statistics[0] is None else "the second")))
    elif statistics[0] is not None and statistics[1] is not None:
        result.statistics_differences = _differences(*statistics)
    return result


def retrain_argv(name: str, out: str | Path) -> list[str]:
    """The ``moma-env train`` arguments (after ``moma-env``) that remake published policy ``name`` into ``out``:
    the command of the settings its manifest records (``config``), every setting that differs
    from today's defaults spelt out, so that a default changed since (``--batch-size`` on
    2026-12-06) does not change the run.

    Raises:
        TrainingDirError: an unknown name, or a policy whose manifest records no command or
            settings its command cannot express (a run made from Python).
    """
    manifest = read_published(name)
    published = manifest.get("published")
    command = published.get("command") if isinstance(published, dict) else None
    if not isinstance(command, str) or not command:
        raise TrainingDirError(f"published policy {name!r} records no moma-env train command: it cannot be retrained from its manifest")
    omits = published.get("command_omits") or {}
    if omits:
        raise TrainingDirError(
            f"published policy {name!r} was trained with settings its command cannot express ({', '.join(sorted(omits))}): "
            "retrain it from Python with its manifest's config"
        )
    recorded = shlex.split(command)
    if recorded[:2] != ["moma-env", "train"] or "--out" not in recorded:
        raise TrainingDirError(f"published policy {name!r} records {command!r}, not a moma-env train command with --out")
    argv, _ = train_command(TrainConfig.from_dict(manifest["config"]), out)
    argv = argv[1:]
    if "--no-progress" not in argv:
        argv.append("--no-progress")
    return argv


def retrain_published(name: str, out: str | Path) -> Comparison:
    """Run published policy ``name``'s recorded command into ``out`` (unless ``out`` holds the
    finished run already), then :func:`compare_runs` ``out`` with the policy.

    Raises:
        TrainingDirError: see :func:`retrain_argv` and :func:`compare_runs`; the training
            command failing (its exit status); ``out`` holding a run of other timesteps (the
            checkpoint of an interrupted run, which resumed would not be the uninterrupted run).
    """
    argv = retrain_argv(name, out)
    out = Path(out)
    if (out / MANIFEST).is_file():
        held, wanted = read_manifest(out)["num_timesteps"], read_published(name)["num_timesteps"]
        if held != wanted:  # a checkpoint of an interrupted run: resuming it would not give the uninterrupted run
            raise TrainingDirError(
                f"{str(out)!r} holds a run of {held} timesteps, not the {wanted} of {name!r}: a resumed run is not the "
                "uninterrupted one, so retrain into an empty folder"
            )
    else:
        from training.cli import main as cli_main

        print("moma-env " + shlex.join(argv), flush=True)
        status = cli_main(argv)
        if status != 0:
            raise TrainingDirError(f"the training command of {name!r} ended with exit status {status}")
    return compare_runs(out, name)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m training.train.reproduce",
        description="Whether two trained runs (folders or published names) are the same policy bit for bit; "
                    "with --retrain, train a published policy again from its manifest's command and check it.",
    )
    parser.add_argument("runs", nargs="+", metavar="RUN",
                        help="two runs to compare (training folders or published names), or with --retrain one published name")
    parser.add_argument("--retrain", action="store_true",
                        help="run the published policy's recorded moma-env train command into --out, then compare "
                             "(default: compare two existing runs)")
    parser.add_argument("--out", type=Path, default=None,
                        help="with --retrain, the folder of the new run (required with --retrain; a folder holding the "
                             "finished run is compared without training again)")
    args = parser.parse_args(argv)
    try:
        if args.retrain:
            if len(args.runs) != 1 or args.out is None:
                parser.error("--retrain takes one published name and --out DIR")
            comparison = retrain_published(args.runs[0], args.out)
            names = (str(args.out), args.runs[0])
        else:
            if len(args.runs) != 2 or args.out is not None:
                parser.error("give two runs to compare (--out only with --retrain)")
            comparison = compare_runs(*args.runs)
            names = (args.runs[0], args.runs[1])
    except TrainingDirError as err:
        print(f"python -m training.train.reproduce: {err}", file=sys.stderr)
        return 2
    print(comparison.report(*names))
    return 0 if comparison.identical else 1


if __name__ == "__main__":
    sys.exit(main())

"""Reproducibility fingerprints: a hash of every bit a seeded environment run returns.

A change meant to be a pure speed-up (or a refactor) must not change one bit of
any seeded run, or every published number (the README's experiment, evaluate and
training tables) has to be made again. This tool hashes seeded runs of every
configuration, action mode and camera backend: per step the observations,
rewards, terminations, truncations and infos (the exact bits of every float),
``state()``, the estimator's estimates and every device's localisation error,
and at the end the estimator's event log; and seeded runs of the paper's
experiments (the square and the line, geometric and rendered with the visual
odometry): every trajectory, metric, waypoint and switch time of the run
record. Run it before and after a change::

    python -m training.fingerprint --out before.json      # on the old code
    python -m training.fingerprint --check before.json    # on the new code: exit 1 on any difference

A fingerprint is a property of the code *and* of the machine's floating point
(BLAS kernels, FMA): compare fingerprints made on one machine only. The file records the
machine (:func:`training.provenance.library_versions`: processor, Python, the numerical
libraries' versions), and ``--check`` names what of it differs when a case differs.
"""

from __future__ import annotations

import argparse
import dataclasses
import enum
import hashlib
import json
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from training.provenance import differing_versions, library_versions

__all__ = ["CASES", "Case", "fingerprint", "main", "serialise"]


#: Cases named after these are runs of the paper's experiments, not env configurations.
_EXPERIMENTS = ("square", "line")


class Case:
    """One seeded run: env configuration ``name`` (``parallel_env(name, **kwargs)``) for
    ``steps`` random-action steps, or, when ``name`` is ``"square"`` or ``"line"``, one
    whole run of that experiment (``SquareConfig(**kwargs)``, ``steps`` None; a
    ``preset=NAME`` keyword applies that experiment preset to it)."""

    def __init__(self, name: str, steps: int | None = None, **kwargs) -> None:
        if (name in _EXPERIMENTS) != (steps is None):
            raise ValueError(f"give steps for an env configuration and none for an experiment, got {name!r} with steps={steps!r}")
        self.name, self.steps, self.kwargs = name, steps, kwargs

    @property
    def is_experiment(self) -> bool:
        """True for a run of a paper experiment."""
        return self.steps is None

    @property
    def label(self) -> str:
        """The name and the keyword arguments, e.g. ``top_observer action_mode=velocity``
        (``experiment square ...`` for an experiment)."""
        words = (["experiment"] if self.is_experiment else []) + [self.name]
        return " ".join(words + [f"{k}={v}" for k, v in sorted(self.kwargs.items())])


def _cases() -> tuple[Case, ...]:
    cases = []
    for name in ("top_observer", "caterpillar", "caterpillar_sled", "caterpillar_multi"):
        for mode in ("switching", "velocity"):
            cases.append(Case(name, 600, action_mode=mode, max_cycles=250))
    cases += [
        Case("top_observer", 600, action_mode="velocity", observer_agent=False, max_cycles=250),
        Case("top_observer", 600, action_mode="switching", observer_agent=True, max_cycles=250),
        Case("top_observer", 300, action_mode="switching", random_scenarios=True, max_cycles=150),
        Case("caterpillar_sled", 300, action_mode="switching", random_scenarios=True, max_cycles=150),
        Case("caterpillar_multi", 300, action_mode="switching", random_scenarios=True, max_cycles=150),
        # The rendered camera: default image, plain floor, the analogue link (interlacing), a pixel observation.
        Case("top_observer", 120, camera_backend="rendered", max_cycles=100),
        Case("top_observer", 60, camera_backend="rendered", floor={"textured": ()}, max_cycles=100),
        Case(
            "top_observer", 60, camera_backend="rendered", max_cycles=100,
            render={"interlaced": True, "blur_sigma_px": 1.0, "noise_std": 6.0},
        ),
        Case("top_observer", 40, camera_backend="rendered", observer_agent=True, observer_image=(96, 80), max_cycles=100),
        Case("caterpillar", 60, camera_backend="rendered", max_cycles=100),
        # The paper's experiments (the README's tables): geometric runs whole, rendered ones cut short.
        Case("square"),
        Case("line"),
        Case("square", camera_backend="rendered", max_time_s=45.0),
        # The paper preset (the authors' calibrated lens, the PAL link, the lab floor's grain), cut short.
        Case("square", preset="paper", max_time_s=45.0),
    ]
    return tuple(cases)


#: The runs hashed by default.
CASES = _cases()


def serialise(value: object, out: list[str]) -> None:
    """Append an exact text form of ``value`` to ``out`` (floats as their hex bits, arrays
    with dtype, shape and bytes; containers item by item, sets sorted)."""
    if isinstance(value, np.ndarray):
        out += ["ndarray", str(value.dtype), str(value.shape), np.ascontiguousarray(value).tobytes().hex()]
    elif isinstance(value, enum.Enum):
        out.append(repr(value))
    elif dataclasses.is_dataclass(value) and not isinstance(value, type):
        out.append(type(value).__name__)
        for field in dataclasses.fields(value):
            out.append(field.name)
            serialise(getattr(value, field.name), out)
        out.append("end")
    elif isinstance(value, (bool, np.bool_, int, np.integer, str, type(None))):
        out += [type(value).__name__, repr(value)]
    elif isinstance(value, (float, np.floating)):
        out += ["float", float(value).hex()]
    elif isinstance(value, dict):
        out.append("dict")
        for key, item in value.items():
            serialise(key, out)
            serialise(item, out)
        out.append("end")
    elif isinstance(value, (list, tuple, set, frozenset)):
        out.append(type(value).__name__)
        for item in sorted(value, key=repr) if isinstance(value, (set, frozenset)) else value:
            serialise(item, out)
        out.append("end")
    else:
        raise TypeError(f"cannot fingerprint a {type(value).__name__}: {value!r}")


def fingerprint(case: Case, seed: int = 0) -> dict:
    """Run ``case`` from ``seed``: its hash (sha256 hex) and episode count (1 for an experiment).

    An env case runs random actions; every 37th step the action of the first
    live agent is left out (the env's default for a missing action).
    """
    if case.is_experiment:
        return _fingerprint_experiment(case, seed)
    from moma_env.env.factory import parallel_env

    env = parallel_env(case.name, **case.kwargs)
    digest = hashlib.sha256()

    def feed(value: object) -> None:
        out: list[str] = []
        serialise(value, out)
        digest.update("|".join(out).encode())

    episodes = 1
    observations, infos = env.reset(seed=seed)
    feed((observations, infos, env.state()))
    for agent in env.possible_agents:
        env.action_space(agent).seed(seed)
    for step in range(case.steps):
        if not env.agents:
            observations, infos = env.reset()
            feed((observations, infos, env.state()))
            episodes += 1
        actions = {agent: env.action_space(agent).sample() for agent in env.agents}
        if step % 37 == 5 and len(actions) > 1:
            actions.pop(next(iter(actions)))
        feed(env.step(actions))
        feed(env.state())
        estimates = env.frame.estimates
        feed({k: (e.T_w_b, e.status, e.phase, e.last_fresh_time, e.n_window) for k, e in estimates.items()})
        feed([env.localisation_error(device) for device in env.devices])
    feed([repr(event) for event in env.estimator.events])
    env.close()
    return {"case": case.label, "steps": case.steps, "episodes": episodes, "sha256": digest.hexdigest()}


def _fingerprint_experiment(case: Case, seed: int) -> dict:
    """Hash of the whole record (:class:`LeapfrogRun`) of one seeded experiment run."""
    if case.name == "square":
        from training.experiments.square import SquareConfig as config_class, run_square as run
    else:
        from training.experiments.line import LineConfig as config_class, run_line as run
    kwargs = dict(case.kwargs)
    preset = kwargs.pop("preset", None)
    config = config_class(**kwargs)
    if preset is not None:
        from training.experiments.presets import get_preset

        config = get_preset(preset).apply(config)
    record = run(config, seed)
    out: list[str] = []
    serialise(record, out)
    digest = hashlib.sha256("|".join(out).encode()).hexdigest()
    return {"case": case.label, "steps": case.steps, "episodes": 1, "sha256": digest}


def _compare(found: Sequence[dict], reference: Sequence[dict]) -> list[str]:
    """Lines naming every case whose hash differs from (or is missing in) ``reference``."""
    known = {r["case"]: r for r in reference}
    problems = []
    for row in found:
        ref = known.get(row["case"])
        if ref is None:
            problems.append(f"not in the reference: {row['case']}")
        elif (ref["steps"], ref["sha256"]) != (row["steps"], row["sha256"]):
            problems.append(f"DIFFERS: {row['case']}")
    return problems


def main(argv: Sequence[str] | None = None, report: Callable[[str], None] = print) -> int:
    """Command line: fingerprint :data:`CASES` (or those whose label contains ``--only``)."""
    parser = argparse.ArgumentParser(prog="python -m training.fingerprint", description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, help="write the fingerprints to this JSON file")
    parser.add_argument("--check", type=Path, help="compare with a JSON file from --out; exit 1 on any difference")
    parser.add_argument("--only", default="", help="only the cases whose label contains this text")
    parser.add_argument("--seed", type=int, default=0, help="seed of every run (default 0)")
    args = parser.parse_args(argv)
    reference = None
    reference_machine = None
    if args.check is not None:
        try:
            stored = json.loads(args.check.read_text())
            reference = stored["fingerprints"]
        except (OSError, ValueError, KeyError, TypeError) as error:
            parser.error(f"--check {args.check}: not a fingerprint file ({error})")
        reference_machine = stored.get("machine")
    cases = [case for case in CASES if args.only in case.label]
    if not cases:
        parser.error(f"--only {args.only!r} matches no case")
    rows = []
    for case in cases:
        start = time.perf_counter()
        rows.append(fingerprint(case, args.seed))
        report(f"{rows[-1]['sha256'][:16]}  {rows[-1]['episodes']:>2} ep  {time.perf_counter() - start:6.1f} s  {case.label}")
    if args.out is not None:
        from moma_env.io import write_json

        write_json(args.out, {"seed": args.seed, "machine": library_versions(), "fingerprints": rows})
    if reference is not None:
        problems = _compare(rows, reference)
        for line in problems:
            report(line)
        if problems:  # a difference the machine may explain rather than the code
            for key, theirs, ours in differing_versions(reference_machine, library_versions()):
                report(f"note: the reference was made with {key} {theirs!r}, this machine has {ours!r}")
        report(f"{len(rows) - len(problems)} of {len(rows)} cases identical to {args.check}")
        return 1 if problems else 0
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""The estimators side by side on the same runs of the paper's square and line.

``moma-env experiment compare --estimators moma,fused,graph,ekf [--runs N] [--observers KINDS]``

For every experiment (square, line), camera (geometric; rendered with
``--cameras geometric,rendered``) and estimator (``moma_env.estimator.registry``
names), ``N`` runs with seeds ``seed .. seed + N - 1`` of the experiment under
the ``paper`` preset (by default) are run with the estimator in place of MOMA:
the same world, the same camera noise draws and the same schedule for every
estimator (the schedule reads the estimates, so trajectories part where the
estimates do). Per estimator the table gives, for the main robot:

* ME_f and ME (cm): the mean over runs of the final error and of the mean
  error at the switches (``moma_env.metrics``), and the final error in % of the
  path;
* ANEES of position (2 dof planar, 3 dof 6-DoF) and of heading (1 dof): the
  mean over time steps of the NEES averaged over runs
  (:func:`training.experiments.consistency.evaluate_runs`), with its nominal
  chi-square bounds (95 %) and the fraction of steps inside them;
* time per update (ms): wall time of the estimator's ``update`` (and its
  ``odometry`` calls for the EKF) per camera frame, measured around the calls.

With ``--observers quadcopter,handheld`` (two or more observer kinds) every
case is run once per observer set: each observer alone, hovering where it
hovers in the team (``LeapfrogConfig.observer_offsets``' default: 0.5 m apart,
centred on the pair), then all of them at once; the ``observers`` column names
the set (``quadcopter@-0.25``, ..., ``quadcopter@-0.25+handheld@+0.25``).
Without it, the experiment's own single observer (``observers`` is its kind).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from moma_env.estimator import EstimatorConfig
from moma_env.estimator.registry import ESTIMATORS, localiser_factory
from moma_env.metrics import aggregate
from moma_env.metrics.consistency import POSITION_3D, POSITION_PLANAR
from moma_env.sim import OdometryConsumer
from training.experiments.consistency import evaluate_runs
from training.experiments.leapfrog_run import LeapfrogConfig, run_leapfrog
from training.experiments.line import LineConfig
from training.experiments.presets import PRESETS, get_preset
from training.experiments.square import SquareConfig

__all__ = [
    "EXPERIMENTS",
    "CAMERAS",
    "TimedFactory",
    "CompareRow",
    "ObserverSet",
    "observer_sets",
    "compare_config",
    "compare_case",
    "run_compare",
    "format_table",
]

#: The experiments compared, by name.
EXPERIMENTS: dict[str, type[LeapfrogConfig]] = {"square": SquareConfig, "line": LineConfig}
#: The observer cameras.
CAMERAS = ("geometric", "rendered")


class _Timed:
    """A localiser that adds the wall time of its ``update`` calls to ``durations``."""

    def __init__(self, inner, durations: list[float]):
        self._inner = inner
        self._durations = durations
        self._pending = 0.0

    def add_robot(self, name, **kwargs) -> None:
        self._inner.add_robot(name, **kwargs)

    def set_static(self, name, static, time) -> None:
        self._inner.set_static(name, static, time)

    def update(self, t, detections) -> None:
        start = time.perf_counter()
        self._inner.update(t, detections)
        self._durations.append(self._pending + time.perf_counter() - start)
        self._pending = 0.0

    def estimates(self):
        return self._inner.estimates()

    def estimate(self, name):
        return self._inner.estimate(name)

    def window_ready(self, name) -> bool:
        return self._inner.window_ready(name)


class _TimedOdometry(_Timed):
    """:class:`_Timed` for a localiser that takes odometry (its calls count towards the next update)."""

    def odometry(self, name, increment, covariance, t) -> None:
        start = time.perf_counter()
        self._inner.odometry(name, increment, covariance, t)
        self._pending += time.perf_counter() - start


class TimedFactory:
    """The localiser factory of estimator ``name``, whose localisers record the wall time (s) of
    every update in :attr:`durations` (a run in this process)."""

    def __init__(self, name: str):
        self.name = name
        self._factory = localiser_factory(name)
        self.durations: list[float] = []

    def __call__(self, config: EstimatorConfig):
        inner = self._factory(config)
        return (_TimedOdometry if isinstance(inner, OdometryConsumer) else _Timed)(inner, self.durations)


@dataclass(frozen=True)
class ObserverSet:
    """Observers of a case: their kinds and lateral offsets (m, ``LeapfrogConfig.observer_offsets``);
    no kinds: the experiment's own observer."""

    kinds: tuple[str, ...] = ()
    offsets: tuple[float, ...] = ()

    @property
    def label(self) -> str:
        """``kind@offset`` joined by ``+`` (the experiment's kind when there are none)."""
        return "+".join(f"{kind}@{offset:+.2f}" for kind, offset in zip(self.kinds, self.offsets))


def observer_sets(kinds: Sequence[str] | None) -> list[ObserverSet]:
    """The observer sets ``--observers kinds`` compares: each observer alone where it hovers
    in the team, then all together; ``[ObserverSet()]`` (the experiment's own) for None or one kind."""
    if not kinds:
        return [ObserverSet()]
    kinds = tuple(kinds)
    if len(kinds) == 1:
        return [ObserverSet(kinds, (0.0,))]
    offsets = LeapfrogConfig(observer=kinds).resolved_observer_offsets
    alone = [ObserverSet((kind,), (offset,)) for kind, offset in zip(kinds, offsets)]
    return [*alone, ObserverSet(kinds, offsets)]


@dataclass(frozen=True)
class CompareRow:
    """One estimator on one experiment and camera, over ``n_runs`` runs.

    Errors in metres, times in seconds; NaN where nothing was measured.
    """

    experiment: str
    camera: str
    estimator: str
    observers: str
    n_runs: int
    n_completed: int
    final_error: float
    final_error_std: float
    mean_error: float
    final_error_pct_path: float
    position_dof: int
    position_anees: float
    position_inside: float
    heading_anees: float
    heading_inside: float
    anees_bounds: tuple[float, float]
    heading_bounds: tuple[float, float]
    time_per_update_s: float
    n_updates: int

    @property
    def consistent(self) -> bool:
        """Both mean ANEES inside their nominal 95 % bounds."""
        lo, hi = self.anees_bounds
        hlo, hhi = self.heading_bounds
        return lo <= self.position_anees <= hi and hlo <= self.heading_anees <= hhi


def compare_config(experiment: str, camera: str, estimator: str, preset: str = "paper",
                   max_time_s: float | None = None, observers: ObserverSet = ObserverSet()) -> LeapfrogConfig:
    """The configuration of one case (ConfigError / ValueError naming a bad argument)."""
    if experiment not in EXPERIMENTS:
        raise ValueError(f"experiments: unknown experiment {experiment!r}; known: {', '.join(EXPERIMENTS)}")
    if camera not in CAMERAS:
        raise ValueError(f"cameras: unknown camera {camera!r}; known: {', '.join(CAMERAS)}")
    placed = {"observer": observers.kinds, "observer_offsets": observers.offsets} if observers.kinds else {}
    config = get_preset(preset).apply(EXPERIMENTS[experiment](localiser=estimator, **placed), camera_backend=camera)
    if max_time_s is not None:
        config = dataclasses.replace(config, max_time_s=max_time_s)
    return config


def compare_case(experiment: str, camera: str, estimator: str, n_runs: int, seed: int, preset: str = "paper",
                 max_time_s: float | None = None, log: Callable[[str], None] | None = None,
                 observers: ObserverSet = ObserverSet()) -> CompareRow:
    """Run one estimator ``n_runs`` times on one experiment, camera and observer set and summarise it."""
    config = compare_config(experiment, camera, estimator, preset, max_time_s, observers)
    label = observers.label or str(config.observer)
    factory = TimedFactory(estimator)
    runs = []
    for k in range(n_runs):
        runs.append(run_leapfrog(config, seed + k, localiser=factory))
        if log is not None:
            final = runs[-1].metrics["moma"].final_error
            log(f"[{experiment}/{camera}/{estimator}/{label}] run {k + 1}/{n_runs} seed {seed + k}: E_f {100 * final:.2f} cm")
    summary = aggregate([run.metrics["moma"] for run in runs])
    components = POSITION_PLANAR if config.planar_ugvs else POSITION_3D
    position, heading = evaluate_runs(runs, components)
    durations = np.asarray(factory.durations)
    return CompareRow(
        experiment=experiment,
        camera=camera,
        estimator=estimator,
        observers=label,
        n_runs=n_runs,
        n_completed=sum(run.completed for run in runs),
        final_error=summary.mean_final_error,
        final_error_std=summary.std_final_error,
        mean_error=summary.mean_mean_error,
        final_error_pct_path=summary.mean_final_error_pct_path,
        position_dof=len(components),
        position_anees=position.mean_anees,
        position_inside=position.fraction_inside,
        heading_anees=heading.mean_anees,
        heading_inside=heading.fraction_inside,
        anees_bounds=position.nominal_bounds,
        heading_bounds=heading.nominal_bounds,
        time_per_update_s=float(durations.mean()) if durations.size else float("nan"),
        n_updates=int(durations.size),
    )


def run_compare(estimators: Sequence[str], experiments: Sequence[str], cameras: Sequence[str], n_runs: int, seed: int,
                preset: str = "paper", max_time_s: float | None = None,
                log: Callable[[str], None] | None = None, observers: Sequence[str] | None = None) -> list[CompareRow]:
    """Every experiment x camera x estimator x observer set (:func:`observer_sets` of ``observers``),
    each on runs ``seed .. seed + n_runs - 1``, in that order. Every configuration is checked before the first run."""
    if int(n_runs) != n_runs or n_runs < 1:
        raise ValueError(f"runs must be an integer >= 1, got {n_runs!r}")
    for name in estimators:
        localiser_factory(name)  # ConfigError for an unknown name, ImportError for a missing extra
    sets = observer_sets(observers)
    cases = [(e, c, name, o) for e in experiments for c in cameras for name in estimators for o in sets]
    for e, c, name, o in cases:
        compare_config(e, c, name, preset, max_time_s, o)
    return [compare_case(e, c, name, int(n_runs), seed, preset, max_time_s, log, o) for e, c, name, o in cases]


def format_table(rows: Sequence[CompareRow]) -> str:
    """A Markdown table, one line per row."""
    head = (
        "| experiment | camera | estimator | observers | runs (done) | ME_f cm | std | ME cm | % of path | ANEES pos (dof) "
        "| in bounds | ANEES heading | in bounds | 95 % bounds pos / heading | ms per update |"
    )
    lines = [head, "|" + "---|" * 15]
    for r in rows:
        lines.append(
            f"| {r.experiment} | {r.camera} | {r.estimator} | {r.observers} | {r.n_runs} ({r.n_completed}) | {100 * r.final_error:.2f} "
            f"| {100 * r.final_error_std:.2f} | {100 * r.mean_error:.2f} | {r.final_error_pct_path:.3f} "
            f"| {r.position_anees:.2f} ({r.position_dof}) | {100 * r.position_inside:.0f} % | {r.heading_anees:.2f} "
            f"| {100 * r.heading_inside:.0f} % | {r.anees_bounds[0]:.2f}-{r.anees_bounds[1]:.2f} / "
            f"{r.heading_bounds[0]:.2f}-{r.heading_bounds[1]:.2f} | {1000 * r.time_per_update_s:.2f} |"
        )
    return "\n".join(lines)


def run_compare_command(args: argparse.Namespace) -> int:
    """The ``compare`` command: the table (or JSON) on stdout, a line per run on stderr; 1 if a run did not complete."""
    start = time.perf_counter()
    try:
        rows = run_compare(args.estimators, args.experiments, args.cameras, args.runs, args.seed, args.preset, args.max_time,
                           log=lambda line: print(line, file=sys.stderr), observers=args.observers)
    except (ValueError, ImportError) as err:
        print(f"moma-env experiment compare: {err}", file=sys.stderr)
        return 2
    wall = time.perf_counter() - start
    if args.json:
        data = {"rows": [dataclasses.asdict(r) | {"consistent": r.consistent} for r in rows], "wall_time_s": wall}
        print(json.dumps(data, indent=2, sort_keys=True))
    else:
        print(format_table(rows))
        print(f"wall time: {wall:.1f} s")
    return 0 if all(r.n_completed == r.n_runs for r in rows) else 1

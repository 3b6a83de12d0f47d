"""Monte Carlo consistency of MOMA's covariance on the paper's square and line.

Each *case* is one experiment (``square`` or ``line``), one estimator mode
(``planar``: UGVs constrained upright on the floor, the default; ``6dof``: their
full pose, as the paper's system) and one observer camera (``geometric`` or
``rendered``), run ``n_runs`` times with seeds ``seed .. seed + n_runs - 1``.
For the main robot's MOMA estimate, at every sample where the estimator says
LOCALISED, the NEES of its position (2 dof planar, 3 dof 6-DoF) and of its
heading (1 dof) against the truth is computed
(:mod:`moma_env.metrics.consistency`), then averaged over runs per time step
and compared with the chi-square bounds. Samples whose covariance block is
singular (the zero covariance of a pose frozen from the known initial pose) are
skipped and counted.

Presentation (table, figures, files) lives in
:mod:`training.experiments.consistency_report`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from moma_env.metrics import NeesAverage, average_nees, trajectory_nees
from moma_env.metrics.consistency import HEADING, POSITION_3D, POSITION_PLANAR
from training.experiments.leapfrog_run import MAIN, CameraFactory, LeapfrogConfig, LeapfrogRun
from training.experiments.line import LineConfig
from training.experiments.runner import run_many
from training.experiments.square import SquareConfig

__all__ = [
    "EXPERIMENTS",
    "MODES",
    "ConsistencyCase",
    "CaseResult",
    "consistency_cases",
    "evaluate_runs",
    "run_case",
    "run_consistency",
]

#: The experiments a case can run, by name.
EXPERIMENTS: dict[str, type[LeapfrogConfig]] = {"square": SquareConfig, "line": LineConfig}
#: Estimator modes: name -> ``planar_ugvs``.
MODES = {"planar": True, "6dof": False}


@dataclass(frozen=True)
class ConsistencyCase:
    """One configuration of the Monte Carlo study.

    Attributes:
        experiment: ``"square"`` or ``"line"``.
        mode: ``"planar"`` or ``"6dof"``.
        camera: ``"geometric"`` or ``"rendered"``.
        n_runs: runs (>= 1).
        config: the experiment's configuration (its defaults, with this mode and camera).
    """

    experiment: str
    mode: str
    camera: str
    n_runs: int
    config: LeapfrogConfig

    @property
    def name(self) -> str:
        """``experiment/mode/camera``, e.g. ``square/planar/geometric``."""
        return f"{self.experiment}/{self.mode}/{self.camera}"

    @property
    def position_components(self) -> tuple[int, ...]:
        """The error components of the position NEES: x, y (planar) or x, y, z (6-DoF)."""
        return POSITION_PLANAR if self.config.planar_ugvs else POSITION_3D


def consistency_cases(
    n_runs: int,
    rendered_runs: int,
    experiments: Sequence[str] = ("square", "line"),
    max_time_s: float | None = None,
) -> list[ConsistencyCase]:
    """The cases: every experiment x mode with the geometric camera (``n_runs`` runs each), then
    with the rendered camera (``rendered_runs`` each; none if 0).

    Args:
        n_runs: runs of each geometric case (>= 1).
        rendered_runs: runs of each rendered case (>= 0).
        experiments: names from :data:`EXPERIMENTS`, in order.
        max_time_s: simulated time limit of a run (s); None: the experiment's.

    Raises:
        ValueError: a count out of range or an unknown experiment, naming the argument.
    """
    if int(n_runs) != n_runs or n_runs < 1:
        raise ValueError(f"n_runs must be an integer >= 1, got {n_runs!r}")
    if int(rendered_runs) != rendered_runs or rendered_runs < 0:
        raise ValueError(f"rendered_runs must be an integer >= 0, got {rendered_runs!r}")
    if not experiments:
        raise ValueError("experiments must name at least one experiment")
    for name in experiments:
        if name not in EXPERIMENTS:
            raise ValueError(f"experiments: unknown experiment {name!r}; known: {', '.join(EXPERIMENTS)}")
    cases = []
    for camera, runs in (("geometric", n_runs), ("rendered", rendered_runs)):
        if runs == 0:
            continue
        for experiment in experiments:
            for mode, planar in MODES.items():
                config = EXPERIMENTS[experiment](planar_ugvs=planar, camera_backend=camera)
                if max_time_s is not None:
                    config = dataclasses.replace(config, max_time_s=max_time_s)
                cases.append(ConsistencyCase(experiment, mode, camera, int(runs), config))
    return cases


@dataclass(frozen=True, eq=False)
class CaseResult:
    """The outcome of one case.

    Attributes:
        case: the case.
        seed: seed of its first run.
        position: the position NEES averaged over runs (2 or 3 dof).
        heading: the heading NEES averaged over runs (1 dof).
        runs: the runs, in seed order (their MOMA trajectories carry covariances).
    """

    case: ConsistencyCase
    seed: int
    position: NeesAverage
    heading: NeesAverage
    runs: tuple[LeapfrogRun, ...]

    @property
    def n_completed(self) -> int:
        """Runs that drove every leg before the time limit."""
        return sum(r.completed for r in self.runs)


def evaluate_runs(
    runs: Sequence[LeapfrogRun], position_components: Sequence[int], confidence: float = 0.95
) -> tuple[NeesAverage, NeesAverage]:
    """Position and heading NEES of the main robot's MOMA estimate, averaged over ``runs``.

    Only the samples where MOMA said LOCALISED count (:attr:`LeapfrogRun.localised`).

    Raises:
        ValueError: no run, or a run without the main robot's LOCALISED mask or covariances.
    """
    if not runs:
        raise ValueError("evaluate_runs needs at least one run")
    times, position, heading = [], [], []
    for run in runs:
        main = run.trajectories[MAIN]
        if MAIN not in run.localised:
            raise ValueError(f"run with seed {run.seed} has no LOCALISED mask of {MAIN}")
        truth, moma, localised = main["truth"], main["moma"], run.localised[MAIN]
        times.append(truth.times)
        position.append(trajectory_nees(moma, truth, position_components, usable=localised))
        heading.append(trajectory_nees(moma, truth, HEADING, usable=localised))
    average = {}
    for name, values, dof in (("position", position, len(position_components)), ("heading", heading, len(HEADING))):
        average[name] = average_nees(
            times, [v for v, _ in values], dof, singular=[s for _, s in values], confidence=confidence
        )
    return average["position"], average["heading"]


def run_case(
    case: ConsistencyCase,
    seed: int,
    jobs: int = 1,
    log: Callable[[str], None] | None = None,
    camera_factory: CameraFactory | None = None,
    confidence: float = 0.95,
) -> CaseResult:
    """Run one case (``case.n_runs`` seeded runs) and average its NEES (see :func:`run_many`)."""
    runs = run_many(case.config, case.n_runs, seed, log=log, jobs=jobs, camera_factory=camera_factory)
    position, heading = evaluate_runs(runs, case.position_components, confidence)
    return CaseResult(case, seed, position, heading, tuple(runs))


def run_consistency(
    cases: Sequence[ConsistencyCase],
    seed: int,
    jobs: int = 1,
    log: Callable[[str], None] | None = None,
    camera_factory: CameraFactory | None = None,
    confidence: float = 0.95,
) -> list[CaseResult]:
    """Every case with the same seeds (``seed .. seed + n_runs - 1``), in order.

    Args:
        cases: from :func:`consistency_cases`.
        seed: seed of the first run of each case.
        jobs: worker processes per case.
        log: gets a line per finished run, prefixed with the case's name.
        camera_factory: the observer's camera (see
            :func:`~training.experiments.leapfrog_run.run_leapfrog`); default
            the case's backend.
        confidence: of the chi-square bounds.
    """
    results = []
    for case in cases:
        case_log = None if log is None else (lambda line, n=case.name: log(f"[{n}] {line}"))
        results.append(run_case(case, seed, jobs, case_log, camera_factory, confidence))
    return results


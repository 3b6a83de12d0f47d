"""The paper's line-following experiment: 4.6 m driven forward, back and forward.

Section IV of the paper ("Line Following"): the main robot, in the top-observer
configuration, drives a straight line of about 4.6 m three consecutive times
(forward, backward, forward: 13.785 m in all); every pass needs 6 switches of
reference (the keypoints, 18 in all), at which the authors measured the robot's
true x with a laser. They report the x error at every keypoint (up to 10 cm), the
error in the distance between consecutive keypoints, and the final error, 7.8 cm
or 0.56 % of the path.

Here the main robot drives along +x of the world (heading 0 throughout, driving
backward on the return pass: the robots are omnidirectional) in legs of
``length / switches_per_pass``; the second robot leapfrogs 0.6 m to its left.
The run is the shared leapfrog core (:mod:`training.experiments.leapfrog_run`);
:func:`line_metrics` computes the keypoint errors of one run and
:func:`summarise_line` their statistics over runs. Presentation lives in
:mod:`training.experiments.line_report`.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from moma_env.config import check_count, check_positive
from moma_env.metrics import error_stats, matched_estimate, nearest_valid_indices, relative_errors
from training.experiments.leapfrog_run import MAIN, LeapfrogConfig, LeapfrogRun, run_leapfrog, summarise

__all__ = ["LineConfig", "LineKeypointErrors", "line_waypoints", "run_line", "line_metrics", "summarise_line"]


@dataclass(frozen=True)
class LineConfig(LeapfrogConfig):
    """The line (defaults: the paper's set-up); the shared fields are :class:`LeapfrogConfig`'s.

    Attributes:
        length: length of the line (m); 13.785 m / 3 passes in the paper.
        passes: times the line is driven, alternately forward and backward.
        switches_per_pass: legs (and keypoints) of the main robot per pass.
        texture_half_width: half-width of the textured floor along the line (m);
            the paper did not run VO here, so the floor is textured throughout
            (the VO's best case).
    """

    experiment = "line"

    length: float = 4.595
    passes: int = 3
    switches_per_pass: int = 6
    texture_half_width: float = 0.5
    max_time_s: float = 900.0

    def __post_init__(self) -> None:
        check_positive("line.length", self.length)
        check_positive("line.texture_half_width", self.texture_half_width)
        check_count("line.passes", self.passes)
        check_count("line.switches_per_pass", self.switches_per_pass)
        super().__post_init__()

    @property
    def leg(self) -> float:
        """Length of one leg of the main robot (m)."""
        return self.length / self.switches_per_pass

    @property
    def n_keypoints(self) -> int:
        """Switches of the main robot over the whole run (the paper's 18)."""
        return self.passes * self.switches_per_pass

    def waypoints(self) -> list[tuple[float, float, float]]:
        """The line's waypoints (see :func:`line_waypoints`)."""
        return line_waypoints(self.length, self.passes, self.switches_per_pass)

    def start_pose(self) -> tuple[float, float, float]:
        """The origin, heading +x (along the line)."""
        return (0.0, 0.0, 0.0)

    @property
    def path_length(self) -> float:
        """Nominal path of the main robot (m): 13.785 m in the paper."""
        return self.passes * self.length

    def textured_regions(self) -> tuple[tuple[float, float, float, float], ...]:
        """Texture along the whole line, ``texture_half_width`` m either side and beyond its ends."""
        w = self.texture_half_width
        return ((-w, -w, self.length + w, w),)


def line_waypoints(length: float, passes: int, switches_per_pass: int) -> list[tuple[float, float, float]]:
    """Waypoints (x, 0, 0): ``switches_per_pass`` equal legs per pass, passes alternating +x and -x."""
    waypoints = []
    for p in range(passes):
        for i in range(1, switches_per_pass + 1):
            f = i / switches_per_pass
            x = f * length if p % 2 == 0 else (1.0 - f) * length
            waypoints.append((x, 0.0, 0.0))
    return waypoints


def run_line(config: LineConfig, seed: int) -> LeapfrogRun:
    """Run the line once with every random draw seeded by ``seed``."""
    return run_leapfrog(config, seed)


@dataclass(frozen=True)
class LineKeypointErrors:
    """The paper's line metrics of one method in one run (m).

    Keypoint k is the k-th instant the main robot was declared static (at the
    end of each of its legs); errors are taken at the valid truth sample nearest
    that instant.

    Attributes:
        keypoint_times: the keypoint instants (s).
        true_x, estimated_x: the main robot's x at the keypoints (m); the
            estimate is NaN where unknown.
        x_errors: signed error along the line, ``estimated_x - true_x`` (m): the
            paper measured x only (with a laser).
        position_errors: planar error E at the keypoints (m).
        relative_errors: error in the distance travelled between consecutive
            keypoints, the start counting as keypoint 0 (m), one per keypoint.
        final_error: E_f at the end of the run (m).
        final_error_pct_path: E_f in % of the nominal path.
    """

    keypoint_times: tuple[float, ...]
    true_x: tuple[float, ...]
    estimated_x: tuple[float, ...]
    x_errors: tuple[float, ...]
    position_errors: tuple[float, ...]
    relative_errors: tuple[float, ...]
    final_error: float
    final_error_pct_path: float

    @property
    def max_abs_x_error(self) -> float:
        """Largest |x error| over the keypoints (m); NaN if none is known."""
        return error_stats(np.abs(self.x_errors)).max

    @property
    def mean_relative_error(self) -> float:
        """Mean error in the distance between keypoints (m); NaN if none is known."""
        return error_stats(self.relative_errors).mean

    def to_dict(self) -> dict[str, object]:
        """Plain mapping for JSON."""
        d = {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items()}
        d["max_abs_x_error"] = self.max_abs_x_error
        d["mean_relative_error"] = self.mean_relative_error
        return d


def line_metrics(run: LeapfrogRun, method: str) -> LineKeypointErrors:
    """Keypoint errors of ``method``'s estimate of the main robot in ``run``."""
    main = run.trajectories[MAIN]
    truth, estimate = main["truth"], main[method]
    times = np.asarray(run.switch_times, dtype=float)
    index = nearest_valid_indices(truth, times)
    estimated = matched_estimate(estimate, truth)[index]
    true_x = truth.poses[index, 0, 3]
    est_x = estimated[:, 0, 3]
    planar = np.hypot(estimated[:, 0, 3] - truth.poses[index, 0, 3], estimated[:, 1, 3] - truth.poses[index, 1, 3])
    start = float(truth.times[np.flatnonzero(truth.valid)[0]])
    relative = relative_errors(estimate, truth, np.concatenate([[start], times])) if times.shape[0] else np.empty(0)
    metrics = run.metrics[method]
    return LineKeypointErrors(
        keypoint_times=tuple(float(t) for t in times),
        true_x=tuple(float(v) for v in true_x),
        estimated_x=tuple(float(v) for v in est_x),
        x_errors=tuple(float(v) for v in est_x - true_x),
        position_errors=tuple(float(v) for v in planar),
        relative_errors=tuple(float(v) for v in relative),
        final_error=metrics.final_error,
        final_error_pct_path=metrics.final_error_pct_path,
    )


def summarise_line(runs: list[LeapfrogRun]) -> dict[str, dict[str, float]]:
    """Per method: :func:`~training.experiments.leapfrog_run.summarise` (final error, % of path,
    track loss over runs) plus the keypoint statistics pooled over every run's keypoints (m).
    """
    summary = summarise(runs)
    for method, stats in summary.items():
        per_run = [line_metrics(run, method) for run in runs]
        x_errors = error_stats(np.abs(np.concatenate([m.x_errors for m in per_run])))
        relative = error_stats(np.concatenate([m.relative_errors for m in per_run]))
        stats.update(
            mean_abs_keypoint_x_error=x_errors.mean,
            max_abs_keypoint_x_error=x_errors.max,
            mean_relative_error=relative.mean,
            max_relative_error=relative.max,
        )
    return summary

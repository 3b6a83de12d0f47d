"""Configuration of the MOMA estimator (frozen, validated dataclasses).

Defaults come from the authors' system (DESIGN.md section 1): a 1 s switch window
at 25 Hz (25 samples) and the outlier gate of their caterpillar code (a start
needs 3 consecutive poses within 4 cm, summed ``|dx|+|dy|+|dz|``; later a pose
more than 15 cm from the mean of the last 3 accepted ones is rejected).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from moma_env.config import ConfigError, check_bool, check_choice, check_count, check_non_negative, check_positive

__all__ = ["OutlierGateConfig", "EstimatorConfig", "FUSIONS"]

#: How several candidate poses of one camera or one robot in a frame are fused:
#: ``"mean"`` (the paper: an unweighted mean) or ``"information"`` (weighted by
#: the inverse of their covariances, :mod:`moma_env.estimator.fusion`).
FUSIONS = ("mean", "information")


@dataclass(frozen=True)
class OutlierGateConfig:
    """Outlier gate on a robot's measured position stream (authors' caterpillar code).

    Distances are the L1 norm of the position difference, ``|dx|+|dy|+|dz|`` (m),
    of the robot body origin in the world frame W; rotations are compared by the
    angle of the relative rotation (rad), which catches a sample of the wrong
    planar-PnP pose (tilted by twice the viewing angle) whose position happens
    to stay within the position tolerance.

    Attributes:
        enabled: False lets every sample through.
        start_samples: consecutive samples needed, pairwise within
            ``start_tolerance_m``, before a robot without accepted history is
            accepted.
        start_tolerance_m: start consistency tolerance (m).
        start_tolerance_rad: start consistency tolerance on rotation (rad).
        history: number of last accepted samples whose mean a new sample is
            compared with.
        jump_tolerance_m: a sample farther than this from that mean is rejected (m).
        jump_tolerance_rad: a sample whose rotation is farther than this from
            the last accepted one is rejected (rad).
        reset_after_s: the history is forgotten when the last accepted sample is
            older than this (s), so a robot that reappears after a gap is
            re-acquired instead of being rejected forever.
    """

    enabled: bool = True
    start_samples: int = 3
    start_tolerance_m: float = 0.04
    history: int = 3
    jump_tolerance_m: float = 0.15
    reset_after_s: float = 1.0
    start_tolerance_rad: float = 0.25
    jump_tolerance_rad: float = 0.3

    def __post_init__(self) -> None:
        check_bool("estimator.gate.enabled", self.enabled)
        check_count("estimator.gate.start_samples", self.start_samples)
        check_positive("estimator.gate.start_tolerance_m", self.start_tolerance_m)
        check_positive("estimator.gate.start_tolerance_rad", self.start_tolerance_rad)
        check_count("estimator.gate.history", self.history)
        check_positive("estimator.gate.jump_tolerance_m", self.jump_tolerance_m)
        check_positive("estimator.gate.jump_tolerance_rad", self.jump_tolerance_rad)
        check_positive("estimator.gate.reset_after_s", self.reset_after_s)


@dataclass(frozen=True)
class EstimatorConfig:
    """Settings of :class:`moma_env.estimator.MomaEstimator`.

    Attributes:
        window: samples averaged at a switch before a static robot's pose is
            frozen (the authors: 1 s at 25 Hz = 25); a full window freezes it.
        min_window: fewest accepted samples a settling robot needs to be
            frozen when another robot is declared mobile (the authors'
            caterpillar averaged 10); with fewer it stays settling, and is no
            reference, until it has them (:meth:`MomaEstimator.window_ready`).
            None means ``min(10, window)``.
        window_outlier_k: a window sample farther than this many times the
            median distance from the window's centre is left out of the mean
            (see :class:`~moma_env.estimator.window.SwitchWindow`).
        window_floor_m, window_floor_rad: the smallest outlier limits (m, rad).
        lost_after_s: a robot not localised for longer than this (s) is LOST.
        settle_delay_s: samples of a robot younger than this after its static
            declaration are left out of its window (s); the authors' caterpillar
            waited 1.5 s after stopping.
        gate: the outlier gate, or None to disable it.
        fusion: how the candidate poses of a camera (one per reference board it
            sees) and of a robot (one per located camera) in one frame are
            fused: ``"mean"``, the paper's unweighted mean (default), or
            ``"information"``, weighted by their covariances
            (:func:`moma_env.estimator.fusion.information_fusion`).
    """

    window: int = 25
    lost_after_s: float = 2.0
    settle_delay_s: float = 0.0
    gate: OutlierGateConfig | None = field(default_factory=OutlierGateConfig)
    min_window: int | None = None
    window_outlier_k: float = 3.0
    window_floor_m: float = 0.002
    window_floor_rad: float = 0.002
    fusion: str = "mean"

    def __post_init__(self) -> None:
        check_count("estimator.window", self.window)
        if self.min_window is None:
            object.__setattr__(self, "min_window", min(10, self.window))
        check_count("estimator.min_window", self.min_window)
        if self.min_window > self.window:
            raise ConfigError("estimator.min_window", f"must be at most window ({self.window}), got {self.min_window}")
        check_positive("estimator.window_outlier_k", self.window_outlier_k)
        check_positive("estimator.window_floor_m", self.window_floor_m)
        check_positive("estimator.window_floor_rad", self.window_floor_rad)
        check_positive("estimator.lost_after_s", self.lost_after_s)
        check_non_negative("estimator.settle_delay_s", self.settle_delay_s)
        check_choice("estimator.fusion", self.fusion, FUSIONS)
        if self.gate is not None and not isinstance(self.gate, OutlierGateConfig):
            raise ConfigError(
                "estimator.gate", f"must be an OutlierGateConfig or None, got {type(self.gate).__name__}"
            )

    @property
    def gate_enabled(self) -> bool:
        """True when a gate is configured and enabled."""
        return self.gate is not None and self.gate.enabled

"""Configuration of the MOMA estimator (frozen, validated dataclasses).

Defaults come from the authors' system (DESIGN.md section 1): a 1 s switch window
at 25 Hz (25 samples) and the outlier gate of their caterpillar code (a start
needs 3 consecutive poses within 4 cm, summed ``|dx|+|dy|+|dz|``; later a pose
more than 15 cm from the mean of the last 3 accepted ones is rejected).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from moma_env.config import ConfigError, check_bool, check_count, check_non_negative, check_positive

__all__ = ["OutlierGateConfig", "EstimatorConfig"]


@dataclass(frozen=True)
class OutlierGateConfig:
    """Outlier gate on a robot's measured position stream (authors' caterpillar code).

    Distances are the L1 norm of the position difference, ``|dx|+|dy|+|dz|`` (m),
    of the robot body origin in the world frame W.

    Attributes:
        enabled: False lets every sample through.
        start_samples: consecutive samples needed, pairwise within
            ``start_tolerance_m``, before a robot without accepted history is
            accepted.
        start_tolerance_m: start consistency tolerance (m).
        history: number of last accepted samples whose mean a new sample is
            compared with.
        jump_tolerance_m: a sample farther than this from that mean is rejected (m).
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

    def __post_init__(self) -> None:
        check_bool("estimator.gate.enabled", self.enabled)
        check_count("estimator.gate.start_samples", self.start_samples)
        check_positive("estimator.gate.start_tolerance_m", self.start_tolerance_m)
        check_count("estimator.gate.history", self.history)
        check_positive("estimator.gate.jump_tolerance_m", self.jump_tolerance_m)
        check_positive("estimator.gate.reset_after_s", self.reset_after_s)


@dataclass(frozen=True)
class EstimatorConfig:
    """Settings of :class:`moma_env.estimator.MomaEstimator`.

    Attributes:
        window: samples averaged at a switch before a static robot's pose is
            frozen (the authors: 1 s at 25 Hz = 25).
        lost_after_s: a robot not localised for longer than this (s) is LOST.
        settle_delay_s: samples of a robot younger than this after its static
            declaration are left out of its window (s); the authors' caterpillar
            waited 1.5 s after stopping.
        gate: the outlier gate, or None to disable it.
    """

    window: int = 25
    lost_after_s: float = 2.0
    settle_delay_s: float = 0.0
    gate: OutlierGateConfig | None = field(default_factory=OutlierGateConfig)

    def __post_init__(self) -> None:
        check_count("estimator.window", self.window)
        check_positive("estimator.lost_after_s", self.lost_after_s)
        check_non_negative("estimator.settle_delay_s", self.settle_delay_s)
        if self.gate is not None and not isinstance(self.gate, OutlierGateConfig):
            raise ConfigError(
                "estimator.gate", f"must be an OutlierGateConfig or None, got {type(self.gate).__name__}"
            )

    @property
    def gate_enabled(self) -> bool:
        """True when a gate is configured and enabled."""
        return self.gate is not None and self.gate.enabled

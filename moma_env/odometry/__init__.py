"""Odometry baselines that MOMA is compared against.

- :mod:`moma_env.odometry.wheel`: wheel odometry (dead reckoning with slip).
- :mod:`moma_env.odometry.visual`: monocular visual odometry on floor frames
  (optical-flow tracking, ground-plane motion, track loss on plain floor).
"""

from moma_env.odometry.visual import VisualOdometry, VisualOdometryConfig
from moma_env.odometry.wheel import WheelOdometry, WheelOdometryConfig, se2_step

__all__ = ["VisualOdometry", "VisualOdometryConfig", "WheelOdometry", "WheelOdometryConfig", "se2_step"]

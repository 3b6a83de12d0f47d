"""Odometry baselines that MOMA is compared against.

- :mod:`moma_env.odometry.wheel`: wheel odometry (dead reckoning with slip).
"""

from moma_env.odometry.wheel import WheelOdometry, WheelOdometryConfig, se2_step

__all__ = ["WheelOdometry", "WheelOdometryConfig", "se2_step"]

"""moma_env: MOMA visual mobile marker odometry as a multi-agent learning environment.

Layers, with imports flowing one way (see DESIGN.md):
world (pymunk truth) -> camera (detections) -> estimator (MOMA estimates)
-> metrics. The estimator imports nothing from the simulator.
"""

__version__ = "0.1.0"

"""The simulation core: one MOMA rig stepped in time, and the snapshot of a step.

* :class:`Simulation`: the world, the cameras, the localiser and the motion
  rules; ``reset(rng) -> Frame``, ``step(Commands) -> Frame`` (or its phases
  ``request`` / ``declare`` / ``advance``).
* :class:`Frame`: the public, immutable snapshot of a step (truth, estimates
  with their covariances, detections, declared states, switches, contacts).
* :class:`Localiser`: the protocol an estimator implements to run in it.
* :class:`MotionRules`: the paper's motion rules.

The environments (:mod:`moma_env.env`) are adapters of this core; it imports
nothing from them.
"""

from moma_env.sim.frame import Frame, Pose2D, Switch
from moma_env.sim.localiser import Localiser, LocaliserFactory, OdometryConsumer
from moma_env.sim.rules import REFUSED_DWELL, REFUSED_NO_REFERENCE, REFUSED_WINDOW, MotionRules
from moma_env.sim.simulation import Commands, Simulation, measured

__all__ = [
    "Commands",
    "Frame",
    "Localiser",
    "LocaliserFactory",
    "MotionRules",
    "OdometryConsumer",
    "Pose2D",
    "REFUSED_DWELL",
    "REFUSED_NO_REFERENCE",
    "REFUSED_WINDOW",
    "Simulation",
    "Switch",
    "measured",
]

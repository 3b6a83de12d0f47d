"""MOMA navigation: plan the turns that take a team to its goals, and check plans against the rules.

* :func:`plan` -- per-configuration turn scheduling on shortest collision-free paths.
* :func:`validate` -- the MOMA rule checker (move in turns, one advance per
  turn, no collision, observability, goals reached); [] for a valid plan.
* :class:`Plan`, :class:`Turn` -- the plan's data types; :class:`PlanningError`.
* :func:`shortest_path` -- visibility-graph paths of a disk among box obstacles.
"""

from moma_env.planning.paths import shortest_path
from moma_env.planning.plan import Plan, PlanningError, Pose2D, Turn
from moma_env.planning.planner import SUPPORTED_CONFIGURATIONS, plan
from moma_env.planning.validate import RuleChecker, coverage_radius, validate

__all__ = [
    "Plan",
    "Turn",
    "Pose2D",
    "PlanningError",
    "plan",
    "validate",
    "RuleChecker",
    "coverage_radius",
    "shortest_path",
    "SUPPORTED_CONFIGURATIONS",
]

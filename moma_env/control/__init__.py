"""Low-level motion controllers built into the robots (used by the env and the scripted agents).

* :class:`WaypointFollower`: go-to-pose for an omnidirectional UGV, on its estimated pose.
* :class:`BoardTrackingController`: the UAV's tracking controller, on board detections only.
"""

from moma_env.control.tracking import BoardTrackingController, TrackingControllerConfig
from moma_env.control.waypoint import WaypointFollower, WaypointFollowerConfig

__all__ = ["WaypointFollower", "WaypointFollowerConfig", "BoardTrackingController", "TrackingControllerConfig"]

"""Which boards the cameras of a scenario see at the start, before anything moves.

Poses come from the configuration alone (no physics): a UGV's camera at
``se2_to_se3(initial_pose) @ T_b_c``, the UAV's camera at its initial
``(x, y, yaw)`` and ``altitude`` with zero tilt, boards at
``se2_to_se3(initial_pose) @ T_b_m`` (robots and sleds). The world builds the
same poses at reset. Visibility is the camera model's geometric test
(:func:`moma_env.camera.marker_visibility`: field of view, size, incidence,
range); occlusion by bodies is not considered (a configuration keeps its lines
of sight inside its obstacle-free corridor).

A configuration's ``required_views()`` names, per camera, the boards (by owner:
robot or sled name) it must see whole at the start; :func:`missing_views` lists
the pairs that fail, which the random generators reject and the tests check.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from moma_env.camera import PinholeCamera, marker_visibility
from moma_env.geometry import se2_to_se3
from moma_env.markers import BoardLayout
from moma_env.scenarios.base import Scenario
from moma_env.world import WorldConfig, uav_body_transform

__all__ = ["start_camera_poses", "start_boards", "visible_marker_counts", "missing_views", "view_neighbours"]


def start_camera_poses(world: WorldConfig) -> dict[str, np.ndarray]:
    """Camera name -> 4x4 ``T_w_c`` at the start (m), robots' cameras then the UAVs'."""
    poses: dict[str, np.ndarray] = {}
    for ugv in world.ugvs:
        T_w_b = se2_to_se3(*ugv.initial_pose)
        for camera in ugv.cameras:
            poses[camera.name] = T_w_b @ camera.T_b_c
    for uav in world.uavs:
        x, y, yaw = uav.initial
        poses[uav.camera_name] = uav_body_transform(x, y, uav.altitude, yaw, 0.0, 0.0) @ uav.camera_mount
    return poses


def start_boards(world: WorldConfig) -> dict[str, tuple[BoardLayout, np.ndarray]]:
    """Owner name (robot, then sled) -> ``(layout, T_w_m)`` of its board at the start (m)."""
    boards: dict[str, tuple[BoardLayout, np.ndarray]] = {}
    for ugv in world.ugvs:
        if ugv.board is not None:
            boards[ugv.name] = (ugv.board, se2_to_se3(*ugv.initial_pose) @ ugv.board_mount)
    for sled in world.sleds:
        boards[sled.name] = (sled.board, se2_to_se3(*sled.initial_pose) @ sled.board_mount)
    return boards


def visible_marker_counts(scenario: Scenario, camera_name: str) -> dict[str, int]:
    """Owner name -> number of its board's markers ``camera_name`` sees at the start.

    KeyError (listing the cameras) for an unknown camera.
    """
    cameras = start_camera_poses(scenario.world)
    if camera_name not in cameras:
        raise KeyError(f"unknown camera {camera_name!r}; known cameras are {list(cameras)}")
    T_c_w = np.linalg.inv(cameras[camera_name])
    model = PinholeCamera(scenario.camera)
    counts = {}
    for owner, (layout, T_w_m) in start_boards(scenario.world).items():
        T_c_m = T_c_w @ T_w_m
        corners_c = layout.marker_corners @ T_c_m[:3, :3].T + T_c_m[:3, 3]
        visible, _ = marker_visibility(model, corners_c, T_c_m[:3, 2])
        counts[owner] = int(visible.sum())
    return counts


def missing_views(scenario: Scenario, required: Mapping[str, Sequence[str]]) -> list[str]:
    """Descriptions of the ``camera -> board owners`` pairs of ``required`` where the
    camera does not see every marker of the board at the start; empty if all do."""
    boards = start_boards(scenario.world)
    missing = []
    for camera_name, owners in required.items():
        counts = visible_marker_counts(scenario, camera_name)
        for owner in owners:
            if owner not in boards:
                missing.append(f"{camera_name} -> {owner}: {owner!r} carries no board")
                continue
            n_markers = len(boards[owner][0].marker_ids)
            if counts[owner] < n_markers:
                missing.append(f"{camera_name} -> {owner}: {counts[owner]} of {n_markers} markers visible")
    return missing


def view_neighbours(world: WorldConfig, views: Mapping[str, Sequence[str]]) -> dict[str, frozenset[str]]:
    """Device -> the devices it shares a view with, from ``views`` (``camera -> board
    owners``, e.g. a configuration's motion views): the robot carrying the camera and each
    owner of a board it watches are each other's neighbours (symmetric; a device is not its
    own). Every UGV and sled of ``world`` has an entry, empty when it shares no view.

    Raises:
        ValueError: a camera no UGV of ``world`` carries, or an owner that is no UGV or sled.
    """
    carrier = {mount.name: ugv.name for ugv in world.ugvs for mount in ugv.cameras}
    devices = [u.name for u in world.ugvs] + [s.name for s in world.sleds]
    neighbours: dict[str, set[str]] = {name: set() for name in devices}
    for camera_name, owners in views.items():
        robot = carrier.get(camera_name)
        if robot is None:
            raise ValueError(f"view of unknown camera {camera_name!r}; cameras: {sorted(carrier)}")
        for owner in owners:
            if owner not in neighbours:
                raise ValueError(f"view of {camera_name!r} on {owner!r}, which is no UGV or sled; devices: {devices}")
            if owner != robot:
                neighbours[robot].add(owner)
                neighbours[owner].add(robot)
    return {name: frozenset(others) for name, others in neighbours.items()}

"""Measure many camera frames at once: the frames of the copies of a vector env.

A vector env steps N copies of a scene; each copy has its own cameras and its
own random generator. Measured one frame at a time, a geometric frame costs
mostly Python and numpy call overhead (each call costs a microsecond or two
however little it computes). :func:`measure_batch` measures the frames of all
geometric cameras with the same PnP solver together, whatever their intrinsics,
limits and noise: one compiled projection of
every board of every frame and one compiled PnP solve of every seen board of
every frame (:class:`~moma_env.camera.geometric.GeometricCamera` uses the same
code for a single frame, so there is one implementation).

The result is bit for bit the list of what ``request.camera.measure(...)``
would return request by request, in request order: each frame draws from its
own generator, the same numbers in the same order (several requests may share
a generator: the draws are made in request order), and a camera that appears
in several requests sees them in request order (its warm-start poses, see
``CameraConfig.pnp_warm_start``). Other backends (e.g.
:class:`~moma_env.camera.rendered.RenderedCamera`) are measured by their own
``measure``, in their place in that order.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from moma_env.camera.backend import BoardView, CameraBackend, OcclusionQuery
from moma_env.camera.geometric import GeometricCamera, FrameGroup, check_frame
from moma_env.estimator.detection import Detection
from moma_env.records import slot_setter_init

__all__ = ["MeasureRequest", "measure_batch"]


@slot_setter_init
@dataclass(frozen=True, slots=True, init=False)
class MeasureRequest:
    """One frame to measure: the arguments of ``camera.measure``.

    Attributes:
        camera: the backend that takes the frame.
        T_w_c: 4x4 pose of the camera frame C in the world W (m).
        boards: the boards in the scene; detections come out in this order.
        time: acquisition time (s).
        rng: the frame's source of noise.
        occluded: optional line-of-sight query (see ``OcclusionQuery``).
    """

    camera: CameraBackend
    T_w_c: np.ndarray
    boards: Sequence[BoardView]
    time: float
    rng: np.random.Generator
    occluded: OcclusionQuery | None = None


def measure_batch(requests: Sequence[MeasureRequest]) -> list[list[Detection]]:
    """The detections of every request: ``[r.camera.measure(r.T_w_c, r.boards, r.time, r.rng, r.occluded) for r in requests]``, bit for bit.

    Requests whose camera is a :class:`GeometricCamera` are grouped by the
    camera's PnP solver (``pnp_method``; each board is projected and solved with
    its own camera's intrinsics, limits and settings); each group
    is projected in one compiled call and solved in one compiled call (one per
    repetition of a camera in the group, when a camera appears more than once).
    Every geometric request is validated before anything is drawn; a bad one
    raises ValueError or TypeError naming ``requests[i]`` and the argument.
    Other backends are called through their ``measure``.

    Detections of a batch of several frames own their arrays (copies, so that
    a kept detection does not keep the whole batch's arrays alive).

    Args:
        requests: the frames, in the order their random draws are made.

    Returns:
        One list of detections per request, in request order.
    """
    requests = list(requests)
    n_requests = len(requests)
    # Per solver (batch_key): the group's requests, then its frames' arguments.
    frames: dict[tuple, tuple[list, ...]] = {}
    for i, request in enumerate(requests):
        if not isinstance(request, MeasureRequest):
            raise TypeError(f"requests[{i}] must be a MeasureRequest, got {type(request).__name__}")
        camera = request.camera
        if isinstance(camera, GeometricCamera):
            try:
                T_w_c, time = check_frame(request.T_w_c, request.time, request.rng)
            except (TypeError, ValueError) as error:
                raise type(error)(f"requests[{i}]: {error}") from None
            group = frames.get(camera.batch_key)
            if group is None:
                frames[camera.batch_key] = ([i], [camera], [T_w_c], [request.boards], [time], [request.rng], [request.occluded])
            else:
                members, cameras, poses, boards, times, rngs, occluded = group
                members.append(i)
                cameras.append(camera)
                poses.append(T_w_c)
                boards.append(request.boards)
                times.append(time)
                rngs.append(request.rng)
                occluded.append(request.occluded)
    if len(frames) == 1:
        members, *arguments = next(iter(frames.values()))
        if len(members) == n_requests:  # every request in one group (a vector env's step): no reordering
            group = FrameGroup(*arguments)
            for f in range(n_requests):
                group.draw(f)
            return group.solve()
    groups = []
    group_of: list[tuple[FrameGroup, int] | None] = [None] * n_requests
    for members, *arguments in frames.values():
        group = FrameGroup(*arguments)
        groups.append((group, members))
        for f, i in enumerate(members):
            group_of[i] = (group, f)
    results: list[list[Detection]] = [[] for _ in requests]
    for i, request in enumerate(requests):
        place = group_of[i]
        if place is None:
            results[i] = request.camera.measure(request.T_w_c, request.boards, request.time, request.rng, request.occluded)
        else:
            place[0].draw(place[1])
    for group, members in groups:
        for i, detections in zip(members, group.solve()):
            results[i] = detections
    return results

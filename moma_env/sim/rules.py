"""The paper's motion rules, enforced by the environment (section II of the paper).

1. A marker is static while the camera that measures it moves and vice versa;
   with several markers the camera may move all the time while one observed
   marker is static.
2. Markers and cameras move in turns.
3. At every transition there is a dwell time during which at least two devices
   are static.

A *device* is anything the owner declares static or mobile: a UGV or a sled. A
request to become static is always granted (the world locks the device). A
request to become mobile is granted only if

* the dwell time has passed since the last device became static (rule 3: the
  estimator averages its switch window meanwhile),
* after the switch every mobile device, the requester included, stays
  localisable from a static reference other than itself, as observed in the
  latest camera frame (rules 1 and 2), and
* the references it needs hold a frozen pose or a ready switch window (the
  estimator's ``window_ready``): a device still collecting its window is no
  reference yet, and a request that needs it is refused with ``window``
  (wait), not ``no_reference``.

A refused request is reported, never raised: the caller puts the reason in
``infos``.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence

from moma_env.estimator import Detection

__all__ = ["MotionRules", "REFUSED_DWELL", "REFUSED_NO_REFERENCE", "REFUSED_WINDOW"]

#: Refusal reasons, as reported in ``infos``.
REFUSED_DWELL = "dwell"
REFUSED_NO_REFERENCE = "no_reference"
REFUSED_WINDOW = "window"


class MotionRules:
    """Grants or refuses state changes of devices.

    Args:
        board_owner: board id -> device (or robot) that carries it.
        camera_owner: camera id -> robot that carries it (the UAV's camera is
            owned by the UAV, which is never a device).
        dwell_s: rule 3's dwell time (s).
    """

    def __init__(self, board_owner: Mapping[int, str], camera_owner: Mapping[str, str], dwell_s: float):
        self._board_owner = dict(board_owner)
        self._camera_owner = dict(camera_owner)
        self._boards_of: dict[str, list[int]] = {}
        for board_id, owner in self._board_owner.items():
            self._boards_of.setdefault(owner, []).append(board_id)
        self._cameras_of: dict[str, list[str]] = {}
        for camera_id, owner in self._camera_owner.items():
            self._cameras_of.setdefault(owner, []).append(camera_id)
        self.dwell_s = dwell_s
        self._last_static_time = float("-inf")

    def reset(self) -> None:
        """Forget the last switch (all devices start static and settled)."""
        self._last_static_time = float("-inf")

    def note_static(self, time: float) -> None:
        """A device became static at ``time`` (s): the dwell starts."""
        self._last_static_time = time

    def dwell_remaining(self, time: float) -> float:
        """Seconds left before a mobile request can be granted (0 if none)."""
        return max(0.0, self._last_static_time + self.dwell_s - time)

    def check_mobile(
        self,
        device: str,
        time: float,
        mobile: Iterable[str],
        references: Iterable[str],
        detections: Sequence[Detection],
        settling: Iterable[str] = (),
    ) -> str | None:
        """None if ``device`` may become mobile now, else the refusal reason.

        Args:
            device: the requester (currently static).
            time: now (s).
            mobile: devices that are mobile now.
            references: static devices whose pose another may rely on after the
                switch: frozen references and devices whose switch window is
                ready (the estimator's ``window_ready``).
            detections: the latest camera frame.
            settling: static devices still collecting their switch window; the
                request is refused with ``window`` if it would be granted with
                them as references.
        """
        if time < self._last_static_time + self.dwell_s - 1e-9:
            return REFUSED_DWELL
        movers = set(mobile)
        movers.add(device)
        if self._all_localisable(movers, set(references) - movers, detections):
            return None
        waiting = set(settling) - movers
        if waiting and self._all_localisable(movers, (set(references) | waiting) - movers, detections):
            return REFUSED_WINDOW
        return REFUSED_NO_REFERENCE

    def _all_localisable(self, movers: set[str], refs: set[str], detections: Sequence[Detection]) -> bool:
        if not refs:
            return False
        located = self._located_cameras(refs, detections)
        localisable = self._localisable
        for mover in movers:
            if not localisable(mover, refs, located, detections):
                return False
        return True

    def _located_cameras(self, refs: set[str], detections: Sequence[Detection]) -> set[str]:
        board_owner, camera_owner = self._board_owner, self._camera_owner
        located = {camera for camera, owner in camera_owner.items() if owner in refs}
        for d in detections:
            owner = board_owner.get(d.board_id)
            if owner in refs and owner != camera_owner.get(d.camera_id):
                located.add(d.camera_id)
        return located

    def _localisable(self, device: str, refs: set[str], located: set[str], detections: Sequence[Detection]) -> bool:
        own_cameras = self._cameras_of.get(device, ())
        board_owner, camera_owner = self._board_owner, self._camera_owner
        for d in detections:
            owner = board_owner.get(d.board_id)
            camera = d.camera_id
            if owner == device and camera in located and camera_owner.get(camera) != device:
                return True
            if camera in own_cameras and owner in refs:
                return True
        return False

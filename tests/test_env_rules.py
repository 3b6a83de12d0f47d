"""The paper's motion rules as the environment enforces them."""

import numpy as np

from moma_env.sim.rules import REFUSED_DWELL, REFUSED_NO_REFERENCE, REFUSED_WINDOW, MotionRules
from moma_env.estimator import Detection


def det(camera: str, board: int) -> Detection:
    return Detection(camera, board, np.eye(4), np.empty((0, 2)), (), 0.0)


def top_rules(dwell=1.0):
    # Three UGVs with boards 0, 1, 2 under one UAV camera.
    return MotionRules({0: "ugv_0", 1: "ugv_1", 2: "ugv_2"}, {"uav/camera": "uav"}, dwell)


def test_top_observer_needs_another_observed_reference():
    rules = top_rules()
    frame = [det("uav/camera", 0), det("uav/camera", 1)]
    refs = {"ugv_0", "ugv_1", "ugv_2"}
    assert rules.check_mobile("ugv_0", 5.0, set(), refs, frame) is None
    # ugv_1 is the only other reference the camera sees: if it is mobile, ugv_0 may not move.
    assert rules.check_mobile("ugv_0", 5.0, {"ugv_1"}, refs - {"ugv_1"}, frame) == REFUSED_NO_REFERENCE
    # ugv_2 is a reference but not observed: not enough.
    assert rules.check_mobile("ugv_0", 5.0, {"ugv_1"}, {"ugv_0", "ugv_2"}, frame) == REFUSED_NO_REFERENCE
    # The requester's own board must be seen, or it cannot be tracked once mobile.
    assert rules.check_mobile("ugv_2", 5.0, set(), refs, frame) == REFUSED_NO_REFERENCE


def test_dwell_after_every_static_declaration():
    rules = top_rules(dwell=1.0)
    frame = [det("uav/camera", 0), det("uav/camera", 1)]
    refs = {"ugv_0", "ugv_1"}
    rules.note_static(10.0)
    assert rules.check_mobile("ugv_0", 10.5, set(), refs, frame) == REFUSED_DWELL
    assert rules.dwell_remaining(10.5) == 0.5
    assert rules.check_mobile("ugv_0", 11.0, set(), refs, frame) is None
    rules.reset()
    assert rules.dwell_remaining(0.0) == 0.0


def test_caterpillar_moves_in_turns():
    # ugv_0 leader carries board 0; ugv_1 follower carries the camera looking at it.
    rules = MotionRules({0: "ugv_0"}, {"ugv_1/camera": "ugv_1"}, 0.0)
    frame = [det("ugv_1/camera", 0)]
    both = {"ugv_0", "ugv_1"}
    # Either may move while the other is a static reference that is observed...
    assert rules.check_mobile("ugv_0", 1.0, set(), both, frame) is None
    assert rules.check_mobile("ugv_1", 1.0, set(), both, frame) is None
    # ...but not both at once (rule 2), and not when the board is out of view.
    assert rules.check_mobile("ugv_1", 1.0, {"ugv_0"}, {"ugv_1"}, frame) == REFUSED_NO_REFERENCE
    assert rules.check_mobile("ugv_0", 1.0, set(), both, []) == REFUSED_NO_REFERENCE
    # A device the estimator has not frozen yet is no reference.
    assert rules.check_mobile("ugv_1", 1.0, set(), {"ugv_1"}, frame) == REFUSED_NO_REFERENCE


def test_a_reference_still_collecting_its_window_means_wait():
    rules = top_rules()
    frame = [det("uav/camera", 0), det("uav/camera", 1)]
    # ugv_1 stopped and is settling: ugv_0 needs it, so the answer is "window" (wait), not "no_reference".
    assert rules.check_mobile("ugv_0", 5.0, set(), {"ugv_0"}, frame, settling={"ugv_1"}) == REFUSED_WINDOW
    assert rules.check_mobile("ugv_0", 5.0, set(), {"ugv_0", "ugv_1"}, frame) is None
    # A settling device that would not help either way does not turn the refusal into "window".
    assert rules.check_mobile("ugv_0", 5.0, set(), {"ugv_0"}, frame, settling={"ugv_2"}) == REFUSED_NO_REFERENCE
    # The dwell is judged first.
    rules.note_static(4.5)
    assert rules.check_mobile("ugv_0", 5.0, set(), {"ugv_0"}, frame, settling={"ugv_1"}) == REFUSED_DWELL

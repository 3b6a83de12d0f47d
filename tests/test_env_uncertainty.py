"""The env passes the estimator's uncertainty on: standard deviations in the
observations, the full covariance in infos, and ``window`` refusals."""

from __future__ import annotations

import math

import numpy as np
import pytest

from moma_env.env.observations import uncertainty
from moma_env.top_observer_v0 import parallel_env


def feature_index(env, agent: str, name: str) -> int:
    return [f.name for f in env.unwrapped.layout.features[agent]].index(name)


def test_observations_carry_the_standard_deviations_and_infos_the_covariance():
    env = parallel_env(action_mode="switching", observer_agent=True)
    obs, infos = env.reset(seed=3)
    pos_i = feature_index(env, "ugv_0", "own.position_std")
    head_i = feature_index(env, "ugv_0", "own.heading_std")
    # Initial references define the world frame: zero covariance.
    assert not infos["ugv_0"]["covariance"].any()
    assert obs["ugv_0"][pos_i] == 0.0 and obs["ugv_0"][head_i] == 0.0
    seen_positive = False
    for _ in range(200):
        actions = {a: 1 if a == "ugv_0" else 0 for a in env.agents if a != "observer"}
        actions["observer"] = np.zeros(env.action_space("observer").shape, dtype=np.float32)
        obs, _, term, trunc, infos = env.step(actions)
        est = env.unwrapped.estimator.estimate("ugv_0")
        np.testing.assert_array_equal(infos["ugv_0"]["covariance"], est.covariance)
        expected = uncertainty(est.position_std_m, est.heading_std_rad)
        np.testing.assert_allclose(obs["ugv_0"][[pos_i, head_i]], np.float32(expected))
        seen_positive |= est.position_std_m > 0.0
        if any(term.values()) or any(trunc.values()):
            break
    assert seen_positive
    uav = env.unwrapped.estimator.estimate("uav")
    i = feature_index(env, "observer", "own.position_std")
    assert obs["observer"][i] == np.float32(uncertainty(uav.position_std_m, uav.heading_std_rad)[0])
    np.testing.assert_array_equal(infos["observer"]["covariance"], uav.covariance)


def test_uncertainty_features_scale_and_clip():
    assert uncertainty(0.05, 0.02) == pytest.approx([0.5, 0.2])
    assert uncertainty(3.0, 1.0) == [1.0, 1.0]
    assert uncertainty(math.nan, math.nan) == [1.0, 1.0]


def test_a_request_that_needs_a_settling_robot_is_refused_with_window():
    """With a dwell shorter than the switch window, the dwell ends before the window
    is ready: the request is refused with ``window`` until it is, then granted."""
    env = parallel_env(action_mode="switching", observer_agent=False, dwell_s=0.2)
    env.reset(seed=1)
    estimator = env.unwrapped.estimator
    reasons: list[str] = []
    stopped = False
    for step in range(400):
        stopped = stopped or step >= 40
        _, _, term, trunc, infos = env.step({"ugv_0": 0 if stopped else 1, "ugv_1": 1 if stopped else 0})
        reasons += infos["ugv_1"]["refused"]
        if "mobile:ugv_1" in infos["ugv_1"]["events"] or any(term.values()) or any(trunc.values()):
            break
    assert "window" in reasons
    assert "mobile:ugv_1" in infos["ugv_1"]["events"]
    # Granted once ugv_0's window was ready: it is a reference now.
    assert estimator.estimate("ugv_0").phase.value == "reference"


def test_env_public_state_for_readers():
    env = parallel_env(action_mode="switching", observer_agent=False)
    env.reset(seed=0)
    core = env.unwrapped
    assert core.devices == ("ugv_0", "ugv_1") and core.sleds == ()
    assert [b[0] for b in core.boards] == ["ugv_0", "ugv_1"]
    views = core.board_views()
    assert [v.board_id for v in views] == [b[1] for b in core.boards] and all(v.up_m is not None for v in views)
    env.step({"ugv_0": 1, "ugv_1": 0})
    assert core.steps == 1 and core.mobile_devices == frozenset({"ugv_0"}) and core.switches_total == 1
    assert core.refused_total == 0 and list(core.cameras)
    with pytest.raises(TypeError):
        core.cameras["x"] = None

"""``tracking``: the UAV tracking controller's settings as an env option."""

from __future__ import annotations

import numpy as np
import pytest

from moma_env.config import ConfigError
from moma_env.control import TrackingControllerConfig
from moma_env.env.config import EnvConfig
from moma_env.env.factory import parallel_env


def altitudes(env, steps: int) -> list[float]:
    env.reset(seed=3)
    out = []
    for _ in range(steps):
        env.step({a: 1 for a in env.agents})
        out.append(env.frame.uavs["uav"].z)
    return out


def test_the_default_is_the_controllers_own_and_a_mapping_sets_its_fields():
    assert parallel_env("top_observer").config.tracking == TrackingControllerConfig()
    env = parallel_env("top_observer", tracking={"fill": 0.3, "max_depth": 4.0})
    assert env.config.tracking == TrackingControllerConfig(fill=0.3, max_depth=4.0)


def test_a_larger_fill_flies_the_uav_lower():
    default = altitudes(parallel_env("top_observer", n_ugvs=3), 60)
    close = altitudes(parallel_env("top_observer", n_ugvs=3, tracking={"fill": 0.8}), 60)
    assert abs(default[0] - close[0]) < 0.01  # the same start, one step apart
    assert np.mean(close[-20:]) < np.mean(default[-20:]) - 0.2


def test_bad_settings_are_refused_naming_the_field():
    with pytest.raises(ConfigError, match="tracking.fill"):
        parallel_env("top_observer", tracking={"fill": 2.0})
    with pytest.raises(ConfigError, match="tracking"):
        parallel_env("top_observer", tracking={"nope": 1.0})
    with pytest.raises(ConfigError, match="env.tracking"):
        EnvConfig(tracking={"fill": 0.3})

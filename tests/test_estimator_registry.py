"""Estimators by name: the registry, the env's ``localiser`` option and the experiments' ``localiser``."""

from __future__ import annotations

import numpy as np
import pytest

from moma_env.env.factory import parallel_env
from moma_env.config import ConfigError
from moma_env.env.config import EnvConfig
from moma_env.estimator import EstimatorConfig, MomaEstimator
from moma_env.estimator.registry import ESTIMATORS, localiser_factory
from moma_env.sim import Localiser
from training.experiments.square import SquareConfig


def available(name: str) -> bool:
    try:
        localiser_factory(name)
    except ImportError:
        return False
    return True


@pytest.mark.parametrize("name", list(ESTIMATORS))
def test_every_name_builds_a_localiser(name):
    if not available(name):
        pytest.skip(f"{name} needs an optional extra")
    assert isinstance(localiser_factory(name)(EstimatorConfig()), Localiser)


def test_moma_is_the_paper_estimator_and_fused_weights_by_information():
    assert localiser_factory("moma") is MomaEstimator
    fused = localiser_factory("fused")(EstimatorConfig(window=7))
    assert isinstance(fused, MomaEstimator)
    assert fused.config.fusion == "information" and fused.config.window == 7


@pytest.mark.parametrize(
    ("make", "field"),
    [(lambda: EnvConfig(localiser="kalman"), "env.localiser"), (lambda: SquareConfig(localiser="kalman"), "square.localiser")],
)
def test_an_unknown_name_is_a_config_error_naming_the_field(make, field):
    with pytest.raises(ConfigError, match=field):
        make()


def test_the_env_selects_an_estimator_by_name_and_moma_by_name_is_the_default():
    runs = {}
    for localiser in (None, "moma", "fused"):
        options = {} if localiser is None else {"localiser": localiser}
        env = parallel_env("top_observer", max_cycles=20, **options)
        obs, _ = env.reset(seed=3)
        trace = [np.concatenate([np.ravel(v) for v in obs.values()])]
        for _ in range(10):
            obs, *_ = env.step({a: env.action_space(a).sample() * 0 for a in env.agents})
            trace.append(np.concatenate([np.ravel(v) for v in obs.values()]))
        runs[localiser] = (np.array(trace), env.estimator.config.fusion)
    np.testing.assert_array_equal(runs[None][0], runs["moma"][0])
    assert runs[None][1] == "mean" and runs["fused"][1] == "information"


@pytest.mark.parametrize("name", ["ekf", "graph"])
def test_the_env_runs_with_the_baselines_by_name(name):
    if not available(name):
        pytest.skip(f"{name} needs an optional extra")
    env = parallel_env("top_observer", max_cycles=20, localiser=name)
    env.reset(seed=1)
    for _ in range(10):
        env.step({a: env.action_space(a).sample() * 0 for a in env.agents})
    estimates = env.estimator.estimates()
    assert set(estimates) >= set(env.simulation.ugvs)
    assert all(e.T_w_b is not None for name, e in estimates.items() if name in env.simulation.ugvs)


def test_an_env_with_the_ekf_copies_mid_episode_and_continues_the_same():
    import pickle

    env = parallel_env("top_observer", max_cycles=20, localiser="ekf")
    env.reset(seed=2)
    actions = {a: env.action_space(a).sample() * 0 for a in env.agents}
    env.step(actions)
    twin = pickle.loads(pickle.dumps(env))
    for _ in range(5):
        a, *_ = env.step(actions)
        b, *_ = twin.step(actions)
    for agent in a:
        np.testing.assert_array_equal(np.ravel(a[agent]), np.ravel(b[agent]))
    np.testing.assert_array_equal(env.estimator.covariance, twin.estimator.covariance)

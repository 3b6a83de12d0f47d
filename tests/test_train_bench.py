"""The training benchmark's rows: where a training run's time goes (env, collection, learner)."""

from __future__ import annotations

import pytest

pytest.importorskip("stable_baselines3")


def test_sb3_row_splits_the_time_into_env_collection_and_learner():
    from training.train.bench import format_training, training_fps

    row = training_fps(512, envs=2, route="shared", scenario="top_observer")
    assert row["timesteps"] >= 512
    # The env's step is part of the collection, and collection plus learning part of the run.
    assert 0.0 < row["env_s"] < row["collect_s"]
    assert row["learn_s"] > 0.0
    assert row["collect_s"] + row["learn_s"] <= row["seconds"]
    env_steps = row["timesteps"] / 2  # two UGV slots per env step on the shared route
    bound = env_steps / (row["collect_s"] - row["env_s"] + row["learn_s"])
    assert row["learner_bound_env_steps_per_s"] == pytest.approx(bound)
    assert row["learner_bound_env_steps_per_s"] > row["env_steps_per_s"]
    table = "\n".join(format_training([row]))
    assert "learner bound" in table and f"{bound:.0f}" in table
    assert f"{100 * row['env_s'] / row['seconds']:.0f}" in table


def test_centralised_row_times_the_env_under_its_wrappers():
    from training.train.bench import training_fps

    row = training_fps(256, envs=1, route="centralised", scenario="top_observer")
    assert 0.0 < row["env_s"] < row["collect_s"]
    assert row["learner_bound_env_steps_per_s"] > row["env_steps_per_s"]


def test_the_env_clock_times_the_vec_env_under_the_wrappers():
    """``training_fps`` times ``venv.unwrapped``'s ``step_wait``: SB3's innermost VecEnv, under
    ``VecNormalize`` and ``VecMonitor``, whose ``step_wait`` is where the copies step."""
    import gymnasium
    from stable_baselines3.common.vec_env import DummyVecEnv, VecMonitor, VecNormalize

    import moma_env  # noqa: F401  (registers the ids)

    inner = DummyVecEnv([lambda: gymnasium.make("moma_env/TopObserver-v0")])
    try:
        assert VecNormalize(VecMonitor(inner)).unwrapped is inner
        assert inner.unwrapped is inner
    finally:
        inner.close()

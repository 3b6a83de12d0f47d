"""``EnvConfig.switch_horizon_s``: the observations' timer since the last switch, its
default, and how a training run, its policy and its evaluations carry another."""

from __future__ import annotations

import numpy as np
import pytest

from agents.learned import LearnedPolicy
from moma_env.config import ConfigError
from moma_env.env.config import DEFAULT_SWITCH_HORIZON_S
from moma_env.env.factory import parallel_env
from training.cli import build_parser
from training.evaluation import evaluate
from training.train.config import TrainConfig
from training.train.evaluation import live_policy
from training.train.run import train


def timer_index(env, agent: str = "ugv_0") -> int:
    return [f.name for f in env.layout.features[agent]].index("time_since_switch")


def held_timers(horizon: float | None, steps: int) -> list[float]:
    """The UGVs' timer over ``steps`` steps of every robot holding, from a fresh episode."""
    options = {} if horizon is None else {"switch_horizon_s": horizon}
    env = parallel_env("top_observer", **options)
    env.reset(seed=3)
    i = timer_index(env)
    timers = []
    for _ in range(steps):
        obs, *_ = env.step({a: 0 for a in env.agents})
        timers.append(float(obs["ugv_0"][i]))
    return timers


def test_by_default_the_timer_stops_at_five_seconds_of_holding_and_the_observation_then_stays():
    env = parallel_env("top_observer")
    env.reset(seed=3)
    dt = 1.0 / env.scenario.world.control_hz
    steps = int(round(2 * DEFAULT_SWITCH_HORIZON_S / dt))
    timers = held_timers(None, steps)
    assert timers[0] < 1.0
    assert timers[-1] == 1.0
    first_one = timers.index(1.0)
    assert first_one * dt == pytest.approx(DEFAULT_SWITCH_HORIZON_S, abs=2 * dt)
    assert all(t == 1.0 for t in timers[first_one:])


def test_a_longer_horizon_keeps_the_timer_moving_while_every_robot_holds():
    env = parallel_env("top_observer", switch_horizon_s=90.0)
    env.reset(seed=3)
    dt = 1.0 / env.scenario.world.control_hz
    timers = held_timers(90.0, int(round(10.0 / dt)))
    assert all(b > a for a, b in zip(timers, timers[1:]))
    # The feature is the time since the switch (the episode's start here) over the horizon.
    assert timers[-1] == pytest.approx(len(timers) * dt / 90.0, abs=2 * dt / 90.0)
    # Everything else is the default env's observation.
    default = parallel_env("top_observer")
    obs_long, _ = env.reset(seed=5)
    obs_default, _ = default.reset(seed=5)
    i = timer_index(env)
    for _ in range(30):
        actions = {a: 1 for a in env.agents}
        obs_long, *_ = env.step(actions)
        obs_default, *_ = default.step(actions)
    for agent in obs_long:
        assert np.array_equal(np.delete(obs_long[agent], i), np.delete(obs_default[agent], i))


@pytest.mark.parametrize("bad, message", [(0, "must be > 0"), (-2.0, "must be > 0"), (float("nan"), "finite"), (True, "number"), ("5", "number")])
def test_a_bad_horizon_is_refused_naming_the_field(bad, message):
    with pytest.raises(ConfigError, match=f"env.switch_horizon_s.*{message}"):
        parallel_env("top_observer", switch_horizon_s=bad)
    with pytest.raises(ConfigError, match=f"switch_horizon_s.*{message}"):
        TrainConfig(scenario="top_observer", switch_horizon_s=bad)


def test_a_run_trained_with_a_horizon_records_it_and_its_policy_fits_only_envs_with_it(tmp_path):
    config = TrainConfig(
        scenario="top_observer", steps=256, envs=1, n_steps=32, batch_size=32, net_arch=(8,), max_cycles=40,
        checkpoint_every=10**6, switch_horizon_s=60.0,
    )
    assert config.env_options["switch_horizon_s"] == 60.0
    assert "switch_horizon_s" not in TrainConfig(scenario="top_observer").env_options
    manifest = train(config, tmp_path / "run")
    assert manifest["config"]["switch_horizon_s"] == 60.0
    policy = LearnedPolicy.from_dir(tmp_path / "run")
    assert policy.env_options["switch_horizon_s"] == 60.0
    # The evaluations during training build the run's envs too.
    assert live_policy(policy.model, config).env_options["switch_horizon_s"] == 60.0
    env = parallel_env("top_observer", observer_agent=False)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="switch_horizon_s=60.0; the env has 5.0"):
        policy.reset(env)
    # The evaluation builds the env the policy fits.
    result = evaluate("top_observer", policy, 1, 10000, max_cycles=20, **{k: v for k, v in policy.env_options.items() if k != "action_mode"})
    assert len(result.episodes) == 1


@pytest.mark.parametrize("backend", ["rllib", "torchrl"])
@pytest.mark.parametrize(
    "flag, value, field",
    [("--switch-horizon", "30", "switch_horizon_s"), ("--team-action", "one_start", "team_action"), ("--init-from", "runs/x", "init_from")],
)
def test_the_other_backends_refuse_the_sb3_backends_env_flags(backend, flag, value, field):
    """The timer (this file), the team action (tests/test_team_action.py) and the start from
    another run's weights (tests/test_init_from.py) are the sb3 backend's."""
    from training.train.rllib_command import rllib_config_from_args
    from training.train.torchrl_command import torchrl_config_from_args

    scenario = "top_observer" if backend == "rllib" else "top_observer_team4"
    algo = ["--algo", "maskable_ppo"] if backend == "torchrl" else []
    args = build_parser().parse_args(["train", "--backend", backend, "--scenario", scenario, *algo, flag, value, "--out", "unused"])
    from_args = rllib_config_from_args if backend == "rllib" else torchrl_config_from_args
    with pytest.raises(ConfigError, match=f"{field}.*drop {flag}"):
        from_args(args)

"""A training run's envs build only the infos its slots read, and learn the same for it."""

from __future__ import annotations

import pytest

pytest.importorskip("stable_baselines3")
torch = pytest.importorskip("torch")

from agents.learned import torch_threads
from training.train.config import TrainConfig
from training.train.envs import env_spec, make_vec_env, wrap_normalisation
from training.train.models import build_model, training_logger
from training.train.shared_vec_env import SharedPolicyVecEnv, TeamVecEnv
from training.train.team_slots import SLOT_INFO_KEYS

SB3_KEYS = {"TimeLimit.truncated", "terminal_observation", "episode"}


def trained_parameters(config: TrainConfig, every_key: bool) -> tuple[dict, list[dict]]:
    """The policy's parameters after ``config.steps`` timesteps, with the run's own envs or
    (``every_key``) the same copies carrying every info key; and the last step's infos."""
    if every_key:
        adapter = SharedPolicyVecEnv if config.route == "shared" else TeamVecEnv
        venv = adapter(env_spec(config), config.envs)
        venv.seed(config.seed)
    else:
        venv = make_vec_env(config, config.seed)
    venv = wrap_normalisation(venv, config)
    seen: list[dict] = []
    step_wait = venv.venv.step_wait

    def keep_infos():
        result = step_wait()
        seen[:] = result[3]
        return result

    venv.venv.step_wait = keep_infos
    try:
        with torch_threads(1):
            model = build_model(config, venv)
            model.set_logger(training_logger(None))
            model.learn(config.steps)
        return {k: v.clone() for k, v in model.policy.state_dict().items()}, list(seen)
    finally:
        venv.close()


@pytest.mark.parametrize(
    "config",
    [
        TrainConfig(scenario="top_observer_team4", algo="maskable_ppo", envs=2, n_steps=32, steps=256, max_cycles=40),
        TrainConfig(scenario="top_observer_team4_legs", algo="maskable_ppo", route="centralised", team_action="one_start",
                    envs=2, n_steps=32, steps=128, max_cycles=40),
    ],
    ids=["shared", "centralised one_start"],
)
def test_the_run_learns_the_same_with_the_slots_infos_alone(config):
    lean, lean_infos = trained_parameters(config, every_key=False)
    full, full_infos = trained_parameters(config, every_key=True)
    assert lean.keys() == full.keys()
    assert all(torch.equal(lean[k], full[k]) for k in lean)
    assert any(not torch.equal(v, torch.zeros_like(v)) for v in lean.values())
    for info in lean_infos:  # a UGV's own info, or the team's: agent -> info
        agent_infos = [info] if config.route == "shared" else [v for k, v in info.items() if k not in SB3_KEYS]
        for agent_info in agent_infos:
            assert set(agent_info) - SB3_KEYS <= set(SLOT_INFO_KEYS) and "action_mask" in agent_info
    assert any("truth" in info or "truth" in next(iter(info.values())) for info in full_infos)

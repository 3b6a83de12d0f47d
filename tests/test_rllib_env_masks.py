"""The RLlib env wrapper's masks (moma_env/integrations/rllib_env.py, no Ray needed): taken
from the step's infos when they carry them, computed otherwise, the same either way."""

from __future__ import annotations

import numpy as np
import pytest

from moma_env.integrations.rllib_env import MASK_KEY, OBS_KEY, masked_parallel_env


@pytest.mark.parametrize(("configuration", "masks_in_infos"), [("top_observer_team4", True), ("top_observer", False)])
def test_the_observed_masks_are_the_rules_and_come_from_the_infos_when_they_carry_them(configuration, masks_in_infos):
    env = masked_parallel_env(configuration, {"max_cycles": 40, "random_scenarios": True})
    raw = env.unwrapped
    assert raw.config.action_masks is masks_in_infos
    computed = []
    action_masks = raw.action_masks

    def counted():
        computed.append(1)
        return action_masks()

    raw.action_masks = counted
    obs, infos = env.reset(seed=4)
    rng = np.random.default_rng(0)
    steps = 0
    while env.agents:
        for agent, o in obs.items():
            np.testing.assert_array_equal(o[MASK_KEY], raw.action_mask(agent).astype(np.float32))
            assert o[OBS_KEY].shape == raw.observation_space(agent).shape
        actions = {a: int(rng.choice(np.flatnonzero(obs[a][MASK_KEY]))) for a in env.agents}
        obs, _, _, _, infos = env.step(actions)
        steps += 1
    assert steps == 40
    # the infos' masks are made by the step itself (counted), the wrapper asks for none more
    wrapper_calls = len(computed) - (steps + 1 if masks_in_infos else 0)
    assert wrapper_calls == (0 if masks_in_infos else steps + 1)

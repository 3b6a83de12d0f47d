"""Action masks through Gymnasium's wrappers, and MaskablePPO on a ``gymnasium.make`` env.

``gymnasium.make`` wraps the centralised team (``OrderEnforcing``,
``PassiveEnvChecker``); Gymnasium 1.x wrappers forward no unknown attribute, so the
masks are reached with ``get_wrapper_attr``, as sb3-contrib does.
"""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest

import moma_env  # noqa: F401  (registers the ids)
from moma_env.registration import GYMNASIUM_IDS, TASK_GYMNASIUM_IDS

sb3_contrib = pytest.importorskip("sb3_contrib")
from sb3_contrib.common.maskable.utils import get_action_masks, is_masking_supported  # noqa: E402


@pytest.mark.parametrize("env_id", sorted({**GYMNASIUM_IDS, **TASK_GYMNASIUM_IDS}))
def test_the_masks_are_reachable_through_the_wrappers(env_id):
    team = gymnasium.make(env_id, action_mode="switching")
    try:
        assert team is not team.unwrapped  # wrapped by make
        team.reset(seed=1)
        masks = team.get_wrapper_attr("action_masks")()
        assert masks.dtype == bool and masks.shape == (int(np.sum(team.action_space.nvec)),)
        np.testing.assert_array_equal(masks, team.unwrapped.action_masks())
        assert is_masking_supported(team)
        np.testing.assert_array_equal(get_action_masks(team), masks)
    finally:
        team.close()


def test_maskable_ppo_trains_on_a_gymnasium_make_env_and_honours_masks():
    from sb3_contrib import MaskablePPO

    team = gymnasium.make("moma_env/TopObserverTeam4-v0")
    model = MaskablePPO("MlpPolicy", team, n_steps=64, batch_size=32, n_epochs=1, seed=0, device="cpu",
                        policy_kwargs={"net_arch": [16]})
    model.learn(256)
    assert model.num_timesteps == 256
    obs, _ = team.reset(seed=3)
    nvec = team.action_space.nvec
    only_hold = np.concatenate([np.eye(n, dtype=bool)[0] for n in nvec])  # every robot's first action only
    for _ in range(5):
        action, _ = model.predict(obs, action_masks=only_hold, deterministic=False)
        assert np.all(action == 0)
    team.close()

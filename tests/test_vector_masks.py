"""A batch's action masks come from its last step's infos when they carry them
(``EnvConfig.action_masks``), computed once; a call on one copy recomputes that copy's."""

from __future__ import annotations

import numpy as np
import pytest

from moma_env import vector
from moma_env.env.parallel import MomaParallelEnv
from moma_env.vector.sharded import copy_action_masks

OPTIONS = {"n_ugvs": 3, "action_mode": "switching", "action_masks": True, "commit_legs": True, "max_cycles": 30}


def _fresh(envs) -> dict[str, np.ndarray]:
    """Every copy's masks computed now, stacked."""
    rows = [envs.call_at(i, copy_action_masks) for i in range(envs.num_envs)]
    return {a: np.stack([row[a] for row in rows]) for a in rows[0]}


def _same(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> bool:
    return a.keys() == b.keys() and all(a[k].dtype == b[k].dtype and np.array_equal(a[k], b[k]) for k in a)


def _advance_first_robot(env: MomaParallelEnv) -> None:
    """Step one copy alone, its first UGV asked to advance (its committed leg changes its mask)."""
    actions = {a: 0 for a in env.agents}
    actions[env.agents[0]] = 1
    env.step(actions)


@pytest.fixture(params=[None, 2], ids=["in-process", "two-workers"])
def envs(request):
    batch = vector.make("top_observer", 3, workers=request.param, **OPTIONS)
    yield batch
    batch.close()


def test_the_masks_after_reset_and_steps_are_those_of_the_copies(envs):
    envs.reset(seed=4)
    assert _same(envs.action_masks(), _fresh(envs))
    rng = np.random.default_rng(0)
    for _ in range(40):  # through autoresets (max_cycles 30)
        envs.step(envs.sample_actions(rng))
        assert _same(envs.action_masks(), _fresh(envs))


def test_a_call_on_one_copy_recomputes_its_masks(envs):
    envs.reset(seed=1)
    before = envs.action_masks()
    envs.call_at(1, _advance_first_robot)
    after = envs.action_masks()
    assert _same(after, _fresh(envs))
    assert not _same(after, before)  # the call changed copy 1's masks: they were not kept
    for agent in before:
        assert np.array_equal(after[agent][[0, 2]], before[agent][[0, 2]])


def test_reset_at_recomputes_that_copys_masks(envs):
    envs.reset(seed=1)
    envs.call_at(2, _advance_first_robot)
    envs.step({a: np.zeros(3, dtype=np.int64) for a in envs.possible_agents})
    envs.reset_at(2, seed=1)
    assert _same(envs.action_masks(), _fresh(envs))


def test_the_returned_masks_are_the_callers(envs):
    envs.reset(seed=0)
    first = envs.action_masks()
    for rows in first.values():
        rows[:] = 0
    assert _same(envs.action_masks(), _fresh(envs))


def test_the_masks_are_computed_once_per_step(monkeypatch):
    calls = []
    masks = MomaParallelEnv.action_masks

    def counted(self):
        calls.append(self)
        return masks(self)

    monkeypatch.setattr(MomaParallelEnv, "action_masks", counted)
    envs = vector.make("top_observer", 4, **OPTIONS)
    envs.reset(seed=0)
    rng = np.random.default_rng(0)
    for _ in range(5):
        envs.step(envs.sample_actions(rng))
        envs.action_masks()
    assert len(calls) == 4 * 6  # each copy's infos at reset and at each step, none for action_masks()


def test_without_masks_in_the_infos_they_are_computed():
    envs = vector.make("top_observer", 2, n_ugvs=3, action_mode="switching", max_cycles=30)
    envs.reset(seed=0)
    envs.step(envs.sample_actions(np.random.default_rng(0)))
    assert _same(envs.action_masks(), _fresh(envs))

"""Behaviour cloning from a scripted teacher (``moma-env train --pretrain``): what the
demonstrations hold, DAgger's labels, the normalisation statistics, the cloning itself,
and a pretrained run's records and reproducibility.

Runs are tiny: plumbing and the direction of learning, not its final quality.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import VecNormalize

from agents.policies.base import ADVANCE, HOLD
from moma_env.config import ConfigError
from training.train.config import TrainConfig
from training.train.envs import env_spec, make_vec_env, wrap_normalisation
from training.train.models import build_model
from training.train.demonstrations import Demonstrations
from training.train.pretrain import ModelRowPolicy, behaviour_clone, choice_agreement, collect_demonstrations, discounted_returns, seed_normalisation
from training.train.run import PRETRAINING, train

TASK = "top_observer_team4"  # greedy parallel turns: several movers, commit_legs, action masks


def tiny(**changes) -> TrainConfig:
    base = dict(
        scenario=TASK, algo="maskable_ppo", steps=128, envs=2, n_steps=16, batch_size=64, net_arch=(16,), max_cycles=60,
        checkpoint_every=10**6, eval_episodes=1, eval_max_cycles=20, pretrain="greedy", pretrain_rows=480, pretrain_epochs=3,
        dagger_rounds=0, dagger_rows=240, dagger_epochs=2,
    )
    return TrainConfig(**(base | changes))


class KeepModel(BaseCallback):
    def _on_step(self) -> bool:
        return True


@pytest.mark.parametrize("route", ["shared", "centralised"])
def test_demonstrations_are_the_teachers_allowed_actions(route):
    config = tiny(route=route)
    demos = collect_demonstrations(env_spec(config), "greedy", 2, 400, seed=0, route=route)
    stride = 2 * 4 if route == "shared" else 2
    assert demos.stride == stride and len(demos) >= 400 and len(demos) % stride == 0
    per_agent = demos.masks.reshape(len(demos), -1, 2)
    actions = demos.actions.reshape(len(demos), -1)
    assert per_agent.shape[1] == (1 if route == "shared" else 4)
    chosen = np.take_along_axis(per_agent, actions[:, :, None], axis=2)[:, :, 0]
    assert chosen.all()  # the teacher never asks for what the rules refuse
    assert (actions == ADVANCE).any() and (actions == HOLD).any()
    venv = make_vec_env(config, 0)  # the run's own envs: the same observation rows
    assert demos.observations.shape == (len(demos), *venv.observation_space.shape)
    venv.close()


def test_the_pipeline_teacher_demonstrates_two_movers_on_the_bent_file():
    config = tiny(scenario="caterpillar_multi_bend4", route="centralised", max_cycles=400)  # the second pair starts at ~7 s
    demos = collect_demonstrations(env_spec(config), "pipeline", 2, 800, seed=0, route="centralised")
    actions = demos.actions.reshape(len(demos), -1)
    masks = demos.masks.reshape(len(demos), -1, 2)
    assert actions.shape[1] == 4
    assert np.take_along_axis(masks, actions[:, :, None], axis=2).all()  # only what the rules allow
    assert (actions == ADVANCE).sum(axis=1).max() == 2  # every other robot of the file at once
    assert not ((actions[:, :-1] == ADVANCE) & (actions[:, 1:] == ADVANCE)).any()  # never two neighbours


def test_a_greedy_teacher_with_a_leg_length_starts_its_legs_with_it():
    config = tiny(scenario="top_observer_team4_legs", pretrain="greedy@1.5", route="centralised", max_cycles=200)
    demos = collect_demonstrations(env_spec(config), "greedy@1.5", 2, 400, seed=0, route="centralised")
    actions = demos.actions.reshape(len(demos), -1)
    masks = demos.masks.reshape(len(demos), actions.shape[1], -1)
    assert masks.shape[2] == 5 and np.take_along_axis(masks, actions[:, :, None], axis=2).all()
    assert set(np.unique(actions)) <= {HOLD, ADVANCE, 3}  # 3: the 1.5 m leg; movers continue with ADVANCE
    assert (actions == 3).any()


def test_with_a_learner_the_learner_acts_and_the_teacher_labels():
    # A learner that holds wherever holding is allowed: no robot starts a leg, so the
    # observations never change much, while the teacher's labels ask robots to advance.
    config = tiny()

    def hold(observations, masks):
        return np.where(masks[:, HOLD], HOLD, ADVANCE)

    demos = collect_demonstrations(env_spec(config), "greedy", 2, 400, seed=0, learner=hold)
    free = demos.masks.all(axis=1)
    assert free.any()
    assert (demos.actions[free] == ADVANCE).any()  # the teacher would have moved
    taught = collect_demonstrations(env_spec(config), "greedy", 2, 400, seed=0)
    assert not np.array_equal(demos.observations, taught.observations)  # the states are the learner's
    assert np.array_equal(demos.observations[:8], taught.observations[:8])  # from the same first layouts


def test_a_collection_reports_each_tenth_of_its_steps_and_its_rows_stay_the_same():
    config = tiny(route="centralised")
    lines = []
    reported = collect_demonstrations(env_spec(config), "greedy", 2, 400, seed=0, route="centralised", report=lines.append)
    silent = collect_demonstrations(env_spec(config), "greedy", 2, 400, seed=0, route="centralised")
    assert [line.split(" %")[0] for line in lines] == [str(10 * k) for k in range(1, 10)]
    assert all("of 200 env steps, copies 0..1" in line for line in lines)  # 400 rows of 2 copies
    assert np.array_equal(reported.observations, silent.observations) and np.array_equal(reported.actions, silent.actions)


def test_the_choice_agreement_counts_the_rows_with_a_choice_only():
    config = tiny(route="centralised")
    demos = collect_demonstrations(env_spec(config), "greedy", 2, 400, seed=0, route="centralised")
    assert choice_agreement(demos, demos.actions) == 1.0
    per_agent = demos.masks.reshape(len(demos), 4, 2)
    forced = ~(per_agent.sum(axis=2) > 1).any(axis=1)
    choice = np.flatnonzero(~forced)
    other = demos.actions.copy()
    other[forced] = 1 - other[forced]  # a forced row's action changed: not counted
    assert choice_agreement(demos, other) == 1.0
    other[choice[:3]] = 1 - other[choice[:3]]
    assert choice_agreement(demos, other) == pytest.approx(1.0 - 3 / len(choice))
    only_forced = Demonstrations(*(getattr(demos, f)[forced] for f in ("observations", "actions", "masks", "rewards", "episode_ends", "complete")),
                                  demos.stride, demos.episodes, demos.successes)
    assert np.isnan(choice_agreement(only_forced, only_forced.actions))


def test_copies_driven_in_two_processes_give_the_rows_of_one():
    config = tiny()
    one = collect_demonstrations(env_spec(config), "greedy", 3, 480, seed=5, route="shared")
    two = collect_demonstrations(env_spec(config), "greedy", 3, 480, seed=5, route="shared", workers=2)  # copies 0-1 here, 2 there
    assert two.stride == one.stride == 3 * 4 and (two.episodes, two.successes) == (one.episodes, one.successes)
    for field in ("observations", "actions", "masks", "rewards", "episode_ends", "complete"):
        assert np.array_equal(getattr(two, field), getattr(one, field)), field


@pytest.mark.parametrize("route", ["shared", "centralised"])
def test_a_model_row_policy_acts_on_each_row_whatever_rows_come_with_it(route):
    config = tiny(route=route, net_arch=(64, 64))
    venv = make_vec_env(config, 0)
    model = build_model(config, venv)
    venv.close()
    demos = collect_demonstrations(env_spec(config), "greedy", 2, 200, seed=3, route=route)
    learner = ModelRowPolicy(model.policy, None)
    whole = learner(demos.observations, demos.masks)
    assert whole.shape == demos.actions.shape and whole.dtype.kind == "i"
    for part in (slice(0, 1), slice(1, 9), slice(5, None)):
        np.testing.assert_array_equal(learner(demos.observations[part], demos.masks[part]), whole[part])
    for i in range(0, len(demos), 7):  # SB3's own predict of the row alone
        alone, _ = model.policy.predict(demos.observations[i : i + 1], deterministic=True, action_masks=demos.masks[i : i + 1])
        np.testing.assert_array_equal(alone.reshape(whole[i].shape), whole[i])
    per_agent = demos.masks.reshape(len(demos), -1, 2)
    chosen = np.take_along_axis(per_agent, whole.reshape(len(demos), -1)[:, :, None], axis=2)[:, :, 0]
    assert chosen.all()  # the most likely allowed action


def test_a_model_row_policy_of_continuous_actions_is_refused():
    config = tiny(scenario="top_observer", action_mode="velocity", algo="ppo", pretrain=None)
    venv = make_vec_env(config, 0)
    model = build_model(config, venv)
    venv.close()
    with pytest.raises(TypeError, match="discrete actions"):
        ModelRowPolicy(model.policy, None)


def learner_refusing_in_workers(observations, masks):
    """A learner (module-level: it pickles to a worker) that holds in this process and
    refuses to act in a worker process."""
    import multiprocessing

    if multiprocessing.parent_process() is not None:
        raise ValueError("this learner refuses to act in a worker")
    return np.zeros((len(observations), 4), dtype=np.int64)


def test_an_error_in_a_worker_process_is_raised_here():
    config = tiny(route="centralised")
    with pytest.raises(ValueError, match="refuses to act in a worker"):
        collect_demonstrations(env_spec(config), "greedy", 3, 120, seed=0, route="centralised", learner=learner_refusing_in_workers, workers=2)


@pytest.mark.parametrize("workers", [0, 3, 1.5])
def test_more_processes_than_copies_are_refused(workers):
    with pytest.raises(ValueError, match="workers"):
        collect_demonstrations(env_spec(tiny()), "greedy", 2, 100, seed=0, workers=workers)


def test_discounted_returns_restart_at_episode_ends():
    # two slots, three steps; slot 0's episode ends at step 1
    rewards = np.array([1.0, 10.0, 2.0, 20.0, 4.0, 40.0])
    ends = np.array([False, False, True, False, False, False])
    out = discounted_returns(rewards, ends, 2, 0.5)
    assert np.allclose(out, [1 + 0.5 * 2, 10 + 0.5 * 20 + 0.25 * 40, 2, 20 + 0.5 * 40, 4, 40])


def test_seeded_statistics_are_those_the_wrapper_gathers_on_the_same_transitions():
    config = tiny()
    demos = collect_demonstrations(env_spec(config), "greedy", 2, 800, seed=0)
    seeded = wrap_normalisation(make_vec_env(config, 0), config)
    seed_normalisation(seeded, demos)
    stepped = wrap_normalisation(make_vec_env(config, 0), config)
    stepped.reset()
    steps = len(demos) // demos.stride
    for t in range(steps):
        if t == steps - 1:  # before the last step the wrapper has seen the observations the demonstrations hold
            obs_mean, obs_var = stepped.obs_rms.mean.copy(), stepped.obs_rms.var.copy()
        stepped.step(demos.actions[t * demos.stride:(t + 1) * demos.stride])
    assert np.array_equal(seeded.obs_rms.mean, obs_mean) and np.array_equal(seeded.obs_rms.var, obs_var)
    assert seeded.ret_rms.var == stepped.ret_rms.var and seeded.ret_rms.mean == stepped.ret_rms.mean
    seeded.close()
    stepped.close()


def test_cloning_brings_the_policy_to_the_teachers_choices():
    config = tiny(net_arch=(32,))
    demos = collect_demonstrations(env_spec(config), "greedy", 2, 2400, seed=0)
    venv = wrap_normalisation(make_vec_env(config, 0), config)
    model = build_model(config, venv)
    seed_normalisation(venv, demos)
    epochs = behaviour_clone(model, demos, venv.normalize_obs, venv.normalize_reward, 15, 64, seed=0)
    assert epochs[-1]["policy_loss"] < epochs[0]["policy_loss"]
    assert epochs[-1]["value_loss"] < epochs[0]["value_loss"]
    assert epochs[-1]["choice_accuracy"] > epochs[0]["choice_accuracy"]
    assert epochs[-1]["accuracy"] >= epochs[-1]["choice_accuracy"]  # forced rows are always right
    venv.close()


def test_a_pretrained_run_records_its_cloning_and_is_reproducible(tmp_path):
    weights = []
    for name in ("a", "b"):
        keep = KeepModel()
        manifest = train(tiny(dagger_rounds=1, eval_every=10**6), tmp_path / name, callbacks=[keep])
        weights.append(keep.model.policy.state_dict())
    assert all(torch.equal(weights[0][k], weights[1][k]) for k in weights[0])
    record = json.loads((tmp_path / "a" / PRETRAINING).read_text())
    assert record["teacher"] == "greedy" and len(record["rounds"]) == 2
    assert record["rounds"][1]["rows"] > record["rounds"][0]["rows"]
    assert "learner_episodes" in record["rounds"][0]
    evaluations = json.loads((tmp_path / "a" / "evaluations.json").read_text())["records"]
    assert evaluations[0]["num_timesteps"] == 0  # the cloned policy, before any PPO update
    assert manifest["config"]["pretrain"] == "greedy"
    keep = KeepModel()
    train(tiny(pretrain=None), tmp_path / "c", callbacks=[keep])
    assert not (tmp_path / "c" / PRETRAINING).exists()
    assert not all(torch.equal(weights[0][k], keep.model.policy.state_dict()[k]) for k in weights[0])


def test_a_cloned_run_with_worker_processes_learns_the_weights_of_one_process(tmp_path):
    # the teacher's rows and the DAgger round's learner (pickled to the worker) split over two processes
    weights = []
    for name, workers in (("one", None), ("two", 2)):
        keep = KeepModel()
        train(tiny(dagger_rounds=1, workers=workers, eval_every=10**6), tmp_path / name, callbacks=[keep])
        weights.append(keep.model.policy.state_dict())
    assert all(torch.equal(weights[0][k], weights[1][k]) for k in weights[0])
    rounds = [json.loads((tmp_path / name / PRETRAINING).read_text())["rounds"] for name in ("one", "two")]
    assert [r["rows"] for r in rounds[0]] == [r["rows"] for r in rounds[1]]


def test_the_frozen_scaling_is_vecnormalizes_and_pickles_after_loading(tmp_path):
    import pickle

    from agents.learned import ObservationScaling

    config = tiny()
    venv = wrap_normalisation(make_vec_env(config, 0), config)
    demos = collect_demonstrations(env_spec(config), "greedy", 2, 400, seed=0)
    seed_normalisation(venv, demos)
    venv.save(tmp_path / "stats.pkl")
    with open(tmp_path / "stats.pkl", "rb") as f:
        loaded = pickle.load(f)  # as LearnedPolicy.from_dir loads a run's statistics: no envs, and SB3 cannot pickle it again
    scaling = pickle.loads(pickle.dumps(ObservationScaling.from_vec_normalize(loaded)))
    rows = demos.observations * np.float32(1.5) + np.float32(0.25)  # some beyond the clip
    assert np.array_equal(scaling(rows), venv.normalize_obs(rows)) and scaling(rows).dtype == np.float32
    venv.close()


def test_another_dagger_teacher_labels_the_rounds_and_its_rows_alone_are_cloned(tmp_path, capsys):
    # cloned from 0.5 m legs, corrected by a teacher starting 1.5 m legs
    config = tiny(scenario="top_observer_team4_legs", route="centralised", pretrain="greedy@0.5", pretrain_rows=240,
                  dagger_teacher="greedy@1.5", dagger_rounds=2, dagger_rows=200, dagger_epochs=3, steps=0, eval_every=10**6,
                  progress_bar=True)
    train(config, tmp_path / "run")
    record = json.loads((tmp_path / "run" / PRETRAINING).read_text())
    assert record["teacher"] == "greedy@0.5" and record["dagger_teacher"] == "greedy@1.5"
    rows = [r["rows"] for r in record["rounds"]]
    assert rows[0] >= 240 and 200 <= rows[1] < rows[0] + 200 and rows[2] == 2 * rows[1]  # the second teacher's rows only
    # where a robot may start, the 1.5 m teacher starts one with the 1.5 m leg, never in the 0.5 m clone's rows
    agreement = [r["learner_choice_agreement"] for r in record["rounds"][:2]]
    assert agreement[0] == 0.0 and 0.0 <= agreement[1] <= 1.0 and "learner_choice_agreement" not in record["rounds"][2]
    err = capsys.readouterr().err.splitlines()
    assert err[0].startswith("moma-env train: pretraining: 240 rows of greedy@0.5 on 2 copies")
    assert any("DAgger round 2 of 2: 200 rows" in line for line in err)
    assert sum("cloned in" in line for line in err) == 3  # the cloning, then each round's fit
    assert any(f"chose as greedy@1.5 on {agreement[0]:.1%}" in line for line in err)
    same = json.loads((tmp_path / "run" / "manifest.json").read_text())["config"]
    assert TrainConfig.from_dict(same) == config


def test_the_rollout_teacher_labels_what_it_chooses_on_its_own_env():
    from moma_env.env.factory import parallel_env
    from training.evaluation.policies import load_policy

    config = tiny(scenario="top_observer_team4_legs", route="centralised", pretrain="rollout@1.5", max_cycles=None)
    spec = env_spec(config)
    demos = collect_demonstrations(spec, "rollout@1.5", 1, 2, seed=3, route="centralised")
    policy = load_policy("rollout@1.5", spec.configuration)
    env = parallel_env(spec.configuration, **(spec.options | dict(policy.env_options)))
    observations, infos = env.reset(seed=3)
    policy.reset(env, seed=3)
    expected = []
    for _ in range(len(demos)):
        actions = policy.act(observations, infos)
        expected.append([actions[a] for a in env.possible_agents if a in actions])
        observations, _, _, _, infos = env.step(actions)
    assert policy.lookaheads > 0  # a start was chosen by looking ahead
    assert demos.actions.tolist() == expected


@pytest.mark.parametrize(
    "changes, words",
    [
        ({"algo": "dqn"}, "PPO"),
        ({"algo": "ppo", "action_mode": "velocity"}, "switching"),
        ({"pretrain": "planned"}, "greedy"),
        ({"pretrain": "greedy@x"}, "leg length"),
        ({"pretrain": "pipeline@1.5"}, "greedy@L"),
        ({"dagger_rounds": -1}, "dagger_rounds"),
        ({"dagger_rows": 0}, "dagger_rows"),
        ({"dagger_teacher": "planned"}, "rollout@L"),
        ({"pretrain": "rollout_nowait@0"}, "leg length"),
        ({"pretrain": "rollout_nowat@1.5"}, "rollout_nowait@L"),
        ({"dagger_teacher": "gredy", "dagger_rounds": 1}, "did you mean 'greedy'?"),
        ({"dagger_teacher": "greedy", "dagger_rounds": 0}, "--dagger-rounds"),
        ({"dagger_teacher": "greedy", "dagger_rounds": 1, "pretrain": None}, "--pretrain"),
    ],
)
def test_bad_pretraining_settings_name_the_field(changes, words):
    with pytest.raises(ConfigError) as err:
        tiny(**changes)
    assert ("pretrain" in str(err.value) or "dagger" in str(err.value)) and words in str(err.value)


def test_the_normalisation_wrapper_is_optional():
    config = tiny(normalize=False)
    venv = wrap_normalisation(make_vec_env(config, 0), config)
    assert not isinstance(venv, VecNormalize)
    model = build_model(config, venv)
    demos = collect_demonstrations(env_spec(config), "greedy", 2, 400, seed=0)
    epochs = behaviour_clone(model, demos, None, None, 2, 64, seed=0)
    assert len(epochs) == 2 and np.isfinite(epochs[-1]["policy_loss"])
    venv.close()


def test_a_cloned_policy_may_be_kept_without_reinforcement_learning(tmp_path):
    manifest = train(tiny(steps=0, eval_every=10**6), tmp_path / "run")
    assert manifest["num_timesteps"] == 0 and (tmp_path / "run" / manifest["model"]).is_file()
    records = json.loads((tmp_path / "run" / "evaluations.json").read_text())["records"]
    assert [r["num_timesteps"] for r in records] == [0]
    with pytest.raises(ConfigError, match="steps"):
        tiny(steps=0, pretrain=None)

"""``moma-env train --kl-to-start BETA``: PPO's loss keeps the policy near the one the run
started from (training/train/kl_to_start.py).

The runs are tiny (networks of 8 units, a few hundred timesteps): the plumbing and the
direction of the penalty, not learning.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import torch
from sb3_contrib.common.maskable.distributions import MaskableCategoricalDistribution, MaskableMultiCategoricalDistribution
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.distributions import CategoricalDistribution, MultiCategoricalDistribution

from agents.learned import TrainingDirError
from moma_env.config import ConfigError
from training.cli import build_parser, main
from training.train.command import train_command
from training.train.config import TrainConfig
from training.train.models import training_logger
from training.train.kl_to_start import START_POLICY, KLToStart, install, kl_divergence, start_policy_from
from training.train.run import train


def tiny(**changes) -> TrainConfig:
    base = dict(scenario="top_observer", steps=256, envs=1, n_steps=32, batch_size=32, net_arch=(8,), max_cycles=40,
                checkpoint_every=10**6, eval_episodes=1, eval_max_cycles=20)
    return TrainConfig(**(base | changes))


@pytest.fixture(scope="module")
def source(tmp_path_factory):
    folder = tmp_path_factory.mktemp("source") / "run"
    return folder, train(tiny(seed=5), folder)


def _categorical(logits) -> CategoricalDistribution:
    logits = torch.as_tensor(logits, dtype=torch.float64)
    return CategoricalDistribution(logits.shape[-1]).proba_distribution(logits)


def test_the_divergence_is_kl_of_the_action_distributions():
    p_logits, q_logits = [[0.3, -1.0, 2.0], [0.0, 0.0, 0.0]], [[1.0, 0.5, -0.5], [2.0, -2.0, 0.0]]
    p, q = torch.softmax(torch.tensor(p_logits, dtype=torch.float64), -1), torch.softmax(torch.tensor(q_logits, dtype=torch.float64), -1)
    expected = (p * (p.log() - q.log())).sum(-1)
    assert torch.allclose(kl_divergence(_categorical(p_logits), _categorical(q_logits)), expected)
    assert torch.equal(kl_divergence(_categorical(p_logits), _categorical(p_logits)), torch.zeros(2, dtype=torch.float64))
    # A MultiDiscrete action: the sum over its sub-actions.
    both = MultiCategoricalDistribution([3, 3]).proba_distribution(torch.tensor([p_logits[0] + p_logits[1]], dtype=torch.float64))
    other = MultiCategoricalDistribution([3, 3]).proba_distribution(torch.tensor([q_logits[0] + q_logits[1]], dtype=torch.float64))
    assert torch.allclose(kl_divergence(both, other), expected.sum().reshape(1))


def test_a_box_actions_divergence_sums_its_dimensions():
    from stable_baselines3.common.distributions import DiagGaussianDistribution

    mean_p, mean_q = torch.tensor([[0.0, 1.0]]), torch.tensor([[0.5, -1.0]])
    log_std_p, log_std_q = torch.tensor([0.0, -1.0]), torch.tensor([0.5, 0.0])
    p = DiagGaussianDistribution(2).proba_distribution(mean_p, log_std_p)
    q = DiagGaussianDistribution(2).proba_distribution(mean_q, log_std_q)
    sp, sq = log_std_p.exp(), log_std_q.exp()
    expected = (log_std_q - log_std_p + (sp**2 + (mean_p - mean_q) ** 2) / (2 * sq**2) - 0.5).sum(-1)
    assert torch.allclose(kl_divergence(p, q), expected)


def test_masked_actions_add_nothing_to_the_divergence():
    """An action the masks refuse has probability 0 in both distributions: the divergence is
    that of the allowed actions, renormalised, and finite."""
    logits = torch.tensor([[0.3, -1.0, 2.0, 5.0]]), torch.tensor([[1.0, 0.5, -0.5, -9.0]])
    mask = np.array([[True, True, True, False]])
    dists = []
    for lg in logits:
        d = MaskableCategoricalDistribution(4).proba_distribution(lg)
        d.apply_masking(mask)
        dists.append(d)
    kl = kl_divergence(*dists)
    allowed = [_categorical(lg[:, :3]) for lg in logits]
    assert torch.isfinite(kl).all()
    assert torch.allclose(kl.double(), kl_divergence(*allowed), atol=1e-6)
    multi = []
    for lg in logits:
        d = MaskableMultiCategoricalDistribution([2, 2]).proba_distribution(lg)
        d.apply_masking(np.array([[True, True, True, False]]))
        multi.append(d)
    expected = kl_divergence(_categorical(logits[0][:, :2]), _categorical(logits[1][:, :2]))  # the second sub-action has one choice
    assert torch.allclose(kl_divergence(*multi).double(), expected, atol=1e-6)


def _model(seed: int = 0) -> PPO:
    import gymnasium

    env = gymnasium.make("moma_env/TopObserver-v0", max_cycles=10)  # the centralised team: a MultiDiscrete action
    model = PPO("MlpPolicy", env, n_steps=16, batch_size=16, seed=seed, device="cpu", policy_kwargs={"net_arch": [8]})
    model.set_logger(training_logger(None))  # what learn() would log to: nothing
    return model


def _copy(model: PPO):
    start = PPO("MlpPolicy", model.env, n_steps=16, batch_size=16, device="cpu", policy_kwargs={"net_arch": [8]}).policy
    start.load_state_dict(model.policy.state_dict())
    return start


def test_from_the_start_policy_the_loss_is_the_runs_own():
    """Where the policy is its start, the penalised evaluation is SB3's with the run's entropy bonus."""
    model = _model()
    obs = torch.as_tensor(np.stack([model.observation_space.sample() for _ in range(5)]))
    actions = torch.as_tensor(np.stack([model.action_space.sample() for _ in range(5)]))
    values, log_prob, entropy = model.policy.evaluate_actions(obs, actions)
    install(model, _copy(model), weight=3.0, ent_coef=0.25)
    assert model.ent_coef == 1.0
    v, lp, penalised = model.policy.evaluate_actions(obs, actions)
    assert torch.equal(v, values) and torch.equal(lp, log_prob)
    assert torch.allclose(penalised, 0.25 * entropy)


def test_the_penalty_pulls_the_policy_back_to_its_start():
    model = _model()
    start = _copy(model)
    with torch.no_grad():
        for parameter in model.policy.action_net.parameters():
            parameter.add_(torch.randn_like(parameter))
    install(model, start, weight=1.0, ent_coef=0.0)
    obs = torch.as_tensor(np.stack([model.observation_space.sample() for _ in range(64)]))
    actions = torch.as_tensor(np.stack([model.action_space.sample() for _ in range(64)]))

    def divergence() -> float:
        with torch.no_grad():
            return float(kl_divergence(model.policy.get_distribution(obs), start.get_distribution(obs)).mean())

    before = divergence()
    optimiser = torch.optim.Adam(model.policy.parameters(), lr=0.02)
    for _ in range(50):
        loss = -model.policy.evaluate_actions(obs, actions)[2].mean()  # SB3's entropy loss: here the penalty alone
        optimiser.zero_grad()
        loss.backward()
        optimiser.step()
    assert before > 0.01 and divergence() < 0.5 * before
    assert all(p.grad is None for p in start.parameters())  # the start policy stays as it was


def _policy_divergence(folder, manifest, start_folder, start_manifest) -> float:
    """Mean KL of a run's final policy from another's, on observations of the env."""
    final = PPO.load(folder / manifest["model"], device="cpu").policy
    start = PPO.load(start_folder / start_manifest["model"], device="cpu").policy
    rng = np.random.default_rng(0)
    obs = torch.as_tensor(rng.normal(size=(256, *final.observation_space.shape)).astype(np.float32))
    with torch.no_grad():
        return float(kl_divergence(final.get_distribution(obs), start.get_distribution(obs)).mean())


def test_a_penalised_run_stays_nearer_its_start_and_logs_the_divergence(source, tmp_path):
    folder, manifest = source
    runs = {beta: train(tiny(init_from=str(folder), learning_rate=3e-3, ent_coef=0.0, kl_to_start=beta), tmp_path / f"b{beta}")
            for beta in (0.0, 30.0)}
    free, kept = (_policy_divergence(tmp_path / f"b{beta}", runs[beta], folder, manifest) for beta in (0.0, 30.0))
    assert kept < 0.5 * free
    start = torch.load(tmp_path / "b30.0" / START_POLICY, weights_only=True)
    given = PPO.load(folder / manifest["model"], device="cpu").policy.state_dict()
    assert start.keys() == given.keys() and all(torch.equal(start[k], given[k]) for k in given)
    assert not (tmp_path / "b0.0" / START_POLICY).exists()
    header, *rows = (tmp_path / "b30.0" / "logs" / "progress_000000000000.csv").read_text().splitlines()
    column = header.split(",").index("train/kl_to_start")
    logged = [float(r.split(",")[column]) for r in rows if r.split(",")[column]]
    assert logged and all(math.isfinite(x) and x >= 0 for x in logged) and max(logged) > 0
    assert runs[30.0]["config"]["kl_to_start"] == 30.0


def test_a_resumed_run_measures_from_the_same_start(source, tmp_path):
    folder, _ = source
    out = tmp_path / "run"
    train(tiny(init_from=str(folder), kl_to_start=1.0, steps=128, checkpoint_every=64), out)
    written = torch.load(out / START_POLICY, weights_only=True)
    from training.train import kl_to_start

    seen = []
    original = kl_to_start.install

    def spy(model, start, weight, ent_coef):
        seen.append((start.state_dict(), weight, ent_coef))
        return original(model, start, weight, ent_coef)

    kl_to_start.install = spy
    try:
        final = train(tiny(init_from=str(folder), kl_to_start=1.0, steps=256, checkpoint_every=64), out, resume=True)
    finally:
        kl_to_start.install = original
    assert final["num_timesteps"] == 256 and len(seen) == 1
    state, weight, ent_coef = seen[0]
    assert weight == 1.0 and ent_coef == 0.01 and all(torch.equal(state[k], written[k]) for k in written)
    (out / START_POLICY).unlink()
    with pytest.raises(TrainingDirError, match=START_POLICY):
        start_policy_from(out, PPO.load(out / final["model"], device="cpu"))


@pytest.mark.parametrize(
    "changes, message",
    [({"kl_to_start": -1.0, "init_from": "runs/x"}, ">= 0"), ({"kl_to_start": float("nan"), "init_from": "runs/x"}, "finite"),
     ({"kl_to_start": 1.0}, "give --init-from or --pretrain"), ({"kl_to_start": 1.0, "init_from": "runs/x", "algo": "a2c"}, "PPO's loss")],
)
def test_bad_kl_to_start_settings_are_refused_naming_the_field(changes, message):
    with pytest.raises(ConfigError, match=f"^kl_to_start: .*{message}"):
        tiny(**changes)


def test_the_cli_takes_the_penalty_and_its_command_line_says_so(source, tmp_path, capsys):
    folder, _ = source
    out = tmp_path / "run"
    code = main(["train", "--scenario", "top_observer", "--timesteps", "64", "--num-envs", "1", "--n-steps", "32", "--batch-size", "32",
                 "--net", "8", "--max-cycles", "40", "--init-from", str(folder), "--kl-to-start", "0.5", "--out", str(out),
                 "--no-progress", "--json"])
    assert code == 0
    manifest = json.loads(capsys.readouterr().out)
    argv, missing = train_command(TrainConfig.from_dict(manifest["config"]), out)
    assert argv[argv.index("--kl-to-start") + 1] == "0.5" and missing == []
    assert "--kl-to-start" not in train_command(tiny(), out)[0]


@pytest.mark.parametrize("backend", ["rllib", "torchrl"])
def test_the_other_backends_refuse_the_penalty(backend):
    from training.train.rllib_command import rllib_config_from_args
    from training.train.torchrl_command import torchrl_config_from_args

    scenario = "top_observer" if backend == "rllib" else "top_observer_team4"
    algo = ["--algo", "maskable_ppo"] if backend == "torchrl" else []
    args = build_parser().parse_args(["train", "--backend", backend, "--scenario", scenario, *algo, "--kl-to-start", "1", "--out", "unused"])
    from_args = rllib_config_from_args if backend == "rllib" else torchrl_config_from_args
    with pytest.raises(ConfigError, match="kl_to_start.*drop --kl-to-start"):
        from_args(args)


class WeightsAtStart(BaseCallback):
    """The policy's weights as learning starts (after a cloning) and the penalty on it."""

    def _on_training_start(self) -> None:
        self.weights = {k: v.clone() for k, v in self.model.policy.state_dict().items()}
        self.penalised = isinstance(self.model.policy.evaluate_actions, KLToStart) and self.model.ent_coef == 1.0

    def _on_step(self) -> bool:
        return True


def test_after_a_cloning_the_start_policy_is_the_clone(tmp_path):
    config = TrainConfig(scenario="top_observer_team4", algo="maskable_ppo", steps=64, envs=2, n_steps=16, batch_size=32, net_arch=(8,),
                         max_cycles=60, checkpoint_every=10**6, pretrain="greedy", pretrain_rows=240, pretrain_epochs=2, dagger_rounds=0,
                         kl_to_start=2.0)
    at_start = WeightsAtStart()
    train(config, tmp_path / "run", callbacks=[at_start])
    written = torch.load(tmp_path / "run" / START_POLICY, weights_only=True)
    assert at_start.penalised and written.keys() == at_start.weights.keys()
    assert all(torch.equal(written[k], at_start.weights[k]) for k in written)
    assert (tmp_path / "run" / "pretrain.json").is_file()

"""A TorchRL MAPPO or IPPO run from start to finish, or resumed (``moma-env train --backend torchrl``).

One loop, TorchRL's parts: a ``Collector`` steps the batched env's TorchRL adapter
(:class:`moma_env.vector.torchrl.MomaTorchRLEnv`, ``config.envs`` copies) with the
shared actor for ``n_steps`` steps per copy, TorchRL's GAE computes every UGV's
advantage from the team reward, and ``MAPPOLoss`` (centralised critic) or
``IPPOLoss`` (independent critic) is minimised over ``num_epochs`` shuffled passes of
``minibatch_size`` env steps (each carrying every UGV), Adam, gradients clipped. The
critic's loss is taken on values normalised by a PopArt running normaliser (MAPPO's
recipe). Actions are drawn from the masked categorical distribution: the motion rules'
masks are part of the observation, so the actor never asks for a refused move.

Determinism: torch's generator is seeded with ``config.seed`` before the networks are
built and the env copies reset with ``seed + i``; on ``config.torch_threads`` threads
while collecting and ``update_threads`` for the updates (which run while every env copy
waits; recorded in the manifest) the same configuration gives the same weights
(``tests/test_train_torchrl.py``).

The output folder has the other backends' layout: ``manifest.json`` (written last,
naming a complete checkpoint; ``"backend": "torchrl"``), the checkpoint it names
(``checkpoint_<steps>.pt``: the actor's, critic's, optimiser's and normaliser's
state, written whole or not at all), and, with ``eval_every``, ``evaluations.json``,
``curves.csv`` and ``curves.png`` of the held-out evaluations, through the harness
(:class:`agents.torchrl_policy.TorchRLPolicy`). The manifest also records the time
spent collecting (the env and the actor's forward passes) and learning, so the
run's env steps per second, with and without the learner, are read from it.

``resume=True`` restores the networks, the optimiser and the normaliser from the
manifest's checkpoint and collects until ``config.steps``; the env copies restart from
new episodes seeded ``seed + steps + i`` (the run before the stop is not replayed).
"""

from __future__ import annotations

import datetime
import io
import re
import time
from pathlib import Path
from typing import Any

from agents.learned import MANIFEST, TrainingDirError, torch_threads
from agents.torchrl_policy import BACKEND, TorchRLPolicy, actor_network, critic_network, load_checkpoint, read_torchrl_manifest
from moma_env import ENV_VERSION
from moma_env.config import ConfigError
from moma_env.io import atomic_write_bytes, write_json
from training.provenance import library_versions
from training.train.backend_run import RunProgress, start_run
from training.train.evaluation import headline
from training.train.config import update_threads
from training.train.torchrl_config import TorchRLTrainConfig

__all__ = ["train_torchrl", "manifest_algorithm", "RESUMABLE_CHANGES", "GROUP"]

#: Fields a resumed run may change; every other must match the run's.
RESUMABLE_CHANGES = frozenset({"steps", "checkpoint_every", "eval_every", "eval_episodes", "eval_seed", "eval_max_cycles",
                               "eval_sample_actions", "torch_threads", "update_threads", "workers"})
#: The TorchRL group of the UGV agents (:data:`moma_env.vector.torchrl.UGV_GROUP`).
GROUP = "ugv"
_CHECKPOINT = re.compile(r"^checkpoint_\d{12}\.pt$")


class _Learner:
    """The env, the networks, the loss and the optimiser of one run."""

    def __init__(self, config: TorchRLTrainConfig, env_seed: int):
        import torch

        from moma_env.vector.torchrl import UGV_GROUP, MomaTorchRLEnv  # first: torchrl imported keeping the start method
        from tensordict.nn import TensorDictModule
        from torchrl.modules import MaskedCategorical, ProbabilisticActor
        from torchrl.modules.value_norm import PopArtValueNorm
        from torchrl.objectives import ValueEstimators
        from torchrl.objectives.multiagent import IPPOLoss, MAPPOLoss

        assert UGV_GROUP == GROUP
        self.config = config
        torch.manual_seed(config.seed)
        self.env = MomaTorchRLEnv(config.scenario, config.envs, seed=env_seed, workers=config.workers, **config.env_options)
        if list(self.env.group_map) != [GROUP]:
            raise ConfigError("scenario", f"{config.scenario!r} has agents outside the UGV group ({sorted(self.env.group_map)}); "
                                          "TorchRL runs train the UGVs with the observer flown by its controller")
        observation = self.env.observation_spec[GROUP, "observation"]
        action = self.env.full_action_spec[GROUP, "action"]
        self.n_agents = len(self.env.group_map[GROUP])
        self.obs_dim = int(observation.shape[-1])
        self.n_actions = int(action.space.n)
        self.actor_net = actor_network(self.n_agents, self.obs_dim, self.n_actions, config.net_arch)
        self.critic_net = critic_network(self.n_agents, self.obs_dim, config.net_arch, config.critic)
        self.actor = ProbabilisticActor(
            TensorDictModule(self.actor_net, in_keys=[(GROUP, "observation")], out_keys=[(GROUP, "logits")]),
            in_keys={"logits": (GROUP, "logits"), "mask": (GROUP, "action_mask")},
            out_keys=[(GROUP, "action")],
            distribution_class=MaskedCategorical,
            return_log_prob=True,
            log_prob_key=(GROUP, "action_log_prob"),
            spec=action,
        )
        critic = TensorDictModule(self.critic_net, in_keys=[(GROUP, "observation")], out_keys=[(GROUP, "state_value")])
        self.value_norm = PopArtValueNorm(shape=1)
        loss_class = MAPPOLoss if config.critic == "centralised" else IPPOLoss
        self.loss = loss_class(actor_network=self.actor, critic_network=critic, value_norm=self.value_norm,
                               clip_epsilon=config.clip_range, entropy_coeff=config.ent_coef)
        self.loss.set_keys(reward=(GROUP, "reward"), action=(GROUP, "action"), sample_log_prob=(GROUP, "action_log_prob"),
                           value=(GROUP, "state_value"), done=(GROUP, "done"), terminated=(GROUP, "terminated"))
        self.loss.make_value_estimator(ValueEstimators.GAE, gamma=config.gamma, lmbda=config.gae_lambda)
        self.optimiser = torch.optim.Adam(self.loss.parameters(), lr=config.learning_rate)
        self.collect_s = 0.0
        self.learn_s = 0.0

    def state(self) -> dict[str, Any]:
        return {
            "actor": self.actor_net.state_dict(), "critic": self.critic_net.state_dict(), "optimiser": self.optimiser.state_dict(),
            "value_norm": self.value_norm.state_dict(), "n_agents": self.n_agents, "obs_dim": self.obs_dim, "n_actions": self.n_actions,
            "net_arch": list(self.config.net_arch), "critic_kind": self.config.critic,
        }

    def restore(self, state: dict[str, Any], where: str) -> None:
        shapes = {"n_agents": self.n_agents, "obs_dim": self.obs_dim, "n_actions": self.n_actions}
        for key, value in shapes.items():
            if state[key] != value:
                raise TrainingDirError(f"the checkpoint {where!r} has {key}={state[key]}, this env gives {value}")
        self.actor_net.load_state_dict(state["actor"])
        self.critic_net.load_state_dict(state["critic"])
        self.optimiser.load_state_dict(state["optimiser"])
        self.value_norm.load_state_dict(state["value_norm"])

    def update(self, batch: Any) -> None:
        """PPO's epochs over one collected batch (``[envs, n_steps]`` env steps)."""
        import torch

        config = self.config
        with torch.no_grad():
            self.loss.value_estimator(batch, params=self.loss.critic_network_params, target_params=self.loss.target_critic_network_params)
        flat = batch.reshape(-1)
        n = flat.shape[0]
        parameters = list(self.loss.parameters())
        for _ in range(config.num_epochs):
            order = torch.randperm(n)
            for start in range(0, n - config.minibatch_size + 1, config.minibatch_size):
                terms = self.loss(flat[order[start:start + config.minibatch_size]])
                total = terms["loss_objective"] + terms["loss_critic"] + terms["loss_entropy"]
                self.optimiser.zero_grad()
                total.backward()
                torch.nn.utils.clip_grad_norm_(parameters, config.max_grad_norm)
                self.optimiser.step()


def _checkpoints(out: Path) -> list[Path]:
    return sorted(p for p in out.iterdir() if p.is_file() and _CHECKPOINT.match(p.name))


def _save(out: Path, learner: _Learner, config: TorchRLTrainConfig, steps: int, wall_time_s: float, extra: dict[str, Any]) -> dict[str, Any]:
    """Checkpoint at ``steps``, then the manifest naming it, then delete older checkpoints."""
    import torch

    name = f"checkpoint_{steps:012d}.pt"
    buffer = io.BytesIO()
    torch.save(learner.state(), buffer)
    atomic_write_bytes(out / name, buffer.getvalue())
    manifest = {
        "format": 1,
        "backend": BACKEND,
        "env_version": ENV_VERSION,
        "num_timesteps": int(steps),
        "algorithm": manifest_algorithm(config),
        "checkpoint": name,
        "config": config.to_dict(),
        "wall_time_s": float(wall_time_s),
        "collect_s": float(learner.collect_s),
        "learn_s": float(learner.learn_s),
        "saved_at": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "versions": library_versions(),
        **extra,
    }
    write_json(out / MANIFEST, manifest)
    for path in _checkpoints(out):
        if path.name != name:
            path.unlink(missing_ok=True)
    return manifest


def _evaluate(learner: _Learner, config: TorchRLTrainConfig) -> dict[str, Any]:
    """The held-out evaluation of the current actor through the harness; its headline numbers."""
    from training.evaluation.harness import evaluate

    policy = TorchRLPolicy(learner.actor_net, learner.n_agents, learner.obs_dim, config.scenario,
                           deterministic=not config.eval_sample_actions, torch_threads=config.torch_threads)
    result = evaluate(config.scenario, policy, config.eval_episodes, config.eval_seed, random_scenarios=True,
                      action_mode=config.action_mode, max_cycles=config.eval_max_cycles,
                      **{k: v for k, v in policy.env_options.items() if k != "action_mode"})
    return headline(result.summary)


def train_torchrl(config: TorchRLTrainConfig, out: str | Path, resume: bool = False) -> dict[str, Any]:
    """Train (or resume) the TorchRL run ``config`` in folder ``out``; return the final manifest.

    Raises:
        moma_env.io.RunFolderError: ``out`` holds another kind of run or files that are not a run.
        ConfigError: ``out`` holds a run and ``resume`` is False; the configuration
            differs from the resumed run's (naming the field); a configuration whose
            observer is an agent.
        agents.learned.TrainingDirError: ``resume`` without a loadable TorchRL run in ``out``.
    """
    from moma_env.vector.torchrl import MomaTorchRLEnv  # noqa: F401  (imports torchrl keeping multiprocessing's start method)
    from torchrl.collectors import Collector

    from training.train.checkpoint import source_revision

    out = Path(out)
    start = start_run(out, resume, config, read_torchrl_manifest, RESUMABLE_CHANGES, lambda folder: bool(_checkpoints(folder)))
    manifest, steps = start.manifest, start.steps
    timings = (0.0, 0.0) if manifest is None else (float(manifest.get("collect_s", 0.0)), float(manifest.get("learn_s", 0.0)))
    with torch_threads(config.torch_threads):
        learner = _Learner(config, env_seed=config.seed + steps)
        if manifest is not None:
            learner.restore(load_checkpoint(out / manifest["checkpoint"]), str(out / manifest["checkpoint"]))
        learner.collect_s, learner.learn_s = timings
        threads = update_threads(config)
        extra = {"git": source_revision(), "update_threads": threads}  # what the updates run on here (a resumed run records its own)
        progress = RunProgress(out, config, start, f"{config.scenario}: TorchRL {manifest_algorithm(config)}, seed {config.seed}")
        last_saved = last_eval = steps
        wall = progress.wall

        def evaluate_now() -> None:
            progress.evaluate(steps, lambda: _evaluate(learner, config))

        collector = Collector(learner.env, learner.actor, frames_per_batch=config.batch_size, total_frames=-1,
                              auto_register_policy_transforms=False)  # a feed-forward actor needs no InitTracker
        manifest_now = manifest
        try:
            batches = iter(collector)
            while steps < config.steps:
                began = time.perf_counter()
                batch = next(batches)
                collected = time.perf_counter()
                with torch_threads(threads):  # every env copy waits for the new weights
                    learner.update(batch)
                collector.update_policy_weights_()
                learner.collect_s += collected - began
                learner.learn_s += time.perf_counter() - collected
                steps += int(batch.numel())
                if steps - last_saved >= config.checkpoint_every and steps < config.steps:
                    manifest_now = _save(out, learner, config, steps, wall(), extra)
                    last_saved = steps
                if config.eval_every > 0 and steps - last_eval >= config.eval_every and steps < config.steps:
                    evaluate_now()
                    last_eval = steps
        finally:
            collector.shutdown()
        if config.eval_every > 0 and not progress.evaluated_at(steps):
            evaluate_now()
        if manifest_now is None or manifest_now["num_timesteps"] != steps:
            manifest_now = _save(out, learner, config, steps, wall(), extra)
    return manifest_now


def manifest_algorithm(config: TorchRLTrainConfig) -> str:
    """``"MAPPO"`` (centralised critic) or ``"IPPO"`` (independent critic)."""
    return "MAPPO" if config.critic == "centralised" else "IPPO"

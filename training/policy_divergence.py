"""How far a trained policy's actions are from another's, on the states the first reaches.

``python -m training.policy_divergence RUN START [--copies 8] [--steps 400] [--seed
5000000] [--sample-actions]`` drives ``--copies`` copies of RUN's own env (its scenario
with the options it trained with, centralised route), copy ``k`` first reset with seed
``--seed + k``, with RUN's policy for ``--steps`` steps (its most likely actions, or
sampled ones, seeded), and at every step compares RUN's action distribution with
START's (each policy with its own observation statistics and, where it masks, the
step's action masks): ``KL(RUN || START)`` in nats, over all rows and over the rows
where the masks leave a choice (the only rows where two masked policies can differ).
START is typically the run RUN started from (``--init-from``), to see how far training
moved it.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from typing import Any

import numpy as np
import torch
from gymnasium import spaces
from sb3_contrib.common.maskable.policies import MaskableActorCriticPolicy

from agents.learned import LearnedPolicy, read_manifest
from training.cli_args import int_at_least
from training.train.config import TrainConfig
from training.train.envs import env_spec
from training.train.kl_to_start import action_distributions, kl_divergence
from training.train.team_slots import EnvSpec
from training.train.shared_vec_env import TeamVecEnv

__all__ = ["divergences", "main"]


def _centralised(directory: str, scenario: str | None = None) -> LearnedPolicy:
    policy = LearnedPolicy.from_dir(directory, scenario)
    if policy.route != "centralised":
        raise ValueError(f"{directory!r} trained on the {policy.route} route; the divergence is measured on the centralised team")
    return policy


def _choice(masks: np.ndarray, action_space: spaces.Space) -> np.ndarray:
    """Per row, whether some (sub-)action's mask allows more than one value."""
    sizes = list(action_space.nvec) if isinstance(action_space, spaces.MultiDiscrete) else [int(action_space.n)]
    return np.stack([part.sum(axis=1) > 1 for part in np.split(masks, np.cumsum(sizes)[:-1], axis=1)], axis=1).any(axis=1)


def _distribution(policy: LearnedPolicy, observations: np.ndarray, masks: np.ndarray) -> Any:
    """``policy``'s action distribution on raw ``observations`` (its own statistics; masked if it masks)."""
    scaled = torch.as_tensor(observations if policy.normalise is None else policy.normalise(observations))
    if isinstance(policy.model.policy, MaskableActorCriticPolicy):
        return policy.model.policy.get_distribution(scaled, action_masks=masks)
    return policy.model.policy.get_distribution(scaled)


def divergences(run: LearnedPolicy, start: LearnedPolicy, spec: EnvSpec, copies: int, steps: int, seed: int, sample: bool) -> tuple[np.ndarray, np.ndarray]:
    """``(kl, choice)``, each of shape ``(steps * copies,)``: ``KL(run || start)`` per row (nats)
    and whether the row's masks left a choice, along ``run``'s actions on ``copies`` copies of
    ``spec`` (copy ``k`` first reset with ``seed + k``; sampled actions drawn with a torch
    generator seeded with ``seed``)."""
    venv = TeamVecEnv(spec, copies)
    venv.seed(seed)
    generator = torch.Generator().manual_seed(seed)
    kls, choices = [], []
    try:
        observations = venv.reset()
        for _ in range(steps):
            masks = np.asarray(venv.action_masks())
            with torch.no_grad():
                ours, theirs = _distribution(run, observations, masks), _distribution(start, observations, masks)
                kls.append(kl_divergence(ours, theirs).numpy())
                parts = [p.probs for p in action_distributions(ours)]  # one per robot of a MultiDiscrete action
                actions = torch.stack([torch.multinomial(p, 1, generator=generator)[:, 0] if sample else p.argmax(dim=1) for p in parts], dim=1)
            choices.append(_choice(masks, venv.action_space))
            observations, _, _, _ = venv.step(actions.numpy() if len(parts) > 1 else actions[:, 0].numpy())
    finally:
        venv.close()
    return np.concatenate(kls), np.concatenate(choices)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="KL divergence of a trained policy from another, on the states the first reaches.")
    parser.add_argument("run", metavar="RUN", help="a centralised moma-env train folder (its policy acts)")
    parser.add_argument("start", metavar="START", help="a centralised train folder of the same task and action (e.g. the run RUN started from)")
    parser.add_argument("--copies", type=int_at_least(1, "copy count"), default=8, help="env copies (default 8)")
    parser.add_argument("--steps", type=int_at_least(1, "step count"), default=400, help="steps of every copy (default 400)")
    parser.add_argument("--seed", type=int_at_least(0, "seed"), default=5_000_000, help="seed of copy 0's first layout and of the sampling (default 5000000)")
    parser.add_argument("--sample-actions", action="store_true", help="RUN samples its actions (default: its most likely ones)")
    args = parser.parse_args(argv)
    try:
        run = _centralised(args.run)
        start = _centralised(args.start, run.configuration)
        spec = env_spec(TrainConfig.from_dict(read_manifest(args.run)["config"]))
    except ValueError as error:  # TrainingDirError names the run
        parser.error(str(error))
    if run.model.action_space != start.model.action_space or run.model.observation_space != start.model.observation_space:
        parser.error(f"{args.run!r} and {args.start!r} have other observation or action spaces")
    torch.set_num_threads(1)
    kl, choice = divergences(run, start, spec, args.copies, args.steps, args.seed, args.sample_actions)
    print(f"{kl.size} rows: KL({args.run} || {args.start}) mean {kl.mean():.4f} nats")
    if choice.any():
        chosen = kl[choice]
        print(f"{chosen.size} rows with a choice: mean {chosen.mean():.4f}, median {np.median(chosen):.4f}, 90th percentile {np.quantile(chosen, 0.9):.4f} nats")
    else:
        print("no row with a choice")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

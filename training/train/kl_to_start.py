"""PPO that stays near the policy it started from (``moma-env train --kl-to-start BETA``).

A run that starts from a clone (``--pretrain``) or from another run (``--init-from``)
and is trained further by PPO may drift from what it started with in states where its
rollouts' advantages are noisy. ``TrainConfig.kl_to_start`` adds to PPO's loss, on
every minibatch of observations ``s``::

    BETA * mean_s KL( pi_theta(.|s) || pi_start(.|s) )

where ``pi_start`` is the policy the run started from, frozen: after the cloning or the
DAgger rounds when the run has them (for a masked policy
both distributions are masked by the same actions: a refused action has probability 0
in both and adds nothing). The divergence is in nats, summed over the sub-actions of a
``MultiDiscrete`` or ``Box`` action.

SB3's PPO and MaskablePPO compute their loss as ``policy_loss - ent_coef *
mean(entropy) + vf_coef * value_loss`` from the policy's ``evaluate_actions``. The
penalty enters through that entropy slot: :func:`install` sets the model's ``ent_coef``
to 1 and has the policy report ``ent_coef * entropy - BETA * KL`` as its entropy, which
gives exactly the run's entropy bonus and the penalty. So SB3's logged
``train/entropy_loss`` is the sum of both terms; the penalty's own divergence is logged
as ``train/kl_to_start``. The saved model is a plain PPO model (the penalty lives on
the policy object only; the saved ``ent_coef`` is 1, which nothing after training
reads).

The start policy's weights are written to :data:`START_POLICY` in the run folder when
the run starts, so that a resumed run measures the divergence from the same policy.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import torch as th
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.policies import ActorCriticPolicy

from agents.learned import TrainingDirError
from moma_env.io import atomic_path

__all__ = ["START_POLICY", "KLToStart", "action_distributions", "install", "kl_divergence", "start_policy_from", "write_start_policy"]

#: The start policy's weights (a torch state dict), in the run folder of a run with ``kl_to_start > 0``.
START_POLICY = "start_policy.pt"


def action_distributions(distribution: Any) -> list[th.distributions.Distribution]:
    """The torch distributions of an SB3 (or sb3-contrib) action distribution: one per
    sub-action of a ``MultiDiscrete`` action, else one."""
    inner = getattr(distribution, "distributions", None)  # sb3-contrib's masked MultiDiscrete
    if inner is None:
        inner = distribution.distribution  # SB3's: a list for MultiDiscrete
    return list(inner) if isinstance(inner, (list, tuple)) else [inner]


def kl_divergence(current: Any, start: Any) -> th.Tensor:
    """``KL(current || start)`` per observation (nats, shape ``(batch,)``) between two SB3
    action distributions of the same action space, summed over sub-actions and action
    dimensions."""
    total: th.Tensor | None = None
    for p, q in zip(action_distributions(current), action_distributions(start), strict=True):
        kl = th.distributions.kl_divergence(p, q)
        if kl.dim() > 1:  # a Gaussian's per-dimension divergences
            kl = kl.sum(dim=tuple(range(1, kl.dim())))
        total = kl if total is None else total + kl
    assert total is not None
    return total


class KLToStart:
    """The policy's ``evaluate_actions`` with the divergence from the start policy in its entropy slot.

    Args:
        model: the PPO or MaskablePPO model being trained (its ``ent_coef`` is set to 1
            by :func:`install`; ``ent_coef`` here is the run's own).
        start: the policy the run started from (frozen here).
        weight: BETA, the penalty's weight (> 0).
        ent_coef: the run's entropy bonus.
    """

    def __init__(self, model: BaseAlgorithm, start: ActorCriticPolicy, weight: float, ent_coef: float):
        self.model = model
        self.policy: ActorCriticPolicy = model.policy
        self.start = start
        self.weight = float(weight)
        self.ent_coef = float(ent_coef)
        # The class's own method: on the instance, evaluate_actions is this penalty once installed.
        # It runs the actor once, get_distribution below once more: one extra actor pass per
        # minibatch. Computing all from one distribution (get_distribution + predict_values)
        # gives the same loss but other floating-point gradient sums, so not the weights of the
        # runs in docs/learning.md bit for bit; kept as it is for that.
        self._evaluate: Callable[..., tuple[th.Tensor, th.Tensor, th.Tensor | None]] = type(self.policy).evaluate_actions.__get__(self.policy)
        start.set_training_mode(False)
        for parameter in start.parameters():
            parameter.requires_grad_(False)

    def __call__(self, obs: Any, actions: th.Tensor, action_masks: Any = None) -> tuple[th.Tensor, th.Tensor, th.Tensor]:
        """``(values, log_prob, ent_coef * entropy - weight * KL)`` of a minibatch."""
        masks = {} if action_masks is None else {"action_masks": action_masks}
        values, log_prob, entropy = self._evaluate(obs, actions, **masks)
        if entropy is None:  # SB3's own estimate where a distribution has no entropy
            entropy = -log_prob
        current = self.policy.get_distribution(obs, **masks)
        with th.no_grad():
            start = self.start.get_distribution(obs, **masks)
        kl = kl_divergence(current, start)
        self.model.logger.record_mean("train/kl_to_start", float(kl.mean().detach()))
        return values, log_prob, self.ent_coef * entropy - self.weight * kl


def install(model: BaseAlgorithm, start: ActorCriticPolicy, weight: float, ent_coef: float) -> KLToStart:
    """Make ``model``'s PPO loss carry ``weight * KL(policy || start)`` besides its entropy
    bonus ``ent_coef`` (see the module docstring); return the penalty."""
    penalty = KLToStart(model, start, weight, ent_coef)
    model.policy.evaluate_actions = penalty  # an instance attribute: the policy's class and saved weights are SB3's
    model.ent_coef = 1.0
    return penalty


def _new_policy(model: BaseAlgorithm, state: dict[str, th.Tensor]) -> ActorCriticPolicy:
    """A policy of ``model``'s class, spaces and network arguments with the weights ``state``
    (built anew: a policy that has evaluated actions holds tensors that cannot be copied)."""
    policy = model.policy_class(model.observation_space, model.action_space, model.lr_schedule, **model.policy_kwargs)
    policy.load_state_dict(state)
    return policy.to(model.device)


def write_start_policy(out: Path, model: BaseAlgorithm) -> ActorCriticPolicy:
    """A copy of ``model``'s policy as it is now, its weights written to ``out`` /
    :data:`START_POLICY` (whole or not at all)."""
    state = {k: v.detach().clone() for k, v in model.policy.state_dict().items()}
    with atomic_path(out / START_POLICY) as tmp:
        th.save(state, tmp)
    return _new_policy(model, state)


def start_policy_from(out: Path, model: BaseAlgorithm) -> ActorCriticPolicy:
    """The start policy of the run in ``out`` (resumed): ``model``'s policy with the weights
    of ``out`` / :data:`START_POLICY`.

    Raises:
        agents.learned.TrainingDirError: the run folder has no loadable start policy.
    """
    path = out / START_POLICY
    try:
        return _new_policy(model, th.load(path, map_location="cpu", weights_only=True))
    except Exception as err:  # missing, damaged (pickle, zip) or of other shapes (torch)
        raise TrainingDirError(f"cannot load {str(path)!r}, the start policy --kl-to-start measures from: {type(err).__name__}: {err}") from None

"""The team reward as named terms: each term is one function and one weight.

A term's function maps the step's :class:`RewardInputs` to a raw value; its
weight is the :class:`~moma_env.env.config.RewardConfig` field of the same
name. The step's reward is the weighted sum, and ``infos[agent]["reward_terms"]``
shows each weighted term. To add a term: write its function, add it to
:data:`REWARD_TERMS`, and add its weight to ``RewardConfig``.

Units: distances in metres, counts per step.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass

from moma_env.env.config import RewardConfig
from moma_env.estimator import Status
from moma_env.geometry import wrap_angle
from moma_env.records import slot_setter_init
from moma_env.scenarios import Scenario
from moma_env.sim import Frame

__all__ = ["REWARD_TERMS", "RewardInputs", "RewardStep", "RewardTerm", "TeamReward"]


@dataclass(frozen=True)
class RewardInputs:
    """What a step's reward terms are computed from.

    Attributes:
        progress: metres the UGVs with goals got closer to them this step (truth, summed).
        mean_error: mean planar position error of the UGVs' estimates (m); a UGV
            without an estimate counts ``RewardConfig.lost_error_m``.
        switches: granted state requests this step.
        refused: refused mobile requests this step.
        new_collisions: collision pairs that were not in contact the step before.
        lost: UGVs whose estimate is LOST.
        newly_reached: UGVs that reached their goal this step.
        finished: the team reached its last goal this step (the episode ends).
    """

    progress: float
    mean_error: float
    switches: int
    refused: int
    new_collisions: int
    lost: int
    newly_reached: int
    finished: bool


@dataclass(frozen=True)
class RewardTerm:
    """A named reward term: ``weight * value(inputs)``, the weight being ``RewardConfig.<name>``."""

    name: str
    value: Callable[[RewardInputs], float]


def _progress(r: RewardInputs) -> float:
    return r.progress


def _localisation_error(r: RewardInputs) -> float:
    return r.mean_error


def _switch(r: RewardInputs) -> float:
    return r.switches


def _refused(r: RewardInputs) -> float:
    return r.refused


def _collision(r: RewardInputs) -> float:
    return r.new_collisions


def _lost(r: RewardInputs) -> float:
    return r.lost


def _goal_bonus(r: RewardInputs) -> float:
    return r.newly_reached


def _time(r: RewardInputs) -> float:
    return 1.0


def _final_error(r: RewardInputs) -> float:
    return r.mean_error if r.finished else 0.0


#: The terms, in the order they are summed.
REWARD_TERMS: tuple[RewardTerm, ...] = (
    RewardTerm("progress", _progress),
    RewardTerm("localisation_error", _localisation_error),
    RewardTerm("switch", _switch),
    RewardTerm("refused", _refused),
    RewardTerm("collision", _collision),
    RewardTerm("lost", _lost),
    RewardTerm("goal_bonus", _goal_bonus),
    RewardTerm("time", _time),
    RewardTerm("final_error", _final_error),
)


@slot_setter_init
@dataclass(frozen=True, slots=True, init=False)
class RewardStep:
    """One step's reward: the total, each weighted term, and what happened."""

    total: float
    terms: Mapping[str, float]
    newly_reached: tuple[str, ...]
    collisions: int


class TeamReward:
    """The shared team reward of an episode; owns what it compares across steps
    (the goal distances, the goals reached, the contacts of the previous step).

    Args:
        scenario: the episode's goals and their tolerances.
        ugvs: the UGVs whose localisation error and loss count.
        weights: the terms' weights.
    """

    def __init__(self, scenario: Scenario, ugvs: tuple[str, ...], weights: RewardConfig):
        for term in REWARD_TERMS:
            if not hasattr(weights, term.name):
                raise AttributeError(f"RewardConfig has no weight for the reward term {term.name!r}")
        self.scenario = scenario
        self.ugvs = ugvs
        self.weights = weights
        self.reached: set[str] = set()
        self._weighted: tuple | None = None  # (weights, their terms): see _weighted_terms

    def reset(self, frame: Frame) -> None:
        """Start an episode at ``frame``: nothing reached, distances and contacts as now."""
        self.reached = set()
        self._previous_distance = self._goal_distances(frame)
        self._previous_contacts: frozenset = frozenset()

    @property
    def done(self) -> bool:
        """True when the scenario has goals and every one has been reached."""
        goals = self.scenario.goals
        return bool(goals) and len(self.reached) == len(goals)

    def _goal_distances(self, frame: Frame) -> dict[str, float]:
        out = {}
        truth = frame.truth
        for device, goal in self.scenario.goals.items():
            x, y, _ = truth[device]
            out[device] = math.hypot(goal[0] - x, goal[1] - y)
        return out

    def step(self, frame: Frame, switches: int, refused: int) -> RewardStep:
        """The reward of the step that produced ``frame``, with its granted and refused requests."""
        w = self.weights
        dist = self._goal_distances(frame)
        previous = self._previous_distance
        progress = sum([previous[d] - v for d, v in dist.items()])
        self._previous_distance = dist
        errors, n_lost = [], 0
        frame_errors, estimates = frame.errors, frame.estimates
        lost_error, lost = w.lost_error_m, Status.LOST
        for device in self.ugvs:
            err = frame_errors[device]
            errors.append(lost_error if math.isnan(err) else err)
            if estimates[device].status is lost:
                n_lost += 1
        newly = []
        scenario = self.scenario
        for device, goal in scenario.goals.items():
            if device in self.reached:
                continue
            yaw = frame.truth[device][2]
            if dist[device] <= scenario.goal_tolerance_m and abs(wrap_angle(goal[2] - yaw)) <= scenario.goal_tolerance_rad:
                self.reached.add(device)
                newly.append(device)
        contacts = frame.contacts
        new_contacts = contacts - self._previous_contacts
        self._previous_contacts = contacts
        inputs = RewardInputs(
            progress=progress,
            mean_error=sum(errors) / max(1, len(errors)),
            switches=switches,
            refused=refused,
            new_collisions=len(new_contacts),
            lost=n_lost,
            newly_reached=len(newly),
            finished=bool(newly) and self.done,
        )
        terms = {}
        total = None
        for name, weight, value in self._weighted_terms(w):
            term = terms[name] = weight * value(inputs)
            total = term if total is None else total + term  # left to right, as the terms are listed
        return RewardStep(float(total), terms, tuple(newly), len(new_contacts))

    def _weighted_terms(self, weights: RewardConfig) -> tuple[tuple[str, float, Callable[[RewardInputs], float]], ...]:
        """``(name, weight, value function)`` of every term of :data:`REWARD_TERMS`, in order, for
        ``weights``: read once per weights object (a frozen ``RewardConfig``), not every step."""
        cached = self._weighted
        if cached is None or cached[0] is not weights:
            cached = self._weighted = (weights, tuple((term.name, getattr(weights, term.name), term.value) for term in REWARD_TERMS))
        return cached[1]

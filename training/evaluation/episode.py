"""One evaluation episode: drive a policy in the env and record what happened.

The harness (not the policy) reads the truth carried in the infos: each robot's
true planar pose, its MOMA estimate, its estimator status and the rule events.
Robots are the UGV agents (the observer, when it is an agent, is not scored).
Poses are planar ``(x, y, yaw)`` in the world frame W (m, rad); times are the
simulation clock (s), one sample at the reset and one after every step.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from moma_env.env.agent_names import is_observer_agent
from moma_env.geometry import wrap_angle
from moma_env.metrics import RunMetrics, Trajectory, TrajectoryRecorder, run_metrics
from training.evaluation.policies import Policy, PolicyEnvError

__all__ = [
    "RobotEpisode", "EpisodeResult", "run_episode", "robot_agents", "schedule_split", "mobile_times", "schedule_bound",
    "start_waves", "fewest_waves",
]

FrameSink = Callable[[np.ndarray], None]


@dataclass(frozen=True, eq=False)
class RobotEpisode:
    """One robot over one episode.

    Attributes:
        truth: true trajectory ``T_w_b`` (planar, z = 0).
        moma: MOMA estimate at the same times (invalid samples: no estimate).
        switch_times: instants (s) the robot's board became static or mobile.
        distance_m: planar length of the true path (m).
        n_switches: static/mobile events of the robot.
        n_refused: its refused requests to become mobile.
        lost: whether its estimator status was ``lost`` at any sample.
        goal_time_s: time (s) it reached its goal; NaN if it did not.
        metrics: ME, E_f, % of path, heading errors of ``moma`` against ``truth``.
        goal_distance_m: planar distance from its true pose at the episode's end to its
            goal's position (m); NaN without a goal.
        goal_heading_error_deg: absolute difference of its true heading at the end and its
            goal's heading (deg, in [0, 180]); NaN without a goal. A goal is reached within
            the scenario's ``goal_tolerance_m`` and ``goal_tolerance_rad`` of both.
        startable_s: how long it stood static, its goal not yet reached, while its action
            mask allowed it to start (s; switching mode; 0 without masks): the time a policy
            left it where it could have sent it on.
    """

    truth: Trajectory
    moma: Trajectory
    switch_times: tuple[float, ...]
    distance_m: float
    n_switches: int
    n_refused: int
    lost: bool
    goal_time_s: float
    metrics: RunMetrics
    goal_distance_m: float = math.nan
    goal_heading_error_deg: float = math.nan
    startable_s: float = 0.0


@dataclass(frozen=True, eq=False)
class EpisodeResult:
    """One episode of one policy.

    Attributes:
        index: episode number k (0-based); the env was reset with ``seed``.
        seed: ``seed + k`` of the evaluation.
        success: every goal reached (the episode terminated).
        truncated: stopped by ``max_cycles``.
        steps: env steps taken.
        duration_s: simulated time of the episode (s).
        time_to_goal_s: simulated time until success (s); NaN without success.
        total_reward: sum of the team reward over the steps.
        n_switches: static/mobile events of every device (sleds included).
        n_refused: refused requests to become mobile.
        lost_track: some robot's estimator was ``lost`` at some step.
        goals: robot -> goal ``(x, y, yaw)`` of this episode's layout.
        robots: robot -> :class:`RobotEpisode`.
        waiting_s: of the time until the last robot reached its goal, how long that
            robot stood while another robot moved (s; NaN without success); see
            :func:`schedule_split`.
        still_s: of that time, how long no robot moved (dwells, settling) (s; NaN
            without success).
        bound_s: the soonest any schedule could reach every goal if each robot is
            mobile as long as it was in this episode and one robot at least stands at
            every instant (s; NaN without success); see :func:`schedule_bound`.
        waves: how many waves of starts the episode took: a wave is the starts that no
            robot's stop separates (NaN without success); see :func:`start_waves`.
        fewest_waves: the fewest waves that the episode's starts (each robot's number of
            legs) allow under the motion rules (NaN without success); see :func:`fewest_waves`.
        fewest_waves_time_s: the time to goal scaled by ``fewest_waves / waves``: what the
            episode would take with its waves packed into the fewest, each at its mean
            length (s, an estimate, not a bound; NaN without success).
    """

    index: int
    seed: int
    success: bool
    truncated: bool
    steps: int
    duration_s: float
    time_to_goal_s: float
    total_reward: float
    n_switches: int
    n_refused: int
    lost_track: bool
    goals: Mapping[str, tuple[float, float, float]]
    robots: Mapping[str, RobotEpisode]
    waiting_s: float = math.nan
    still_s: float = math.nan
    bound_s: float = math.nan
    waves: float = math.nan
    fewest_waves: float = math.nan
    fewest_waves_time_s: float = math.nan

    def row(self) -> dict[str, Any]:
        """The episode as one flat CSV row (distances in m, angles in deg, times in s)."""
        row: dict[str, Any] = {
            "episode": self.index,
            "seed": self.seed,
            "success": int(self.success),
            "truncated": int(self.truncated),
            "steps": self.steps,
            "duration_s": self.duration_s,
            "time_to_goal_s": self.time_to_goal_s,
            "total_reward": self.total_reward,
            "n_switches": self.n_switches,
            "n_refused": self.n_refused,
            "lost_track": int(self.lost_track),
            "waiting_s": self.waiting_s,
            "still_s": self.still_s,
            "bound_s": self.bound_s,
            "waves": self.waves,
            "fewest_waves": self.fewest_waves,
            "fewest_waves_time_s": self.fewest_waves_time_s,
        }
        for name, r in self.robots.items():
            m = r.metrics
            row |= {
                f"{name}_distance_m": r.distance_m,
                f"{name}_n_switches": r.n_switches,
                f"{name}_n_refused": r.n_refused,
                f"{name}_lost": int(r.lost),
                f"{name}_goal_time_s": r.goal_time_s,
                f"{name}_ME_m": m.mean_error,
                f"{name}_E_f_m": m.final_error,
                f"{name}_E_f_pct_path": m.final_error_pct_path,
                f"{name}_mean_heading_error_deg": m.mean_heading_error_deg,
                f"{name}_final_heading_error_deg": m.final_heading_error_deg,
                f"{name}_goal_distance_m": r.goal_distance_m,
                f"{name}_goal_heading_error_deg": r.goal_heading_error_deg,
                f"{name}_startable_s": r.startable_s,
            }
        return row


def robot_agents(env: Any) -> list[str]:
    """The scored robots of ``env``: its agents except the observers."""
    return [a for a in env.possible_agents if not is_observer_agent(a)]


class _RobotLog:
    """Per-step accumulation for one robot (recorders and counters)."""

    __slots__ = ("truth", "moma", "switch_times", "n_switches", "n_refused", "lost", "goal_time", "mobile", "startable_s", "_startable_from")

    def __init__(self, capacity: int):
        self.truth = TrajectoryRecorder(capacity=capacity)
        self.moma = TrajectoryRecorder(capacity=capacity)
        self.switch_times: list[float] = []
        self.n_switches = 0
        self.n_refused = 0
        self.lost = False
        self.goal_time = math.nan
        self.mobile: list[bool] = []
        self.startable_s = 0.0
        self._startable_from: float | None = None  # the last sample's time if the robot could have started then

    def record(self, name: str, t: float, info: Mapping[str, Any]) -> None:
        if self._startable_from is not None:
            self.startable_s += t - self._startable_from
        mask = info.get("action_mask")
        startable = info.get("static") is True and not info.get("reached_goal", False) and mask is not None and bool(np.any(mask[1:]))
        self._startable_from = t if startable else None
        self.truth.append(t, info["truth"][:3])
        self.moma.append(t, info["estimate"])
        self.mobile.append(info.get("static") is False)
        if info["status"] == "lost":
            self.lost = True
        switched = False
        for event in info["events"]:
            kind, _, rest = event.partition(":")
            device = rest.split(":", 1)[0]
            if kind in ("static", "mobile") and device == name:
                switched = True
                self.n_switches += 1
            elif kind == "refused" and device == name:
                self.n_refused += 1
            elif kind == "goal" and device == name and math.isnan(self.goal_time):
                self.goal_time = t
        if switched:
            self.switch_times.append(t)

    def result(self, goal: Sequence[float] | None) -> RobotEpisode:
        """The robot's episode; ``goal``: its ``(x, y, yaw)`` goal, None without one."""
        truth = self.truth.to_trajectory()
        moma = self.moma.to_trajectory()
        switches = tuple(self.switch_times)
        distance = heading = math.nan
        if goal is not None and len(truth):
            (x, y), yaw = truth.xy[-1], truth.yaw[-1]
            distance = math.hypot(goal[0] - x, goal[1] - y)
            heading = abs(math.degrees(float(wrap_angle(goal[2] - yaw))))
        return RobotEpisode(
            truth=truth,
            moma=moma,
            switch_times=switches,
            distance_m=truth.path_length(),
            n_switches=self.n_switches,
            n_refused=self.n_refused,
            lost=self.lost,
            goal_time_s=self.goal_time,
            metrics=run_metrics(moma, truth, switches),
            goal_distance_m=distance,
            goal_heading_error_deg=heading,
            startable_s=self.startable_s,
        )


def schedule_split(times: Sequence[float], mobile: Mapping[str, Sequence[bool]], goal_times: Mapping[str, float]) -> tuple[float, float]:
    """Where the time of a successful episode went, seen from its last robot to arrive.

    The robot that reached its goal last (largest of ``goal_times``, s) sets the time to
    goal ``T``. Each step ``k`` (from sample ``k - 1`` to ``k``, ``times`` in s) up to
    ``T`` is counted by the robots' states after it (``mobile[robot][k]``): if that
    robot stood, the step counts as *waiting* when some other robot moved, and as
    *still* when none did. ``T`` minus both is the time the last robot moved, so
    ``T = moving + waiting + still``: a schedule that spends less of ``T`` waiting or
    still brings the team in sooner.

    Returns:
        ``(waiting_s, still_s)``; NaN for both if some robot has no goal time (NaN).
    """
    if not goal_times or any(math.isnan(t) for t in goal_times.values()):
        return math.nan, math.nan
    last = max(goal_times, key=lambda name: goal_times[name])
    end = goal_times[last]
    waiting = still = 0.0
    for k in range(1, len(times)):
        if times[k] > end + 1e-9:
            break
        if mobile[last][k]:
            continue
        dt = times[k] - times[k - 1]
        if any(flags[k] for name, flags in mobile.items() if name != last):
            waiting += dt
        else:
            still += dt
    return waiting, still


def mobile_times(times: Sequence[float], mobile: Mapping[str, Sequence[bool]]) -> dict[str, float]:
    """How long (s) each robot was mobile: the steps ``k`` (from sample ``k - 1`` to
    ``k``, ``times`` in s) after which it was (``mobile[robot][k]``, the convention of
    :func:`schedule_split`)."""
    return {
        name: sum(times[k] - times[k - 1] for k in range(1, len(times)) if flags[k])
        for name, flags in mobile.items()
    }


def schedule_bound(mobile_s: Mapping[str, float]) -> float:
    """The soonest (s) a schedule can bring every robot in, if robot ``r`` must be mobile
    for ``mobile_s[r]`` seconds and at every instant one robot at least stands (the
    motion rules' static reference, with the UGVs as the references).

    With ``n`` robots at most ``n - 1`` move at once and none moves longer than the
    schedule, so it lasts at least ``max(max(mobile_s), sum(mobile_s) / (n - 1))``;
    with one robot, its mobile time. The switch windows and dwells are not counted, so
    a real schedule needs more: this bounds what a better order of moves can gain on
    the same legs.

    Raises:
        ValueError: no robots, or a time that is negative or not finite.
    """
    values = list(mobile_s.values())
    if not values:
        raise ValueError("schedule_bound needs at least one robot")
    for name, value in mobile_s.items():
        if not math.isfinite(value) or value < 0.0:
            raise ValueError(f"mobile time of {name!r} must be a finite number >= 0 s, got {value!r}")
    longest = max(values)
    if len(values) == 1:
        return longest
    return max(longest, sum(values) / (len(values) - 1))


def start_waves(mobile: Mapping[str, Sequence[bool]]) -> tuple[dict[str, int], int]:
    """Each robot's starts and the team's waves of starts, from the robots' states after
    each sample (``mobile[robot][k]``, the convention of :func:`schedule_split`).

    A robot starts at sample ``k`` when it is mobile there and was not at ``k - 1``, and
    stops when the reverse. A wave is the starts that no stop separates: the first start
    of the episode, or the first after a stop, begins one. In a step, the starts (the
    state requests) come before the stops (a leg ending under the step's commands).

    Returns:
        ``(starts, waves)``: robot -> how many times it started, and the number of waves.
    """
    starts = dict.fromkeys(mobile, 0)
    flags = list(mobile.values())
    names = list(mobile)
    n_samples = min((len(f) for f in flags), default=0)
    waves = 0
    stopped = True  # the reset: the first start begins a wave
    for k in range(1, n_samples):
        started = False
        for name, f in zip(names, flags):
            if f[k] and not f[k - 1]:
                starts[name] += 1
                started = True
        if started and stopped:
            waves += 1
            stopped = False
        if any(f[k - 1] and not f[k] for f in flags):
            stopped = True
    return starts, waves


def fewest_waves(starts: Mapping[str, int]) -> int:
    """The fewest waves of starts (:func:`start_waves`) in which robot ``r`` can start
    ``starts[r]`` legs: a wave holds at most one start of each robot (its leg must stop
    before it starts again, and a stop ends the wave) and, with ``n`` robots, at most
    ``n - 1`` starts (one robot at least stands: the motion rules' static reference, with
    the robots as the references, as :func:`schedule_bound` takes them), so
    ``max(max(starts), ceil(sum(starts) / (n - 1)))``; with one robot, its starts. It
    counts no other rule: where the cameras' views forbid some robots to move together
    (a file of robots, each seeing the one ahead), fewer waves may not be reachable.

    Raises:
        ValueError: no robots, or a count that is negative or not an integer.
    """
    if not starts:
        raise ValueError("fewest_waves needs at least one robot")
    for name, count in starts.items():
        if isinstance(count, bool) or not isinstance(count, int) or count < 0:
            raise ValueError(f"starts of {name!r} must be an integer >= 0, got {count!r}")
    counts = list(starts.values())
    if len(counts) == 1:
        return counts[0]
    return max(max(counts), -(-sum(counts) // (len(counts) - 1)))


def _count_events(infos: Mapping[str, Mapping[str, Any]]) -> tuple[int, int]:
    switches = refused = 0
    for info in infos.values():
        for event in info.get("events", ()):
            if event.startswith(("static:", "mobile:")):
                switches += 1
            elif event.startswith("refused:"):
                refused += 1
    return switches, refused


def run_episode(env: Any, policy: Policy, index: int, seed: int, frame_sink: FrameSink | None = None) -> EpisodeResult:
    """Run one episode of ``policy`` in ``env`` reset with ``seed``; record it.

    Args:
        env: a :class:`moma_env.env.parallel.MomaParallelEnv` (any render mode;
            with ``frame_sink`` it must be ``"rgb_array"``).
        policy: see :class:`training.evaluation.policies.Policy`.
        index: the episode number stored in the result.
        seed: the env's reset seed, also given to ``policy.reset``.
        frame_sink: called with every rendered frame ``(H, W, 3) uint8``, the
            reset's first, when given.

    Raises:
        PolicyEnvError: ``policy.reset`` refused the env (a ValueError of the policy's).
    """
    if frame_sink is not None and getattr(env, "render_mode", None) != "rgb_array":
        raise ValueError("recording frames needs an env with render_mode='rgb_array'")
    observations, infos = env.reset(seed=seed)
    try:
        policy.reset(env, seed=seed)
    except ValueError as err:  # what a policy raises for an env it cannot act in
        raise PolicyEnvError(f"{type(policy).__name__} cannot act in this env: {err}") from err
    robots = robot_agents(env)
    capacity = env.max_cycles + 1
    logs = {name: _RobotLog(capacity) for name in robots}
    t = env.frame.time
    times = [t]
    for name in robots:
        logs[name].record(name, t, infos[name])
    if frame_sink is not None:
        frame_sink(env.render())
    steps, total_reward, n_switches, n_refused = 0, 0.0, 0, 0
    terminated = truncated = False
    while env.agents:
        actions = policy.act(observations, infos)
        observations, rewards, terminations, truncations, infos = env.step(actions)
        steps += 1
        t = env.frame.time
        times.append(t)
        total_reward += next(iter(rewards.values()), 0.0)
        s, r = _count_events(infos)
        n_switches += s
        n_refused += r
        for name in robots:
            logs[name].record(name, t, infos[name])
        terminated = any(terminations.values())
        truncated = any(truncations.values())
        if frame_sink is not None:
            frame_sink(env.render())
    duration = float(env.frame.time)
    goals = {name: tuple(float(v) for v in goal) for name, goal in env.scenario.goals.items()}
    results = {name: log.result(goals.get(name)) for name, log in logs.items()}
    mobile = {name: log.mobile for name, log in logs.items()}
    if terminated and robots:
        waiting, still = schedule_split(times, mobile, {name: r.goal_time_s for name, r in results.items()})
        bound = schedule_bound(mobile_times(times, mobile))
        starts, waves = start_waves(mobile)
        fewest = fewest_waves(starts)
        packed = duration * fewest / waves if waves else duration
    else:
        waiting = still = bound = waves = fewest = packed = math.nan
    return EpisodeResult(
        index=index,
        seed=seed,
        success=bool(terminated),
        truncated=bool(truncated and not terminated),
        steps=steps,
        duration_s=duration,
        time_to_goal_s=duration if terminated else math.nan,
        total_reward=float(total_reward),
        n_switches=n_switches,
        n_refused=n_refused,
        lost_track=any(r.lost for r in results.values()),
        goals=goals,
        robots=results,
        waiting_s=waiting,
        still_s=still,
        bound_s=bound,
        waves=float(waves),
        fewest_waves=float(fewest),
        fewest_waves_time_s=float(packed),
    )

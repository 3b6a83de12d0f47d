"""An env step in phases: PendingStep, run_phases and Simulation.phases.

A batch runs each phase of every copy's step before the next phase; the results must be
those of stepping each env alone, bit for bit, and a step's calls out of order are refused.
"""

import numpy as np
import pytest

from moma_env.camera import make_camera
from moma_env.env.factory import parallel_env
from moma_env.env.parallel import MEASUREMENT, STEP_PHASES, run_phases
from moma_env.scenarios import make_scenario
from moma_env.sim import Simulation, measured
from moma_env.vector.env import measure_copies
from serialised import text


def envs(name, n, **options):
    out = [parallel_env(name, max_cycles=15, **options) for _ in range(n)]
    for i, env in enumerate(out):
        env.reset(seed=20 + i)
    return out


def random_actions(env, rng):
    """Every agent's uniform random action, drawn from ``rng``."""
    out = {}
    for agent in env.agents:
        space = env.action_space(agent)
        out[agent] = int(rng.integers(space.n)) if hasattr(space, "n") else rng.uniform(space.low, space.high).astype(space.dtype)
    return out


@pytest.mark.parametrize("name, options", [("top_observer", {"action_mode": "switching"}), ("caterpillar_multi", {"action_mode": "velocity"})])
@pytest.mark.parametrize("n", [1, 3])
def test_a_batch_run_phase_by_phase_is_each_env_stepped_alone(name, options, n):
    batch, alone = envs(name, n, **options), envs(name, n, **options)
    rng = np.random.default_rng(5)
    ended = 0
    for _ in range(40):
        actions = [random_actions(env, rng) for env in batch]
        got = run_phases([env.begin_step(a) for env, a in zip(batch, actions)], measure_copies)
        expected = [env.step(a) for env, a in zip(alone, actions)]
        assert text(got) == text(expected)
        for i, (b, a) in enumerate(zip(batch, alone)):
            assert text(b.state()) == text(a.state())
            if not b.agents:
                ended += 1
                b.reset(seed=100 + i)
                a.reset(seed=100 + i)
    assert ended > 0  # episodes ended and restarted within the run


def test_every_env_runs_a_phase_before_any_runs_the_next():
    batch = envs("top_observer", 3, action_mode="switching")
    log = []

    def logged(index, name, function):
        def call(*args, **kwargs):
            log.append((name, index))
            return function(*args, **kwargs)

        return call

    for i, env in enumerate(batch):
        sim = env.simulation
        sim.world.step = logged(i, "world", sim.world.step)
        sim.localiser.update = logged(i, "localiser", sim.localiser.update)
        env._reward.step = logged(i, "reward", env._reward.step)
    rng = np.random.default_rng(0)
    run_phases([env.begin_step(random_actions(env, rng)) for env in batch], measure_copies)
    assert log == [(name, i) for name in ("world", "localiser", "reward") for i in range(3)]


def test_a_pending_step_refuses_calls_out_of_order():
    (env,) = envs("top_observer", 1, action_mode="switching")
    step = env.begin_step(random_actions(env, np.random.default_rng(0)))
    with pytest.raises(RuntimeError, match="not reached its cameras"):
        step.detected([])
    requests = step.to_cameras()
    assert step.camera_requests is requests and step.to_cameras() is requests
    with pytest.raises(RuntimeError, match="awaits the detections"):
        step.advance()
    result = step.finish(measured(requests))
    assert step.result is result and len(result) == 5
    for call in (step.advance, step.to_cameras, lambda: step.finish([]), lambda: step.detected([])):
        with pytest.raises(RuntimeError, match="finished already"):
            call()


def test_an_error_in_a_phase_ends_the_step():
    (env,) = envs("top_observer", 1, action_mode="switching")

    def broken(*args, **kwargs):
        raise ArithmeticError("reward")

    env._reward.step = broken
    step = env.begin_step(random_actions(env, np.random.default_rng(0)))
    step.detected(measured(step.to_cameras()))
    with pytest.raises(ArithmeticError, match="reward"):
        while step.advance():
            pass
    with pytest.raises(RuntimeError, match="finished already"):
        step.advance()
    assert step.result is None


def test_a_bad_action_is_refused_by_begin_step():
    (env,) = envs("top_observer", 1, action_mode="switching")
    with pytest.raises(KeyError, match="unknown agent"):
        env.begin_step({"stranger": 0})


def simulation():
    scenario = make_scenario("top_observer")
    wc = scenario.world
    names = [c.name for u in wc.ugvs for c in u.cameras] + [wc.uav.camera_name]
    sim = Simulation(scenario, {c: make_camera(c, scenario.camera) for c in names})
    sim.reset(np.random.default_rng(3))
    return sim


def test_the_simulations_phases_are_its_advance():
    by_phases, by_advance = simulation(), simulation()
    ugv = by_phases.ugvs[0]
    for sim in (by_phases, by_advance):
        sim.request({ugv: True})
    for k in range(20):
        velocities = {ugv: (0.1, 0.0, 0.05 * k)}
        phases = by_phases.phases(velocities)
        assert next(phases) is None  # the world has moved
        requests = next(phases)
        assert phases.send(measured(requests)) is None  # the localiser has updated
        with pytest.raises(StopIteration) as done:
            next(phases)
        frame = by_advance.advance(velocities)
        assert done.value.value is by_phases.frame
        assert text(_frame_values(by_phases.frame)) == text(_frame_values(frame))


def _frame_values(frame):
    return (frame.time, dict(frame.truth), dict(frame.estimated), dict(frame.errors), sorted(frame.mobile))


def test_a_simulation_refuses_a_second_move_and_a_localise_without_move():
    sim = simulation()
    with pytest.raises(RuntimeError, match="without move"):
        sim.localise([])
    requests = sim.move({})
    with pytest.raises(RuntimeError, match="called twice"):
        sim.move({})
    with pytest.raises(RuntimeError, match="called twice"):
        next(sim.phases({}))
    sim.localise(measured(requests))
    with pytest.raises(RuntimeError, match="without move"):
        sim.localise([])
    sim.advance({})  # after a refused call the simulation steps on


@pytest.mark.parametrize("n", [1, 3])
def test_timed_phases_give_the_same_steps_and_time_every_phase(n):
    timed, untimed = envs("top_observer", n, action_mode="switching"), envs("top_observer", n, action_mode="switching")
    seconds = {}
    rng = np.random.default_rng(2)
    for _ in range(5):
        actions = [random_actions(env, rng) for env in timed]
        got = run_phases([env.begin_step(a) for env, a in zip(timed, actions)], measure_copies, seconds)
        expected = run_phases([env.begin_step(a) for env, a in zip(untimed, actions)], measure_copies)
        assert text(got) == text(expected)
    assert set(seconds) == {*STEP_PHASES[1:], MEASUREMENT}
    assert all(value > 0 for value in seconds.values())


def test_a_batch_stepped_in_chunks_is_the_batch_stepped_at_once(monkeypatch):
    import moma_env.vector.env as vector_env
    from moma_env import vector

    def batch():
        envs = vector.make("top_observer", 7, action_mode="switching", max_cycles=12)
        envs.reset(seed=4)
        return envs

    whole, chunked = batch(), batch()
    measured_sizes = []

    def counting(requests):
        measured_sizes.append(len(requests))
        return measure_copies(requests)

    chunked.measure = counting
    rng = np.random.default_rng(1)
    for _ in range(30):  # episodes end (max_cycles 12) and the copies reset themselves
        actions = whole.sample_actions(rng)
        expected = whole.step(actions)
        monkeypatch.setattr(vector_env, "PHASE_CHUNK", 3)
        got = chunked.step(actions)
        monkeypatch.undo()
        assert text(got) == text(expected)
    assert measured_sizes == [3, 3, 1] * 30  # every step in chunks of 3, 3 and 1 copies

"""Fast paths of the simulation's per-step copies and snapshots, each against the code it
replaced (kept here as the reference), on random inputs, with exact equality."""

import copy
import math
import pickle
import struct

import numpy as np
import pytest

from moma_env.camera import make_camera
from moma_env.estimator import Phase
from moma_env.geometry import se2_to_se3, se3_to_se2
from moma_env.scenarios import make_scenario
from moma_env.sim import Commands, Simulation

_SPECIAL = (0.0, -0.0, 1.0, -1.0, math.pi, -math.pi, 1e-300, -5e-324, 1e300, math.inf, -math.inf, math.nan)


def simulation(name):
    scenario = make_scenario(name)
    wc = scenario.world
    names = [c.name for u in wc.ugvs for c in u.cameras] + [u.camera_name for u in wc.uavs]
    return Simulation(scenario, {c: make_camera(c, scenario.camera) for c in names})


def bits(values):
    return struct.pack(f"{len(values)}d", *values)


def reference_se2_to_se3(x, y, yaw, z=0.0):
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0, x], [s, c, 0.0, y], [0.0, 0.0, 1.0, z], [0.0, 0.0, 0.0, 1.0]])


def reference_se3_to_se2(T):
    R = T[:3, :3]
    return float(T[0, 3]), float(T[1, 3]), math.atan2(R[1, 0], R[0, 0])


def random_planar(rng, trial):
    if trial % 5 == 0:
        x, y, yaw, z = (float(rng.choice(_SPECIAL)) for _ in range(4))
        return x, y, (yaw if not math.isinf(yaw) else 0.0), z  # math.cos(inf) raises in both
    values = [float(v) for v in rng.uniform(-10.0, 10.0, 4)]
    if trial % 5 == 1:
        values[:3] = [int(v) for v in values[:3]]  # integers, as a caller may pass
    return tuple(values)


def test_se2_to_se3_is_the_nested_list_array():
    rng = np.random.default_rng(0)
    for trial in range(2000):
        x, y, yaw, z = random_planar(rng, trial)
        for args in ((x, y, yaw), (x, y, yaw, z)):
            fast, reference = se2_to_se3(*args), reference_se2_to_se3(*args)
            assert fast.dtype == reference.dtype and fast.shape == reference.shape == (4, 4)
            assert fast.flags.c_contiguous and fast.flags.writeable and fast.flags.owndata
            assert fast.tobytes() == reference.tobytes()
    # A new array every call: writing one changes no later one.
    first = se2_to_se3(1.0, 2.0, 0.5)
    first[:] = 7.0
    assert se2_to_se3(1.0, 2.0, 0.5).tobytes() == reference_se2_to_se3(1.0, 2.0, 0.5).tobytes()


def test_se3_to_se2_reads_the_same_doubles():
    rng = np.random.default_rng(1)
    for trial in range(2000):
        if trial % 4 == 0:
            T = rng.choice(np.array(_SPECIAL), size=(4, 4))
        elif trial % 4 == 1:
            T = se2_to_se3(*rng.uniform(-10.0, 10.0, 3))
        else:
            T = rng.normal(size=(4, 4)) * 10.0 ** rng.integers(-5, 6)
        if trial % 7 == 0:
            T = np.asfortranarray(T)
        fast, reference = se3_to_se2(T), reference_se3_to_se2(T)
        assert all(type(v) is float for v in fast)
        assert bits(fast) == bits(reference)
    ints = np.arange(16).reshape(4, 4)
    assert bits(se3_to_se2(ints)) == bits(reference_se3_to_se2(ints))
    assert all(type(v) is float for v in se3_to_se2(ints))


def reference_devices_as_they_were(sim):
    """Simulation.reference_devices as it was: computed from the frame and the localiser at every call."""
    estimates = sim.frame.estimates
    window_ready = sim.localiser.window_ready
    ready, settling = set(), set()
    for device in sim.devices:
        phase = estimates[device].phase
        if phase is Phase.REFERENCE:
            ready.add(device)
        elif phase is Phase.SETTLING:
            (ready if window_ready(device) else settling).add(device)
    return ready, settling


def check_references(sim):
    reference = reference_devices_as_they_were(sim)
    got = sim.reference_devices()
    assert got == reference and all(type(s) is set for s in got)
    # New sets at every call: changing them changes no later answer.
    got[0].add("nope")
    got[1].clear()
    assert sim.reference_devices() == reference


@pytest.mark.parametrize("name", ["top_observer", "caterpillar_sled"])
def test_reference_devices_and_mobile_follow_every_switch(name):
    sim = simulation(name)
    sim.reset(np.random.default_rng(3))
    rng = np.random.default_rng(4)
    devices = sim.devices
    mobile = set()
    for step in range(120):
        check_references(sim)
        assert type(sim.mobile) is frozenset and sim.mobile == mobile and sim.frame.mobile == mobile
        # Declarations between frames change the answer at once (the cache is dropped).
        if rng.random() < 0.3:
            device = devices[int(rng.integers(len(devices)))]
            static = device in mobile
            sim.declare(device, static)
            (mobile.discard if static else mobile.add)(device)
            check_references(sim)
            assert sim.mobile == mobile
            if rng.random() < 0.5:
                sim.refresh()
                check_references(sim)
        requests = {d: bool(rng.random() < 0.5) for d in devices if rng.random() < 0.3}
        ugvs = [d for d in sim.ugvs if d in mobile or requests.get(d)]
        frame = sim.step(Commands(requests=requests, velocities={u: rng.uniform(-0.2, 0.2, 3) for u in ugvs}))
        for switch in frame.switches:
            if switch.kind == "mobile":
                mobile.add(switch.device)
            elif switch.kind == "static":
                mobile.discard(switch.device)
        assert sim.mobile == mobile == frame.mobile
        # The frame's fields (made positionally) hold what each name says.
        assert frame.time == sim.time and frame.steps == step + 1 and type(frame.steps) is int
        assert tuple(frame.truth) == tuple(frame.estimated) == tuple(frame.errors) == devices
        assert set(frame.estimates) >= set(devices) and tuple(frame.uavs) == sim.world.uav_names
        assert type(frame.detections) is tuple and type(frame.switches) is tuple
        assert frame.contacts == sim.world.collisions_since_last_step and tuple(frame.ropes) == sim.sleds
        assert type(frame.last_switch_time) is float and frame.dwell_remaining == sim.rules.dwell_remaining(frame.time)
        if step % 40 == 39:  # copies carry a valid cache
            for clone in (copy.deepcopy(sim), pickle.loads(pickle.dumps(sim))):
                check_references(clone)
                assert clone.mobile == mobile


def test_a_ready_settling_device_made_mobile_leaves_the_ready_set_at_once():
    """A switch drops the kept answer: a settling device with a ready window that is declared
    mobile is no reference any more (window_ready turns False before the next frame)."""
    sim = simulation("top_observer")
    sim.reset(np.random.default_rng(5))
    device = sim.ugvs[0]
    sim.declare(device, False)
    for _ in range(3):
        sim.step(Commands())
    sim.declare(device, True)
    for _ in range(200):
        sim.step(Commands())
        check_references(sim)
        if sim.frame.estimates[device].phase is Phase.SETTLING and sim.localiser.window_ready(device):
            break
    else:
        pytest.fail("the window never became ready")
    assert device in sim.reference_devices()[0]
    sim.declare(device, False)
    check_references(sim)
    assert device not in sim.reference_devices()[0]

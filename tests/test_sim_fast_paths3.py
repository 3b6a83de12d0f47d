"""Third round of the simulation's snapshot fast paths: the records whose ``__init__`` now sets
their slots through the slots' own setters (Detection, Frame, BoardView.trusted) behave as
the dataclass-generated constructors they replaced (kept here as the reference: the same
fields made by ``dataclasses.make_dataclass``), and a frame's true poses are still
:meth:`Simulation.device_pose` of every device."""

import copy
import dataclasses
import math
import pickle
from types import MappingProxyType

import numpy as np
import pytest

from moma_env.camera import BoardView, make_camera, up_in_board
from moma_env.estimator import Detection
from moma_env.scenarios import make_scenario
from moma_env.sim import Commands, Frame, Simulation


def reference_class(cls):
    """A frozen, slotted, identity-compared dataclass with ``cls``'s fields and the generated ``__init__``."""
    specs = []
    for f in dataclasses.fields(cls):
        if f.default is not dataclasses.MISSING:
            specs.append((f.name, f.type, dataclasses.field(default=f.default)))
        else:
            specs.append((f.name, f.type))
    return dataclasses.make_dataclass("Reference" + cls.__name__, specs, frozen=True, eq=False, slots=True)


def values(record, cls):
    return [getattr(record, f.name) for f in dataclasses.fields(cls)]


def same_values(a, b):
    assert len(a) == len(b)
    for x, y in zip(a, b):
        if isinstance(x, float) and math.isnan(x):
            assert isinstance(y, float) and math.isnan(y)
        else:
            assert x is y


def detection_arguments(rng):
    T = rng.standard_normal((4, 4))
    corners = rng.standard_normal((8, 2))
    cov = rng.standard_normal((6, 6))
    return ["cam", int(rng.integers(0, 9)), T, corners, (1, 2), float(rng.uniform(0, 5)), float(rng.uniform(0, 1)), cov, cov * 0.5]


@pytest.mark.parametrize("n_args", range(6, 10))
def test_detection_is_the_generated_record(n_args):
    rng = np.random.default_rng(n_args)
    Reference = reference_class(Detection)
    args = detection_arguments(rng)[:n_args]
    same_values(values(Detection(*args), Detection), values(Reference(*args), Reference))
    names = [f.name for f in dataclasses.fields(Detection)][:n_args]
    kwargs = dict(zip(names, args))
    d = Detection(**kwargs)
    same_values(values(d, Detection), values(Reference(**kwargs), Reference))
    with pytest.raises(dataclasses.FrozenInstanceError):
        d.board_id = 3  # type: ignore[misc]
    e = dataclasses.replace(d, board_id=7)
    assert e.board_id == 7 and e.T_c_m is d.T_c_m and type(e) is Detection
    for twin in (pickle.loads(pickle.dumps(d)), copy.deepcopy(d)):
        for a, b in zip(values(d, Detection), values(twin, Detection)):
            if isinstance(a, np.ndarray):
                assert np.array_equal(a, b)
            elif isinstance(a, float) and math.isnan(a):
                assert math.isnan(b)
            else:
                assert a == b
    assert repr(d).replace("Detection(", "") == repr(Reference(**kwargs)).replace("ReferenceDetection(", "")
    assert d.n_markers == 2


def test_detection_refuses_what_the_generated_init_refused():
    Reference = reference_class(Detection)
    args = detection_arguments(np.random.default_rng(0))
    for cls in (Detection, Reference):
        with pytest.raises(TypeError):
            cls(*args[:5])
        with pytest.raises(TypeError):
            cls(*args, None)
        with pytest.raises(TypeError):
            cls(*args[:6], colour="red")
        with pytest.raises(TypeError):
            cls(*args[:6], camera_id="again")


def frame_arguments():
    return dict(
        time=1.5, steps=3, truth=MappingProxyType({"a": (0.0, 1.0, 2.0)}), uavs=MappingProxyType({}), estimates=MappingProxyType({}),
        estimated=MappingProxyType({"a": None}), errors=MappingProxyType({"a": math.nan}), detections=(), mobile=frozenset({"a"}),
        switches=(), contacts=frozenset(), ropes=MappingProxyType({}), last_switch_time=0.5, dwell_remaining=0.25,
    )


def test_frame_is_the_generated_record():
    Reference = reference_class(Frame)
    kwargs = frame_arguments()
    f = Frame(**kwargs)
    same_values(values(f, Frame), values(Reference(**kwargs), Reference))
    same_values(values(Frame(*kwargs.values()), Frame), values(f, Frame))
    with pytest.raises(dataclasses.FrozenInstanceError):
        f.time = 2.0  # type: ignore[misc]
    with pytest.raises(TypeError):
        Frame(*list(kwargs.values())[:-1])
    with pytest.raises(TypeError):
        Frame(**kwargs, extra=1)
    g = dataclasses.replace(f, steps=4)
    assert g.steps == 4 and g.truth is f.truth
    h = pickle.loads(pickle.dumps(f))
    assert isinstance(h.truth, MappingProxyType) and dict(h.truth) == dict(f.truth) and h.time == f.time
    assert repr(f).replace("Frame(", "") == repr(Reference(**kwargs)).replace("ReferenceFrame(", "")


def test_a_trusted_board_view_is_the_checked_one():
    scenario = make_scenario("top_observer")
    ugv = scenario.world.ugvs[0]
    up = up_in_board(ugv.board_mount)
    up.setflags(write=False)
    T = np.eye(4)
    T[:3, 3] = (0.5, -0.25, 0.3)
    trusted = BoardView.trusted(4, ugv.board, T, up)
    checked = BoardView(4, ugv.board, T, up)
    assert type(trusted) is BoardView
    assert (trusted.board_id, trusted.layout) == (checked.board_id, checked.layout)
    assert np.array_equal(trusted.T_w_m, checked.T_w_m) and np.array_equal(trusted.up_m, checked.up_m)
    assert trusted.T_w_m is T and trusted.up_m is up
    with pytest.raises(dataclasses.FrozenInstanceError):
        trusted.board_id = 5  # type: ignore[misc]
    assert BoardView.trusted(1, ugv.board, T).up_m is None


@pytest.mark.parametrize("name", ["top_observer", "caterpillar_sled"])
def test_a_frames_truth_is_every_devices_pose(name):
    scenario = make_scenario(name)
    wc = scenario.world
    cameras = [c.name for u in wc.ugvs for c in u.cameras] + [u.camera_name for u in wc.uavs]
    sim = Simulation(scenario, {c: make_camera(c, scenario.camera) for c in cameras})
    rng = np.random.default_rng(5)
    sim.reset(np.random.default_rng(1))
    for step in range(30):
        wants = {d: bool(rng.integers(2)) for d in sim.devices if rng.uniform() < 0.2}
        velocities = {u: rng.uniform(-0.3, 0.3, 3) for u in sim.ugvs}
        frame = sim.step(Commands(requests=wants, velocities=velocities))
        assert list(frame.truth) == list(sim.devices)
        for device in sim.devices:
            assert frame.truth[device] == sim.device_pose(device)
    twin = copy.deepcopy(sim)
    assert [twin.device_pose(d) for d in twin.devices] == [sim.device_pose(d) for d in sim.devices]
    velocities = {u: (0.2, 0.0, 0.1) for u in sim.ugvs}
    a, b = sim.step(Commands(velocities=velocities)), twin.step(Commands(velocities=velocities))
    assert dict(a.truth) == dict(b.truth)

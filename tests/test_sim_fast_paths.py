"""Fast paths of the simulation core and the camera glue, each against the code it
replaced (kept here as the reference), on random inputs, with exact equality."""

import numpy as np
import pytest

from moma_env.camera import BoardView, make_camera, up_in_board
from moma_env.camera.geometric import board_up_rows
from moma_env.geometry import se2_to_se3
from moma_env.markers import BoardLayout
from moma_env.scenarios import make_scenario
from moma_env.sim import Commands, Simulation
from moma_env.sim.simulation import _LineOfSight


def simulation(name):
    scenario = make_scenario(name)
    wc = scenario.world
    names = [c.name for u in wc.ugvs for c in u.cameras] + [u.camera_name for u in wc.uavs]
    return Simulation(scenario, {c: make_camera(c, scenario.camera) for c in names})


def assert_same_view(fast, reference, copied=False):
    assert type(fast) is BoardView
    assert type(fast.board_id) is int and fast.board_id == reference.board_id
    assert fast.layout == reference.layout if copied else fast.layout is reference.layout
    assert fast.T_w_m.dtype == reference.T_w_m.dtype and fast.T_w_m.tobytes() == reference.T_w_m.tobytes()
    if reference.up_m is None:
        assert fast.up_m is None
    else:
        assert not fast.up_m.flags.writeable
        assert fast.up_m.dtype == reference.up_m.dtype and fast.up_m.tobytes() == reference.up_m.tobytes()


def test_trusted_views_equal_the_checked_ones():
    rng = np.random.default_rng(0)
    layout = BoardLayout()
    for board_id in range(50):
        T = se2_to_se3(*rng.uniform(-5.0, 5.0, 3))
        up = rng.normal(size=3)
        up /= np.linalg.norm(up)
        for up_m in (None, up):
            if up_m is not None:
                up_m = up_m.copy()
                up_m.setflags(write=False)
            assert_same_view(BoardView.trusted(board_id, layout, T, up_m), BoardView(board_id, layout, T, up_m))
    view = BoardView.trusted(3, layout, T, None)
    with pytest.raises(AttributeError):
        view.board_id = 4  # frozen like any other view


@pytest.mark.parametrize("name", ["top_observer", "caterpillar", "caterpillar_sled"])
def test_board_views_equal_the_checked_views_of_the_world(name):
    """Simulation.board_views as it was: ``BoardView(...)`` of each board's world pose and mount up."""
    sim = simulation(name)
    sim.reset(np.random.default_rng(1))
    wc = sim.scenario.world
    up = {d.name: up_in_board(d.board_mount) for d in (*wc.ugvs, *wc.sleds)}
    rng = np.random.default_rng(2)
    for step in range(20):
        reference = [BoardView(b, layout, sim.world.board_transform(d), up[d]) for d, b, layout in sim.boards]
        fast = sim.board_views()
        assert len(fast) == len(reference)
        for f, r in zip(fast, reference):
            assert_same_view(f, r)
        ugv = wc.ugvs[step % len(wc.ugvs)].name
        sim.step(Commands(requests={ugv: True}, velocities={ugv: rng.uniform(-0.3, 0.3, 3)}))


class _RecordingWorld:
    def __init__(self):
        self.calls = []

    def segment_blocked(self, p_from_xy, p_to_xy, ignore=()):
        self.calls.append((tuple(float(v) for v in p_from_xy), tuple(float(v) for v in p_to_xy), tuple(ignore)))
        return len(self.calls) % 3 == 0


class _FakeSimulation:
    def __init__(self, positions):
        self.device_positions = positions
        self.world = _RecordingWorld()


def reference_line_of_sight(simulation, camera_owner, p_from, p_to):
    """_LineOfSight.__call__ as it was (min() with a key function, numpy slices)."""
    x, y = float(p_to[0]), float(p_to[1])
    positions = simulation.device_positions
    nearest = min(positions, key=lambda item: (item[1][0] - x) ** 2 + (item[1][1] - y) ** 2)[0]
    return simulation.world.segment_blocked(p_from[:2], p_to[:2], ignore=(camera_owner, nearest))


def test_line_of_sight_picks_the_device_min_picks():
    rng = np.random.default_rng(3)
    for trial in range(400):
        n = int(rng.integers(1, 7))
        # Coarse grids make ties (the first of equals wins) and exact zeros common.
        xy = rng.integers(-3, 4, size=(n, 2)) * 0.5 if trial % 2 else rng.uniform(-4.0, 4.0, size=(n, 2))
        positions = [(f"d{k}", (float(x), float(y))) for k, (x, y) in enumerate(xy)]
        if trial % 7 == 0:
            positions[int(rng.integers(n))] = ("nan", (float("nan"), 0.0))
        p_from = rng.uniform(-4.0, 4.0, 3)
        p_to = rng.integers(-3, 4, size=3) * 0.5 if trial % 3 else rng.uniform(-4.0, 4.0, 3)
        fast_sim, reference_sim = _FakeSimulation(positions), _FakeSimulation(positions)
        fast = _LineOfSight(fast_sim, "owner")(p_from, p_to)
        reference = reference_line_of_sight(reference_sim, "owner", p_from, p_to)
        assert fast == reference
        assert fast_sim.world.calls == reference_sim.world.calls


def reference_board_up_rows(boards):
    rows = np.full((len(boards), 3), np.nan)
    for k, board in enumerate(boards):
        if board.up_m is not None:
            rows[k] = board.up_m
    return rows


def test_board_up_rows_equal_the_row_by_row_assignment():
    rng = np.random.default_rng(4)
    layout = BoardLayout()
    for n in range(8):
        boards = []
        for k in range(n):
            up = rng.normal(size=3)
            boards.append(BoardView(k, layout, np.eye(4), up / np.linalg.norm(up) if rng.random() < 0.7 else None))
        fast, reference = board_up_rows(boards), reference_board_up_rows(boards)
        assert fast.shape == reference.shape == (n, 3) and fast.dtype == reference.dtype
        assert fast.tobytes() == reference.tobytes()


def test_copies_show_read_only_up_vectors_too():
    """The board views share one up vector per board: read-only, in copies as well."""
    import copy
    import pickle

    sim = simulation("caterpillar_sled")
    sim.reset(np.random.default_rng(5))
    for clone in (copy.deepcopy(sim), pickle.loads(pickle.dumps(sim))):
        views, reference = clone.board_views(), sim.board_views()
        assert len(views) == len(reference)
        for view, original in zip(views, reference):
            assert_same_view(view, original, copied=True)
            with pytest.raises(ValueError):
                view.up_m[0] = 1.0

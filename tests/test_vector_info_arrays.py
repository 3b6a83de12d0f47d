"""The infos' small arrays carried between processes as columns (moma_env.vector.info_arrays):
after a pickle round trip the receiver's infos are the sender's, keys in their order, and the
sender's own infos are left as they were."""

import multiprocessing as mp
import pickle

import numpy as np
import pytest

from moma_env import vector
from moma_env.vector.info_arrays import lift_arrays, put_arrays
from moma_env.vector.sharded import send_reply
from serialised import text


def _infos():
    """Three copies' infos: a column every copy holds, one whose shape differs in a copy, one
    a copy lacks, a 0-d array, an object array, a Fortran-ordered one and a nested dict."""
    out = []
    for i in range(3):
        mask = np.array([1, 0, i], dtype=np.int8)
        out.append({
            "ugv_0": {
                "truth": (0.1 * i, 0.0, 0.0),
                "covariance": np.full((6, 6), float(i)),
                "ragged": np.zeros(2 if i < 2 else 3),
                "scalar": np.array(float(i)),
                "objects": np.array([None, i], dtype=object),
                "fortran": np.asfortranarray(np.arange(6.0).reshape(2, 3) + i),
                "action_mask": mask,
            },
            "ugv_1": {"covariance": np.eye(6) * i, **({"only_some": np.ones(2)} if i != 1 else {})},
            "final_info": {"ugv_0": {"covariance": np.eye(6)}},
        })
    return out


def test_the_receiver_gets_the_senders_infos_and_the_sender_keeps_its_own():
    infos = _infos()
    before = text(infos)
    originals = [info["ugv_0"]["covariance"] for info in infos]
    columns, lifted = lift_arrays(infos)
    assert {(key, inner) for key, inner, _ in columns} == {("ugv_0", "covariance"), ("ugv_0", "action_mask"), ("ugv_1", "covariance")}
    assert all(info["ugv_0"]["covariance"] is None for info in infos)
    assert infos[0]["ugv_0"]["ragged"] is not None and infos[0]["ugv_1"]["only_some"] is not None
    wire = pickle.dumps((infos, columns), protocol=pickle.HIGHEST_PROTOCOL)
    put_arrays(infos, columns, lifted)
    assert text(infos) == before
    assert [info["ugv_0"]["covariance"] for info in infos] == originals  # the same objects back
    received, received_columns = pickle.loads(wire)
    put_arrays(received, received_columns)
    assert text(received) == before
    assert [list(info["ugv_0"]) for info in received] == [list(info["ugv_0"]) for info in infos]
    assert received[2]["ugv_0"]["action_mask"].dtype == np.int8


def test_no_copies_or_no_arrays_lift_nothing():
    assert lift_arrays([]) == ((), [])
    infos = [{"a": {"x": 1.0}}, {"a": {"x": 2.0}}]
    assert lift_arrays(infos) == ((), [])
    assert infos == [{"a": {"x": 1.0}}, {"a": {"x": 2.0}}]


def test_a_column_of_the_wrong_length_is_refused():
    infos = _infos()
    columns, _ = lift_arrays(infos)
    with pytest.raises(ValueError, match="'ugv_0'/'covariance' holds 3 arrays for 2 copies"):
        put_arrays(infos[:2], columns)


def test_a_workers_step_carries_the_infos_arrays_as_columns():
    local = vector.make("top_observer_team4", 4, max_cycles=10)
    sharded = vector.make("top_observer_team4", 4, workers=2, max_cycles=10)  # copies 2, 3 in the worker
    try:
        assert text(sharded.reset(seed=3)) == text(local.reset(seed=3))
        rng = np.random.default_rng(0)
        for _ in range(12):  # over the episodes' ends (autoresets: final infos one level down)
            actions = local.sample_actions(rng)
            got, want = sharded.step(actions), local.step(actions)
            assert text(got) == text(want)
        # rows of the worker's columns (in this process, each copy's arrays are its own)
        for key in ("action_mask", "covariance"):
            assert got[4][2]["ugv_0"][key].base is got[4][3]["ugv_0"][key].base is not None
            own = want[4][2]["ugv_0"][key].base
            assert own is None or own is not want[4][3]["ugv_0"][key].base
    finally:
        sharded.close()
        local.close()


def test_a_worker_sends_its_infos_arrays_as_columns_and_keeps_its_own():
    here, there = mp.Pipe()
    try:
        infos = _infos()
        result = ({"ugv_0": np.zeros((3, 2))}, tuple(infos))
        before = text(result)
        send_reply(here, "step", result)
        assert text(result) == before  # the worker's own infos, arrays back in place
        status, (value, columns), _ = there.recv()
        assert status == "ok" and len(columns) == 3 and value[-1][0]["ugv_0"]["covariance"] is None
        send_reply(here, "state", result)  # other commands: the result as it is
        assert text(there.recv()[1]) == before
    finally:
        here.close()
        there.close()

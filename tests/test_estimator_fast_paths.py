"""The estimator's per-update fast paths give the same bits as the plain numpy they replace.

Each reference below is the straightforward implementation the estimator had
before (numpy medians, np.eye / np.zeros blocks, numpy input checks); the fast
code must agree with it exactly, signed zeros included, and refuse exactly the
same inputs with the same messages.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np
import pytest
from error_bits import reference_mean_error

from moma_env import geometry as g
from moma_env.estimator import Detection, EstimatorConfig, MomaEstimator, OutlierGate, OutlierGateConfig, SwitchWindow
from moma_env.estimator import moma as moma_module
from moma_env.estimator.uncertainty import (
    LinearError,
    RunningErrorMean,
    compose_jacobian_first,
    compose_jacobians,
    inverse_jacobian,
    skew,
    upright_projection_jacobian,
)

NO_CORNERS = np.empty((0, 2))


def same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


def random_pose(rng: np.random.Generator, scale_r: float = 3.0, scale_t: float = 2.0) -> np.ndarray:
    return g.make_transform(g.rotvec_to_matrix(rng.normal(0.0, scale_r, 3)), rng.normal(0.0, scale_t, 3))


# ------------------------------------------------------------------ the window
def reference_inliers(poses: list[np.ndarray], k: float, floor_m: float, floor_rad: float) -> list[int]:
    n = len(poses)
    if n <= 2:
        return list(range(n))
    stack = np.array(poses)
    t = stack[:, :3, 3]
    d_t = np.sqrt(((t - np.median(t, axis=0)) ** 2).sum(axis=1))
    flat = stack[:, :3, :3].reshape(n, 9)
    traces = flat @ flat.T.copy()  # a general product (flat @ flat.T takes BLAS's symmetric one)
    sums = []
    for row in traces.tolist():  # left to right, as a compiled loop adds
        total = 0.0
        for v in row:
            total += v
        sums.append(total)
    medoid = sums.index(max(sums))
    d_r = np.array([math.acos(c) for c in np.clip((traces[medoid] - 1.0) / 2.0, -1.0, 1.0).tolist()])  # the C library's
    limit_t = max(k * float(np.median(d_t)), floor_m)
    limit_r = max(k * float(np.median(d_r)), floor_rad)
    return [i for i in range(n) if d_t[i] <= limit_t and d_r[i] <= limit_r]


def reference_mean(poses: list[np.ndarray], index: list[int]) -> np.ndarray:
    if len(index) == 1:
        return poses[index[0]].copy()
    R_sum = np.zeros((3, 3))
    t_sum = np.zeros(3)
    for i in index:
        R_sum += poses[i][:3, :3]
        t_sum += poses[i][:3, 3]
    T = np.empty((4, 4))
    T[:3, :3] = g.project_to_rotation(R_sum)
    T[:3, 3] = t_sum / len(index)
    T[3] = (0.0, 0.0, 0.0, 1.0)
    return T


def window_stream(rng: np.random.Generator, n: int) -> list[np.ndarray]:
    """Noisy samples of one pose with a few flipped / shifted outliers and exact repeats."""
    truth = random_pose(rng)
    poses = []
    for _ in range(n):
        u = rng.random()
        if u < 0.15:  # the other planar-PnP pose
            T = truth @ g.make_transform(g.rot_x(rng.uniform(0.1, 0.5)), [0.0, rng.uniform(0.02, 0.2), 0.0])
        elif u < 0.25 and poses:  # an exact repeat (ties in the medians and the medoid)
            T = poses[int(rng.integers(len(poses)))].copy()
        else:
            noise = rng.choice([1e-6, 1e-3, 1e-2])
            T = truth @ g.make_transform(g.rotvec_to_matrix(rng.normal(0.0, noise, 3)), rng.normal(0.0, noise, 3))
        poses.append(T)
    return poses


@pytest.mark.parametrize("seed", range(40))
def test_window_inliers_and_mean_match_the_numpy_reference_bit_for_bit(seed):
    rng = np.random.default_rng(seed)
    capacity = int(rng.integers(1, 30))
    k, floor_m, floor_rad = float(rng.choice([1.5, 3.0])), float(rng.choice([1e-4, 0.002])), 0.002
    window = SwitchWindow(capacity, k, floor_m, floor_rad)
    for _ in range(2):  # and again after a clear
        poses = window_stream(rng, capacity)
        for n, T in enumerate(poses, start=1):
            window.append(T, payload=n)
            if rng.random() < 0.7:  # not always asked: the sums then catch up several samples at once
                index = reference_inliers(poses[:n], k, floor_m, floor_rad)
                assert window.inliers() == index
                assert same_bits(window.mean(), reference_mean(poses[:n], index))
                assert same_bits(window.mean(), reference_mean(poses[:n], index))  # the cached one
                assert window.payloads(index) == [i + 1 for i in index]
        index = reference_inliers(poses, k, floor_m, floor_rad)
        assert window.full and window.inliers() == index
        assert same_bits(window.mean(), reference_mean(poses, index))
        window.clear()
        assert len(window) == 0 and not window.full


def test_window_mean_is_a_new_array_each_time():
    window = SwitchWindow(5)
    for k in range(4):
        window.append(g.make_transform(g.rot_z(0.001 * k), [0.001 * k, 0.0, 0.0]))
    a = window.mean()
    a[0, 3] = 99.0
    assert window.mean()[0, 3] != 99.0
    one = SwitchWindow(3)
    T = g.make_transform(g.rot_z(0.3), [1.0, 2.0, 3.0])
    one.append(T)
    m = one.mean()
    m[0, 3] = 99.0
    assert one.mean()[0, 3] == 1.0 and T[0, 3] == 1.0


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_window_with_a_non_finite_sample_uses_numpy_statistics(bad):
    rng = np.random.default_rng(3)
    poses = window_stream(rng, 12)
    poses[5] = poses[5].copy()
    poses[5][1, 3] = bad
    window = SwitchWindow(12)
    for n, T in enumerate(poses, start=1):
        window.append(T)
        assert window.inliers() == reference_inliers(poses[:n], 3.0, 0.002, 0.002)
    window.clear()
    for n, T in enumerate(poses[:5], start=1):  # finite again after the clear
        window.append(T)
        assert window.inliers() == reference_inliers(poses[:n], 3.0, 0.002, 0.002)


def test_window_accepts_what_np_array_accepts():
    window = SwitchWindow(3)
    window.append(np.eye(4).tolist())
    window.append(np.eye(4, dtype=np.float32))
    window.append(np.eye(4, dtype=int))
    assert window.inliers() == [0, 1, 2]
    assert same_bits(window.mean(), np.eye(4))


# ------------------------------------------------------------------ the error model
def reference_covariance(error: LinearError, P: dict) -> np.ndarray:
    S = error.Q.copy()
    items = list(error.J.items())
    for s, Js in items:
        for r, Jr in items:
            S += Js @ P[(s, r)] @ Jr.T
    return 0.5 * (S + S.T)


def same_error(a: LinearError, b: LinearError) -> bool:
    return list(a.J) == list(b.J) and all(same_bits(a.J[s], b.J[s]) for s in a.J) and same_bits(a.Q, b.Q)


def random_error(rng: np.random.Generator, keys: list[int]) -> LinearError:
    chosen = [s for s in keys if rng.random() < 0.6]
    Q = rng.normal(size=(6, 6))
    return LinearError({s: rng.normal(size=(6, 6)) for s in chosen}, Q @ Q.T)


@pytest.mark.parametrize("seed", range(10))
def test_running_error_mean_matches_linear_error_mean(seed):
    rng = np.random.default_rng(seed)
    running = RunningErrorMean()
    errors: list[LinearError] = []
    P = {}
    for a in range(3):
        for b in range(3):
            P[(a, b)] = rng.normal(size=(6, 6))
    for _ in range(60):
        u = rng.random()
        if u < 0.1:
            errors = []  # a cleared window
        elif u < 0.2 and len(errors) > 2:
            del errors[int(rng.integers(len(errors)))]  # an inlier turned outlier
        elif u < 0.25 and len(errors) > 1:
            errors = errors[:-1]
        else:
            errors = errors + [random_error(rng, [0, 1, 2])]
        if not errors:
            continue
        got = running.mean(errors)
        assert same_error(got, reference_mean_error(errors))
        assert running.mean(list(errors)) is got
        assert same_bits(got.covariance(P), reference_covariance(got, P))
        assert same_error(LinearError.mean(errors), reference_mean_error(errors))
    running.clear()
    assert same_error(running.mean(errors), reference_mean_error(errors))


@pytest.mark.parametrize("seed", range(6))
def test_stacked_error_products_match_the_products_one_by_one(seed):
    """Errors on many references (a team's): the covariance's K^2 products and the
    transform's K products, computed stacked, are the bits of the loops they replace,
    with the joint covariance's lower blocks the transposed views the estimator keeps."""
    rng = np.random.default_rng(seed)
    for _ in range(40):
        k = int(rng.integers(0, 9))
        keys = [int(key) for key in rng.permutation(12)[:k]]
        P = {}
        for i, a in enumerate(keys):
            for b in keys[i:]:
                C = rng.normal(size=(6, 6))
                P[(a, b)] = C
                P[(b, a)] = C.T
        Q = rng.normal(size=(6, 6))
        error = LinearError({s: rng.normal(size=(6, 6)) for s in keys}, Q @ Q.T)
        assert same_bits(error.covariance(P), reference_covariance(error, P))
        A = rng.normal(size=(6, 6))
        moved = error.transformed(A)
        assert list(moved.J) == keys
        for s in keys:
            assert same_bits(moved.J[s], A @ error.J[s])
        assert same_bits(moved.Q, A @ error.Q @ A.T)


def test_linear_error_helpers_copy_the_jacobian_dict():
    e = LinearError({0: np.eye(6)})
    for other in (e.plus_noise(np.eye(6), None), e.plus_noise(np.eye(6), np.eye(6)), e.transformed(np.eye(6))):
        assert other.J is not e.J
        other.J[1] = np.eye(6)
        assert list(e.J) == [0]


def reference_compose(T_x_y, T_y_z):
    R = T_x_y[:3, :3]
    J_A = np.eye(6)
    J_A[:3, 3:] = -skew(R @ T_y_z[:3, 3])
    J_B = np.zeros((6, 6))
    J_B[:3, :3] = R
    J_B[3:, 3:] = R
    return J_A, J_B


def reference_inverse(T_x_y):
    Rt = T_x_y[:3, :3].T
    t_inv = -Rt @ T_x_y[:3, 3]
    J = np.zeros((6, 6))
    J[:3, :3] = -Rt
    J[:3, 3:] = skew(t_inv) @ Rt
    J[3:, 3:] = -Rt
    return J


def reference_upright(T_w_x, T_b_x):
    R0 = T_w_x[:3, :3] @ T_b_x[:3, :3].T
    cx, cy, cz = R0[0, 0], R0[1, 0], R0[2, 0]
    h2 = cx * cx + cy * cy
    yaw = math.atan2(cy, cx)  # the C library's, as the pose's own projection
    c, s = math.cos(yaw), math.sin(yaw)
    tx, ty = float(T_b_x[0, 3]), float(T_b_x[1, 3])
    dyaw = np.array((-cz * cx / h2, -cz * cy / h2, 1.0))
    J = np.zeros((6, 6))
    J[0, 0] = 1.0
    J[1, 1] = 1.0
    J[0, 3:] = (s * tx + c * ty) * dyaw
    J[1, 3:] = -(c * tx - s * ty) * dyaw
    J[5, 3:] = dyaw
    return J


@pytest.mark.parametrize("seed", range(5))
def test_jacobians_match_the_block_built_reference_bit_for_bit(seed):
    rng = np.random.default_rng(seed)
    specials = [np.eye(4), g.make_transform(g.rot_z(0.5), [0.0, 0.0, 0.0]), g.make_transform(np.eye(3), [0.0, -0.0, 1.0])]
    poses = specials + [random_pose(rng) for _ in range(200)]
    for A, B in zip(poses, poses[1:] + poses[:1]):
        for got, want in zip(compose_jacobians(A, B), reference_compose(A, B)):
            assert same_bits(got, want)
        assert same_bits(compose_jacobian_first(A, B), reference_compose(A, B)[0])
        assert same_bits(inverse_jacobian(A), reference_inverse(A))
        assert same_bits(upright_projection_jacobian(A, B), reference_upright(A, B))


class ReferenceGate:
    """The outlier gate as it was written in plain Python (deques of tuples), before its
    state became one array judged by a compiled call: the reference of the test below."""

    def __init__(self, cfg: OutlierGateConfig):
        self.cfg = cfg
        self.accepted: deque = deque(maxlen=cfg.history)
        self.rotation = None
        self.last_accepted = 0.0
        self.pending: deque = deque(maxlen=cfg.start_samples)
        self.last_pending = 0.0

    @staticmethod
    def split(T):
        (a, b, c, x), (d, e, f, y), (g_, h, i, z) = T[:3].tolist()
        return (x, y, z), (a, b, c, d, e, f, g_, h, i)

    @staticmethod
    def total(values):
        """Left to right from 0.0 (``sum`` of floats compensates since Python 3.12)."""
        out = 0.0
        for v in values:
            out += v
        return out

    @classmethod
    def angle(cls, a, b):
        trace = cls.total(x * y for x, y in zip(a, b))
        return math.acos(min(1.0, max(-1.0, 0.5 * (trace - 1.0))))

    def reset(self, seed=None, time=0.0):
        self.accepted.clear()
        self.pending.clear()
        self.rotation = None
        if seed is not None:
            p, R = self.split(seed)
            self.accepted.append(p)
            self.rotation = R
            self.last_accepted = time

    def accept(self, T, time):
        cfg = self.cfg
        p, R = self.split(T)
        if self.accepted and time - self.last_accepted > cfg.reset_after_s:
            self.accepted.clear()
            self.rotation = None
        if self.accepted:
            n = len(self.accepted)
            mean = [self.total(q[k] for q in self.accepted) / n for k in range(3)]
            if self.total(abs(p[k] - mean[k]) for k in range(3)) > cfg.jump_tolerance_m:
                return False
            if self.rotation is not None and self.angle(self.rotation, R) > cfg.jump_tolerance_rad:
                return False
            self.accepted.append(p)
            self.rotation = R
            self.last_accepted = time
            return True
        if self.pending and time - self.last_pending > cfg.reset_after_s:
            self.pending.clear()
        self.pending.append((p, R))
        self.last_pending = time
        if len(self.pending) < cfg.start_samples:
            return False
        items = tuple(self.pending)
        for i in range(len(items)):
            for j in range(i + 1, len(items)):
                l1 = self.total(abs(items[i][0][k] - items[j][0][k]) for k in range(3))
                if l1 > cfg.start_tolerance_m or self.angle(items[i][1], items[j][1]) > cfg.start_tolerance_rad:
                    return False
        self.accepted.extend(q for q, _ in items)
        self.rotation = R
        self.pending.clear()
        self.last_accepted = time
        return True


@pytest.mark.parametrize("seed", range(6))
def test_gate_decides_as_the_plain_python_gate(seed):
    """A smooth stream with jumps, wrong rotations, samples at the jump tolerance from the
    accepted mean (where the mean's last bits decide), gaps longer than ``reset_after_s``
    and resets (seeded or not): every decision as the reference's."""
    rng = np.random.default_rng(seed)
    cfg = [OutlierGateConfig(), OutlierGateConfig(history=1, start_samples=5), OutlierGateConfig(history=6, start_samples=2)][seed % 3]
    gate, reference = OutlierGate(cfg), ReferenceGate(cfg)
    p, w, t = rng.normal(0.0, 1.0, 3), rng.normal(0.0, 1.0, 3), 0.0
    decisions = []
    for _ in range(800):
        t += 0.04 if rng.random() > 0.05 else rng.uniform(0.5, 2.0)
        p, w = p + rng.normal(0.0, 0.01, 3), w + rng.normal(0.0, 0.02, 3)
        q, v = p, w
        u = rng.random()
        if u < 0.1:
            q = p + rng.normal(0.0, 0.2, 3)  # a jump
        elif u < 0.25 and reference.accepted:  # at the tolerance from the accepted mean
            mean = np.mean(np.array(reference.accepted), axis=0)
            q = mean + np.eye(3)[rng.integers(3)] * rng.choice([-1.0, 1.0]) * cfg.jump_tolerance_m * rng.uniform(0.9, 1.1)
        if rng.random() < 0.1:
            v = w + rng.normal(0.0, 0.4, 3)  # a wrong rotation
        T = g.make_transform(g.rotvec_to_matrix(v), q)
        r = rng.random()
        if r < 0.03:
            seed_pose = T if r < 0.02 else None
            gate.reset(seed=seed_pose, time=t)
            reference.reset(seed=seed_pose, time=t)
        else:
            got = gate.accept(T, t)
            assert got == reference.accept(T, t), t
            decisions.append(got)
        assert gate.has_history == bool(reference.accepted)
    assert 50 < sum(decisions) < len(decisions) - 50  # both outcomes, many times


# ------------------------------------------------------------------ the input checks
_EYE3 = np.eye(3)


def reference_check(d: Detection) -> str | None:
    """The message update() raised before the fast checks, None if it accepted ``d``."""
    what = f"detection of board {d.board_id} by camera {d.camera_id!r}"
    T_c_m = d.T_c_m
    if not isinstance(T_c_m, np.ndarray) or T_c_m.shape != (4, 4) or not np.isfinite(T_c_m).all():
        return f"{what}: T_c_m must be a finite 4x4 array"
    R = T_c_m[:3, :3]
    if (
        np.abs(R.T @ R - _EYE3).max() > 1e-6
        or np.linalg.det(R) <= 0.0
        or np.abs(T_c_m[3] - (0.0, 0.0, 0.0, 1.0)).max() > 1e-6
    ):
        return f"{what}: T_c_m must be a rigid transform"
    cov = d.covariance
    if cov is not None and (
        not isinstance(cov, np.ndarray)
        or cov.shape != (6, 6)
        or not np.isfinite(cov).all()
        or np.abs(cov - cov.T).max() > 1e-9 * max(1.0, float(np.abs(cov).max()))
        or (np.diag(cov) < 0.0).any()
    ):
        return f"{what}: covariance must be a finite symmetric 6x6 array with a non-negative diagonal"
    return None


def bad_poses(rng: np.random.Generator) -> list:
    R = g.rotvec_to_matrix(rng.normal(0.0, 2.0, 3))
    T = g.make_transform(R, rng.normal(0.0, 1.0, 3))
    out = [T, T.astype(np.float32), T.tolist(), T[:3], np.eye(4, dtype=int), np.zeros((4, 4)), T * -1.0]
    for eps in (1e-7, 9.9e-7, 1e-6, 1.0000001e-6, 1.01e-6, 2e-6, 1e-3):  # around the tolerance
        for where in ((0, 0), (1, 2), (2, 1), (3, 0), (3, 3)):
            bent = T.copy()
            bent[where] += eps * rng.choice([-1.0, 1.0])
            out.append(bent)
        scaled = T.copy()
        scaled[:3, :3] *= 1.0 + eps / 2.0
        out.append(scaled)
    for bad in (np.nan, np.inf, -np.inf, 1e308):
        broken = T.copy()
        broken[int(rng.integers(4)), int(rng.integers(4))] = bad
        out.append(broken)
    huge = T.copy()
    huge[:3, 3] = (1e308, 1e308, -1e308)  # finite, but its sum is not
    out.append(huge)
    reflected = T.copy()
    reflected[:3, 0] *= -1.0
    out.append(reflected)
    return out


def bad_covariances(rng: np.random.Generator) -> list:
    A = rng.normal(size=(6, 6))
    C = A @ A.T
    out = [None, C, C.astype(np.float32), C.tolist(), np.eye(5), -np.eye(6), np.zeros((6, 6)), np.eye(6, dtype=int)]
    for eps in (0.5e-9, 0.99e-9, 1e-9, 1.01e-9, 2e-9):
        for scale in (1e-6, 1.0, 1e4):
            skewed = C * scale
            skewed[1, 4] += eps * max(1.0, float(np.abs(skewed).max()))
            out.append(skewed)
    negative = C.copy()
    negative[3, 3] = -1e-300
    out.append(negative)
    zero = C.copy()
    zero[2, 2] = -0.0
    out.append(zero)
    for bad in (np.nan, np.inf, 1e308):
        broken = C.copy()
        broken[0, 5] = broken[5, 0] = bad
        out.append(broken)
    return out


def one_robot_estimator() -> MomaEstimator:
    est = MomaEstimator(EstimatorConfig())
    est.add_robot("a", boards={0: np.eye(4)}, static=True, initial_pose=np.eye(4))
    est.add_robot("uav", cameras={"down": np.eye(4)}, static=False)
    return est


@pytest.mark.filterwarnings("ignore::RuntimeWarning")  # the accepted 1e308 translations overflow downstream
@pytest.mark.parametrize("seed", range(3))
def test_update_refuses_exactly_what_the_numpy_checks_refused(seed):
    rng = np.random.default_rng(seed)
    est = one_robot_estimator()
    t = 0.0
    n_refused = n_accepted = 0
    covariances = bad_covariances(rng)
    for T in bad_poses(rng):
        for cov in covariances:
            d = Detection("down", 0, T, NO_CORNERS, (), t, covariance=cov)
            want = reference_check(d)
            if want is None:
                t += 0.04
                est.update(t, [d])
                n_accepted += 1
            else:
                with pytest.raises(ValueError) as info:
                    est.update(t + 0.04, [d])
                assert str(info.value).startswith(want)
                assert est.time == t
                n_refused += 1
    assert n_refused > 100 and n_accepted > 10


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_the_fast_checks_never_pass_what_the_exact_checks_refuse():
    rng = np.random.default_rng(7)
    for T in bad_poses(rng):
        if moma_module._clearly_rigid(T):
            moma_module._check_pose(Detection("down", 0, T, NO_CORNERS, (), 0.0))
    for cov in bad_covariances(rng):
        if cov is not None and moma_module._clearly_valid_covariance(cov):
            moma_module._check_covariance(Detection("down", 0, np.eye(4), NO_CORNERS, (), 0.0, covariance=cov))


def test_update_takes_any_iterable_of_detections():
    est = one_robot_estimator()
    T = g.make_transform(g.rot_x(np.pi), [0.0, 0.0, 2.0])
    d = Detection("down", 0, T, NO_CORNERS, (), 0.04)
    est.update(0.04, (d,))
    est.update(0.08, iter([d]))
    est.update(0.12, (x for x in [d]))
    assert est.camera_pose("down") is not None
    with pytest.raises(ValueError, match="detected twice"):
        est.update(0.16, [d, d])


# ------------------------------------------------------------------ the compiled update steps
def random_covariance(rng: np.random.Generator) -> np.ndarray:
    L = rng.normal(0.0, 0.01, (6, 6))
    return L @ L.T


def reference_through(error: LinearError, A, B, cov, persistent):
    """transformed(A).plus_noise(B, cov, persistent) as numpy computed them before the kernel."""
    J = {s: A @ Js for s, Js in error.J.items()}
    Q = A @ error.Q @ A.T
    P = None if error.P is None else A @ error.P @ A.T
    if persistent is not None and cov is not None:
        added = B @ persistent @ B.T
        P = added if P is None else P + added
    if cov is not None:
        Q = Q + B @ cov @ B.T
    return J, Q, P


@pytest.mark.parametrize("seed", range(4))
def test_an_error_through_a_step_is_numpy_s_bit_for_bit(seed):
    rng = np.random.default_rng(seed)
    for case in range(200):
        keys = list(range(case % 4))
        error = LinearError({k: rng.normal(size=(6, 6)) for k in keys}, random_covariance(rng), random_covariance(rng) if case % 3 else None)
        A, B = rng.normal(size=(6, 6)), rng.normal(size=(6, 6))
        cov = random_covariance(rng) if case % 5 else None
        persistent = random_covariance(rng) if case % 2 else None
        got = error.through(A, B, cov, persistent)
        J, Q, P = reference_through(error, A, B, cov, persistent)
        assert list(got.J) == keys and all(same_bits(got.J[k], J[k]) for k in keys)
        assert same_bits(got.Q, Q) and (P is None) == (got.P is None) and (P is None or same_bits(got.P, P))
        plain = error.transformed(A)
        J, Q, P = reference_through(error, A, B, None, None)
        assert all(same_bits(plain.J[k], J[k]) for k in keys) and same_bits(plain.Q, Q)
        noisy = error.plus_noise(B, cov, persistent)  # numpy's plus_noise: no transform
        P = error.P
        if persistent is not None and cov is not None:
            added = B @ persistent @ B.T
            P = added if P is None else P + added
        assert all(same_bits(noisy.J[k], error.J[k]) for k in keys)
        assert same_bits(noisy.Q, error.Q if cov is None else error.Q + B @ cov @ B.T)
        assert (P is None) == (noisy.P is None) and (P is None or same_bits(noisy.P, P))


@pytest.mark.parametrize("seed", range(3))
def test_the_compiled_detection_steps_are_the_helpers_bit_for_bit(seed):
    from moma_env.estimator.kernels import body_from_board_seen, body_from_mounted_frame, camera_from_reference_board

    rng = np.random.default_rng(seed)
    for _ in range(300):
        T_w_m, T_c_m, T_w_c, mount = (random_pose(rng) for _ in range(4))
        board_J, cov, persistent = rng.normal(size=(6, 6)), random_covariance(rng), random_covariance(rng)
        # a camera from a reference board
        T_m_c = g.invert(T_c_m)
        J_ref, J_meas = compose_jacobians(T_w_m, T_m_c)
        A = J_meas @ inverse_jacobian(T_c_m)
        got = camera_from_reference_board(T_w_m, board_J, T_c_m, cov, True, persistent, True)
        for x, y in zip(got, (T_w_m @ T_m_c, J_ref @ board_J, A @ cov @ A.T + 0.0, A @ persistent @ A.T)):
            assert same_bits(x, y)
        assert same_bits(camera_from_reference_board(T_w_m, board_J, T_c_m, cov, False, persistent, False)[2], np.zeros((6, 6)))
        # a body from a board seen by a located camera, upright and not
        T_w_b_board = T_w_c @ T_c_m
        J_cam, J_meas = compose_jacobians(T_w_c, T_c_m)
        inverse = g.invert(mount)
        for planar in (True, False):
            if planar:
                sample, A = g.upright_body_from_mount(T_w_b_board, mount, 0.3), upright_projection_jacobian(T_w_b_board, mount)
            else:
                sample, A = T_w_b_board @ inverse, compose_jacobian_first(T_w_b_board, inverse)
            got = body_from_board_seen(T_w_c, T_c_m, mount, inverse, planar, 0.3)
            assert same_bits(got[0], sample) and same_bits(got[1], A @ J_cam) and same_bits(got[2], A @ J_meas)
            got = body_from_mounted_frame(T_w_c, mount, inverse, planar, 0.3)
            if planar:
                assert same_bits(got[0], g.upright_body_from_mount(T_w_c, mount, 0.3)) and same_bits(got[1], upright_projection_jacobian(T_w_c, mount))
            else:
                assert same_bits(got[0], T_w_c @ inverse) and same_bits(got[1], compose_jacobian_first(T_w_c, inverse))


@pytest.mark.parametrize("seed", range(3))
def test_a_sample_from_a_board_seen_is_the_two_steps_it_fuses_bit_for_bit(seed):
    """sample_from_board_seen = body_from_board_seen, then LinearError.through, for camera
    errors of zero, one and two references, with and without P, and detections with and
    without their noise."""
    from moma_env.estimator.kernels import body_from_board_seen, sample_from_board_seen
    from moma_env.estimator.uncertainty import noise_operands

    rng = np.random.default_rng(seed)
    for k in range(300):
        T_w_c, T_c_m, mount = (random_pose(rng) for _ in range(3))
        inverse = g.invert(mount)
        keys = [[], ["a"], ["a", "b"]][k % 3]
        camera_error = LinearError(
            {key: rng.normal(size=(6, 6)) for key in keys}, random_covariance(rng), random_covariance(rng) if k % 2 else None
        )
        cov = None if k % 5 == 0 else random_covariance(rng)
        persistent = None if cov is None or k % 4 == 0 else random_covariance(rng)
        planar = bool(k % 7 < 4)
        sample, A_cam, A_meas = body_from_board_seen(T_w_c, T_c_m, mount, inverse, planar, 0.3)
        want = camera_error.through(A_cam, A_meas, cov, persistent)
        names, *operands = camera_error.operands()
        got_sample, *parts = sample_from_board_seen(T_w_c, T_c_m, mount, inverse, planar, 0.3, *operands, *noise_operands(cov, persistent))
        got = LinearError.of_operands(names, *parts)
        assert same_bits(got_sample, sample)
        assert list(got.J) == list(want.J) and all(same_bits(got.J[key], want.J[key]) for key in keys)
        assert same_bits(got.Q, want.Q)
        assert (got.P is None) == (want.P is None) and (got.P is None or same_bits(got.P, want.P))

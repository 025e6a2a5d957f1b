"""SO(3) helpers: round trips, near-0/near-pi accuracy, conventions (oracles: closed forms)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from imugen.core import rotations as r

finite = st.floats(-1.0, 1.0, allow_nan=False)
unit_axis = st.tuples(finite, finite, finite).filter(lambda v: np.linalg.norm(v) > 1e-3)


def _axis(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


@settings(max_examples=200, deadline=None)
@given(unit_axis, st.floats(0.0, np.pi - 1e-9))
def test_exp_log_round_trip(axis, angle):
    phi = _axis(axis) * angle
    back = r.log_quat(r.exp_quat(phi))
    np.testing.assert_allclose(back, phi, rtol=0, atol=1e-14 + 1e-15 * angle)
    back2 = r.log_dcm(r.exp_dcm(phi))
    np.testing.assert_allclose(back2, phi, rtol=0, atol=2e-8 if angle > 3.1 else 1e-13)


@pytest.mark.parametrize("angle", [0.0, 1e-300, 1e-20, 1e-12, 1e-8, 1e-4, 1e-2])
def test_small_angles_relative_accuracy(angle):
    phi = _axis([0.3, -0.5, 0.8]) * angle
    C = r.exp_dcm(phi)
    # first-order oracle: C = I + [phi]x + O(angle^2)
    np.testing.assert_allclose(C, np.eye(3) + r.skew(phi), rtol=0, atol=angle**2 + 1e-300)
    back = r.log_dcm(C)
    if angle > 0:
        # relative accuracy limited by the rounding of the matrix entries near 1
        assert np.linalg.norm(back - phi) <= 1e-15 + 1e-12 * angle
    else:
        assert np.all(back == 0)


@pytest.mark.parametrize("delta", [0.0, 1e-12, 1e-8, 1e-4])
def test_log_near_pi(delta):
    axis = _axis([1.0, 2.0, -0.5])
    phi = axis * (np.pi - delta)
    back = r.log_dcm(r.exp_dcm(phi))
    # near pi the axis sign is ambiguous only at exactly pi
    if delta == 0:
        assert abs(abs(np.dot(_axis(back), axis)) - 1) < 1e-12
        assert abs(np.linalg.norm(back) - np.pi) < 1e-12
    else:
        np.testing.assert_allclose(back, phi, atol=1e-7)


def test_against_scipy_independent_implementation():
    rng = np.random.default_rng(1)
    phi = rng.normal(size=(500, 3))
    phi *= (rng.uniform(0, np.pi, 500) / np.linalg.norm(phi, axis=1))[:, None]
    C = r.exp_dcm(phi)
    np.testing.assert_allclose(C, Rotation.from_rotvec(phi).as_matrix(), atol=1e-14)
    q = r.exp_quat(phi)
    np.testing.assert_allclose(q[:, [1, 2, 3, 0]], Rotation.from_rotvec(phi).as_quat(), atol=1e-15)
    np.testing.assert_allclose(r.log_dcm(C), phi, atol=1e-12)


def test_quat_dcm_round_trip_and_orthonormal():
    rng = np.random.default_rng(2)
    q = r.quat_normalize(rng.normal(size=(1000, 4)))
    C = r.quat_to_dcm(q)
    np.testing.assert_allclose(
        C @ np.swapaxes(C, -1, -2), np.broadcast_to(np.eye(3), C.shape), atol=1e-14
    )
    np.testing.assert_allclose(np.linalg.det(C), 1.0, atol=1e-14)
    q2 = r.dcm_to_quat(C)
    q_pos = np.where(q[:, :1] < 0, -q, q)
    np.testing.assert_allclose(q2, q_pos, atol=1e-14)
    # product of quaternions == product of matrices
    p = r.quat_normalize(rng.normal(size=(1000, 4)))
    np.testing.assert_allclose(r.quat_to_dcm(r.quat_mul(p, q)), r.quat_to_dcm(p) @ C, atol=1e-14)
    np.testing.assert_allclose(r.quat_to_dcm(r.quat_conj(q)), np.swapaxes(C, -1, -2), atol=1e-15)


def test_skew_is_cross():
    rng = np.random.default_rng(3)
    a, b = rng.normal(size=(2, 50, 3))
    np.testing.assert_allclose((r.skew(a) @ b[..., None])[..., 0], np.cross(a, b), atol=1e-15)


def test_euler_convention():
    # yaw 0 faces East, +pi/2 faces North
    np.testing.assert_allclose(r.euler_to_dcm(0, 0, 0) @ [1, 0, 0], [1, 0, 0], atol=1e-15)
    np.testing.assert_allclose(r.euler_to_dcm(0, 0, np.pi / 2) @ [1, 0, 0], [0, 1, 0], atol=1e-15)
    # pitch positive: nose up
    fwd = r.euler_to_dcm(0, 0.3, 0) @ [1, 0, 0]
    np.testing.assert_allclose(fwd, [np.cos(0.3), 0, np.sin(0.3)], atol=1e-15)
    # roll positive: right wing (-y body) goes down, left wing up
    left = r.euler_to_dcm(0.2, 0, 0) @ [0, 1, 0]
    assert left[2] > 0
    # independent implementation: scipy intrinsic z-y-x with pitch sign flipped
    rng = np.random.default_rng(4)
    roll, yaw = rng.uniform(-np.pi, np.pi, (2, 200))
    pitch = rng.uniform(-1.5, 1.5, 200)
    C = r.euler_to_dcm(roll, pitch, yaw)
    ref = Rotation.from_euler("ZYX", np.column_stack([yaw, -pitch, roll])).as_matrix()
    np.testing.assert_allclose(C, ref, atol=1e-14)
    np.testing.assert_allclose(r.dcm_to_euler(C), np.column_stack([roll, pitch, yaw]), atol=1e-12)


def test_euler_at_gimbal_lock_is_finite():
    C = r.euler_to_dcm(0.4, np.pi / 2, 0.1)
    e = r.dcm_to_euler(C)
    assert np.all(np.isfinite(e))
    assert abs(e[1] - np.pi / 2) < 1e-7
    np.testing.assert_allclose(r.euler_to_dcm(*e), C, atol=1e-7)


def test_right_jacobian_oracle():
    # d/dt Exp(phi(t)) = Exp(phi) [J_r phi_dot]x, checked with a central difference
    rng = np.random.default_rng(5)
    for angle in (1e-5, 0.5, 2.0, 3.0):
        phi = _axis(rng.normal(size=3)) * angle
        dphi = rng.normal(size=3)
        h = 1e-6
        dC = (r.exp_dcm(phi + h * dphi) - r.exp_dcm(phi - h * dphi)) / (2 * h)
        omega = r.right_jacobian(phi) @ dphi
        np.testing.assert_allclose(dC, r.exp_dcm(phi) @ r.skew(omega), atol=1e-8)
        np.testing.assert_allclose(
            r.right_jacobian_inv(phi) @ r.right_jacobian(phi), np.eye(3), atol=1e-12
        )


def test_quat_continuous():
    rng = np.random.default_rng(6)
    q = r.exp_quat(np.cumsum(rng.normal(scale=0.3, size=(100, 3)), axis=0))
    flipped = q * rng.choice([-1.0, 1.0], size=(100, 1))
    c = r.quat_continuous(flipped, ref=q[0])
    np.testing.assert_allclose(c, q, atol=0)

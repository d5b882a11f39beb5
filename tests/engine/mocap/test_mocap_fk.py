"""Forward kinematics and quaternion helpers against hand-computed answers."""
import numpy as np
import pytest

from engine.mocap import Motion, Skeleton, forward_kinematics
from engine.mocap import quaternions as quat
from tests.engine.mocap.helpers import axis_angle, chain_skeleton, constant_motion


def test_fk_chain_with_known_angles_gives_exact_positions():
    skel = chain_skeleton()
    n = 3
    rots = quat.identity((n, 4))
    # frame 1: a rotated +90 deg about Z (X -> Y); frame 2: root yaw +90 about Y, b bent +90 about Y
    rots[1, 1] = axis_angle("Z", np.pi / 2)
    rots[2, 0] = axis_angle("Y", np.pi / 2)
    rots[2, 2] = axis_angle("Y", np.pi / 2)
    root = np.array([[0, 0, 0], [1, 0, 0], [0, 0, 2.0]])
    pos, glob = forward_kinematics(constant_motion(skel, n, 30, rots, root))
    expected = np.array([
        [[0, 0, 0], [0, 1, 0], [0.5, 1, 0], [0.75, 1, 0]],
        # a's frame: X->Y, so b at a + (0, 0.5, 0), b_end another 0.25 along Y
        [[1, 0, 0], [1, 1, 0], [1, 1.5, 0], [1, 1.75, 0]],
        # root yaw +90 about Y maps X -> -Z; b bends another 90 about Y so its X maps to -X
        [[0, 0, 2], [0, 1, 2], [0, 1, 1.5], [-0.25, 1, 1.5]],
    ])
    np.testing.assert_allclose(pos, expected, atol=1e-12)
    np.testing.assert_allclose(glob[2, 2], quat.to_matrix(axis_angle("Y", np.pi)), atol=1e-12)


def test_fk_is_vectorised_identically_to_a_per_frame_loop():
    rng = np.random.default_rng(0)
    skel = chain_skeleton()
    rots = quat.normalize(rng.normal(size=(50, 4, 4)))
    motion = constant_motion(skel, 50, 30, rots, rng.normal(size=(50, 3)))
    pos, _ = forward_kinematics(motion)
    for f in (0, 17, 49):
        g = quat.to_matrix(rots[f, 0])
        p = motion.root_positions_m[f]
        for j in range(1, 4):
            p = p + g @ skel.offsets_m[j]
            g = g @ quat.to_matrix(rots[f, j])
            np.testing.assert_allclose(pos[f, j], p, atol=1e-12)


@pytest.mark.parametrize("order", ["ZXY", "ZYX", "XYZ", "YXZ"])
def test_euler_matches_matrix_product_and_round_trips(order):
    rng = np.random.default_rng(1)
    angles = rng.uniform(-1.2, 1.2, size=(20, 3))
    q = quat.from_euler(angles, order)
    for a, qi in zip(angles, q):
        m = np.eye(3)
        for axis, ang in zip(order, a):
            m = m @ quat.to_matrix(axis_angle(axis, ang))
        np.testing.assert_allclose(quat.to_matrix(qi), m, atol=1e-12)
    np.testing.assert_allclose(quat.to_euler(q, order), angles, atol=1e-10)


def test_slerp_midpoint_and_matrix_round_trip():
    a = axis_angle("Y", 0.2)
    b = axis_angle("Y", 1.0)
    np.testing.assert_allclose(quat.slerp(a, b, 0.5), axis_angle("Y", 0.6), atol=1e-12)
    np.testing.assert_allclose(quat.slerp(a, -b, 0.25), axis_angle("Y", 0.4), atol=1e-12)  # short arc
    q = quat.normalize(np.random.default_rng(2).normal(size=(10, 4)))
    back = quat.from_matrix(quat.to_matrix(q))
    np.testing.assert_allclose(np.abs(np.sum(back * q, axis=-1)), 1.0, atol=1e-12)


def test_skeleton_rejects_bad_topology_and_motion_rejects_bad_shapes():
    with pytest.raises(ValueError, match="topologically"):
        Skeleton(("a", "b"), np.array([1, -1]), np.zeros((2, 3)))
    with pytest.raises(ValueError, match="do not match"):
        Motion(chain_skeleton(), 30, np.zeros((5, 3)), quat.identity((5, 3)))

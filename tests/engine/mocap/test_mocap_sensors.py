"""Virtual accelerometers/gyros and the sensor-error model against exact physics."""
import numpy as np
import pytest

import engine.mocap as M
from engine.mocap import SensorErrorModel, SensorPlacement, virtual_accelerometers, virtual_gyroscopes
from engine.mocap import quaternions as quat
from engine.mocap.transform import _REFLECT_X
from tests.engine.mocap.helpers import axis_angle, chain_skeleton, constant_motion

G = M.GRAVITY_MPS2


def test_static_sensor_reads_one_g_up_and_rotates_with_a_tilted_bone():
    skel = chain_skeleton()
    theta = 0.3
    rots = quat.identity((5, 4))
    rots[:, 1] = axis_angle("Z", theta)  # tilt segment a (and b under it) by theta about Z
    motion = constant_motion(skel, 5, 100.0, rots)
    mount = quat.to_matrix(axis_angle("X", np.pi / 2))  # sensor Y axis along joint -Z... a real mounting turn
    sensors = [SensorPlacement("flat", 2, np.array([0.2, 0, 0]), np.eye(3)),
               SensorPlacement("turned", 2, np.zeros(3), mount)]
    acc = virtual_accelerometers(motion, sensors)
    up_in_joint = np.array([np.sin(theta), np.cos(theta), 0.0])  # R_z(theta)^T (0, 1, 0)
    np.testing.assert_allclose(acc[:, 0], np.tile(up_in_joint, (5, 1)), atol=1e-12)
    np.testing.assert_allclose(acc[:, 1], np.tile(mount.T @ up_in_joint, (5, 1)), atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(acc, axis=-1), 1.0, atol=1e-12)


def test_sensor_on_a_rotating_arm_reads_centripetal_plus_gravity_and_gyro_reads_omega():
    skel = chain_skeleton()
    fps, omega, n = 120.0, 2 * np.pi * 1.5, 240
    t = np.arange(n) / fps
    rots = quat.identity((n, 4))
    rots[:, 0] = axis_angle("Y", omega * t)  # spin the whole body about the vertical axis
    motion = constant_motion(skel, n, fps, rots)
    radius = 0.5 + 0.1  # b is 0.5 m out along X, sensor a further 0.1 m
    sensors = [SensorPlacement("arm", 2, np.array([0.1, 0, 0]), np.eye(3))]
    acc = virtual_accelerometers(motion, sensors)[:, 0]
    dt = 1 / fps
    centripetal = 4 * np.sin(omega * dt / 2) ** 2 / dt**2 * radius  # exact for the central difference
    assert centripetal == pytest.approx(omega**2 * radius, rel=1e-3)
    np.testing.assert_allclose(acc[:, 0], -centripetal / G, atol=1e-9)  # towards the axis = -X in the arm
    np.testing.assert_allclose(acc[:, 1], 1.0, atol=1e-9)
    np.testing.assert_allclose(acc[:, 2], 0.0, atol=1e-9)
    gyro = virtual_gyroscopes(motion, sensors)[:, 0]
    np.testing.assert_allclose(gyro, np.tile([0, omega, 0], (n, 1)), atol=1e-9)


def test_falling_sensor_reads_zero_and_clip_saturates():
    skel = chain_skeleton()
    t = np.arange(30) / 30
    root = np.zeros((30, 3))
    root[:, 1] = 10 - 0.5 * G * t**2
    motion = constant_motion(skel, 30, 30, root_m=root)
    acc = virtual_accelerometers(motion, [SensorPlacement("s", 1, np.zeros(3), np.eye(3))])
    np.testing.assert_allclose(acc, 0.0, atol=1e-9)  # free fall: an accelerometer reads nothing
    root[:, 1] = 20 * G * t**2  # 40 g upwards + 1 g gravity
    acc = virtual_accelerometers(constant_motion(skel, 30, 30, root_m=root),
                                 [SensorPlacement("s", 1, np.zeros(3), np.eye(3))], clip_g=12)
    np.testing.assert_allclose(acc[:, 0, 1], 12.0)


def _symmetric(motion: M.Motion) -> M.Motion:
    """The same motion on a skeleton made exactly left/right symmetric (mirroring is then exact)."""
    s = motion.skeleton
    off = s.offsets_m.copy()
    pairs = M.left_right_pairs(s)
    paired = {j for p in pairs for j in p}
    off[[j for j in range(s.n_joints) if j not in paired], 0] = 0.0
    for left, right in pairs:
        off[right] = _REFLECT_X @ off[left]
    return M.Motion(M.Skeleton(s.names, s.parents, off, s.end_site), motion.fps, motion.root_positions_m,
                    motion.rotations)


def test_mirrored_walk_swaps_left_and_right_sensors_with_lateral_axis_flipped():
    motion = _symmetric(M.load_clip(M.sample_clips()["16_16"], fps=30))
    names = M.STANDARD_SENSORS
    placements = M.standard_placements(motion.skeleton, names)
    acc = virtual_accelerometers(motion, placements)
    mirrored = virtual_accelerometers(M.mirror(motion), placements)
    flip = np.array([1.0, -1.0, 1.0])  # sensor Y = Z x X is the axis whose handedness the mirror reverses
    for i, name in enumerate(names):
        other = name.replace("left", "#").replace("right", "left").replace("#", "right")
        if other not in names:
            continue  # right_foot has no left twin
        np.testing.assert_allclose(mirrored[:, i], acc[:, names.index(other)] * flip, atol=1e-9, err_msg=name)
    assert np.abs(acc[:, names.index("left_forearm")] - acc[:, names.index("right_forearm")]).mean() > 0.1
    heading = M.root_heading(motion)
    np.testing.assert_allclose(M.root_heading(M.mirror(motion)), -heading, atol=1e-9)
    twice = M.mirror(M.mirror(motion))
    np.testing.assert_allclose(twice.rotations, motion.rotations, atol=1e-15)


def test_mirror_refuses_an_asymmetric_rest_pose():
    skel = M.Skeleton(("root", "lhip", "rhip"), np.array([-1, 0, 0]),
                      np.array([[0, 0, 0], [0.1, -0.1, 0], [0.0, -0.1, 0.1]]))
    with pytest.raises(ValueError, match="not mirror-symmetric"):
        M.mirror(constant_motion(skel, 3, 30))


def test_standard_placements_on_cmu_follow_the_seed_conventions():
    skel = M.load_clip(M.sample_clips()["16_16"]).skeleton
    roles = M.joint_roles(skel)
    p = {s.name: s for s in M.standard_placements(skel, M.STANDARD_SENSORS)}
    assert p["left_wrist"].joint == roles["left_elbow"] and p["right_ankle"].joint == roles["right_knee"]
    forearm = skel.offsets_m[roles["left_wrist"]]
    np.testing.assert_allclose(p["left_wrist"].offset_m, 0.875 * forearm, atol=1e-12)
    np.testing.assert_allclose(p["left_wrist"].rotation[:, 0], forearm / np.linalg.norm(forearm), atol=1e-12)  # X distal
    assert p["left_wrist"].rotation[1, 2] > 0.99  # CMU zero pose is a T-pose: arm Z = world up
    assert p["left_ankle"].rotation[2, 2] > 0.9  # leg Z = forward (+Z)
    assert p["chest"].offset_m[2] > 0 > p["lower_back"].offset_m[2]  # chest in front, back sensor behind
    with pytest.raises(ValueError, match="unknown sensor"):
        M.standard_placements(skel, ["left_elbow_pad"])


def test_error_model_is_deterministic_and_matches_its_parameters():
    rng = np.random.default_rng(5)
    clean = np.tile([0.0, 1.0, 0.0], (20000, 2, 1))
    noisy = SensorErrorModel(noise_g=0.3, saturation_g=None)
    a = noisy.apply(clean, 100, np.random.default_rng(7))
    b = noisy.apply(clean, 100, np.random.default_rng(7))
    np.testing.assert_array_equal(a, b)
    assert np.std(a - clean) == pytest.approx(0.3, rel=0.02)
    biased = SensorErrorModel(bias_g=0.2).apply(clean, 100, rng)
    offset = (biased - clean)[0]
    np.testing.assert_allclose(biased - clean, np.broadcast_to(offset, clean.shape), atol=1e-12)  # constant
    slipped = SensorErrorModel(misalignment_rad=0.2).apply(clean, 100, rng)
    np.testing.assert_allclose(np.linalg.norm(slipped, axis=-1), 1.0, atol=1e-12)  # a rotation keeps |a|
    assert np.abs(slipped - clean).max() > 1e-3
    np.testing.assert_array_equal(SensorErrorModel().apply(clean, 100, rng), clean)
    loud = SensorErrorModel(noise_g=50.0).apply(clean, 100, rng)
    assert loud.max() == 12.0 and loud.min() == -12.0


def test_timing_jitter_shifts_a_ramp_by_the_jitter():
    ramp = np.arange(1000, dtype=float)[:, None, None] * np.ones((1, 1, 3))  # 1 g per sample
    out = SensorErrorModel(jitter_s=0.002, saturation_g=None).apply(ramp, 100, np.random.default_rng(3))
    shift_samples = (out - ramp)[5:-5, 0, 0]
    assert np.std(shift_samples) == pytest.approx(0.2, rel=0.1)  # 2 ms at 100 Hz = 0.2 samples


def test_seed000_preset_reproduces_the_papers_real_vs_virtual_gap_on_shipped_clips():
    rng = np.random.default_rng(0)
    model = SensorErrorModel.seed000()
    errors = []
    for name in ("16_11", "16_35", "16_01", "135_04"):
        motion = M.load_clip(M.sample_clips()[name], fps=30)
        clean = virtual_accelerometers(motion, M.standard_placements(motion.skeleton), clip_g=12)
        errors.append(M.mean_squared_error_g2(model.apply(clean, 30, rng), clean))
    assert np.mean(errors) == pytest.approx(1.6, rel=0.1)

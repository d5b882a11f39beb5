"""Re-basing joint frames onto a T-pose: positions unchanged, zero pose upright, Bandai mirrors, and the
standard sensors point the anatomical way on every source."""
import numpy as np
import pytest

import engine.mocap as M
from engine.mocap.sensors import _sensor_world


def _sources(shared) -> dict[str, M.Motion]:
    clips = {"cmu_asf": M.load_clip(M.sample_clips()["16_16"])}
    if shared is not None:
        clips["cmu_bvh"] = M.read_bvh(shared / "cmu-bvh/131_01.bvh")
        clips["bandai"] = M.read_bvh(shared / "bandai-namco-1/data/dataset-1_walk_normal_001.bvh")
    return clips


@pytest.fixture(scope="module")
def sources():
    from bench.support.shared_data import find_shared_mocap
    return _sources(find_shared_mocap())


@pytest.mark.parametrize("kind", ["cmu_asf", "cmu_bvh", "bandai"])
def test_rebase_keeps_positions_and_makes_an_upright_tpose(sources, kind):
    if kind not in sources:
        pytest.skip("shared mocap set absent")
    motion = sources[kind]
    rebased = M.rebase_to_tpose(motion)
    np.testing.assert_allclose(M.forward_kinematics(rebased)[0], M.forward_kinematics(motion)[0], atol=1e-9)
    rest = rebased.skeleton.rest_positions()
    r = M.joint_roles(rebased.skeleton)
    assert rest[r["head"], 1] > rest[r["upper_back"], 1] > rest[r["pelvis"], 1] > rest[r["left_knee"], 1] > rest[r["left_ankle"], 1]
    for side, sign in (("left", 1), ("right", -1)):
        assert sign * rest[r[f"{side}_hand"], 0] > 0.5  # arms out sideways, left = +X
        assert abs(rest[r[f"{side}_hand"], 1] - rest[r[f"{side}_shoulder"], 1]) < 0.05  # horizontal
        assert rest[r[f"{side}_toe"], 2] > rest[r[f"{side}_ankle"], 2] + 0.05  # feet point forward (+Z)


def test_bandai_mirrors_exactly_after_rebasing(sources):
    if "bandai" not in sources:
        pytest.skip("shared mocap set absent")
    motion = sources["bandai"]
    with pytest.raises(ValueError, match="rebase_to_tpose"):
        M.mirror(motion)
    rebased = M.rebase_to_tpose(motion)
    original = M.forward_kinematics(rebased)[0]
    mirrored = M.forward_kinematics(M.mirror(rebased))[0]
    reflect = np.array([-1.0, 1.0, 1.0])
    for left, right in M.left_right_pairs(rebased.skeleton):  # Bandai's skeleton is symmetric to 1e-3 cm
        np.testing.assert_allclose(mirrored[:, left], original[:, right] * reflect, atol=1e-4)


@pytest.mark.parametrize("kind", ["cmu_asf", "cmu_bvh", "bandai"])
def test_trunk_and_leg_sensors_face_the_way_the_body_walks(sources, kind):
    """Chest sensor Z points forward, lower-back Z backward, shin Z forward, bone-axis sensors X point down the
    leg — measured against the walking heading over a real walk, for each source's own frame conventions."""
    if kind not in sources:
        pytest.skip("shared mocap set absent")
    motion = sources[kind]
    names = ["chest", "lower_back", "left_shin", "left_ankle"]
    _, rot = _sensor_world(motion, M.standard_placements(motion.skeleton, names), None)
    heading = M.root_heading(motion)
    forward = np.stack([np.sin(heading), np.zeros_like(heading), np.cos(heading)], axis=-1)
    z_fwd = np.einsum("fsi,fi->fs", rot[..., 2], forward).mean(axis=0)
    x_up = rot[..., 1, 0].mean(axis=0)  # world-up component of each sensor's X axis
    assert z_fwd[0] > 0.9 and z_fwd[1] < -0.9
    assert z_fwd[2] > 0.7 and z_fwd[3] > 0.7
    assert x_up[0] > 0.9 and x_up[2] < -0.7 and x_up[3] < -0.7

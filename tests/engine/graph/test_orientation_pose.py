"""Posing the worn segments onto their measured orientations (engine/graph/orientation_pose.py, issue 18), on the
shipped CMU clips, against answers known by construction: a segment turned by a known rotation, orientations
turned by yaws the posing must not see, and the batch search equal to the live decoder; `courtside synthesize
--calibration` with a record that calibrated the sensors' orientations poses with their yaw, batch = live = the
console's engine."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from engine.graph.config import GraphConfig
from engine.graph.graph import MotionGraph
from engine.graph.online import FixedLagSynthesizer
from engine.graph.orientation_pose import SegmentPoser, SegmentPosing
from engine.graph.orientation_term import node_sensor_orientations
from engine.graph.search import ViterbiSearch
from engine.graph.viterbi import Observations, SearchWeights
from engine.mocap import joint_roles
from engine.mocap import quaternions as quat
from engine.mocap import standard_placements, virtual_accelerometers
from engine.mocap.orientation import to_device_earth, virtual_orientations, yaw_about_up
from engine.mocap.orientation_calibration import OrientationCalibration

YAWS = np.array([2.0, -1.3, 0.4, 3.0, -2.5, 1.1])  # per-sensor device yaw offsets (rad)
WEIGHTS = SearchWeights(1.0, 0.0, 0.0, forgetting=0.9, decision_frames=6, blend_paths=4, orientation=1.0)


@pytest.fixture(scope="module")
def graph(sample_motions):
    return MotionGraph.build(sample_motions, standard_placements(sample_motions[0].skeleton), GraphConfig())


@pytest.fixture(scope="module")
def poser(graph):
    return SegmentPoser(graph, list(range(6)))


def _own(graph, nodes):
    """The nodes' own sensor orientations (clip frame = the world the database was captured in)."""
    return node_sensor_orientations(graph)[nodes]


@pytest.mark.parametrize("use_yaw", [True, False])
def test_the_played_pose_s_own_orientations_change_nothing(graph, poser, use_yaw):
    nodes = np.arange(0, graph.n_nodes, 37)
    posed = poser.pose(nodes, _own(graph, nodes), use_yaw=use_yaw)
    assert np.allclose(posed, graph.node_positions_m[nodes], atol=1e-5)


def test_a_turned_forearm_turns_the_hand_about_the_elbow_and_nothing_else(graph, poser):
    roles = joint_roles(graph.skeleton)
    node = 40
    measured = _own(graph, np.array([node]))[0].copy()
    turn = quat.from_rotvec(np.array([0.0, 0.0, np.radians(30.0)]))  # 30 deg about the forward axis
    measured[1] = quat.multiply(turn, measured[1])  # right forearm
    posed = poser.pose(np.array([node]), measured[None])[0]
    played = graph.node_positions_m[node].astype(float)
    elbow = roles["right_elbow"]
    below = poser.below[1]
    want = quat.rotate(turn, played[below] - played[elbow]) + played[elbow]
    assert np.allclose(posed[below], want, atol=1e-5)
    assert np.allclose(posed[~below], played[~below], atol=1e-5)
    assert np.linalg.norm(posed[roles["right_hand"]] - played[roles["right_hand"]]) > 0.05


@pytest.mark.parametrize("share", [1.0, 0.4])
def test_a_hinged_limb_turns_about_the_shoulder_keeping_the_elbow_angle(graph, share):
    """hinge_share 1: the unworn upper arm turns with the worn forearm about the shoulder (the played elbow angle
    kept: every joint of the arm turns rigidly); a share s splits the turn: s about the shoulder, the rest about
    the (moved) elbow. The forearm ends at its measured orientation either way."""
    roles = joint_roles(graph.skeleton)
    poser = SegmentPoser(graph, list(range(6)), hinge_share=share)
    shoulder, elbow = roles["right_shoulder"], roles["right_elbow"]
    assert poser.hinge_pivot[1] == shoulder and poser.hinge_pivot[4] == -1   # forearm hinged, lower back not
    node = 40
    measured = _own(graph, np.array([node]))[0].copy()
    angle = np.radians(30.0)
    measured[1] = quat.multiply(quat.from_rotvec(np.array([0.0, 0.0, angle])), measured[1])  # right forearm
    posed = poser.pose(np.array([node]), measured[None])[0]
    played = graph.node_positions_m[node].astype(float)
    arm = poser.below[1] | (np.arange(len(played)) == elbow)
    limb = quat.from_rotvec(np.array([0.0, 0.0, share * angle]))
    rest = quat.from_rotvec(np.array([0.0, 0.0, (1 - share) * angle]))
    step = quat.rotate(limb, played[arm] - played[shoulder]) + played[shoulder]
    new_elbow = step[np.flatnonzero(arm) == elbow][0]
    want = quat.rotate(rest, step - new_elbow) + new_elbow
    assert np.allclose(posed[arm], want, atol=1e-5)
    assert np.allclose(posed[~arm], played[~arm], atol=1e-5)


def test_tilt_posing_ignores_every_sensor_s_yaw_and_relative_posing_a_shared_one(graph, poser, sample_motions):
    """A clip's true orientations, once as measured and once turned by per-sensor yaws (tilt posing must not
    see them) or by one yaw for all (relative posing must not see it: only yaw relative to the pelvis counts)."""
    motion = sample_motions[1]
    q = virtual_orientations(motion, standard_placements(motion.skeleton))[::5]
    nodes = np.arange(len(q)) * 3 % graph.n_nodes
    tilt = poser.pose(nodes, q, use_yaw=False)
    assert np.allclose(poser.pose(nodes, quat.multiply(yaw_about_up(YAWS), q), use_yaw=False), tilt, atol=1e-5)
    relative = poser.pose(nodes, q, use_yaw=True)
    assert np.allclose(poser.pose(nodes, quat.multiply(yaw_about_up(0.7), q), use_yaw=True), relative, atol=1e-5)
    assert not np.allclose(relative, tilt, atol=1e-3)


def test_posing_another_clip_s_nodes_gives_the_worn_bones_the_clip_s_elevation(graph, poser, sample_motions):
    """Nodes of clip 1 posed onto clip 0's true orientations: each worn bone (elbow -> wrist, knee -> ankle)
    rises from the vertical exactly as in clip 0 (same skeleton: the sensors' frames sit on the bones), where
    the played pose was degrees off."""
    from engine.mocap import forward_kinematics

    roles = joint_roles(graph.skeleton)
    motion = sample_motions[0]
    q = virtual_orientations(motion, standard_placements(motion.skeleton))
    other = np.flatnonzero(graph.node_clip == 1)[: len(q)]
    truth = forward_kinematics(motion)[0][: len(other)]
    bones = [(roles[f"{s}_{a}"], roles[f"{s}_{b}"]) for s in ("left", "right")
             for a, b in (("elbow", "wrist"), ("knee", "ankle"))]

    def elevation_deg(pts):
        d = np.stack([pts[:, b] - pts[:, a] for a, b in bones], axis=1)
        return np.degrees(np.arcsin(d[..., 1] / np.linalg.norm(d, axis=-1)))

    posed = poser.pose(other, q[: len(other)])
    assert np.abs(elevation_deg(posed) - elevation_deg(truth)).max() < 0.5
    assert np.abs(elevation_deg(graph.node_positions_m[other].astype(float)) - elevation_deg(truth)).mean() > 5.0


def test_live_equals_batch_with_posing(graph, sample_motions):
    """With a calibration (the search's heading part on known offsets, segments posed with their yaw), the
    fixed-lag decoder's emitted joints equal the batch search's posed joints, bit for bit."""
    motion = sample_motions[0]
    placements = standard_placements(motion.skeleton)
    q_world = virtual_orientations(motion, placements)
    acc = virtual_accelerometers(motion, placements) + np.random.default_rng(3).normal(0.0, 0.2, (len(q_world), 6, 3))
    q_device = to_device_earth(q_world, YAWS)
    calibration = OrientationCalibration(YAWS, np.tile([1.0, 0.0, 0.0, 0.0], (6, 1)))
    batch = ViterbiSearch(graph, WEIGHTS).run(Observations(acc, quat_wxyz=q_device,
                                                           orientation_calibration=calibration))
    posing = SegmentPosing.for_search(graph, tuple(range(6)), WEIGHTS, calibration)
    want = posing.decide(batch.blend_nodes, batch.ground_m, batch.heading_rad,
                         *posing.over_take(acc, q_device)).joint_positions_m
    syn = FixedLagSynthesizer(graph, 2.0, WEIGHTS, confidence_reference=1.0, orientation_calibration=calibration)
    out = []
    for t in range(len(acc)):
        out += syn.push(acc[t], quat_wxyz=q_device[t])
    out += syn.flush()
    assert np.array_equal(np.stack([p.joint_positions_m for p in out]), want)
    played = posing.decide(batch.blend_nodes, batch.ground_m, batch.heading_rad,
                           *posing.over_take(None, np.full_like(q_device, np.nan))).joint_positions_m
    assert not np.allclose(want, played, atol=1e-3)


def test_without_sensors_or_with_gain_zero_the_database_pose_plays(graph):
    assert SegmentPosing.for_search(graph, tuple(range(6)), replace(WEIGHTS, segment_pose=0.0)) is None
    assert SegmentPosing.for_search(graph, None, WEIGHTS) is None


def _take_with_npose_capture(tmp_path, motion, seed: int = 4):
    """A take of ``motion`` as orientation IMUs record it after the athlete held the N-pose for 1 s (the
    realistic filter error model over capture and take alike), and the record of the calibration that capture
    gives (what the wizard saves: nominal mountings, the orientation pair per sensor)."""
    import json

    from engine.mocap import SEED000_SENSORS, root_heading
    from engine.mocap.calibrated import orientation_fields
    from engine.mocap.orientation import OrientationErrorModel
    from engine.mocap.orientation_calibration import pose_sensor_orientations

    names = list(SEED000_SENSORS)
    placements = standard_placements(motion.skeleton, names)
    heading = root_heading(motion)
    n_capture = int(motion.fps)
    held = pose_sensor_orientations(motion.skeleton, names, heading_rad=float(heading[0]))
    q = np.concatenate([np.repeat(held[None], n_capture, axis=0), virtual_orientations(motion, placements)])
    readings = OrientationErrorModel.realistic().apply(q, motion.fps, np.random.default_rng(seed))
    cal = OrientationCalibration.from_still_pose(readings[:n_capture], pose_sensor_orientations(motion.skeleton, names))
    np.savez(tmp_path / "take.npz", acc_g=virtual_accelerometers(motion, placements), fps=motion.fps,
             sensor_names=np.array(names), quat_wxyz=readings[n_capture:],
             position_m=motion.root_positions_m[:, [0, 2]], heading_rad=heading)
    record = tmp_path / "take.calibration.json"
    record.write_text(json.dumps({"schema": "courtside.sensor_calibration", "schema_version": 1, "sensors": {
        f"st1/{k}": {"segment": p.name, "rotation": p.rotation.tolist(), "gravity_sensor_g": [0, 1, 0],
                     "norm_error_g": 0.0, "correction_deg": 0.0, "passed": True,
                     **orientation_fields(cal.yaw_rad[k], cal.mount_wxyz[k])} for k, p in enumerate(placements)}}))
    return tmp_path / "take.npz", record


def test_synthesize_with_an_orientation_calibration_poses_with_yaw_live_as_offline(graph, sample_motions, tmp_path,
                                                                                 capsys):
    """`courtside synthesize --calibration REC` on a take with orientations: the record's orientation calibration
    poses the segments with their yaw (the output differs from tilt-only posing and says which it did); the batch
    search gives the live decoder's poses (`--lag`, root fusion off: the batch fuses over the whole take), and
    the console's engine for that record (`load_spec(graph, calibration)`, which says `calibrated yaw` in its
    status label) gives `--lag`'s poses, bit for bit."""
    import json

    from engine.graph.cli import synthesize_main
    from engine.graph.online_engine import load_spec
    from engine.graph.inputs import read_take
    from engine.mocap import load_sensor_calibration
    from engine.stream.offline import drive_take
    from engine.stream.poses_file import load_poses

    graph_path = tmp_path / "g.npz"
    graph.save(graph_path)
    take, record = _take_with_npose_capture(tmp_path, sample_motions[1])
    base = ["--graph", str(graph_path), "--input", str(take), "-o", str(tmp_path / "out.bvh")]

    def run(name: str, *extra: str) -> tuple[np.ndarray, dict]:
        assert synthesize_main(base + ["--save-poses", str(tmp_path / f"{name}.npz"), *extra]) == 0
        summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
        return load_poses(tmp_path / f"{name}.npz").joint_positions_m, summary

    yaw, summary = run("yaw", "--calibration", str(record), "--no-root-fusion")
    assert summary["segment_posing"] == "calibrated yaw"
    tilt, summary = run("tilt", "--no-root-fusion")
    assert summary["segment_posing"] == "tilt only"
    moved = np.linalg.norm(yaw - tilt, axis=-1).max(axis=1)
    print(f"yaw posing moved joints by up to {100 * moved.max():.1f} cm (median frame {100 * np.median(moved):.1f} cm)")
    assert np.median(moved) > 0.01
    live, _ = run("live", "--calibration", str(record), "--no-root-fusion", "--lag", "1.0")
    assert np.array_equal(live, yaw)
    fused, _ = run("fused", "--calibration", str(record), "--lag", "1.0")
    spec = load_spec(graph_path, load_sensor_calibration(record))
    assert spec.label.endswith("acc+orientation (calibrated yaw))"), spec.label
    frames = read_take(take, graph.config.sensor_names, graph.config.fps)
    console = drive_take(spec.make(1.0), frames.obs.acc_g, frames.obs, int(frames.frame[0]), spec.rate_hz)
    assert np.array_equal(np.stack([p.joint_positions_m for p in console]), fused)
    assert load_spec(graph_path).label.endswith("acc+orientation (tilt only))")


def test_strap_refinement_learns_a_constant_strapping_error(graph, poser):
    """Every sensor strapped 8 degrees off what the calibration assumed (a posing error in the N-pose capture): the
    measured orientations are the played ones times that constant rotation in each segment's frame. Without the
    refinement the posed joints move off the played pose; with it (time constant 1 s) they come back part of the
    way (the pelvis yaw alignment mixes the pelvis sensor's own error into every misfit)."""
    from engine.graph.poses import blended_joint_positions

    nodes = (np.arange(400) * 7) % graph.n_nodes
    error = quat.from_rotvec(np.array([[np.radians(8.0), 0.0, 0.0], [0.0, np.radians(8.0), 0.0]] * 3))
    world = quat.multiply(_own(graph, nodes), error)
    share = np.ones((len(nodes), 6))
    ground, heading = np.zeros((len(nodes), 2)), np.zeros(len(nodes))
    played = blended_joint_positions(graph, nodes[:, None], ground, heading)
    calibration = OrientationCalibration(np.zeros(6), np.tile(quat.identity(), (6, 1)))

    def worst_cm(strap_s: float) -> float:
        posing = SegmentPosing(poser, 1.0, calibration, strap_time_constant_s=strap_s)
        out = posing.decide(nodes[:, None], ground, heading, world, share).joint_positions_m
        return 100 * np.abs(out - played)[-50:].max()

    unrefined, refined = worst_cm(0.0), worst_cm(1.0)
    assert unrefined > 5.0 and refined < 0.7 * unrefined   # measured 7.2 -> 4.4 cm (docstring of `_refined`)


def test_strap_refinement_learns_little_from_a_segment_the_played_poses_do_not_fit(graph, poser):
    """A segment 30 degrees off every played pose (a motion the database lacks, not a posing error of a few
    degrees) weighs little in its strapping estimate (STRAP_MISFIT_SCALE_RAD, 20 degrees): over two time
    constants it learns a far smaller share of its misfit than the segments 8 degrees off learn of theirs."""
    nodes = (np.arange(2 * int(graph.config.fps)) * 7) % graph.n_nodes
    angles = np.full(6, np.radians(8.0))
    angles[1] = np.radians(30.0)  # the right forearm
    angles[4] = 0.0  # the pelvis sensor exact: its error would mix into every misfit (`_refined`)
    error = quat.from_rotvec(np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] * 3) * angles[:, None])
    world = quat.multiply(_own(graph, nodes), error)
    posing = SegmentPosing(poser, 1.0, OrientationCalibration(np.zeros(6), np.tile(quat.identity(), (6, 1))),
                           strap_time_constant_s=1.0)
    posing.decide(nodes[:, None], np.zeros((len(nodes), 2)), np.zeros(len(nodes)), world, np.ones((len(nodes), 6)))
    limbs = [0, 1, 2, 3]
    learnt_share = 2 * np.arccos(np.clip(np.abs(posing._strap[limbs, 0]), 0.0, 1.0)) / angles[limbs]
    assert np.all(learnt_share[[0, 2, 3]] > 0.7)  # measured 0.86: the 8-deg misfits weigh 0.85
    assert learnt_share[1] < 0.5 * learnt_share[[0, 2, 3]].min()  # unweighted: the same share (measured 0.32)


def test_the_console_on_a_graph_file_applies_the_record_s_mountings_as_synthesize_does(graph, sample_motions,
                                                                                     tmp_path, capsys):
    """A record whose left forearm sensor sits 30 deg twisted (its readings turned alike): the console's engine on
    the graph file (`load_spec(graph, record)`) turns each pushed frame's readings into the nominal frame as
    `courtside synthesize --calibration --lag` turns the take, so both give the same poses, bit for bit; without
    the turn the poses differ."""
    import json

    from engine.graph.cli import synthesize_main
    from engine.graph.inputs import read_take
    from engine.graph.online_engine import load_spec
    from engine.mocap import load_sensor_calibration
    from engine.stream.offline import drive_take
    from engine.stream.poses_file import load_poses

    graph_path = tmp_path / "g.npz"
    graph.save(graph_path)
    take, record = _take_with_npose_capture(tmp_path, sample_motions[1])
    a = np.radians(30.0)
    twist = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    with np.load(take) as data:
        arrays = dict(data)
    arrays["acc_g"][:, 0] = arrays["acc_g"][:, 0] @ twist  # the strapped sensor reads twistᵀ a
    np.savez(take, **arrays)
    content = json.loads(record.read_text())
    entry = content["sensors"]["st1/0"]
    entry["rotation"] = (np.array(entry["rotation"]) @ twist).tolist()
    entry["correction_deg"] = 30.0
    record.write_text(json.dumps(content))
    assert synthesize_main(["--graph", str(graph_path), "--input", str(take), "-o", str(tmp_path / "out.bvh"),
                            "--calibration", str(record), "--lag", "1.0", "--save-poses",
                            str(tmp_path / "poses.npz")]) == 0
    capsys.readouterr()
    offline = load_poses(tmp_path / "poses.npz").joint_positions_m
    frames = read_take(take, graph.config.sensor_names, graph.config.fps)

    def console(spec) -> np.ndarray:
        poses = drive_take(spec.make(1.0), frames.obs.acc_g, frames.obs, int(frames.frame[0]), spec.rate_hz)
        return np.stack([p.joint_positions_m for p in poses])

    calibration = load_sensor_calibration(record)
    assert np.array_equal(console(load_spec(graph_path, calibration)), offline)
    calibration.rotations.pop("left_forearm")  # the same record without the forearm's mounting
    assert not np.allclose(console(load_spec(graph_path, calibration)), offline, atol=1e-4)

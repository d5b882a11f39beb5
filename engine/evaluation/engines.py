"""The engines run on a take's simulated inputs, each returning world joint positions on the take's
frame grid, so one scorer (metrics.frame_errors) judges them all; the motion graph also returns its exported
BVH read back, scored beside its shown poses (one decided pose: they agree to the file's precision).

Start state: every engine starts from the camera's first fix (root ground position and heading); without a
camera that is all it gets. With the camera on, all three pull their root onto the camera track with the bounded
root warp (engine/graph/warp.py), and with root fusion (engine/graph/root_fusion.py, the default) the output root
is the camera track smoothed over the lag (the whole take for the batch rows), each engine's own root used only
where the camera gives no fix: the same root for every engine and sensor set, the poses their own.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engine.graph.confidence import reference_cost_per_sample
from engine.graph.graph import MotionGraph
from engine.graph.online import FixedLagSynthesizer
from engine.graph.geometry import rotate_ground
from engine.graph.orientation_pose import SegmentPosing, decided_path_poses
from engine.graph.root_fusion import RootFusion, fuse_track
from engine.graph.viterbi import Observations, SearchWeights
from engine.graph.search import ViterbiSearch
from engine.graph.warp import RootWarp
from engine.mocap import Motion, SensorErrorModel, Skeleton, forward_kinematics, quaternions
from engine.mocap.orientation_calibration import OrientationCalibration
from engine.stream import EngineSpec, drive_frames
from engine.stream.decided import exported_joint_positions, has_rotations, poses_to_motion

from .metrics import hips_heading
from .simulate import SimulatedCameraTrack
from .takes import Take, yaw_quaternion


@dataclass
class Prediction:
    """World joints (T, J, 3) on the take's frame grid; `source_clip` (T,) database clip of each output frame
    where the engine plays database frames (motion graph, nearest neighbour), else None; `confidence` where the
    engine reports one (the motion graph's online decoder)."""

    joints_m: np.ndarray
    source_clip: np.ndarray | None = None
    confidence: np.ndarray | None = None  # (T,) the online decoder's per-frame confidence
    exported_m: np.ndarray | None = None  # (T, J, 3) the BVH written from the decided poses, read back (engines
    # that decide rotations: the file a user exports, scored beside the poses shown)


def start_state(take: Take, camera_position_m: np.ndarray, camera_heading_rad: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """(root position (3,), root rotation (4,)) of the take's first frame as the camera's first fix puts it:
    ground position and heading from the camera, height and body pose from the truth (the start pose)."""
    first = take.segments[0].motion
    root = first.root_positions_m[0].copy()
    root[[0, 2]] = camera_position_m[0]
    turn = float(camera_heading_rad[0] - take.heading_rad[0])
    return root, quaternions.multiply(yaw_quaternion(turn), first.rotations[0, 0])


def motion_graph(graph: MotionGraph, acc_g: np.ndarray | None, sensor_indices: tuple[int, ...],
                 camera_position_m: np.ndarray, camera_heading_rad: np.ndarray, weights: SearchWeights,
                 use_camera: bool, warp: RootWarp = RootWarp.off(), lag_s: float | None = None,
                 fusion: RootFusion = RootFusion.off(), error_model: SensorErrorModel | None = None,
                 quat_wxyz: np.ndarray | None = None,
                 calibration: OrientationCalibration | None = None) -> Prediction:
    """Batch Viterbi search, or with `lag_s` the online fixed-lag decoder (what a live user sees, with its
    confidence against the database's own clips observed through `error_model`, default seed 000's); without the
    camera only its first fix is kept (where the paths start) and the root is neither warped nor fused.
    `quat_wxyz` (T, S, 4): the graph sensors' device-earth orientations (the search's term if
    `weights.orientation` > 0; the worn segments posed onto them if `weights.segment_pose` > 0, with their yaw
    relative to the pelvis when the N-pose `calibration` is given)."""
    pos, head = camera_position_m.copy(), camera_heading_rad.copy()
    if not use_camera:
        pos[1:], head[1:] = np.nan, np.nan
    warp = warp if use_camera else RootWarp.off()
    fusion = fusion if use_camera else RootFusion.off()
    acc = acc_g[:, list(sensor_indices)] if weights.acc and acc_g is not None else None
    sensors = tuple(sensor_indices) if acc is not None else None
    quats = quat_wxyz[:, list(sensor_indices)] if acc is not None and quat_wxyz is not None else None
    calibration = None if calibration is None or quats is None else calibration.select(sensor_indices)
    if lag_s is None:
        res = ViterbiSearch(graph, weights, warp=warp).run(
            Observations(acc, pos, head, sensors, quats, orientation_calibration=calibration))
        ground, heading = fuse_track(fusion, graph.config.fps, pos, head, res.ground_m, res.heading_rad)
        posing = SegmentPosing.for_search(graph, sensors, weights, calibration)
        decided = decided_path_poses(graph, res.nodes, res.blend_nodes, ground, heading, posing, acc, quats)
        exported = None if decided.local_rotations is None else exported_joint_positions(
            Motion(graph.skeleton, graph.config.fps, decided.root_m, decided.local_rotations))
        return Prediction(decided.joint_positions_m, graph.node_clip[res.nodes].astype(int), exported_m=exported)
    reference = reference_cost_per_sample(graph, weights, warp, sensors, error_model=error_model,
                                          camera_noise_m=fusion.position_noise_m,
                                          camera_noise_rad=fusion.heading_noise_rad)
    syn = FixedLagSynthesizer(graph, lag_s, weights, sensors, warp=warp, fusion=fusion,
                              confidence_reference=reference, orientation_calibration=calibration)
    poses = drive_frames(syn, acc, pos, head, quat_wxyz=quats)
    return Prediction(np.stack([p.joint_positions_m for p in poses]),
                      graph.node_clip[np.array([p.node for p in poses])].astype(int),
                      np.array([p.confidence for p in poses]),
                      exported_joint_positions(poses_to_motion(graph.skeleton, graph.config.fps, poses))
                      if has_rotations(poses) else None)


def fused_joints(joints_m: np.ndarray, take: Take, camera: SimulatedCameraTrack, fusion: RootFusion) -> np.ndarray:
    """An engine's world joints (T, J, 3) on the take's grid turned and moved, frame by frame, onto the fused
    root (root_fusion.fuse_track of the camera fixes, the engine's own root -- joint 0 on the ground, the hips'
    heading -- where the camera gives none): OLNG and the HMM get the motion graph's root."""
    if not fusion.enabled:
        return joints_m
    own_ground, own_heading = joints_m[:, 0, [0, 2]], hips_heading(joints_m, take.skeleton)
    ground, heading = fuse_track(fusion, take.fps, camera.position_m, camera.heading_rad, own_ground, own_heading)
    out = np.array(joints_m, float, copy=True)
    out[..., [0, 2]] = rotate_ground(out[..., [0, 2]] - own_ground[:, None], (heading - own_heading)[:, None]) \
        + ground[:, None]
    return out


def on_take_grid(values: np.ndarray, times_s: np.ndarray, take: Take) -> np.ndarray:
    """Resample per-frame arrays (T', ...) given at `times_s` onto the take's frames (linear in time)."""
    t = np.arange(take.n_frames) / take.fps
    flat = values.reshape(len(values), -1)
    return np.stack([np.interp(t, times_s, flat[:, k]) for k in range(flat.shape[1])], axis=1).reshape(
        (take.n_frames,) + values.shape[1:])


def _camera_at(camera: tuple[np.ndarray, np.ndarray], times_s: np.ndarray, take: Take
               ) -> tuple[np.ndarray, np.ndarray]:
    """The camera track (on the take's frames) at other times: position linear, heading unwrapped then linear."""
    t = np.arange(take.n_frames) / take.fps
    pos = np.stack([np.interp(times_s, t, camera[0][:, k]) for k in (0, 1)], axis=1)
    return pos, np.interp(times_s, t, np.unwrap(camera[1]))


def olng(kb, config, acc_g: np.ndarray, times_s: np.ndarray, take: Take, root0_m: np.ndarray,
         root_quat0: np.ndarray, camera: tuple[np.ndarray, np.ndarray] | None = None,
         warp: RootWarp = RootWarp(), fixes: SimulatedCameraTrack | None = None,
         fusion: RootFusion = RootFusion.off()) -> Prediction:
    """OLNG (seed 003) on its four wrist/ankle accelerometers at the knowledge-base rate; `camera` = (ground
    (T, 2), heading (T,)) on the take's frames pulls its root (else only the start is given); with `fixes` (the
    raw camera track) the output root is fused (`fused_joints`)."""
    from engine.olng.evaluation import reconstruct

    cam = None if camera is None else _camera_at(camera, times_s, take)
    world, _, _ = reconstruct(kb, config, acc_g, root0_m, root_quat0, cam, warp)
    joints = on_take_grid(world, times_s, take)
    return Prediction(joints if fixes is None else fused_joints(joints, take, fixes, fusion))


def online(spec: EngineSpec, acc_g: np.ndarray, times_s: np.ndarray, take: Take,
           camera: tuple[np.ndarray, np.ndarray] | None, fixes: SimulatedCameraTrack, fusion: RootFusion,
           lag_s: float | None = None) -> Prediction:
    """Any registered engine through the `engine.stream.OnlineEngine` protocol (`drive_frames`, the push loop
    every driver uses) on its own sensors at its own rate (``acc_g`` (T', S, 3) at ``times_s``); ``camera`` =
    (ground (T, 2), heading (T,)) on the take's frames gives every frame its fix and the output root is fused
    (`fused_joints`), else it gets no fix at all. ``lag_s`` None: the engine's shortest (0)."""
    pos, head = (None, None) if camera is None else _camera_at(camera, times_s, take)
    poses = drive_frames(spec.make(0.0 if lag_s is None else lag_s), acc_g, pos, head)
    joints = on_take_grid(np.stack([p.joint_positions_m for p in poses]), times_s[[p.t for p in poses]], take)
    return Prediction(joints if camera is None else fused_joints(joints, take, fixes, fusion))


def hmm(model, acc_g: np.ndarray, gyro_rps: np.ndarray, skeleton: Skeleton, take: Take, root0_m: np.ndarray,
        root_quat0: np.ndarray, camera: tuple[np.ndarray, np.ndarray] | None = None,
        warp: RootWarp = RootWarp(), fixes: SimulatedCameraTrack | None = None,
        fusion: RootFusion = RootFusion.off()) -> Prediction:
    """Hierarchical HMM (seed 004) on its IMU(s) at the take rate: its decided poses (no whole-take foot-skate IK:
    the console never shows one, issue 29); `camera`, `fixes` and `fusion` as in `olng`."""
    from engine.hmm.evaluation import reconstruct, to_motion

    if camera is not None and abs(model.fps - take.fps) > 1e-9:
        camera = _camera_at(camera, np.arange(len(acc_g)) / model.fps, take)
    cam_pos, cam_head = (None, None) if camera is None else camera
    root, quats, _ = reconstruct(model, acc_g, gyro_rps, skeleton.n_joints, root0_m, root_quat0, cam_pos, cam_head,
                                 skeleton, warp)
    joints, _ = forward_kinematics(to_motion(skeleton, model.fps, root, quats, foot_ik=False))
    if len(joints) != take.n_frames:
        joints = on_take_grid(joints, np.arange(len(joints)) / model.fps, take)
    return Prediction(joints if fixes is None else fused_joints(joints, take, fixes, fusion))

"""The three engines run on a take's simulated inputs, each returning world joint positions on the take's
frame grid, so one scorer (metrics.frame_errors) judges them all.

Start state: every engine starts from the camera's first fix (root ground position and heading); without a
camera that is all it gets. With the camera on, all three pull their root onto the camera track with the bounded
root warp (engine/graph/warp.py).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engine.graph.graph import MotionGraph
from engine.graph.online import FixedLagSynthesizer
from engine.graph.poses import blended_joint_positions, world_joint_positions
from engine.graph.viterbi import Observations, SearchWeights, ViterbiSearch
from engine.graph.warp import RootWarp
from engine.mocap import Skeleton, forward_kinematics, quaternions

from .takes import Take, yaw_quaternion


@dataclass
class Prediction:
    """World joints (T, J, 3) on the take's frame grid; `source_clip` (T,) database clip of each output frame
    where the engine plays database frames (motion graph, nearest neighbour), else None."""

    joints_m: np.ndarray
    source_clip: np.ndarray | None = None


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
                 use_camera: bool, warp: RootWarp = RootWarp.off(), lag_s: float | None = None) -> Prediction:
    """Batch Viterbi search, or with `lag_s` the online fixed-lag decoder (what a live user sees); without the
    camera only its first fix is kept (where the paths start) and the root is not warped."""
    pos, head = camera_position_m.copy(), camera_heading_rad.copy()
    if not use_camera:
        pos[1:], head[1:] = np.nan, np.nan
    warp = warp if use_camera else RootWarp.off()
    acc = acc_g[:, list(sensor_indices)] if weights.acc and acc_g is not None else None
    sensors = tuple(sensor_indices) if acc is not None else None
    if lag_s is None:
        res = ViterbiSearch(graph, weights, warp=warp).run(Observations(acc, pos, head, sensors))
        joints = world_joint_positions(graph, res.nodes, res.ground_m, res.heading_rad) if res.blend_nodes is None \
            else blended_joint_positions(graph, res.blend_nodes, res.ground_m, res.heading_rad)
        return Prediction(joints, graph.node_clip[res.nodes].astype(int))
    syn = FixedLagSynthesizer(graph, lag_s, weights, sensors, warp=warp)
    poses = []
    for t in range(len(pos)):
        poses += syn.push(None if acc is None else acc[t], pos[t], float(head[t]))
    poses += syn.flush()
    return Prediction(np.stack([p.joint_positions_m for p in poses]),
                      graph.node_clip[np.array([p.node for p in poses])].astype(int))


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
         warp: RootWarp = RootWarp()) -> Prediction:
    """OLNG (seed 003) on its four wrist/ankle accelerometers at the knowledge-base rate; `camera` = (ground
    (T, 2), heading (T,)) on the take's frames pulls its root (else only the start is given)."""
    from engine.olng.evaluation import reconstruct

    cam = None if camera is None else _camera_at(camera, times_s, take)
    world, _, _ = reconstruct(kb, config, acc_g, root0_m, root_quat0, cam, warp)
    return Prediction(on_take_grid(world, times_s, take))


def hmm(model, acc_g: np.ndarray, gyro_rps: np.ndarray, skeleton: Skeleton, take: Take, root0_m: np.ndarray,
        root_quat0: np.ndarray, camera: tuple[np.ndarray, np.ndarray] | None = None,
        warp: RootWarp = RootWarp()) -> Prediction:
    """Hierarchical HMM (seed 004) on its IMU(s) at the take rate, with its foot-skate IK; `camera` as in `olng`."""
    from engine.hmm.evaluation import reconstruct, to_motion

    if camera is not None and abs(model.fps - take.fps) > 1e-9:
        camera = _camera_at(camera, np.arange(len(acc_g)) / model.fps, take)
    cam_pos, cam_head = (None, None) if camera is None else camera
    root, quats, _ = reconstruct(model, acc_g, gyro_rps, skeleton.n_joints, root0_m, root_quat0, cam_pos, cam_head,
                                 skeleton, warp)
    joints, _ = forward_kinematics(to_motion(skeleton, model.fps, root, quats, foot_ik=True))
    if len(joints) != take.n_frames:
        joints = on_take_grid(joints, np.arange(len(joints)) / model.fps, take)
    return Prediction(joints)

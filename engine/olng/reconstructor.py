"""Streaming full-body reconstruction from 4 accelerometers: kNN -> OLNG -> kernel-prior energy (spec A2.10).

`OLNGReconstructor.push(acc_g)` takes one reading per sensor (S, 3) in g, at the knowledge-base rate (and, when the
sensors stream them, each one's orientation quaternion and angular rate: searched on as yaw-free tilt and rate,
`engine.olng.channels`), and returns the pose for that same frame (no look-ahead, so the console can use it live). Root motion is not sensed: it is
the Eq. 1-weighted average of the hypotheses' root velocity, yaw rate and height, integrated (spec A2.9) -- and,
when the overhead camera's position / heading are passed to `push`, pulled towards them after every frame by the
motion graph's bounded root warp (engine/graph/warp.py; the first fix places the root), so the global error is the
camera's, not metres of integrated drift.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from engine.graph.warp import RootWarp, warp_one
from engine.mocap import heading_from_positions, joint_roles, quaternions

from engine.olng.channels import check_channels, search_vector, tilt_from_device_earth
from engine.olng.config import OLNGConfig
from engine.olng.energy import FrameProblem, KernelEnergy
from engine.olng.graph import OnlineLazyNeighbourhoodGraph, path_weights
from engine.olng.knowledge_base import KnowledgeBase
from engine.olng.pose import UP, fk_root_frame, pose_quats, quat_to_matrix, yaw_quat
from engine.olng.threads import single_blas_thread
from engine.olng.yaw import YawOffsets, relative_yaw

G_MPS2 = 9.80665


@dataclass(frozen=True)
class ReconstructedPose:
    """One output frame. local_quats include the integrated heading on the root, so (root_pos_m, local_quats)
    is a complete BVH-style pose; joints_root_m is what the paper's error metric compares."""

    q: np.ndarray               # (J*3,) pose vector, heading removed
    local_quats: np.ndarray     # (J, 4)
    root_pos_m: np.ndarray      # (3,) world, Y up
    heading_rad: float
    joints_root_m: np.ndarray   # (J, 3) root frame
    joints_world_m: np.ndarray  # (J, 3)


@dataclass
class StepTimings:
    """Accumulated wall time per stage (s) and frames, for the bench's per-step split."""

    search_s: float = 0.0
    graph_s: float = 0.0
    optimise_s: float = 0.0
    frames: int = 0
    subspace_dims: list[int] = field(default_factory=list)


class OLNGReconstructor:
    """Online reconstruction against a KnowledgeBase (see module doc)."""

    def __init__(self, kb: KnowledgeBase, config: OLNGConfig = OLNGConfig(),
                 root_warp: RootWarp = RootWarp(), channels: tuple[str, ...] | None = None) -> None:
        """``channels``: the IMU channels to search on (`engine.olng.channels.CHANNELS`); None = those the first
        complete frame brings that the knowledge base holds (fixed from then on: one search space per session)."""
        self.kb = kb
        self.channels = None if channels is None else check_channels(channels)
        self.root_warp = root_warp
        self._hips: tuple[int, int] | None = None  # found on the first camera heading (see _body_offset)
        self._fixed = False  # has a camera fix placed the root yet?
        self.config = config
        self.graph: OnlineLazyNeighbourhoodGraph | None = None   # built once the channels are known
        self._tree = None
        self._query_prev: np.ndarray | None = None
        self._yaw: YawOffsets | None = None      # relative-yaw term (orientation channel, engine/olng/yaw.py)
        self.energy = KernelEnergy(kb.rig, kb.sensors.tip, config.energy, (kb.sensors.bone, kb.sensors.local_rot))
        self._tilt_now: np.ndarray | None = None   # this frame's measured sensor tilts (orientation channel)
        self.timings = StepTimings()
        self._k = config.graph.k_neighbours
        self._i_best = config.graph.i_best
        self._iterations = config.energy.max_iterations
        self._scale = 1.0 / config.energy.length_unit_m
        self._x_hist: list[np.ndarray] = []   # last two outputs' root-frame positions (energy units)
        self._q_prev: np.ndarray | None = None
        self._frames_prev: tuple[np.ndarray, np.ndarray] | None = None  # the last output's sensor frames and tilt
        self._alpha_prev: np.ndarray | None = None
        self.dropped_readings = 0   # non-finite input axes replaced by the previous reading
        self._root = np.zeros(3)
        self._heading = 0.0
        self._one_thread = single_blas_thread()

    def set_effort(self, k_neighbours: int, i_best: int, iterations: int | None = None) -> None:
        """Search K neighbours, keep I hypotheses and give the energy ``iterations`` majorise-minimise steps
        (None: as configured) from the next frame on (a live engine that cannot keep up trades accuracy for
        time: `engine.olng.keep_up`); the graph takes columns of any width."""
        self._k, self._i_best = int(k_neighbours), int(i_best)
        if iterations is not None:
            self._iterations = int(iterations)

    def reset_root(self, root_pos_m: np.ndarray, heading_rad: float) -> None:
        """Place the (unsensed) root, e.g. at the camera's position estimate."""
        self._root = np.asarray(root_pos_m, dtype=float).copy()
        self._heading = float(heading_rad)

    def _sensor_accel_root(self, alpha_g: np.ndarray) -> np.ndarray:
        """Reading rotated into the root frame with the previous output's sensor frames, gravity removed
        (spec A2.6: root acceleration and fictitious forces ignored on purpose). (S, 3) in m/s^2."""
        sensor_rot, tilt = self._frames_prev   # (S, 3, 3) root <- sensor, (3, 3) root tilt: kept by `_emit`
        gravity_root = G_MPS2 * tilt.T @ UP
        return np.einsum("sij,sj->si", sensor_rot, alpha_g * G_MPS2) - gravity_root

    def _problem(self, nodes: np.ndarray, weights: np.ndarray, alpha_g: np.ndarray) -> FrameProblem:
        kb, dt, scale = self.kb, self.kb.dt_s, self._scale
        pose_targets = kb.q[nodes]
        if not self._x_hist:
            return FrameProblem(weights, pose_targets, None, None, None, start_pose=weights @ pose_targets,
                                tilt_targets=self._tilt_targets(len(nodes)))
        x_t = self._x_hist[-1]
        acc = kb.a_mps2[nodes].reshape(len(nodes), -1) * scale
        # velocity of the database frame before each path's last frame, so (velocity, weight) share a path (A6.3)
        before = np.maximum(nodes - 1, 0)
        before = np.where(kb.clip_id[before] == kb.clip_id[nodes], before, nodes)
        vel_prev = kb.v_mps[before] * scale                                         # (I, J, 3)
        reading = self._alpha_prev if self.config.energy.control_reading == "previous" else alpha_g
        accel_root = self._sensor_accel_root(reading) * scale         # (S, 3)
        tips = kb.sensors.tip
        control = (x_t.reshape(-1, 3)[tips][None] + vel_prev[:, tips] * dt + 0.5 * accel_root[None] * dt**2).reshape(len(nodes), -1)
        motion = smooth = None
        if len(self._x_hist) >= 2:
            vel = kb.v_mps[nodes].reshape(len(nodes), -1) * scale
            motion = x_t + vel * dt + 0.5 * acc * dt**2
            smooth = 2 * x_t - self._x_hist[-2] + acc * dt**2
        return FrameProblem(weights, pose_targets, motion, smooth, control, start_pose=self._q_prev,
                            tilt_targets=self._tilt_targets(len(nodes)))

    def _tilt_targets(self, count: int) -> np.ndarray | None:
        """The measured tilts as the tilt term's target for every hypothesis (None without orientations)."""
        if self._tilt_now is None:
            return None
        lever = self.config.energy.tilt_lever_m / self.config.energy.length_unit_m
        return np.broadcast_to(self._tilt_now.reshape(-1) * lever, (count, self._tilt_now.size))

    def push(self, acc_g: np.ndarray, camera_position_m: np.ndarray | None = None,
             camera_heading_rad: float | None = None, *, quat_wxyz: np.ndarray | None = None,
             gyro_rps: np.ndarray | None = None) -> ReconstructedPose:
        """Reconstruct the pose for this input frame. acc_g: (S, 3) readings in g, sensor order of the database;
        optional camera fix: ground position (x, z) m and body heading rad (NaN / None = no fix this frame);
        optional quat_wxyz (S, 4) sensor -> device earth (Z up, any yaw) and gyro_rps (S, 3) in sensor axes.
        BLAS runs on one thread during the step (engine/olng/threads.py: tiny matrices, 15x faster)."""
        with self._one_thread():
            return self._push(acc_g, camera_position_m, camera_heading_rad, quat_wxyz, gyro_rps)

    def _query(self, alpha: np.ndarray, quat_wxyz: np.ndarray | None, gyro_rps: np.ndarray | None) -> np.ndarray:
        """The search vector of this frame; the first call fixes the channels (and builds the graph). A channel
        missing or NaN in a later frame holds its previous value, as a dropped acceleration does."""
        n = len(self.kb.sensors.bone)
        if self.channels is None:
            given = {"orientation": quat_wxyz is not None and np.all(np.isfinite(quat_wxyz)),
                     "gyro": gyro_rps is not None and np.all(np.isfinite(gyro_rps))}
            self.channels = ("acc",) + tuple(c for c in ("orientation", "gyro") if given[c] and c in self.kb.channels)
        if self.graph is None:
            gc = self.config.graph
            table, self._tree = self.kb.search(self.channels, gc.tilt_weight, gc.gyro_weight_s)
            self.graph = OnlineLazyNeighbourhoodGraph(self.kb.clip_id, gc, table)
            if "orientation" in self.channels and self.kb.yaw_rad is not None and gc.yaw_weight > 0 and n > 1:
                self._yaw = YawOffsets(relative_yaw(self.kb.yaw_rad.astype(float)), self.kb.fps, gc.yaw_weight,
                                       min_frames=gc.yaw_min_frames)
        if self._yaw is not None:
            self._yaw.observe(None if quat_wxyz is None else np.asarray(quat_wxyz, float).reshape(n, 4))
        tilt = None if quat_wxyz is None else tilt_from_device_earth(np.asarray(quat_wxyz, float).reshape(n, 4))
        gyro = None if gyro_rps is None else np.asarray(gyro_rps, float).reshape(n, 3)
        if "orientation" in self.channels and tilt is None:
            tilt = np.full((n, 3), np.nan)
        if "gyro" in self.channels and gyro is None:
            gyro = np.full((n, 3), np.nan)
        query = search_vector(self.channels, alpha.reshape(n, 3), tilt, gyro,
                              self.config.graph.tilt_weight, self.config.graph.gyro_weight_s)
        if not np.all(np.isfinite(query)):
            if self._query_prev is None:
                raise ValueError(f"the first frame must bring every channel searched on ({', '.join(self.channels)})")
            query = np.where(np.isfinite(query), query, self._query_prev)
        self._query_prev = query
        if "orientation" in self.channels:   # for the energy's tilt term; a missing sensor holds its last tilt
            self._tilt_now = tilt if self._tilt_now is None else np.where(np.isfinite(tilt), tilt, self._tilt_now)
        return query

    def _push(self, acc_g: np.ndarray, camera_position_m: np.ndarray | None, camera_heading_rad: float | None,
              quat_wxyz: np.ndarray | None, gyro_rps: np.ndarray | None) -> ReconstructedPose:
        alpha = np.asarray(acc_g, dtype=float).reshape(-1)
        if alpha.shape != (self.kb.alpha_g.shape[1],):
            raise ValueError(f"expected {self.kb.alpha_g.shape[1] // 3} sensors x 3 axes, got shape {np.shape(acc_g)}")
        if not np.all(np.isfinite(alpha)):
            # a dropped sample (NaN from the gateway): hold the last complete reading rather than stop the stream
            if self._alpha_prev is None:
                raise ValueError("the first reading must be complete (got NaN/inf)")
            alpha = np.where(np.isfinite(alpha), alpha, self._alpha_prev.reshape(-1))
            self.dropped_readings += 1
        t0 = time.perf_counter()
        query = self._query(alpha, quat_wxyz, gyro_rps)
        idx, dist = self.kb.neighbours(query, self._k, self._tree)
        if self._yaw is not None:
            dist = self._yaw.distances(idx, dist)
        t1 = time.perf_counter()
        self.graph.push(idx, dist, query)
        nodes, costs = self.graph.best(self._i_best)
        weights = path_weights(costs)
        if self._yaw is not None:
            self._yaw.update(nodes, weights)
        t2 = time.perf_counter()
        problem = self._problem(nodes, weights, alpha.reshape(-1, 3))
        q = problem.start_pose if not self._x_hist else self.energy.solve(problem, self._iterations)
        t3 = time.perf_counter()
        self.timings.search_s += t1 - t0
        self.timings.graph_s += t2 - t1
        self.timings.optimise_s += t3 - t2
        self.timings.frames += 1
        self.timings.subspace_dims.append(self.energy.last_dims)
        self._alpha_prev = alpha.reshape(-1, 3)
        return self._emit(q, nodes, weights, camera_position_m, camera_heading_rad)

    def _follow_camera(self, joints_untwisted: np.ndarray, position_m, heading_rad) -> None:
        """Pull the integrated root towards a camera fix (the first one places it). The camera reports where the
        body faces (hips), the integrated yaw is the root's twist: their offset is read off this frame's pose
        (`joints_untwisted`: root-relative joints turned by the root's rotation without the integrated yaw)."""
        pos = None if position_m is None or np.any(np.isnan(position_m)) else complex(position_m[0], position_m[1])
        head = None if heading_rad is None or np.isnan(heading_rad) else float(heading_rad)
        if pos is None and head is None:
            return
        offset = self._body_offset(joints_untwisted) if head is not None else 0.0
        ground, body = complex(self._root[0], self._root[2]), self._heading + offset
        if not self._fixed:
            ground, body = (pos if pos is not None else ground), (head if head is not None else body)
            self._fixed = True
        else:
            ground, body = warp_one(ground, body, pos, head, self.root_warp, self.kb.fps)
        self._root[0], self._root[2] = ground.real, ground.imag
        self._heading = body - offset

    def _body_offset(self, joints_untwisted: np.ndarray) -> float:
        """Where the hips face minus the integrated yaw (rad). A rig whose joint names engine.mocap does not know
        (a synthetic test rig) has no hips to read: its integrated yaw is taken as the body heading."""
        if self._hips is None:
            from engine.olng.mocap_bridge import skeleton_from_rig

            try:
                roles = joint_roles(skeleton_from_rig(self.kb.rig))
                self._hips = (roles["left_hip"], roles["right_hip"])
            except ValueError:
                self._hips = (-1, -1)
        if self._hips[0] < 0:
            return 0.0
        return float(heading_from_positions(joints_untwisted[None], *self._hips)[0])

    def _emit(self, q: np.ndarray, nodes: np.ndarray, weights: np.ndarray, camera_position_m=None,
              camera_heading_rad=None) -> ReconstructedPose:
        kb, dt = self.kb, self.kb.dt_s
        pos, rot = fk_root_frame(kb.rig, q[None])
        joints_root = pos[0]
        self._x_hist = (self._x_hist + [joints_root.reshape(-1) * self._scale])[-2:]
        self._q_prev = q
        vel_heading = weights @ kb.root_vel_heading_mps[nodes]
        c, s = np.cos(self._heading), np.sin(self._heading)
        self._root[0] += dt * (c * vel_heading[0] + s * vel_heading[2])
        self._root[2] += dt * (-s * vel_heading[0] + c * vel_heading[2])
        self._root[1] = float(weights @ kb.root_height_m[nodes])
        self._heading += dt * float(weights @ kb.yaw_rate_rps[nodes])
        quats = pose_quats(kb.rig, q)
        tilt = quat_to_matrix(quats[0])
        # the next frame's control term reads this output's sensor frames (one FK per frame, not two)
        self._frames_prev = (rot[0, kb.sensors.bone] @ kb.sensors.local_rot, tilt)
        self._follow_camera(joints_root @ tilt.T, camera_position_m, camera_heading_rad)
        quats[0] = quaternions.multiply(yaw_quat(np.array(self._heading)), quats[0])
        world = self._root + joints_root @ quat_to_matrix(quats[0]).T
        return ReconstructedPose(q=q, local_quats=quats, root_pos_m=self._root.copy(), heading_rad=self._heading,
                                 joints_root_m=joints_root, joints_world_m=world)

"""The OLNG knowledge base: per-frame poses, root-frame joint kinematics and simulated sensor readings
(spec A2.1), with a kd-tree over the 12-D readings (A2.3) -- or, when the database also holds each sensor's tilt
and angular rate (issue 18, `engine.olng.channels`), over the readings plus those, one tree per channel set.

Built from plain per-clip arrays so it does not depend on which reader produced the motion; the bridge in
`engine.olng.mocap_bridge` turns `engine.mocap.Motion` clips into these arrays.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from engine.array_checks import check_arrays, check_index_range, load_npz
from engine.olng.channels import check_channels, search_vector
from engine.olng.pose import Rig, fk_root_frame, pose_vectors, reference_quats, tilted


@dataclass(frozen=True)
class SensorRig:
    """Where the worn sensors sit, in the order of the reading vector ([LW, RW, LA, RA] for the paper).

    bone: joint whose global rotation carries each sensor; local_rot: (S, 3, 3) sensor axes (columns) in that
    joint's frame; tip: the joint next to each sensor whose position the control term predicts."""

    bone: np.ndarray       # (S,) int
    local_rot: np.ndarray  # (S, 3, 3)
    tip: np.ndarray        # (S,) int


@dataclass(frozen=True)
class ClipArrays:
    """One clip at the knowledge-base rate: local joint quaternions (F, J, 4) (w,x,y,z), root positions (F, 3) m
    in the world (Y up), the simulated accelerometer readings (F, S, 3) in g and, optionally, each sensor's tilt
    (F, S, 3) (up in sensor axes, `engine.olng.channels`) and angular rate (F, S, 3) rad/s."""

    local_quats: np.ndarray
    root_pos_m: np.ndarray
    acc_g: np.ndarray
    name: str = ""
    tilt: np.ndarray | None = None
    gyro_rps: np.ndarray | None = None
    yaw_rad: np.ndarray | None = None     # (F, S) each sensor's yaw (twist about up) in the world, engine/olng/yaw.py


def within_clip_derivatives(values: np.ndarray, clip_id: np.ndarray, dt_s: float) -> tuple[np.ndarray, np.ndarray]:
    """First and second time derivatives of (N, ...) values, central inside each clip, one-sided at clip ends
    (differences never straddle a clip boundary)."""
    vel = np.empty_like(values, dtype=float)
    acc = np.empty_like(values, dtype=float)
    starts = np.flatnonzero(np.r_[True, clip_id[1:] != clip_id[:-1]])
    ends = np.r_[starts[1:], len(clip_id)]
    for s, e in zip(starts, ends):
        seg = values[s:e]
        if e - s < 3:
            vel[s:e] = 0.0 if e - s == 1 else (seg[-1] - seg[0]) / dt_s
            acc[s:e] = 0.0
            continue
        vel[s:e] = np.gradient(seg, dt_s, axis=0)
        second = (seg[2:] - 2 * seg[1:-1] + seg[:-2]) / dt_s**2
        acc[s + 1 : e - 1] = second
        acc[s] = second[0]
        acc[e - 1] = second[-1]
    return vel, acc


@dataclass
class KnowledgeBase:
    """Flattened database over all clips (N frames). Units: positions m, time s, readings g, angles rad."""

    rig: Rig
    sensors: SensorRig
    fps: float
    q: np.ndarray               # (N, J*3) pose vectors, root heading removed
    x_m: np.ndarray             # (N, J, 3) joint positions in the root frame
    v_mps: np.ndarray           # (N, J, 3) their velocities
    a_mps2: np.ndarray          # (N, J, 3) their accelerations
    alpha_g: np.ndarray         # (N, S*3) simulated readings
    clip_id: np.ndarray         # (N,) int
    root_vel_heading_mps: np.ndarray  # (N, 3) root velocity in the heading frame (x lateral, y up, z forward)
    yaw_rate_rps: np.ndarray    # (N,) heading rate
    root_height_m: np.ndarray   # (N,)
    clip_names: tuple[str, ...] = ()
    tilt: np.ndarray | None = None      # (N, S*3) up direction in each sensor's axes (orientation channel)
    gyro_rps: np.ndarray | None = None  # (N, S*3) angular rate in each sensor's axes (gyro channel)
    yaw_rad: np.ndarray | None = None   # (N, S) each sensor's yaw about up (orientation channel: relative yaw)
    _tree: cKDTree | None = None
    _searches: dict | None = None       # (channels, weights) -> (features (N, D), kd-tree)

    @property
    def size(self) -> int:
        return len(self.clip_id)

    @property
    def dt_s(self) -> float:
        return 1.0 / self.fps

    @property
    def tree(self) -> cKDTree:
        """kd-tree over the readings, built on first use (about a second per 500k frames)."""
        if self._tree is None:
            self._tree = cKDTree(self.alpha_g, leafsize=32)
        return self._tree

    @property
    def channels(self) -> tuple[str, ...]:
        """The IMU channels this database can search on (acc always; orientation / gyro when simulated)."""
        return ("acc",) + (("orientation",) if self.tilt is not None else ()) + (("gyro",) if self.gyro_rps is not None else ())

    def search(self, channels: tuple[str, ...], tilt_weight: float, gyro_weight_s: float) -> tuple[np.ndarray, cKDTree]:
        """The (N, D) search features of ``channels`` (`engine.olng.channels.search_vector`) and their kd-tree,
        built once per channel set and weights. Accelerations only: the readings and `tree` themselves."""
        channels = check_channels(channels)
        missing = set(channels) - set(self.channels)
        if missing:
            raise ValueError(f"this knowledge base holds no {', '.join(sorted(missing))} channel (rebuild it with them)")
        if channels == ("acc",):
            return self.alpha_g, self.tree
        key = (channels, float(tilt_weight), float(gyro_weight_s))
        self._searches = {} if self._searches is None else self._searches
        if key not in self._searches:
            blocks = [None if a is None else a.reshape(self.size, -1, 3) for a in (self.tilt, self.gyro_rps)]
            table = search_vector(channels, self.alpha_g.reshape(self.size, -1, 3), *blocks, tilt_weight, gyro_weight_s)
            self._searches[key] = (table, cKDTree(table, leafsize=32))
        return self._searches[key]

    def neighbours(self, alpha_g: np.ndarray, k: int, tree: cKDTree | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The k nearest database frames to one reading (S*3,) -- or a search vector of ``tree`` (`search`):
        (indices ascending, their Euclidean distances).

        Sorted by database index because the OLNG finds predecessors by binary search on each column."""
        k = min(k, self.size)
        dist, idx = (self.tree if tree is None else tree).query(alpha_g, k=k, workers=1)
        dist, idx = np.atleast_1d(dist), np.atleast_1d(idx)
        order = np.argsort(idx)
        return idx[order], dist[order]

    @classmethod
    def from_clips(cls, rig: Rig, sensors: SensorRig, clips: list[ClipArrays], fps: float) -> "KnowledgeBase":
        """Stack clips into one database; every clip gets its own id so OLNG paths never cross between clips."""
        if not clips:
            raise ValueError("knowledge base needs at least one clip")
        dt = 1.0 / fps
        joints = len(rig.parents)
        for cid, clip in enumerate(clips):
            if clip.local_quats.shape[1:] != (joints, 4):
                raise ValueError(f"clip {clip.name or cid}: local_quats shape {clip.local_quats.shape} does not match {joints} joints")
            if len(clip.acc_g) != len(clip.local_quats) or len(clip.root_pos_m) != len(clip.local_quats):
                raise ValueError(f"clip {clip.name or cid}: acc/root/pose frame counts differ")
        ref = reference_quats(np.concatenate([tilted(c.local_quats)[0] for c in clips]))
        rig = Rig(rig.names, rig.parents, rig.offsets_m, rig.end_site, ref)
        q_parts, head_parts, root_parts, ids = [], [], [], []
        for cid, clip in enumerate(clips):
            q, heading = pose_vectors(clip.local_quats, ref)
            q_parts.append(q)
            head_parts.append(np.unwrap(heading))
            root_parts.append(clip.root_pos_m)
            ids.append(np.full(len(q), cid))
        clip_id = np.concatenate(ids)
        q = np.concatenate(q_parts)
        heading = np.concatenate(head_parts)
        root = np.concatenate(root_parts)
        x = np.concatenate([fk_root_frame(rig, part)[0] for part in np.array_split(q, max(1, len(q) // 20000))])
        v, a = within_clip_derivatives(x, clip_id, dt)
        root_vel_world, _ = within_clip_derivatives(root, clip_id, dt)
        yaw_rate, _ = within_clip_derivatives(heading, clip_id, dt)
        c, s = np.cos(heading), np.sin(heading)
        # world -> heading frame: rotate by -heading about +Y
        root_vel_heading = np.stack(
            [c * root_vel_world[:, 0] - s * root_vel_world[:, 2], root_vel_world[:, 1], s * root_vel_world[:, 0] + c * root_vel_world[:, 2]],
            -1,
        )
        alpha = np.concatenate([clip.acc_g.reshape(len(clip.acc_g), -1) for clip in clips])
        extra = {}
        for channel in ("tilt", "gyro_rps", "yaw_rad"):
            given = [getattr(clip, channel) is not None for clip in clips]
            if any(given) and not all(given):
                raise ValueError(f"{channel}: some clips have it and some not (the database searches on one channel set)")
            if all(given):
                extra[channel] = np.concatenate([getattr(c, channel).reshape(len(c.acc_g), -1) for c in clips]).astype(np.float32)
        # float32 for the per-joint tables: a 500k-frame database stays under 1 GB; values are mm-accurate
        f32 = np.float32
        return cls(
            rig=rig, sensors=sensors, fps=fps, q=q.astype(f32), x_m=x.astype(f32), v_mps=v.astype(f32),
            a_mps2=a.astype(f32), alpha_g=alpha, clip_id=clip_id,
            root_vel_heading_mps=root_vel_heading, yaw_rate_rps=yaw_rate, root_height_m=root[:, 1].copy(),
            clip_names=tuple(clip.name for clip in clips), **extra,
        )

    def save(self, path: str | Path) -> None:
        """Write the database as one .npz (the kd-tree is rebuilt on load: it is fast and version-proof)."""
        np.savez_compressed(
            path, names=np.array(self.rig.names), parents=self.rig.parents, offsets_m=self.rig.offsets_m,
            end_site=np.zeros(len(self.rig.parents), bool) if self.rig.end_site is None else self.rig.end_site,
            ref_quats=self.rig.ref_quats,
            sensor_bone=self.sensors.bone, sensor_local_rot=self.sensors.local_rot, sensor_tip=self.sensors.tip,
            fps=self.fps, q=self.q, x_m=self.x_m, v_mps=self.v_mps, a_mps2=self.a_mps2, alpha_g=self.alpha_g,
            clip_id=self.clip_id, root_vel_heading_mps=self.root_vel_heading_mps, yaw_rate_rps=self.yaw_rate_rps,
            root_height_m=self.root_height_m, clip_names=np.array(self.clip_names),
            **{k: v for k, v in (("tilt", self.tilt), ("gyro_rps", self.gyro_rps), ("yaw_rad", self.yaw_rad))
               if v is not None},
        )

    @classmethod
    def load(cls, path: str | Path) -> "KnowledgeBase":
        """A database written by `save`; a file that is not one — or holds arrays of the wrong shape, kind or
        range — is refused with one line (MalformedFileError) before anything uses it."""
        from engine.errors import MalformedFileError

        data = load_npz(path, "an OLNG knowledge base")
        optional = {k: v for k, v in OPTIONAL_CHANNEL_ARRAYS.items() if k in data}   # older files lack them
        sizes = check_arrays(path, data, KB_ARRAYS | optional)
        fps = float(data["fps"])
        if fps <= 0 or sizes["N"] == 0:
            raise MalformedFileError(path, None, f"not an OLNG knowledge base: fps {fps:g}, {sizes['N']} frames")
        for name, low, high in (("parents", -1, sizes["J"]), ("sensor_bone", 0, sizes["J"]),
                                ("sensor_tip", 0, sizes["J"]), ("clip_id", 0, sizes["C"])):
            check_index_range(path, name, data[name], low, high)
        try:
            rig = Rig(tuple(str(n) for n in data["names"]), data["parents"], data["offsets_m"], data["end_site"],
                      data["ref_quats"])
        except ValueError as exc:
            raise MalformedFileError(path, None, f"not an OLNG knowledge base: {exc}") from exc
        sensors = SensorRig(data["sensor_bone"], data["sensor_local_rot"], data["sensor_tip"])
        fields = {k: data[k] for k in ("q", "x_m", "v_mps", "a_mps2", "alpha_g", "clip_id",
                                       "root_vel_heading_mps", "yaw_rate_rps", "root_height_m") + tuple(optional)}
        return cls(rig=rig, sensors=sensors, fps=fps, clip_names=tuple(str(n) for n in data["clip_names"]), **fields)


# what `KnowledgeBase.save` writes (engine.array_checks): J joints, S sensors, N frames, C clips
KB_ARRAYS = {
    "names": ("U", ("J",)), "parents": ("i", ("J",)), "offsets_m": ("f", ("J", 3)), "end_site": ("b", ("J",)),
    "ref_quats": ("f", ("J", 4)), "sensor_bone": ("i", ("S",)), "sensor_local_rot": ("f", ("S", 3, 3)),
    "sensor_tip": ("i", ("S",)), "fps": ("f", ()), "q": ("f", ("N", "J*3")), "x_m": ("f", ("N", "J", 3)),
    "v_mps": ("f", ("N", "J", 3)), "a_mps2": ("f", ("N", "J", 3)), "alpha_g": ("f", ("N", "S*3")),
    "clip_id": ("i", ("N",)), "root_vel_heading_mps": ("f", ("N", 3)), "yaw_rate_rps": ("f", ("N",)),
    "root_height_m": ("f", ("N",)), "clip_names": ("U", ("C",)),
}
# the orientation / gyro channels (issue 18), written when the database holds them
OPTIONAL_CHANNEL_ARRAYS = {"tilt": ("f", ("N", "S*3")), "gyro_rps": ("f", ("N", "S*3")), "yaw_rad": ("f", ("N", "S"))}

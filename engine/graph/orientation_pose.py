"""Posing the instrumented segments from their measured orientations (issue 18): the search plays database poses,
the orientations then turn each worn segment onto what its sensor says.

Why: a database-playing method cannot pass the database oracle (the nearest database pose per frame), and on
motions the database lacks that floor is high (gestures left out: 7.4 cm root-relative against 12.5 for the mean
pose). A forearm, shin, pelvis or chest sensor's orientation says where that segment points *now*, whether or not
the database holds the pose: turning the segment's subtree (hand below the forearm, foot below the shin, the
upper body below the chest) onto it moves the pose off the database toward the truth. An unworn upper arm or
thigh above a worn forearm or shin takes ``hinge_share`` of that turn about the shoulder / hip (the played
elbow / knee angle is kept for that share: the limb moves as a whole), the forearm / shin the rest about its own
joint; other unworn segments (neck, head) keep the played pose.

Frames: a segment's orientation is its sensor's (sensor -> world) quaternion; the database side is
`orientation_term.node_sensor_orientations` (the node's pose in its clip frame), the measured side the sensors'
world orientations after calibration (`orientation_calibration`): each sensor's yaw relative to the pelvis sensor
is what counts, so the measured orientations are turned about the vertical so the pelvis sensor's yaw equals the
played pose's, and the pose is placed on the path as before. Without a pelvis sensor only the tilt of each segment
(its swing away from the played pose's yaw) is applied."""
from __future__ import annotations

import numpy as np

from engine.mocap import quaternions as quat
from engine.mocap.orientation import from_device_earth, twist_yaw, yaw_about_up
from engine.mocap.orientation_calibration import OrientationCalibration
from engine.mocap.roles import joint_roles
from engine.mocap.sensors import standard_placements

from .graph import MotionGraph
from .limb_prior import LimbPrior, rotation_between
from .acc_tilt import TiltFromAccelerations
from .orientation_term import REFERENCE_SENSOR, node_sensor_orientations, places_sensors
from .decided import DecidedPoses, decided_poses
from .poses import node_global_rotations
from .viterbi import SearchWeights


# worn segment's joint role -> the joint role its unworn parent segment turns about (the hinge share). The spine
# (chest turning partly about the lower back) was tried: gestures left out 7.6 cm either way, so it is not here.
HINGES = {"left_elbow": "left_shoulder", "right_elbow": "right_shoulder", "left_knee": "left_hip",
          "right_knee": "right_hip"}

# the played worn segment's misfit (angle to its measured orientation) at which the looked-up upper arm / thigh
# has taken 1 - 1/e of the turn from the hinge share's: arms on held-out gestures 20 / 40 deg / always -> 5.76 /
# 5.80 / 5.81 cm, turning walks 4.56 / 4.29 / 5.0 (the hinge share alone: 6.45 and 4.25). The thighs too since
# then: gesture knees 7.4 / 6.8 -> 6.9 / 6.0 cm, walks unchanged (ungated, a thigh lookup had moved the gesture
# knees from 6.8 to 10.1 cm: the played thigh of a standing pose that fits is better)
PRIOR_MISFIT_RAD = np.radians(40.0)
# the strap refinement's misfit scale: a frame's weight in a sensor's strapping estimate falls as
# exp(-(θ / scale)²), θ the misfit the estimate leaves. A posing error is a few degrees; a motion the database
# lacks misfits by tens, for seconds, and counting it alike taught the estimate the database's misfit instead.
# Gesture sessions (`courtside evaluate --session`, 63 clips, 6 takes), held N-pose / 8-deg posing error:
# unweighted 5.7 / 6.1 cm, a hard 15-deg gate 5.0 / 6.1, this weight at 20 deg 5.1 / 5.9 (chained takes 5.8 /
# 6.0 / 5.9); a hard gate also never learns a posing error beyond it.
STRAP_MISFIT_SCALE_RAD = np.radians(20.0)


def _descendants(parents: np.ndarray, joint: int) -> np.ndarray:
    """(J,) bool: the joints below `joint` (not itself) in the skeleton's tree."""
    below = np.zeros(len(parents), bool)
    for j in range(len(parents)):  # parents come before children in every engine skeleton
        p = parents[j]
        below[j] = p >= 0 and (p == joint or below[p])
    return below


def _partial_turn(turn: np.ndarray, share: np.ndarray) -> np.ndarray:
    """(..., 4) the rotations `turn` (..., 4) scaled to `share` (...,) of their angle about the same axis: the
    short-arc slerp from the identity, in closed form (0 = identity, 1 = the turn itself)."""
    turn = np.where(turn[..., :1] < 0, -turn, turn)  # the short arc
    sin_half = np.linalg.norm(turn[..., 1:], axis=-1, keepdims=True)
    half = np.arctan2(sin_half, turn[..., :1]) * share[..., None]
    axis = turn[..., 1:] / np.maximum(sin_half, 1e-12)
    return np.concatenate([np.cos(half), axis * np.sin(half)], axis=-1)


class SegmentPoser:
    """For one sensor selection of a graph: which joints each sensor's segment moves, in levels of the tree (a
    level's segments lie in disjoint subtrees, so each level is turned in one vectorised step: live, one frame's
    8 blended poses cost a handful of numpy calls per level, not per sensor)."""

    def __init__(self, graph: MotionGraph, sensor_indices: list[int] | tuple[int, ...], hinge_share: float = 0.0,
                 limb_prior_k: int = 0, prior_misfit_rad: float = PRIOR_MISFIT_RAD) -> None:
        names = [graph.config.sensor_names[i] for i in sensor_indices]
        placements = standard_placements(graph.skeleton, names)
        parents = np.asarray(graph.skeleton.parents)
        self.graph = graph
        self.sensor_indices = list(sensor_indices)
        self.n_sensors = len(self.sensor_indices)
        self.reference = names.index(REFERENCE_SENSOR) if REFERENCE_SENSOR in names else None
        self.joints = np.array([p.joint for p in placements])
        roles = joint_roles(graph.skeleton)
        self.joint_role = {joint: role for role, joint in roles.items()}
        self.left_hip, self.right_hip = roles["left_hip"], roles["right_hip"]
        self.below = np.stack([_descendants(parents, j) for j in self.joints])  # (S, J)
        self.hinge_pivot = self._hinge_pivots(roles, parents) if hinge_share > 0 or limb_prior_k > 0 \
            else np.full(self.n_sensors, -1)
        # (S,) each sensor's share of its turn taken about its hinge pivot (0: no hinge)
        self.hinge_shares = np.where(self.hinge_pivot >= 0, float(hinge_share), 0.0)
        # every node's sensor orientations (N, S, 4), computed here (FK of every node: seconds on a large graph)
        # so that no live frame waits for it
        self.node_orientations = node_sensor_orientations(graph)[:, self.sensor_indices]
        carries = self.below[:, self.joints]  # (S, S): sensor k's segment lies below sensor i's
        self.prior_limb = np.full(self.n_sensors, -1)  # sensor -> its limb in `limb_prior` (-1: none)
        self.prior_misfit_rad = prior_misfit_rad
        self.limb_prior = self._limb_prior(carries, parents, limb_prior_k) if limb_prior_k > 0 else None
        level = np.zeros(self.n_sensors, int)  # 1 + the deepest level among the sensors above it
        for i in np.argsort([self._depth(parents, j) for j in self.joints], kind="stable"):
            above = np.flatnonzero(carries[:, i])
            level[i] = 1 + level[above].max() if len(above) else 0
        self.levels = []  # per level: (its sensors, joint -> which of them turns it, sensor -> which carries it)
        for lv in range(level.max() + 1 if self.n_sensors else 0):
            members = np.flatnonzero(level == lv)
            joint_owner = np.full(len(parents), -1)
            hinge_owner = np.full(len(parents), -1)   # joint -> which member's limb turns it about the pivot
            carrier = np.full(self.n_sensors, -1)
            for m, i in enumerate(members):
                joint_owner[self.below[i]] = m
                if self.hinge_pivot[i] >= 0:
                    hinge_owner[_descendants(parents, self.hinge_pivot[i])] = m
                carrier[carries[i]] = m
                carrier[i] = m
            self.levels.append((members, joint_owner, hinge_owner, carrier))

    def _hinge_pivots(self, roles: dict[str, int], parents: np.ndarray) -> np.ndarray:
        """(S,) the joint a worn segment's limb turns about (`HINGES`: shoulder above a forearm, hip above a
        shin) when the segment between carries no sensor, else -1."""
        sensor_joints = set(int(j) for j in self.joints)
        pivots = np.full(self.n_sensors, -1)
        for i, joint in enumerate(self.joints):
            pivot_role = HINGES.get(self.joint_role.get(int(joint), ""))
            if pivot_role is None:
                continue
            pivot = roles[pivot_role]
            between, j = set(), int(parents[joint])
            while j >= 0 and j != pivot:
                between.add(j)
                j = int(parents[j])
            if j == pivot and not (between | {pivot}) & sensor_joints:
                pivots[i] = pivot
        return pivots

    def _limb_prior(self, carries: np.ndarray, parents: np.ndarray, k: int) -> LimbPrior | None:
        """The database lookup of the unworn upper limbs (limb_prior.py) for every hinge sensor with a worn
        anchor above it (the deepest sensor carrying it: the chest above a forearm, the pelvis above a shin)."""
        segments, anchors = [], []
        for i in np.flatnonzero(self.hinge_pivot >= 0):
            above = np.flatnonzero(carries[:, i])
            if len(above):
                segments.append(i)
                anchors.append(above[np.argmax([self._depth(parents, self.joints[a]) for a in above])])
        if not segments:
            return None
        self.prior_limb[segments] = np.arange(len(segments))
        return LimbPrior(self.node_orientations, self.graph.node_positions_m, np.array(segments),
                         np.array(anchors), self.hinge_pivot[segments], self.joints[segments], k)

    @staticmethod
    def _depth(parents: np.ndarray, joint: int) -> int:
        d = 0
        while parents[joint] >= 0:
            joint, d = parents[joint], d + 1
        return d

    def pose(self, nodes: np.ndarray, quat_world: np.ndarray, gain: float | np.ndarray = 1.0, use_yaw: bool = True
             ) -> np.ndarray:
        """(..., J, 3) the clip-frame joint positions of `posed`."""
        return self.posed(nodes, quat_world, gain, use_yaw)[0]

    def posed(self, nodes: np.ndarray, quat_world: np.ndarray, gain: float | np.ndarray = 1.0, use_yaw: bool = True
              ) -> tuple[np.ndarray, np.ndarray]:
        """(clip-frame joint positions (..., J, 3), clip-frame joint rotations (..., J, 4)) of `nodes` (...,) with
        each worn segment's subtree turned onto the measured orientation `quat_world` (..., S, 4) (sensor ->
        world, calibrated; every turn is applied to the joints' rotations and positions alike, so the positions
        are the forward kinematics of the rotations; a frame whose
        quaternions are not all finite keeps the played pose), by `gain` of the way (1 = all of it; a float, or
        an array broadcasting to (..., S): per sample and sensor).

        With `use_yaw` and a pelvis sensor, each segment takes its measured yaw relative to the pelvis (the
        measured orientations turned about the vertical so the pelvis sensor's yaw is the node's: the yaw
        offsets must be calibrated); otherwise each takes only its measured tilt, keeping the yaw the played
        pose (after its parents' turns) gives it: no yaw calibration needed."""
        nodes = np.asarray(nodes, dtype=np.intp)
        pts = self.graph.node_positions_m[nodes].astype(float)
        glob = node_global_rotations(self.graph, nodes)
        current = self.node_orientations[nodes]
        q = np.broadcast_to(np.asarray(quat_world, float), current.shape)
        ok = np.isfinite(q).all(axis=(-1, -2))
        q = np.where(ok[..., None, None], q, quat.identity())
        share = np.where(ok[..., None], np.broadcast_to(gain, current.shape[:-1]), 0.0)
        relative = use_yaw and self.reference is not None
        if relative:
            turn = twist_yaw(current[..., self.reference, :]) - twist_yaw(q[..., self.reference, :])
            q = quat.multiply(yaw_about_up(turn)[..., None, :], q)
        for members, joint_owner, hinge_owner, carrier in self.levels:
            cur, meas = current[..., members, :], q[..., members, :]
            target = meas if relative else quat.multiply(yaw_about_up(twist_yaw(cur) - twist_yaw(meas)), meas)
            turn = _partial_turn(quat.multiply(target, quat.conjugate(cur)), share[..., members])
            segment_turn = turn
            if np.any(hinge_owner >= 0):
                # the limb first turns as a whole about the shoulder / hip by hinge_share of the turn, the
                # segment then the rest about its own joint (same axis: the two parts compose to the turn)
                limb_share = self.hinge_shares[members] * np.ones(turn.shape[:-1])
                limb_turn = _partial_turn(turn, limb_share)
                segment_turn = _partial_turn(turn, 1.0 - limb_share)
                if self.limb_prior is not None:
                    limb_turn, segment_turn, turn = self._prior_turns(
                        pts, current, members, target, share[..., members], limb_turn, segment_turn, turn,
                        not relative)
                self._turn_joints(pts, glob, limb_turn, hinge_owner, self.hinge_pivot[members])
            self._turn_joints(pts, glob, segment_turn, joint_owner, self.joints[members])
            held = carrier >= 0
            current[..., held, :] = quat.multiply(turn[..., carrier[held], :], current[..., held, :])
        return self._keep_heading(self.graph.node_positions_m[nodes], pts, glob)

    def _prior_turns(self, pts: np.ndarray, current: np.ndarray, members: np.ndarray, target: np.ndarray,
                     share: np.ndarray, limb_turn: np.ndarray, segment_turn: np.ndarray, turn: np.ndarray,
                     tilt_only: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(limb, segment, whole) turns of a level's members (..., M, 4) with the limb prior: a member with a
        looked-up upper limb turns it about the shoulder / hip onto the looked-up direction (in its anchor's
        posed frame), then its segment about the moved elbow / knee onto the measured orientation; the others
        keep the hinge-share turns given."""
        prior = self.prior_limb[members]
        has = prior >= 0
        if not has.any():
            return limb_turn, segment_turn, turn
        m, h = np.flatnonzero(has), prior[has]
        anchors = self.limb_prior.anchors[h]
        ends, pivots = self.joints[members[m]], self.hinge_pivot[members[m]]
        limb = pts[..., ends, :] - pts[..., pivots, :]
        played = limb / np.maximum(np.linalg.norm(limb, axis=-1, keepdims=True), 1e-12)
        wanted = quat.rotate(current[..., anchors, :], self.limb_prior.directions(
            current[..., anchors, :], target[..., m, :], h, tilt_only))
        limb_turn, segment_turn, turn = limb_turn.copy(), segment_turn.copy(), turn.copy()
        # the lookup takes over as the played forearm's misfit grows: a played pose whose forearm already
        # points as measured (a walk the database holds) keeps its upper arm, with the hinge-share turn
        misfit = quat.multiply(target[..., m, :], quat.conjugate(current[..., members[m], :]))
        misfit_rad = 2 * np.arccos(np.clip(np.abs(misfit[..., 0]), 0.0, 1.0))
        trust = 1.0 - np.exp(-(misfit_rad / self.prior_misfit_rad) ** 2)
        looked_up = _partial_turn(rotation_between(played, wanted), share[..., m])
        limb_turn[..., m, :] = quat.slerp(limb_turn[..., m, :], looked_up, trust)
        moved = quat.multiply(limb_turn[..., m, :], current[..., members[m], :])
        segment_turn[..., m, :] = _partial_turn(quat.multiply(target[..., m, :], quat.conjugate(moved)),
                                                share[..., m])
        turn[..., m, :] = quat.multiply(segment_turn[..., m, :], limb_turn[..., m, :])
        return limb_turn, segment_turn, turn

    @staticmethod
    def _turn_joints(pts: np.ndarray, glob: np.ndarray, turn: np.ndarray, owner_of: np.ndarray,
                     pivots: np.ndarray) -> None:
        """Turn, in place, each joint of `pts` (..., J, 3) owned by a member (`owner_of` (J,): member index or
        -1) by that member's `turn` (..., M, 4) about its pivot joint (`pivots` (M,), -1: the member turns
        nothing), and the rotations `glob` (..., J, 4) of those joints and of the pivots alike (turning the
        points below a joint about it is turning that joint's segment)."""
        moved = owner_of >= 0
        owner = owner_of[moved]
        pivot = pts[..., pivots[owner], :]
        pts[..., moved, :] = quat.rotate(turn[..., owner, :], pts[..., moved, :] - pivot) + pivot
        members = np.flatnonzero(pivots >= 0)
        joints = np.concatenate([np.flatnonzero(moved), pivots[members]])
        by = np.concatenate([owner, members])
        glob[..., joints, :] = quat.multiply(turn[..., by, :], glob[..., joints, :])

    def _keep_heading(self, played: np.ndarray, posed: np.ndarray, glob: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray]:
        """(`posed`, `glob`) turned about the vertical through the root so the hips heading is the played pose's:
        the path (camera, root fusion) decides where the body faces, the sensors only how it is posed around
        it."""
        def heading(p: np.ndarray) -> np.ndarray:
            lateral = p[..., self.left_hip, :] - p[..., self.right_hip, :]
            return np.arctan2(-lateral[..., 2], lateral[..., 0])

        turn = yaw_about_up(heading(played) - heading(posed))[..., None, :]
        root = posed[..., :1, :]
        return quat.rotate(turn, posed - root) + root, quat.multiply(turn, glob)


class SegmentPosing:
    """The output side of the worn sensors, shared by the batch search and the fixed-lag decoder (same input, same
    output): the decided (blended) poses with each worn segment turned onto what its sensor says. With
    orientations and a `calibration` (the N-pose capture's yaw offsets and strapping) segments take their yaw
    relative to the pelvis too; with orientations alone, their tilt; with accelerations alone (and
    `tilt_time_constant_s` > 0), their tilt from the low-passed accelerations (acc_tilt.py), each sensor's share
    falling while it accelerates. Stateful (the low-pass): feed every sample in order through `sample`.

    With a calibration and a pelvis sensor, `strap_time_constant_s` > 0 also refines each sensor's strapping over
    the take: the N-pose capture carries the athlete's posing error (each segment a few degrees off the template)
    into every later orientation as a constant rotation in the segment's frame, while the played poses' own
    misfits change from motion to motion. So a slow running mean (exponential, that time constant) of each
    segment's measured-against-played rotation, in its own frame, estimates the constant part, and the measured
    orientations are turned back by it; a frame counts less the more misfit the estimate leaves
    (`STRAP_MISFIT_SCALE_RAD`: a motion the database lacks misfits by far more, for seconds at a time). Stateful
    too: the decided frames go through `joint_positions` in order (batch and live alike)."""

    def __init__(self, poser: SegmentPoser, gain: float, calibration: OrientationCalibration | None = None,
                 tilt_time_constant_s: float = 0.0, strap_time_constant_s: float = 0.0) -> None:
        self.poser, self.gain, self.calibration = poser, gain, calibration
        refines = calibration is not None and poser.reference is not None and strap_time_constant_s > 0
        self._strap_rate = 1.0 / (strap_time_constant_s * poser.graph.config.fps) if refines else 0.0
        self._strap = np.tile(quat.identity(), (poser.n_sensors, 1))  # running strap correction (S, 4)
        self._acc_tilt = TiltFromAccelerations(poser.graph.config.fps, tilt_time_constant_s) \
            if tilt_time_constant_s > 0 and calibration is None else None  # calibrated: posed with yaw, never by acc

    @classmethod
    def for_search(cls, graph: MotionGraph, sensor_indices: tuple[int, ...] | None, weights: SearchWeights,
                   calibration: OrientationCalibration | None = None) -> "SegmentPosing | None":
        """None where there is nothing to pose: `weights.segment_pose` 0, no sensors, or a graph without joint
        rotations."""
        if weights.segment_pose <= 0 or not sensor_indices or not places_sensors(graph):
            return None
        return cls(SegmentPoser(graph, sensor_indices, weights.hinge_share, weights.limb_prior_k),
                   weights.segment_pose, calibration,
                   weights.tilt_from_acc_s, weights.strap_refine_s)

    def world_orientations(self, quat_device: np.ndarray) -> np.ndarray:
        """(..., S, 4) device-earth readings -> sensor orientations in the world (each still turned by its
        unknown yaw without a calibration; the tilt-only posing does not read it)."""
        if self.calibration is not None:
            return self.calibration.world(quat_device)
        return from_device_earth(np.asarray(quat_device, float))

    def sample(self, acc_g: np.ndarray | None, quat_device: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        """One sample's posing inputs: (sensor orientations in the world (S, 4), shares (S,) of the turn); the
        orientations when the sample has them all, else the tilt from the accelerations, else nothing (share 0)."""
        n = self.poser.n_sensors
        tilt = None if self._acc_tilt is None or acc_g is None else self._acc_tilt.push(acc_g)
        if quat_device is not None and np.isfinite(quat_device).all():
            return self.world_orientations(quat_device), np.full(n, self.gain)
        if tilt is not None:
            return tilt[0], self.gain * tilt[1]
        return np.tile(quat.identity(), (n, 1)), np.zeros(n)

    def over_take(self, acc_g: np.ndarray | None, quat_device: np.ndarray | None
                  ) -> tuple[np.ndarray, np.ndarray]:
        """`sample` over a whole take ((T, S, 3) g and/or (T, S, 4) device-earth): ((T, S, 4), (T, S)). A sample
        with a missing acceleration (a dropout: NaN) has none, as the live push loop (`engine.stream.drive_frames`)
        gives the decoder none, so the low-pass sees the same samples batch and live."""
        n_samples = len(acc_g) if acc_g is not None else len(quat_device)
        out = [self.sample(None if acc_g is None or not np.isfinite(acc_g[t]).all() else acc_g[t],
                           None if quat_device is None else quat_device[t]) for t in range(n_samples)]
        return np.stack([o[0] for o in out]), np.stack([o[1] for o in out])

    def decide(self, blend_nodes: np.ndarray, ground_m: np.ndarray, heading_rad: np.ndarray, world: np.ndarray,
               share: np.ndarray) -> DecidedPoses:
        """The decided poses (decided.py) of `blend_nodes` (T, k), each column posed by its sample's (`sample`)
        orientations (T, S, 4) and shares (T, S), blended as rotations and placed at (ground, heading). Nothing
        to pose (every share 0): exactly the played blend."""
        if not np.any(share):
            return decided_poses(self.poser.graph, blend_nodes, ground_m, heading_rad)
        if self._strap_rate > 0:
            world = self._refined(blend_nodes[:, 0], world, share)
        _, glob = self.poser.posed(blend_nodes, world[:, None], share[:, None, :], use_yaw=self.calibration is not None)
        return decided_poses(self.poser.graph, blend_nodes, ground_m, heading_rad, glob)

    def _refined(self, nodes: np.ndarray, world: np.ndarray, share: np.ndarray) -> np.ndarray:
        """(T, S, 4) `world` turned back by the running strap correction (class doc), updated frame by frame with
        each frame's measured-against-played rotation of every sensor that has a reading (share > 0), weighted
        by how well the estimate so far explains it (`STRAP_MISFIT_SCALE_RAD`); the played orientations are those
        of `nodes` (T,) (each frame's best path), the measured ones turned about the vertical so the pelvis
        sensors' yaws agree (only yaw relative to the pelvis is calibrated). That turn takes the pelvis sensor's
        own error into every misfit, so the estimate recovers a constant strapping error only in part (the unit
        test: 7.2 -> 4.4 cm)."""
        played = self.poser.node_orientations[nodes]
        ref = self.poser.reference
        aligned = quat.multiply(yaw_about_up(twist_yaw(played[:, ref]) - twist_yaw(world[:, ref]))[:, None], world)
        misfit = quat.multiply(quat.conjugate(played), aligned)   # (T, S, 4) in each segment's frame
        out = np.empty_like(world)
        for t in range(len(world)):
            dot = np.sum(misfit[t] * self._strap, axis=-1)  # ± cos(half the misfit the estimate leaves)
            r = np.where(dot[:, None] < 0, -misfit[t], misfit[t])
            weight = np.exp(-(2 * np.arccos(np.clip(np.abs(dot), 0.0, 1.0)) / STRAP_MISFIT_SCALE_RAD) ** 2)
            rate = np.where(share[t] > 0, self._strap_rate * weight, 0.0)[:, None]
            self._strap = quat.normalize((1.0 - rate) * self._strap + rate * r)
            out[t] = quat.multiply(world[t], quat.conjugate(self._strap))
        return out


def decided_path_poses(graph: MotionGraph, nodes: np.ndarray, blend_nodes: np.ndarray | None,
                       ground_m: np.ndarray, heading_rad: np.ndarray, posing: SegmentPosing | None = None,
                       acc_g: np.ndarray | None = None, quat_device: np.ndarray | None = None) -> DecidedPoses:
    """The decided poses of a batch search's decisions -- `nodes` (T,), or the blend of the best paths
    `blend_nodes` (T, k), at (ground, heading) -- with the worn segments posed by the take's samples (`acc_g`
    (T, S, 3), `quat_device` (T, S, 4), `SegmentPosing.over_take`) when there is a `posing`: what the fixed-lag
    decoder emits for the same decisions."""
    blend = np.asarray(nodes)[:, None] if blend_nodes is None else blend_nodes
    if posing is None or (acc_g is None and quat_device is None):
        return decided_poses(graph, blend, ground_m, heading_rad)
    return posing.decide(blend, ground_m, heading_rad, *posing.over_take(acc_g, quat_device))

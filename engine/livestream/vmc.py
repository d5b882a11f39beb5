"""The VMC protocol (Virtual Motion Capture, OSC over UDP, port 39539) out of the engine, for Unity (EVMC4U),
Blender (VMC4B), VSeeFace and other VMC receivers.

Per frame one OSC bundle: ``/VMC/Ext/Root/Pos "root" px py pz qx qy qz qw`` (the avatar root, left at the origin),
``/VMC/Ext/Bone/Pos <HumanBodyBones name> px py pz qx qy qz qw`` for every mapped bone, ``/VMC/Ext/OK 1`` and
``/VMC/Ext/T <seconds>``. Bones are named as Unity's ``HumanBodyBones`` and mapped from the engine's joint roles
(one explicit table, like `engine.mocap.roles`). Rotations are each mapped bone's rotation relative to its nearest
mapped ancestor, in T-pose-based frames (`engine.mocap.rest_pose.tpose_bases`: identity = the avatar's T-pose
facing forward), so joints the avatar lacks (CMU's extra spine and neck joints) fold into the next mapped bone.
``Hips`` carries the world position. Coordinates go from the engine's right-handed Y-up world (X left, Z forward)
to Unity's left-handed one (X right): ``(x, y, z) -> (-x, y, z)``, quaternion ``(w, x, y, z) -> (w, x, -y, -z)``.
UDP to 127.0.0.1 unless another host is given."""
from __future__ import annotations

import numpy as np

from engine.mocap import joint_roles
from engine.mocap import quaternions as quat
from engine.mocap.rest_pose import tpose_bases
from engine.mocap.skeleton import Motion, forward_kinematics

DEFAULT_PORT = 39539
_SIDE_PARTS = {"hip": "UpperLeg", "knee": "LowerLeg", "ankle": "Foot", "toe": "Toes", "clavicle": "Shoulder",
               "shoulder": "UpperArm", "elbow": "LowerArm", "wrist": "Hand"}
ROLE_TO_BONE = {"pelvis": "Hips", "lower_back": "Spine", "upper_back": "Chest", "neck": "Neck", "head": "Head",
                **{f"{side}_{part}": f"{side.capitalize()}{bone}" for side in ("left", "right")
                   for part, bone in _SIDE_PARTS.items()}}


def to_unity_position(p: np.ndarray) -> np.ndarray:
    return np.asarray(p, float) * np.array([-1.0, 1.0, 1.0])


def to_unity_quaternion_xyzw(q_wxyz: np.ndarray) -> np.ndarray:
    w, x, y, z = np.moveaxis(np.asarray(q_wxyz, float), -1, 0)
    return np.stack([x, -y, -z, w], axis=-1)


class VmcSkeletonMap:
    """Which joint is which HumanBodyBones bone, and each mapped bone's nearest mapped ancestor, for a skeleton."""

    def __init__(self, skeleton) -> None:
        roles = joint_roles(skeleton)
        self.skeleton = skeleton
        self.joint_of = {ROLE_TO_BONE[r]: j for r, j in roles.items() if r in ROLE_TO_BONE}
        mapped = set(self.joint_of.values())
        self.parent_of: dict[str, str | None] = {}
        bone_of = {j: b for b, j in self.joint_of.items()}
        for bone, j in self.joint_of.items():
            p = skeleton.parents[j]
            while p >= 0 and p not in mapped:
                p = skeleton.parents[p]
            self.parent_of[bone] = bone_of[p] if p >= 0 else None
        self.bases = tpose_bases(skeleton)

    def bone_transforms(self, motion: Motion) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Per bone: (position (F, 3) m, rotation (F, 4) wxyz) in the engine's world frame convention: ``Hips``
        world position and T-pose-based world rotation, other bones position and rotation relative to their
        mapped parent."""
        pos, glob = forward_kinematics(motion)
        glob_t = glob @ self.bases[None]  # T-pose-based world rotations (identity in the T-pose)
        out = {}
        for bone, j in self.joint_of.items():
            parent = self.parent_of[bone]
            if parent is None:
                out[bone] = (pos[:, j], quat.from_matrix(glob_t[:, j]))
            else:
                pj = self.joint_of[parent]
                rel = np.swapaxes(glob_t[:, pj], -1, -2)
                out[bone] = (np.einsum("fij,fj->fi", rel, pos[:, j] - pos[:, pj]),
                             quat.from_matrix(rel @ glob_t[:, j]))
        return out


class VmcSender:
    """Sends a Motion's frames as VMC bundles over UDP (python-osc)."""

    def __init__(self, skeleton, host: str = "127.0.0.1", port: int = DEFAULT_PORT) -> None:
        from pythonosc.udp_client import SimpleUDPClient

        self.map = VmcSkeletonMap(skeleton)
        self._client = SimpleUDPClient(host, port)
        self.frames_sent = 0

    def send_motion(self, motion: Motion) -> None:
        from pythonosc.osc_bundle_builder import IMMEDIATELY, OscBundleBuilder
        from pythonosc.osc_message_builder import OscMessageBuilder

        def message(address: str, *args) -> object:
            builder = OscMessageBuilder(address=address)
            for a in args:
                builder.add_arg(a)
            return builder.build()

        bones = self.map.bone_transforms(motion)
        for f in range(motion.n_frames):
            bundle = OscBundleBuilder(IMMEDIATELY)
            bundle.add_content(message("/VMC/Ext/Root/Pos", "root", 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0))
            for bone, (p, q) in bones.items():
                px, py, pz = (float(v) for v in to_unity_position(p[f]))
                qx, qy, qz, qw = (float(v) for v in to_unity_quaternion_xyzw(q[f]))
                bundle.add_content(message("/VMC/Ext/Bone/Pos", bone, px, py, pz, qx, qy, qz, qw))
            bundle.add_content(message("/VMC/Ext/OK", 1))
            bundle.add_content(message("/VMC/Ext/T", float(self.frames_sent / motion.fps)))
            self._client.send(bundle.build())
            self.frames_sent += 1

"""A real mocap clip as the synthetic camera's player: its skeleton drawn as capsules, its root as ground truth.

Why: scripted bodies move like puppets; a CMU clip gives real silhouettes (arm swing, leg spread, jumps) so the
tracker is scored on the shapes it will meet on court. Engine world (Y up) maps to court as
``(x, y, z) = (X, Z, Y - floor)`` (docs/CONTRACTS.md), shifted so the clip's mean root position lands on
``centre_court_m``. The ground truth is the root (pelvis) projected to the ground, heading from the hips.
"""
from __future__ import annotations

import numpy as np

from engine.mocap import Motion, forward_kinematics, joint_roles, root_heading
from gateway.camera.body import HAIR, SHIRT, SHORTS, SKIN, Capsules
from gateway.camera.paths import PlayerPath, PlayerState

SHOES = (30, 30, 30)
_TRUNK = [("pelvis", "lower_back", 0.15, SHORTS), ("lower_back", "upper_back", 0.15, SHIRT),
          ("upper_back", "neck", 0.12, SHIRT), ("neck", "head", 0.06, SKIN)]
_LIMBS = [("pelvis", "hip", 0.1, SHORTS), ("hip", "knee", 0.075, SHORTS), ("knee", "ankle", 0.06, SKIN),
          ("ankle", "toe", 0.05, SHOES), ("upper_back", "shoulder", 0.07, SHIRT), ("shoulder", "elbow", 0.05, SHIRT),
          ("elbow", "wrist", 0.045, SKIN)]
HEAD_RADIUS_M = 0.11


class MocapBody:
    """Callable ``body(t_s, state, gait_phase) -> Capsules`` for :class:`SyntheticCourtCamera` (``state`` and
    ``gait_phase`` are ignored: the clip itself moves the limbs). Times outside the clip clamp to its ends."""

    def __init__(self, motion: Motion, centre_court_m: tuple[float, float] = (0.0, -8.0), start_s: float = 0.0):
        positions, _ = forward_kinematics(motion)
        roles = joint_roles(motion.skeleton)
        foot = [roles[f"{s}_{p}"] for s in ("left", "right") for p in ("ankle", "toe")]
        floor = positions[:, foot, 1].min() - 0.05
        shift = np.asarray(centre_court_m, float) - motion.root_positions_m[:, [0, 2]].mean(axis=0)
        court = np.stack([positions[..., 0] + shift[0], positions[..., 2] + shift[1], positions[..., 1] - floor], -1)
        self._court_positions = court  # (F, J, 3)
        self.fps = motion.fps
        self.start_s = start_s
        bones = list(_TRUNK) + [(f"{s}_{a}" if a != "pelvis" and a != "upper_back" else a, f"{s}_{b}", r, c)
                                for s in ("left", "right") for a, b, r, c in _LIMBS]
        self._a = np.array([roles[a] for a, _, _, _ in bones])
        self._b = np.array([roles[b] for _, b, _, _ in bones])
        self._radius = np.array([r for *_, r, _ in bones] + [HEAD_RADIUS_M])
        self._colour = [c for *_, c in bones] + [HAIR]
        self._neck, self._head = roles["neck"], roles["head"]
        heading = root_heading(motion, positions)
        t = start_s + np.arange(motion.n_frames) / motion.fps
        self.path = PlayerPath(t, motion.root_positions_m[:, [0, 2]] + shift, heading, np.zeros(len(t)))

    def __call__(self, t_s: float, state: PlayerState | None = None, gait_phase_rad: float = 0.0) -> Capsules:
        f = float(np.clip((t_s - self.start_s) * self.fps, 0, len(self._court_positions) - 1))
        i = min(int(f), len(self._court_positions) - 2)
        w = f - i
        joints = (1 - w) * self._court_positions[i] + w * self._court_positions[i + 1]
        neck, head = joints[self._neck], joints[self._head]
        skull = head + 0.1 * (head - neck) / max(np.linalg.norm(head - neck), 1e-6)
        start = np.vstack([joints[self._a], skull])
        end = np.vstack([joints[self._b], skull])
        return Capsules(start, end, self._radius, self._colour)

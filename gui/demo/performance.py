"""The demo's performance: shipped CMU clips the demo's motion graph does NOT contain (held out), chained on the
court and looped, with the worn sensors' virtual accelerometer readings and the ground truth they imply."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from engine.mocap import (SEED000_SENSORS, Skeleton, forward_kinematics, load_clip, root_heading, sample_clips,
                          standard_placements, virtual_accelerometers)

from engine.stream.databases import GRAPH_FPS

HELD_OUT_CLIPS = ("16_32", "16_36", "16_05")  # walk, run, forward jump: not in the demo's motion graph
EXTRA_SENSORS = ("left_wrist", "right_wrist", "left_ankle", "right_ankle", "right_foot")
STATION_SENSORS = {1: SEED000_SENSORS, 2: EXTRA_SENSORS}  # station id -> worn sensors, in sensor-index order
COURT_START_M = np.array([-5.0, -10.0])  # court (x, y) where the performance starts: inside the near baseline
# The second athlete (issue 20): other held-out clips, on the far half, wearing the six seed-000 sensors on station 3
PLAYER, OPPONENT = "player", "opponent"
OPPONENT_CLIPS = ("16_21", "16_11")  # two more walks: not in the demo's motion graph either
OPPONENT_STATION = 3
OPPONENT_START_M = np.array([-5.0, 10.0])


@dataclass
class Performance:
    """Held-out clips back to back, placed on the court, played in a loop that never teleports.

    Pass 0 plays the frames as placed (start S -> end E along the baseline); pass 1 plays the same frames turned
    180 degrees about the midpoint of S and E, so it runs E -> S; and so on. A rigid turn leaves every worn
    sensor's reading unchanged, so the stations simply loop the readings while the body shuttles along the
    baseline — and the overhead camera's tracker never sees a jump."""

    fps: float
    positions_m: np.ndarray  # (F, J, 3) pass-0 world positions (X, Y up, Z) with (X, Z) = court (x, y)
    heading_rad: np.ndarray  # (F,) pass-0 root heading
    acc_g: dict[str, np.ndarray]  # sensor name -> (F, 3) virtual accelerometer reading, sensor frame
    skeleton: Skeleton
    clip_names: tuple[str, ...]

    @property
    def parents(self) -> np.ndarray:
        return np.asarray(self.skeleton.parents)

    @property
    def n_frames(self) -> int:
        return len(self.positions_m)

    def _frames(self, t_s: float | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        k = np.floor(np.asarray(t_s, float) * self.fps).astype(int)
        return k % self.n_frames, (k // self.n_frames) % 2 == 1

    def pose_at(self, t_s: float) -> np.ndarray:
        """(J, 3) joint positions ``t_s`` seconds after the performance started."""
        frame, turned = self._frames(t_s)
        pos = self.positions_m[int(frame)].copy()
        if turned:
            pivot2 = self.positions_m[0, 0, [0, 2]] + self.positions_m[-1, 0, [0, 2]]
            pos[:, [0, 2]] = pivot2 - pos[:, [0, 2]]
        return pos

    def ground_path(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Root court (x, y) (N, 2) and heading (N,) at times ``t_s``: what the overhead camera should see."""
        frame, turned = self._frames(t_s)
        xy = self.positions_m[frame, 0][:, [0, 2]]
        pivot2 = self.positions_m[0, 0, [0, 2]] + self.positions_m[-1, 0, [0, 2]]
        xy = np.where(turned[:, None], pivot2 - xy, xy)
        heading = np.angle(np.exp(1j * (self.heading_rad[frame] + np.where(turned, np.pi, 0.0))))
        return xy, heading


def build_performance(clip_names: tuple[str, ...] = HELD_OUT_CLIPS, fps: float = GRAPH_FPS,
                      start_m: np.ndarray = COURT_START_M) -> Performance:
    """Chain the clips: each starts where the previous one ended (ground position), all on one skeleton,
    starting at court ``start_m`` (the opponent's: `OPPONENT_START_M`, on the far half)."""
    clips = sample_clips()
    missing = [c for c in clip_names if c not in clips]
    if missing:
        raise ValueError(f"unknown clip(s) {missing}; shipped: {sorted(clips)}")
    names = sorted({n for sensors in STATION_SENSORS.values() for n in sensors})
    positions, accs = [], {n: [] for n in names}
    cursor = np.array(start_m, float)
    for name in clip_names:
        motion = load_clip(clips[name], fps=fps)
        pos, glob = forward_kinematics(motion)
        acc = virtual_accelerometers(motion, standard_placements(motion.skeleton, tuple(names)), fk=(pos, glob))
        pos = pos.copy()
        pos[..., 0] += cursor[0] - pos[0, 0, 0]
        pos[..., 2] += cursor[1] - pos[0, 0, 2]
        cursor = pos[-1, 0, [0, 2]]
        positions.append(pos)
        for k, n in enumerate(names):
            accs[n].append(acc[:, k])
        skeleton = motion.skeleton
    pos = along_baseline(np.concatenate(positions), np.asarray(start_m, float))
    heading = np.concatenate([root_heading(load_clip(clips[c], fps=fps), p)
                              for c, p in zip(clip_names, np.split(pos, np.cumsum([len(p) for p in positions])[:-1]))])
    return Performance(fps, pos, heading, {n: np.concatenate(v) for n, v in accs.items()}, skeleton,
                       tuple(clip_names))


def along_baseline(positions_m: np.ndarray, start_m: np.ndarray) -> np.ndarray:
    """Turn the whole performance about its start so it travels along +X (parallel to the baseline), as a
    baseline rally does; the accelerometers are unaffected (they read in the sensor frame)."""
    root = positions_m[:, 0, [0, 2]]
    dx, dz = root[-1] - root[0]
    beta = math.pi / 2 - math.atan2(dx, dz)  # heading rotation that takes the travel direction onto +X
    c, s = math.cos(beta), math.sin(beta)
    rel = positions_m[..., [0, 2]] - root[0]
    out = positions_m.copy()
    out[..., 0] = start_m[0] + rel[..., 0] * c + rel[..., 1] * s
    out[..., 2] = start_m[1] - rel[..., 0] * s + rel[..., 1] * c
    return out


def placements_for_demo(perf: Performance) -> list:
    """Standard placements of every worn demo sensor (the calibration wizard's segments)."""
    return standard_placements(perf.skeleton, tuple(n for names in STATION_SENSORS.values() for n in names))


def build_opponent() -> Performance:
    """The second athlete's performance (`OPPONENT_CLIPS` from `OPPONENT_START_M`)."""
    return build_performance(OPPONENT_CLIPS, start_m=OPPONENT_START_M)


def sensor_segments() -> dict[tuple[str, int], str]:
    """(station, sensor) -> worn placement name, for the device panel's body diagram and the recording gate
    (both athletes' sensors)."""
    worn = {(f"st{sid}", i): name for sid, names in STATION_SENSORS.items() for i, name in enumerate(names)}
    return worn | {(f"st{OPPONENT_STATION}", i): name for i, name in enumerate(SEED000_SENSORS)}


def synthesis_sensors(station: int = 1) -> list[tuple[str, int]]:
    """Live sensors feeding the graph's sensors (SEED000 order), all on ``station`` (the opponent's: 3)."""
    return [(f"st{station}", i) for i in range(len(SEED000_SENSORS))]


class TruthClock:
    """Ground truth for the console: gateway time -> performance joint positions (looped)."""

    def __init__(self, perf: Performance, t0_monotonic_s: float) -> None:
        self.perf = perf
        self.t0 = t0_monotonic_s

    @property
    def parents(self) -> np.ndarray:
        return self.perf.parents

    def __call__(self, t_host_s: float) -> np.ndarray | None:
        if t_host_s < self.t0:
            return None
        return self.perf.pose_at(t_host_s - self.t0)


def truth_from_events(events: list[dict]) -> TruthClock | None:
    """Ground truth of a recorded demo take, from the `TruthAnnouncer` event it carries (None if absent)."""
    for header in events:
        if "truth_clips" in header and "truth_t0_s" in header:
            perf = build_performance(tuple(header["truth_clips"]))
            return TruthClock(perf, float(header["truth_t0_s"]))
    return None

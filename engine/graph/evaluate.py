"""Leave-one-out evaluation, as in seed 000 Tables 2/3.

For each test clip: remove it (and everything derived from it) from the graph, simulate what the worn sensors
and the camera would have measured on it (virtual accelerometers + the seed-000 sensor error model; ground
position + heading with camera-like noise), synthesise, and score against the clip: average joint error (cm,
the paper's joint set, each pose in its own root frame so global drift is not counted twice), global root
position error (cm) and heading error (deg).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engine import progress
from engine.mocap import SensorErrorModel, error_joint_indices

from .clips import ClipData
from .geometry import wrap_angle
from .graph import MotionGraph
from .poses import root_local, world_joint_positions
from .viterbi import Observations, SearchWeights
from .search import ViterbiSearch


@dataclass(frozen=True)
class Setting:
    """One row of the table: which sensors are worn and which weights of eq. 6 are used."""

    name: str
    sensor_indices: tuple[int, ...]
    weights: SearchWeights


@dataclass(frozen=True)
class Noise:
    """Camera-side measurement noise (the sensor side uses engine.mocap's SensorErrorModel)."""

    position_m: float = 0.05
    heading_rad: float = np.radians(10.0)


@dataclass
class ClipScore:
    joint_cm: np.ndarray  # (T,) mean over error joints per frame
    position_cm: np.ndarray  # (T,)
    heading_deg: np.ndarray  # (T,)
    label_hit: np.ndarray  # (T,) bool: the synthesised node comes from a clip with the test clip's label


def simulate_inputs(clip: ClipData, sensor_indices: tuple[int, ...], error_model: SensorErrorModel,
                    noise: Noise, rng: np.random.Generator, fps: float) -> Observations:
    """What the worn sensors and the overhead camera would report for this clip."""
    acc = error_model.apply(clip.acc_g[:, list(sensor_indices)], fps, rng)
    pos = clip.ground_m + rng.normal(0.0, noise.position_m, clip.ground_m.shape)
    head = clip.heading_rad + rng.normal(0.0, noise.heading_rad, clip.n_frames)
    return Observations(acc_g=acc, position_m=pos, heading_rad=head, sensor_indices=sensor_indices)


def for_setting(obs: Observations, weights: SearchWeights) -> Observations:
    """Drop the global inputs a setting does not use; keep the first sample so paths start in the right place."""
    pos, head = obs.position_m.copy(), obs.heading_rad.copy()
    if weights.position == 0:
        pos[1:] = np.nan
    if weights.heading == 0:
        head[1:] = np.nan
    return Observations(obs.acc_g if weights.acc else None, pos, head, obs.sensor_indices)


def score(graph: MotionGraph, clip: ClipData, error_joints: np.ndarray, obs: Observations,
          weights: SearchWeights) -> ClipScore:
    res = ViterbiSearch(graph, weights).run(obs)
    synth = world_joint_positions(graph, res.nodes, res.ground_m, res.heading_rad)
    a = root_local(synth[:, error_joints], res.ground_m, res.heading_rad)
    b = root_local(clip.positions_m[:, error_joints], clip.ground_m, clip.heading_rad)
    return ClipScore(joint_cm=100 * np.linalg.norm(a - b, axis=2).mean(axis=1),
                     position_cm=100 * np.linalg.norm(res.ground_m - clip.ground_m, axis=1),
                     heading_deg=np.degrees(np.abs(wrap_angle(res.heading_rad - clip.heading_rad))),
                     label_hit=(np.array(graph.label_names)[graph.node_label[res.nodes]] == clip.label
                                if np.any(np.array(graph.label_names)[graph.node_label] == clip.label)
                                else np.zeros(0, dtype=bool)))  # label absent from the graph: not scored


def graph_leave_one_out(graph: MotionGraph, clips: list[ClipData], skeleton, settings: list[Setting],
                  test_clips: list[int], seed: int = 0, noise: Noise = Noise(),
                  error_model: SensorErrorModel | None = None) -> dict[str, list[ClipScore]]:
    """Scores per setting over the test clips (each synthesised from the graph without itself)."""
    error_model = error_model or SensorErrorModel.seed000()
    joints = error_joint_indices(skeleton)
    out: dict[str, list[ClipScore]] = {s.name: [] for s in settings}
    all_sensors = tuple(range(graph.n_sensors))
    for ci in progress.bar(test_clips, desc="leave-one-out", unit="clip"):
        sub = graph.without_clips([ci])
        rng = np.random.default_rng([seed, ci])
        full = simulate_inputs(clips[ci], all_sensors, error_model, noise, rng, graph.config.fps)
        for s in settings:
            obs = Observations(full.acc_g[:, list(s.sensor_indices)], full.position_m, full.heading_rad,
                               s.sensor_indices)
            out[s.name].append(score(sub, clips[ci], joints, for_setting(obs, s.weights), s.weights))
    return out


def summarise(scores: list[ClipScore]) -> dict[str, float]:
    """Mean (sd) over all frames of all test clips, as the paper reports."""
    j = np.concatenate([s.joint_cm for s in scores])
    p = np.concatenate([s.position_cm for s in scores])
    h = np.concatenate([s.heading_deg for s in scores])
    hit = np.concatenate([s.label_hit for s in scores])
    return {"joint_cm": j.mean(), "joint_sd": j.std(), "pos_cm": p.mean(), "pos_sd": p.std(),
            "head_deg": h.mean(), "head_sd": h.std(), "label_pct": 100 * hit.mean() if len(hit) else np.nan,
            "frames": len(j)}

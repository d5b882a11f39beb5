"""Which clips are held out, what each row runs, and the scores per row.

A *row* is one engine or baseline with one sensor set and one camera setting. Every row of a held-out set
sees the same simulated inputs (one draw of the sensor error model and of the camera noise per take), and
every row's database is the same set of clips minus the held-out ones.

Protocols:
* chained takes: `plan_chained_takes` picks held-out clips of changing contents; each take (≥ 60 s by
  default) is scored whole, with a per-second trace;
* leave-one-group-out: every clip of one content (or style) removed from the database; some of them scored,
  each as its own take.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np

from engine.errors import CourtsideError
from engine import progress
from engine.graph.clips import ClipData
from engine.graph.graph import MotionGraph
from engine.graph.viterbi import SearchWeights
from engine.graph.root_fusion import RootFusion
from engine.graph.warp import RootWarp
from engine.mocap import SEED003_SENSORS, Motion, SensorErrorModel
from engine.mocap.orientation import OrientationErrorModel
from engine.stream import EngineSpec, engine_names
from engine.stream.registry import adapter

from . import baselines, engines, simulate
from .labels import ClipLabel
from .metrics import FrameErrors, frame_errors, per_second
from .takes import Take, chain_clips

# worn-sensor sets of the motion graph and the nearest neighbour, by count (seed 000's placements)
SENSOR_SETS: dict[int, tuple[str, ...]] = {
    6: ("left_forearm", "right_forearm", "left_shin", "right_shin", "lower_back", "chest"),
    4: ("left_forearm", "right_forearm", "left_shin", "right_shin"),
    2: ("left_forearm", "right_forearm"),
    1: ("right_forearm",),
}
HMM_IMUS: dict[int, tuple[str, ...]] = {1: ("right_foot",), 2: ("right_foot", "right_wrist")}
BASELINES = "baselines"  # the mean pose and the nearest neighbour: rows beside the engines, not an engine
OWN_ROWS = ("motion-graph", "olng", "hmm", BASELINES)  # run by their own row code below; other engines generically
INPUTS = ("acc", "acc+ori")  # the motion graph's rows: accelerations only / + orientations (issue 18)
ORACLE = "database oracle"

CAMERA_ON, CAMERA_OFF = "yes", "no"


@dataclass(frozen=True)
class Row:
    """One line of the table. camera: "yes" (the whole track), "no" (the first fix only: where the root starts)."""

    engine: str
    sensors: str
    camera: str


@dataclass
class RowScores:
    """Per-take results of one row."""

    errors: list[FrameErrors] = field(default_factory=list)
    clips_used: list[int] = field(default_factory=list)  # distinct database clips played (graph / NN)
    longest_run_s: list[float] = field(default_factory=list)  # longest stretch played from one clip
    seconds: float = 0.0  # compute time
    confidence: list[np.ndarray] = field(default_factory=list)  # per take, per frame (online motion graph only)
    exported: list[FrameErrors] = field(default_factory=list)  # the exported BVH's errors (engines deciding rotations)


@dataclass
class EvalConfig:
    """What to run and with which inputs."""

    sensor_sets: tuple[int, ...] = (6, 4, 2, 1)
    engines: tuple[str, ...] = field(default_factory=lambda: engine_choices())
    camera: simulate.CameraModel = simulate.CameraModel()
    error_model: SensorErrorModel | None = field(default_factory=SensorErrorModel.seed000)
    weights: SearchWeights = field(default_factory=SearchWeights.camera_following)
    warp: RootWarp = field(default_factory=RootWarp)  # root warping towards the camera (graph, OLNG, HMM)
    fusion: RootFusion = field(default_factory=RootFusion)  # with the camera: the output root = the smoothed track
    nn_window: int = 15
    lag_s: float | None = None  # motion graph: None = batch search, else the online fixed-lag decoder
    seed: int = 0
    inputs: tuple[str, ...] = ("acc",)  # motion graph rows per sensor set (INPUTS)
    orientation_model: OrientationErrorModel = field(default_factory=OrientationErrorModel.realistic)
    orientation_weight: float = 1.0  # SearchWeights.orientation of the acc+ori rows
    capture: simulate.CalibrationCapture | None = field(default_factory=simulate.CalibrationCapture)
    # the acc+ori rows' N-pose capture before each take (None: no calibration, segments posed by tilt only)


@dataclass
class Database:
    """Clips at the graph rate with their labels, and the full graph built from them."""

    motions: list[Motion]
    labels: list[ClipLabel]
    clips: list[ClipData]
    graph: MotionGraph

    def held_out(self, clip_ids: list[int]) -> "HeldOut":
        return HeldOut(self, sorted(set(clip_ids)))


class HeldOut:
    """Every engine's database without the held-out clips, built on first use."""

    def __init__(self, db: Database, clip_ids: list[int]) -> None:
        self.db, self.clip_ids = db, clip_ids
        self.graph = db.graph.without_clips(clip_ids)
        self.train = [i for i in range(len(db.motions)) if i not in set(clip_ids)]
        self._nn: dict[tuple[int, ...], baselines.NearestNeighbour] = {}
        self._hmm: dict[tuple[str, ...], object] = {}
        self._specs: dict[str, EngineSpec] = {}

    def nearest_neighbour(self, sensors: tuple[int, ...], window: int) -> baselines.NearestNeighbour:
        if sensors not in self._nn:
            self._nn[sensors] = baselines.NearestNeighbour(self.graph, sensors, window)
        return self._nn[sensors]

    @cached_property
    def olng_kb(self):
        from engine.olng.config import KnowledgeBaseConfig
        from engine.olng.mocap_bridge import build_knowledge_base

        return build_knowledge_base([self.db.motions[i] for i in self.train], KnowledgeBaseConfig())

    def hmm_model(self, imus: tuple[str, ...]):
        from engine.hmm.evaluation import train_model

        if imus not in self._hmm:
            self._hmm[imus] = train_model([self.db.motions[i] for i in self.train], imus,
                                          [self.db.labels[i].content for i in self.train])
        return self._hmm[imus]


    def engine_spec(self, name: str) -> EngineSpec:
        """A registered engine on the training clips, by its adapter's database builder (`engine.stream.registry`)."""
        if name not in self._specs:
            self._specs[name] = adapter(name).build_spec([self.db.motions[i] for i in self.train],
                                                         f"{len(self.train)} training clips")
        return self._specs[name]


def engine_choices() -> tuple[str, ...]:
    """What --engines may name: every registered engine, and the baselines."""
    names = engine_names()
    return (*names[:1], BASELINES, *names[1:])


def graph_sensor_indices(graph: MotionGraph, count: int) -> tuple[int, ...]:
    names = graph.config.sensor_names
    if count not in SENSOR_SETS or any(n not in names for n in SENSOR_SETS[count]):
        raise CourtsideError(f"sensor set {count} ({', '.join(SENSOR_SETS.get(count, ()))}) is not in the graph's "
                             f"sensors ({', '.join(names)}); build the graph with the seed-000 sensors")
    return tuple(names.index(n) for n in SENSOR_SETS[count])


def _clip_stats(source_clip: np.ndarray | None, fps: float) -> tuple[int, float]:
    if source_clip is None:
        return 0, float("nan")
    change = np.flatnonzero(np.diff(source_clip) != 0)
    runs = np.diff(np.r_[-1, change, len(source_clip) - 1])
    return int(len(np.unique(source_clip))), float(runs.max() / fps)


def evaluate_take(take: Take, held: HeldOut, cfg: EvalConfig, rng_seed: list[int],
                  results: dict[Row, RowScores]) -> None:
    """Simulate the inputs of one take once and score every configured row on them (appends to `results`)."""
    graph = held.graph
    streams = np.random.SeedSequence(rng_seed).spawn(5)
    cam = simulate.camera_track(take, cfg.camera, np.random.default_rng(streams[0]))
    cam_pos, cam_head = cam.filled()
    acc, _ = simulate.accelerometers(take, graph.config.sensor_names, cfg.error_model,
                                     np.random.default_rng(streams[1]))
    root0, quat0 = engines.start_state(take, cam_pos, cam_head)
    skeleton = take.skeleton

    def record(row: Row, run) -> None:
        t0 = time.perf_counter()
        pred = run()
        scores = results.setdefault(row, RowScores())
        scores.seconds += time.perf_counter() - t0
        scores.errors.append(frame_errors(pred.joints_m, take.joints_m, skeleton))
        if pred.exported_m is not None:
            scores.exported.append(frame_errors(pred.exported_m, take.joints_m, skeleton))
        if pred.confidence is not None:
            scores.confidence.append(pred.confidence)
        used, longest = _clip_stats(pred.source_clip, take.fps)
        scores.clips_used.append(used)
        scores.longest_run_s.append(longest)

    sets = [(k, graph_sensor_indices(graph, k)) for k in cfg.sensor_sets] if (
        "motion-graph" in cfg.engines or BASELINES in cfg.engines) else []
    off = (cam_pos[:1], cam_head[:1])
    if BASELINES in cfg.engines:
        record(Row("mean pose", "-", CAMERA_ON),
               lambda: engines.Prediction(baselines.mean_pose(graph, cam_pos, cam_head)))
        record(Row("mean pose", "-", CAMERA_OFF),
               lambda: engines.Prediction(baselines.mean_pose(graph, np.repeat(off[0], take.n_frames, 0),
                                                              np.repeat(off[1], take.n_frames))))
        record(Row(ORACLE, "-", CAMERA_ON),
               lambda: engines.Prediction(*_oracle(graph, take, cam_pos, cam_head)))
    if "motion-graph" in cfg.engines:
        quats, calibration, acc_ori = None, None, acc
        if "acc+ori" in cfg.inputs and cfg.capture is not None and cfg.capture.from_take:
            acc_ori, quats, calibration = simulate.take_calibrated_sensors(
                take, graph.config.sensor_names, acc, cfg.orientation_model, np.random.default_rng(streams[4]),
                cfg.capture, graph)
        elif "acc+ori" in cfg.inputs and cfg.capture is not None:
            quats, calibration = simulate.calibrated_orientations(
                take, graph.config.sensor_names, cfg.orientation_model, np.random.default_rng(streams[4]),
                cfg.capture, graph.skeleton)
        elif "acc+ori" in cfg.inputs:
            quats = simulate.orientations(take, graph.config.sensor_names, cfg.orientation_model,
                                          np.random.default_rng(streams[4]))
        for inputs in cfg.inputs:
            name, ori = ("motion graph", 0.0) if inputs == "acc" else ("motion graph +ori", cfg.orientation_weight)
            w_on = replace(cfg.weights, orientation=ori)
            w_off = replace(w_on, position=0.0, heading=0.0)
            for k, idx in sets:
                for camera, w in ((CAMERA_ON, w_on), (CAMERA_OFF, w_off)):
                    record(Row(name, str(k), camera),
                           lambda: engines.motion_graph(graph, acc_ori if ori else acc, idx, cam.position_m,
                                                        cam.heading_rad, w,
                                                        camera == CAMERA_ON, cfg.warp, cfg.lag_s, cfg.fusion,
                                                        cfg.error_model, quats if ori else None,
                                                        calibration))
        record(Row("camera only (W_A=0)", "0", CAMERA_ON),
               lambda: engines.motion_graph(graph, None, (), cam.position_m, cam.heading_rad,
                                            replace(cfg.weights, acc=0.0), True,
                                            cfg.warp, cfg.lag_s, cfg.fusion, cfg.error_model))
    if BASELINES in cfg.engines:
        for k, idx in sets:
            nn = held.nearest_neighbour(idx, cfg.nn_window)
            for camera in (CAMERA_ON, CAMERA_OFF):
                def run_nn(nn=nn, idx=idx, camera=camera):
                    on = camera == CAMERA_ON
                    joints, nodes = nn.predict(acc[:, list(idx)], cam_pos if on else None, cam_head if on else None,
                                               cam_pos[0], float(cam_head[0]))
                    return engines.Prediction(joints, graph.node_clip[nodes].astype(int))
                record(Row("nearest neighbour", str(k), camera), run_nn)
    if "olng" in cfg.engines:
        kb = held.olng_kb
        acc4, times = simulate.accelerometers(take, SEED003_SENSORS, cfg.error_model,
                                              np.random.default_rng(streams[2]), fps=kb.fps)
        from engine.olng.config import OLNGConfig

        record(Row("olng (wrists+ankles)", "4", CAMERA_OFF),
               lambda: engines.olng(kb, OLNGConfig(), acc4, times, take, root0, quat0))
        record(Row("olng (wrists+ankles)", "4", CAMERA_ON),
               lambda: engines.olng(kb, OLNGConfig(), acc4, times, take, root0, quat0, (cam_pos, cam_head),
                                    cfg.warp, cam, cfg.fusion))
    if "hmm" in cfg.engines:
        for k, imus in HMM_IMUS.items():
            model = held.hmm_model(imus)
            imu_acc, _ = simulate.accelerometers(take, imus, cfg.error_model, np.random.default_rng([*rng_seed, 7, k]))
            gyro = simulate.gyroscopes(take, imus)
            record(Row(f"hmm ({'+'.join(imus)})", str(k), CAMERA_OFF),
                   lambda: engines.hmm(model, imu_acc, gyro, skeleton, take, root0, quat0))
            record(Row(f"hmm ({'+'.join(imus)})", str(k), CAMERA_ON),
                   lambda: engines.hmm(model, imu_acc, gyro, skeleton, take, root0, quat0, (cam_pos, cam_head),
                                       cfg.warp, cam, cfg.fusion))
    for name in (e for e in cfg.engines if e not in OWN_ROWS):
        spec = held.engine_spec(name)
        acc_s, times = simulate.accelerometers(take, spec.sensor_names, cfg.error_model,
                                               np.random.default_rng([*rng_seed, 11]), fps=spec.rate_hz)
        for camera in (CAMERA_OFF, CAMERA_ON):
            record(Row(name, str(len(spec.sensor_names)), camera),
                   lambda spec=spec, acc_s=acc_s, times=times, camera=camera: engines.online(
                       spec, acc_s, times, take, (cam_pos, cam_head) if camera == CAMERA_ON else None,
                       cam, cfg.fusion, cfg.lag_s))


def _oracle(graph: MotionGraph, take: Take, cam_pos: np.ndarray, cam_head: np.ndarray
            ) -> tuple[np.ndarray, np.ndarray]:
    joints, nodes = baselines.database_oracle(graph, take.joints_m, take.skeleton, cam_pos, cam_head)
    return joints, graph.node_clip[nodes].astype(int)


def chained_takes(db: Database, takes: list[list[int]], cfg: EvalConfig, max_clip_s: float | None = None
                  ) -> tuple[dict[Row, RowScores], list[Take]]:
    """Each take's clips held out of every database (whole, even when only their start is played), the take
    simulated and scored whole."""
    results: dict[Row, RowScores] = {}
    built = []
    for k, ids in enumerate(progress.bar(takes, desc="takes", unit="take")):
        take = chain_clips(db.motions, ids, [lab.content for lab in db.labels], max_clip_s=max_clip_s)
        evaluate_take(take, db.held_out(ids), cfg, [cfg.seed, k], results)
        built.append(take)
    return results, built


def group_out(db: Database, key: str, groups: list[str], test_clips: int, cfg: EvalConfig, session: bool = False
              ) -> dict[str, dict[Row, RowScores]]:
    """Leave-one-group-out: per group (a content or a style, `key`), every clip of it removed from the
    database; `test_clips` of them (spread over the group; 0 = all) scored, each as its own take, or with
    `session` chained into one take (one calibration capture, as an athlete repeating that motion for a while:
    what the strap refinement needs, and what a 4-s clip cannot show)."""
    out = {}
    values = [getattr(lab, key) for lab in db.labels]
    for g in groups:
        members = [i for i, v in enumerate(values) if v == g]
        if not members:
            raise CourtsideError(f"no clip has {key} {g!r}; known: {', '.join(sorted(set(values)))}")
        tests = members if not test_clips else [members[i] for i in
                                                 sorted(set(np.linspace(0, len(members) - 1, test_clips).astype(int)))]
        held = db.held_out(members)
        results: dict[Row, RowScores] = {}
        takes = [tests] if session else [[ci] for ci in tests]
        for ids in progress.bar(takes, desc=f"{key} {g}", unit="take"):
            evaluate_take(chain_clips(db.motions, ids, [lab.content for lab in db.labels]), held, cfg,
                          [cfg.seed, *ids], results)
        out[g] = results
    return out


def traces(scores: RowScores, fps: float) -> list[dict[str, list[float]]]:
    """Per take: per-second global / root-relative / position / heading error."""
    return [{f: [round(float(v), 2) for v in per_second(getattr(e, f), fps)]
             for f in ("global_cm", "root_relative_cm", "position_cm", "heading_deg")} for e in scores.errors]


def pooled(per_group: dict[str, dict[Row, RowScores]]) -> dict[Row, RowScores]:
    """Every group's takes of each row together (a leave-one-content-out run's overall line)."""
    out: dict[Row, RowScores] = {}
    for results in per_group.values():
        for row, scores in results.items():
            acc = out.setdefault(row, RowScores())
            acc.errors += scores.errors
            acc.clips_used += scores.clips_used
            acc.longest_run_s += scores.longest_run_s
            acc.seconds += scores.seconds
            acc.confidence += scores.confidence
            acc.exported += scores.exported
    return out

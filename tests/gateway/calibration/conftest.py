"""An emulated subject in the N-pose: the engine's standard sensor placements on a shipped CMU skeleton, each
sensor mounted with a known tilt error, read through the firmware emulator's StillSource plus noise and bias.

The subject stands in the standard set-up's reference N-pose (gateway.calibration.pose.reference_npose: arms
straight down, legs straight), so its forearm and shin segments are really rotated away from the skeleton's
zero pose (a T-pose) and the specs are ``CalibrationService.standard()``'s.

Orientation-capable sensors (`with_orientation`): each also reports what a magnetometer-free fusion filter
would, the realistic error model of the emulators (`engine.mocap.orientation.OrientationErrorModel.realistic`:
a random yaw per sensor, drift, a random walk, 2 deg of wandering tilt) on the sensor's true orientation; its
strapping is the subject's own mounting (the model's misalignment is off: the accelerometer sees the same one).
The draw is kept, so each sensor's yaw offset at any moment is known."""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import pytest

from engine.mocap import SEED000_SENSORS, load_clip, quaternions, sample_clips, standard_placements
from engine.mocap.orientation import OrientationErrorModel, OrientationErrors
from firmware_protocol.emulator.motion import StillSource
from gateway.calibration import CalibrationWizard, minimal_rotation, segment_specs_from_placements
from gateway.calibration.pose import reference_npose

RATE_HZ = 100.0
NOISE_G = 0.005
FILTER = replace(OrientationErrorModel.realistic(), misalignment_deg=0.0)


def tilt_rotation(rng: np.random.Generator, up: np.ndarray, max_deg: float) -> np.ndarray:
    """A rotation about a random axis perpendicular to ``up`` (an observable mounting error)."""
    axis = np.cross(up, rng.normal(size=3))
    axis /= np.linalg.norm(axis)
    angle = np.radians(rng.uniform(0.3 * max_deg, max_deg))
    return minimal_rotation(up, np.cos(angle) * up + np.sin(angle) * np.cross(axis, up))


@dataclass
class Subject:
    """Sensor ids -> segment names, true sensor->segment rotations, biases (g), and each sensor's segment
    orientation in the pose the subject holds (world <- segment, default identity = the zero pose)."""

    segments: dict
    true_rotation: dict
    bias_g: dict
    world_from_segment: dict = field(default_factory=dict)
    quat_device: np.ndarray | None = None  # (F, S, 4) at RATE_HZ from t = 0, sensors in `segments` order
    filter_errors: OrientationErrors | None = None  # the draw behind quat_device

    def world_from_sensor(self, sensor_id: str) -> np.ndarray:
        return self.world_from_segment.get(sensor_id, np.eye(3)) @ self.true_rotation[sensor_id]

    def gravity_reading(self, sensor_id: str) -> np.ndarray:
        """The noiseless, unbiased still reading (3,) g: world up in sensor axes."""
        return self.world_from_sensor(sensor_id).T @ np.array([0.0, 1.0, 0.0])

    def samples(self, sensor_id: str, t_s: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Still readings (N, 3) g of one sensor in the held pose."""
        world_from_sensor = self.world_from_sensor(sensor_id)
        source = StillSource(1, quaternions.from_matrix(world_from_sensor)[None])
        clean = source.acceleration_g(t_s)[:, 0]
        return clean + self.bias_g[sensor_id] + rng.normal(0.0, NOISE_G, clean.shape)

    def quats(self, sensor_id: str, t_s: np.ndarray) -> np.ndarray | None:
        """The sensor's filter readings (N, 4) at ``t_s`` (None: an accelerometer-only subject)."""
        if self.quat_device is None:
            return None
        frames = np.clip(np.rint(np.asarray(t_s) * RATE_HZ).astype(int), 0, len(self.quat_device) - 1)
        return self.quat_device[frames, list(self.segments).index(sensor_id)]

    def filter_tilt_deg(self, t_s: np.ndarray) -> dict:
        """Each sensor's filter tilt error (deg) averaged over the readings at ``t_s``: what a still capture
        cannot tell from the strapping."""
        from engine.mocap.orientation_calibration import mean_orientation

        frames = np.clip(np.rint(np.asarray(t_s) * RATE_HZ).astype(int), 0, len(self.quat_device) - 1)
        w = np.abs(mean_orientation(self.filter_errors.tilt_wxyz[frames])[:, 0])
        return dict(zip(self.segments, np.degrees(2 * np.arccos(np.clip(w, 0.0, 1.0)))))

    def yaw_offsets_rad(self, t_s: float) -> dict:
        """Each sensor's earth-frame yaw at ``t_s`` (the known answer of an orientation calibration)."""
        frame = min(int(round(t_s * RATE_HZ)), len(self.filter_errors.yaw_rad) - 1)
        return dict(zip(self.segments, self.filter_errors.yaw_rad[frame]))


def with_orientation(subject: Subject, seed: int, seconds: float = 60.0) -> Subject:
    """The subject's sensors streaming orientations too (module docstring), for ``seconds`` from t = 0."""
    q_world = quaternions.from_matrix(np.stack([subject.world_from_sensor(s) for s in subject.segments]))
    n = int(seconds * RATE_HZ)
    errors = FILTER.draw(n, len(q_world), RATE_HZ, np.random.default_rng(seed))
    return replace(subject, quat_device=errors.apply(np.broadcast_to(q_world, (n,) + q_world.shape)),
                   filter_errors=errors)


@pytest.fixture(scope="session")
def skeleton():
    return load_clip(sample_clips()["16_01"]).skeleton


@pytest.fixture(scope="session")
def npose_world(skeleton) -> dict:
    """Segment name -> world <- segment rotation (3, 3) in the reference N-pose, for the seed-000 sensors."""
    glob = reference_npose(skeleton)[1]
    return {p.name: glob[p.joint] for p in standard_placements(skeleton, SEED000_SENSORS)}


@pytest.fixture(scope="session")
def specs(skeleton):
    """What ``CalibrationService.standard()`` uses (the reference N-pose)."""
    glob = reference_npose(skeleton)[1]
    return segment_specs_from_placements(standard_placements(skeleton, SEED000_SENSORS), pose_rotations=glob)


@pytest.fixture
def subject(specs, npose_world) -> Subject:
    rng = np.random.default_rng(11)
    segments = {f"st0/{i}": name for i, name in enumerate(specs)}
    true_rotation = {sid: tilt_rotation(rng, specs[seg].expected_up, 20.0) @ specs[seg].nominal_rotation
                     for sid, seg in segments.items()}
    bias = {sid: rng.normal(0.0, 0.01, 3) for sid in segments}
    return Subject(segments, true_rotation, bias, {sid: npose_world[seg] for sid, seg in segments.items()})


@pytest.fixture
def wizard(specs, subject) -> CalibrationWizard:
    wiz = CalibrationWizard(specs, pose="npose")
    for sid, seg in subject.segments.items():
        wiz.assign(sid, seg)
    return wiz


def feed(wizard: CalibrationWizard, subject: Subject, t0: float, t1: float, rng, overrides=None) -> float:
    """Push [t0, t1) at RATE_HZ for every sensor in 50 ms packets; ``overrides[sid](t) -> acc`` replaces a
    sensor's still readings (movement, taps). Returns t1."""
    t_all = np.arange(t0, t1, 1.0 / RATE_HZ)
    overrides = overrides or {}
    for start in range(0, len(t_all), 5):
        t = t_all[start : start + 5]
        for sid in subject.segments:
            acc = subject.samples(sid, t, rng)
            if sid in overrides:
                acc = overrides[sid](t, acc)
            wizard.push(sid, t, acc, subject.quats(sid, t))
    return t1

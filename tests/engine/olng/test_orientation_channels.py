"""OLNG on the orientation and angular-rate channels (issue 18): features that do not depend on the device's
per-sensor yaw, acc-only unchanged, channels fixed by the first frame, and a live change of effort."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from engine.mocap import (SEED003_SENSORS, forward_kinematics, load_clip, resample, sample_clips, standard_placements,
                          virtual_accelerometers, virtual_gyroscopes)
from engine.mocap.orientation import OrientationErrorModel, to_device_earth, virtual_orientations
from engine.olng.channels import tilt_from_device_earth, tilt_from_world
from engine.olng.config import KnowledgeBaseConfig, NeighbourhoodGraphConfig, OLNGConfig
from engine.olng.mocap_bridge import build_knowledge_base
from engine.olng.reconstructor import OLNGReconstructor

HELD_OUT = "16_32"
CONFIG = OLNGConfig(graph=NeighbourhoodGraphConfig(k_neighbours=512, i_best=32))


@pytest.fixture(scope="module")
def kb():
    clips = [load_clip(p) for n, p in sample_clips().items() if n.startswith("16_") and n != HELD_OUT]
    return build_knowledge_base(clips, KnowledgeBaseConfig())


@pytest.fixture(scope="module")
def take():
    """80 frames of the held-out walk at 25 Hz: acc, true sensor -> world quaternions, gyro."""
    motion = resample(load_clip(sample_clips()[HELD_OUT]), 25.0)
    placements = standard_placements(motion.skeleton, SEED003_SENSORS)
    fk = forward_kinematics(motion)
    sl = slice(20, 100)
    return (virtual_accelerometers(motion, placements, fk=fk)[sl], virtual_orientations(motion, placements, fk=fk)[sl],
            virtual_gyroscopes(motion, placements, fk=fk)[sl])


def _run(kb, acc, quats=None, gyro=None, channels=None, config=CONFIG) -> tuple[np.ndarray, OLNGReconstructor]:
    rec = OLNGReconstructor(kb, config, channels=channels)
    none = [None] * len(acc)
    quats = none if quats is None else quats
    gyro = none if gyro is None else gyro
    out = np.stack([rec.push(a, quat_wxyz=q, gyro_rps=g).joints_root_m for a, q, g in zip(acc, quats, gyro)])
    return out, rec


def test_tilt_is_the_up_vector_whatever_the_device_yaw() -> None:
    rng = np.random.default_rng(3)
    q_world = rng.normal(size=(50, 4, 4))
    q_world /= np.linalg.norm(q_world, axis=-1, keepdims=True)
    up = tilt_from_world(q_world)
    assert np.allclose(np.linalg.norm(up, axis=-1), 1.0)
    for yaw in (0.0, rng.uniform(-np.pi, np.pi, 4)):
        assert np.allclose(tilt_from_device_earth(to_device_earth(q_world, yaw)), up, atol=1e-12)


def test_database_tilt_is_what_a_still_accelerometer_reads() -> None:
    """A motion held still: every sensor's accelerometer reads exactly its up vector in g, which is the tilt
    the database stores -- the two channels share frames and sign."""
    from engine.mocap import Motion
    from engine.olng.mocap_bridge import clip_arrays

    walk = load_clip(sample_clips()[HELD_OUT])
    still = Motion(walk.skeleton, 25.0, np.repeat(walk.root_positions_m[40:41], 10, 0),
                   np.repeat(walk.rotations[40:41], 10, 0))
    arrays = clip_arrays(still, standard_placements(walk.skeleton, SEED003_SENSORS))
    assert np.allclose(arrays.tilt, arrays.acc_g, atol=1e-9) and np.allclose(arrays.gyro_rps, 0.0, atol=1e-9)
    assert np.ptp(arrays.tilt.reshape(-1, 3), axis=0).max() > 0.5   # the four sensors are tilted differently


def test_random_per_sensor_yaw_gives_the_same_poses_as_aligned_yaw(kb, take) -> None:
    acc, q_world, gyro = take
    aligned, rec = _run(kb, acc, to_device_earth(q_world, 0.0), gyro)
    assert rec.channels == ("acc", "orientation", "gyro")
    yaws = np.random.default_rng(7).uniform(-np.pi, np.pi, 4)
    turned, _ = _run(kb, acc, to_device_earth(q_world, yaws), gyro)
    assert np.allclose(turned, aligned, atol=1e-6)


def test_orientations_find_the_right_database_frames(kb, take) -> None:
    """A clip of the database streamed back with its exact orientations: the tilt + gyro search returns that
    clip's own frames as nearest neighbours (distance 0 on every channel)."""
    start, n = 200, 30
    rec = OLNGReconstructor(kb, CONFIG, channels=("acc", "orientation", "gyro"))
    table, tree = kb.search(rec.channels, CONFIG.graph.tilt_weight, CONFIG.graph.gyro_weight_s)
    dist, idx = tree.query(table[start:start + n], k=1)
    assert np.all(idx == np.arange(start, start + n)) and np.all(dist < 1e-9)


def test_accelerations_only_do_not_change(kb, take) -> None:
    """The acc-only search is the paper's 12-D one, bit for bit, whether or not the database holds the new
    channels -- and a stream without orientations runs acc-only."""
    acc, _, _ = take
    with_channels, rec = _run(kb, acc)
    assert rec.channels == ("acc",)
    without = dataclasses.replace(kb, tilt=None, gyro_rps=None, _tree=None, _searches=None)
    plain, _ = _run(without, acc)
    assert np.array_equal(with_channels, plain)
    with pytest.raises(ValueError, match="no orientation channel"):
        _run(without, acc[:1], channels=("acc", "orientation"))


def test_realistic_orientation_errors_and_a_dropped_quaternion_keep_running(kb, take) -> None:
    acc, q_world, gyro = take
    quats = OrientationErrorModel.realistic().apply(q_world, 25.0, np.random.default_rng(0))
    quats[10, 2] = np.nan   # one sensor's orientation missing for a frame: held, as a dropped acceleration is
    out, rec = _run(kb, acc, quats, gyro)
    assert rec.channels == ("acc", "orientation", "gyro") and np.all(np.isfinite(out))


def test_effort_change_narrows_the_search_from_the_next_frame(kb, take) -> None:
    acc, _, _ = take
    rec = OLNGReconstructor(kb, CONFIG)
    for a in acc[:10]:
        rec.push(a)
    assert len(rec.graph.current.idx) == 512
    rec.set_effort(128, 8)
    for a in acc[10:20]:
        pose = rec.push(a)
    assert len(rec.graph.current.idx) == 128 and np.all(np.isfinite(pose.joints_world_m))


def test_device_yaw_offsets_are_estimated_online(kb, take) -> None:
    """Held-out walk, each device's north turned at random: the relative-yaw estimator recovers each sensor's
    offset against sensor 0 (the truth is known: the turns we applied)."""
    acc, q_world, gyro = take
    yaws = np.random.default_rng(11).uniform(-np.pi, np.pi, 4)
    _, rec = _run(kb, acc, to_device_earth(q_world, yaws), gyro)
    assert rec._yaw is not None and rec._yaw.ready
    truth = np.angle(np.exp(1j * (yaws[1:] - yaws[0])))
    error_deg = np.degrees(np.abs(np.angle(np.exp(1j * (rec._yaw.offsets_rad - truth)))))
    assert np.all(error_deg < 10.0), error_deg   # measured 3.5-6.2 degrees


def test_online_engine_uses_the_streamed_channels_and_live_keeps_up(kb, take) -> None:
    """The registry adapter: the spec names the channels the knowledge base can search on, a session searches on
    what its first frame brings; only the live engine times itself, and when frames cost more than its budget
    it narrows the search and says so (budget forced tiny here, so the step down is certain)."""
    from engine.olng.keep_up import Effort, KeepUp, effort_levels
    from engine.olng.online_engine import olng_spec

    acc, q_world, gyro = take
    spec = olng_spec(kb, "walks")
    assert spec.inputs == ("acc", "orientation", "gyro")
    offline = spec.make(0.0)
    offline.push(acc[0], quat_wxyz=to_device_earth(q_world[0], 0.4), gyro_rps=gyro[0])
    assert offline.channels == ("acc", "orientation", "gyro") and offline.keep_up is None and offline.status == ""
    live = spec.live(0.0)
    live.keep_up = KeepUp(effort_levels(Effort(4096, 256, 5)), frame_period_s=1e-6, window=5)
    for a in acc[:12]:
        assert np.isfinite(live.push(a)[0].joint_positions_m).all()
    assert live.channels == ("acc",)
    # far over its (tiny) budget it drops as many levels as halvings at once: straight to the floor
    assert live.keep_up.level == 6 and (live.rec._k, live.rec._i_best, live.rec._iterations) == (256, 16, 1)
    assert live.status.startswith("olng cheaper setting to keep up: K 256 / I 16 / 1 it instead of K 4096 / I 256")


def test_energy_tilt_of_a_database_pose_is_the_database_tilt(kb) -> None:
    """The tilt term's FK (root tilt, bone rotation, sensor mounting) gives every database pose exactly the tilt
    the knowledge base simulated for it from the clip's world FK."""
    from engine.olng.energy import KernelEnergy

    energy = KernelEnergy(kb.rig, kb.sensors.tip, CONFIG.energy, (kb.sensors.bone, kb.sensors.local_rot))
    frames = np.arange(0, kb.size, max(1, kb.size // 40))
    lever_units = CONFIG.energy.tilt_lever_m / CONFIG.energy.length_unit_m
    predicted = energy.features(kb.q[frames].astype(float))["tilt"] / lever_units
    assert np.allclose(predicted, kb.tilt[frames], atol=2e-3)


def test_saved_knowledge_base_keeps_its_channels(kb, tmp_path) -> None:
    from engine.olng.knowledge_base import KnowledgeBase

    kb.save(tmp_path / "kb.npz")
    loaded = KnowledgeBase.load(tmp_path / "kb.npz")
    assert loaded.channels == ("acc", "orientation", "gyro")
    for name in ("tilt", "gyro_rps", "yaw_rad"):
        assert np.array_equal(getattr(loaded, name), getattr(kb, name))

"""Writers of real device formats, fed by the project's own virtual sensors, for known-answer import tests.

Each writer lays the file out as the device software does (docs/imu-import.md cites the sources): x-IMU3
data-logger folders with the API's exact CSV headings and ``{:.6}`` number format, Xsens MVNX XML with its
calibration frames and ``sensorOrientation``/``sensorFreeAcceleration``, the MT Manager tab-separated text export
with its ``//`` preamble, and generic CSV/TSV in g or m/s² with w-first or w-last quaternions.

Frames: our world is Y up, X left, Z forward; Xsens and x-IMU3 worlds are Z up. ``TO_Z_UP`` maps ours to an
X-forward, Y-left, Z-up world (a proper rotation)."""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from engine.mocap import (GRAVITY_MPS2, Motion, SensorPlacement, forward_kinematics, load_clip, resample,
                          sample_clips, virtual_accelerometers, virtual_gyroscopes)
from engine.mocap import quaternions as quat

TO_Z_UP = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


@dataclass
class Truth:
    """Ground truth of a virtual recording: acc_g (F, S, 3) sensor frame, rot (F, S, 3, 3) sensor -> our world,
    gyro_rps (F, S, 3), fps, names (standard placements)."""

    acc_g: np.ndarray
    rot: np.ndarray
    gyro_rps: np.ndarray
    fps: float
    names: list[str]

    def rot_z_up(self, north_deg: float = 37.0) -> np.ndarray:
        """Sensor -> Z-up device world, whose X (magnetic north) is ``north_deg`` from the subject's forward."""
        c, s = np.cos(np.radians(north_deg)), np.sin(np.radians(north_deg))
        return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ TO_Z_UP @ self.rot

    def quat_z_up(self) -> np.ndarray:
        return quat.canonical_sign(quat.from_matrix(self.rot_z_up()))

    def free_acc_z_up_mps2(self) -> np.ndarray:
        world = np.einsum("fsij,fsj->fsi", self.rot_z_up(), self.acc_g) * GRAVITY_MPS2
        return world - np.array([0.0, 0.0, GRAVITY_MPS2])


def virtual_recording(motion: Motion, placements: list[SensorPlacement]) -> Truth:
    fk = forward_kinematics(motion)
    joints = [p.joint for p in placements]
    rot = fk[1][:, joints] @ np.stack([p.rotation for p in placements])
    return Truth(virtual_accelerometers(motion, placements, fk=fk), rot, virtual_gyroscopes(motion, placements, fk=fk),
                 motion.fps, [p.name for p in placements])


def smoothed(motion: Motion, smooth_s: float = 0.02) -> Motion:
    """``motion`` low-passed (Gaussian, sigma ``smooth_s``): twice-differentiated marker jitter would otherwise
    give ~0.7 g of noise at 100 Hz, far more than a real IMU's ~0.01 g."""
    from dataclasses import replace

    from scipy.ndimage import gaussian_filter1d

    sigma = smooth_s * motion.fps
    q = motion.rotations.copy()
    flip = np.cumprod(np.where(np.sum(q[1:] * q[:-1], axis=-1) < 0, -1.0, 1.0), axis=0)
    q[1:] *= flip[..., None]
    q = quat.normalize(gaussian_filter1d(q, sigma, axis=0, mode="nearest"))
    root = gaussian_filter1d(motion.root_positions_m, sigma, axis=0, mode="nearest")
    return replace(motion, rotations=q, root_positions_m=root)


def clip(name: str = "16_11", fps: float = 100.0) -> Motion:
    """A shipped clip at ``fps``, smoothed (:func:`smoothed`)."""
    return smoothed(resample(load_clip(sample_clips()[name]), fps))


def _local_from_global(skeleton, glob: np.ndarray) -> np.ndarray:
    """Local joint rotation matrices (J, 3, 3) from global ones."""
    local = glob.copy()
    for j in range(1, skeleton.n_joints):
        local[j] = glob[skeleton.parents[j]].T @ glob[j]
    return local


def _yaw(angle_rad: float) -> np.ndarray:
    return quat.from_rotvec(np.array([0.0, angle_rad, 0.0]))


def write_generic_csv(path: Path, truth: Truth, units: str = "m/s2", quat_order: str = "xyzw", delimiter: str = ",",
                      time_unit: str = "ms") -> dict[str, tuple[list[str], list[str]]]:
    """One row per sample: time, then per sensor ax ay az (units) and a quaternion (sensor -> Z-up world) in
    ``quat_order``; returns name -> (acc columns, quat columns)."""
    scale = {"g": 1.0, "m/s2": GRAVITY_MPS2, "mg": 1000.0}[units]
    t = np.arange(len(truth.acc_g)) / truth.fps * {"s": 1.0, "ms": 1e3, "us": 1e6}[time_unit]
    q = truth.quat_z_up()
    q = q if quat_order == "wxyz" else q[..., [1, 2, 3, 0]]
    header, cols, columns = ["time"], [t[:, None]], {}
    for k, name in enumerate(truth.names):
        acc_names = [f"{name}_acc_{a}" for a in "xyz"]
        quat_names = [f"{name}_q{i}" for i in range(4)]
        header += acc_names + quat_names
        cols += [truth.acc_g[:, k] * scale, q[:, k]]
        columns[name] = (acc_names, quat_names)
    rows = np.hstack(cols)
    lines = [delimiter.join(header)] + [delimiter.join(f"{v:.7g}" for v in r) for r in rows]
    path.write_text("\n".join(lines) + "\n")
    return columns


def write_ximu3_logger(root: Path, truth: Truth, serials: list[str], device_names: list[str],
                       start_us: list[int]) -> Path:
    """An x-IMU3 data-logger recording folder: per device ``"<name> <serial> (USB)"`` with Inertial.csv,
    Quaternion.csv (every second sample, as a lower AHRS message rate would) and Command.json."""
    root.mkdir(parents=True, exist_ok=True)
    n = len(truth.acc_g)
    t_rel_us = np.round(np.arange(n) / truth.fps * 1e6).astype(np.int64)
    q = truth.quat_z_up()
    gyro_dps = np.degrees(truth.gyro_rps)
    for k, (serial, device) in enumerate(zip(serials, device_names)):
        folder = root / f"{device} {serial} (USB)"
        folder.mkdir()
        ts = start_us[k] + t_rel_us
        rows = ["Timestamp (us),Gyroscope X (deg/s),Gyroscope Y (deg/s),Gyroscope Z (deg/s),"
                "Accelerometer X (g),Accelerometer Y (g),Accelerometer Z (g)"]
        rows += [f"{ts[i]},{gyro_dps[i, k, 0]:.6f},{gyro_dps[i, k, 1]:.6f},{gyro_dps[i, k, 2]:.6f},"
                 f"{truth.acc_g[i, k, 0]:.6f},{truth.acc_g[i, k, 1]:.6f},{truth.acc_g[i, k, 2]:.6f}" for i in range(n)]
        (folder / "Inertial.csv").write_text("\n".join(rows) + "\n")
        qrows = ["Timestamp (us),W,X,Y,Z"] + [f"{ts[i]},{q[i, k, 0]:.6f},{q[i, k, 1]:.6f},{q[i, k, 2]:.6f},"
                                              f"{q[i, k, 3]:.6f}" for i in range(0, n, 2)]
        (folder / "Quaternion.csv").write_text("\n".join(qrows) + "\n")
        ping = {"ping": {"interface": "USB", "name": device, "sn": serial}}  # x-IMU3-API ping_response.rs
        (folder / "Command.json").write_text("[\n    " + json.dumps(ping) + "\n]")
    return root


MVN_LABELS = {"lower_back": "Pelvis", "chest": "T8", "left_forearm": "LeftForeArm", "right_forearm": "RightForeArm",
              "left_shin": "LeftLowerLeg", "right_shin": "RightLowerLeg", "right_foot": "RightFoot"}


def write_mvnx(path: Path, truth: Truth, extra_labels: tuple[str, ...] = ("Head",)) -> list[str]:
    """An MVNX 4 file: subject with sensors (the truth's, under their MVN labels, plus ``extra_labels`` that carry
    identity orientation and zero free acceleration), the three calibration frames, then normal frames."""
    labels = [MVN_LABELS[n] for n in truth.names] + list(extra_labels)
    n, s_extra = len(truth.acc_g), len(extra_labels)
    q = np.concatenate([truth.quat_z_up(), np.tile([1.0, 0, 0, 0], (n, s_extra, 1))], axis=1)
    free = np.concatenate([truth.free_acc_z_up_mps2(), np.zeros((n, s_extra, 3))], axis=1)
    out = ['<?xml version="1.0" encoding="UTF-8" standalone="no" ?>',
           '<mvnx version="4" xmlns="http://www.xsens.com/mvn/mvnx">',
           '<mvn version="2022.0.0" build="build"/>', '<comment></comment>',
           f'<subject label="test" torsoColor="#ea6852" frameRate="{truth.fps:g}" segmentCount="23" '
           'recDate="Tue Dec 01 12:00:00.000 2026" recDateMSecsSinceEpoch="0" originalFilename="take.mvn" '
           'configuration="FullBody" userScenario="noLevel" processingQuality="HD">',
           '<segments><segment label="Pelvis" id="1"><points><point label="pHipOrigin"><pos_b>0 0 0</pos_b></point>'
           '</points></segment></segments>', '<sensors>'] + [f'<sensor label="{lab}"/>' for lab in labels] + \
          ['</sensors>', f'<frames segmentCount="23" sensorCount="{len(labels)}" jointCount="22">']
    for kind in ("identity", "tpose", "tpose-isb"):
        out.append(f'<frame time="0" tc="" ms="" type="{kind}"><orientation>1 0 0 0</orientation>'
                   '<position>0 0 0</position></frame>')
    for i in range(n):
        t_ms = int(round(i / truth.fps * 1000))
        out.append(f'<frame time="{t_ms}" index="{i}" tc="00:00:00:{i:02d}" ms="{1.7e12 + t_ms:.0f}" type="normal">'
                   f'<orientation>1 0 0 0</orientation>'
                   f'<sensorFreeAcceleration>{" ".join(f"{v:.6f}" for v in free[i].ravel())}</sensorFreeAcceleration>'
                   f'<sensorMagneticField>{" ".join("0.1" for _ in range(3 * len(labels)))}</sensorMagneticField>'
                   f'<sensorOrientation>{" ".join(f"{v:.6f}" for v in q[i].ravel())}</sensorOrientation>'
                   '</frame>')
    out += ['</frames>', '</subject>', '<securityCode code="KeyCode"/>', '</mvnx>']
    path.write_text("\n".join(out) + "\n")
    return labels


def write_mt_exports(folder: Path, truth: Truth, device_ids: list[str], packet_start: int = 51400) -> list[Path]:
    """MT Manager 2022 text exports, one per device (``MT_<id>_000-000.txt``): ``//`` preamble, tab-separated
    PacketCounter, SampleTimeFine (10 kHz), Acc (m/s²), Gyr (rad/s), Quat_q0..3 (sensor -> ENU)."""
    folder.mkdir(parents=True, exist_ok=True)
    n = len(truth.acc_g)
    q = truth.quat_z_up()
    stf = 1_234_567 + np.round(np.arange(n) / truth.fps * 10_000).astype(np.int64)
    paths = []
    for k, dev in enumerate(device_ids):
        lines = ["// General information: ", "//  MT Manager version: 2022.2.0 ",
                 "//  XDA version: 2022.2.0 build 7381 rev 124627 built on 2023-07-19", "// Device information: ",
                 f"//  DeviceId: {dev}", "//  ProductCode: MTW2-3A7G6", "//  Firmware Version: 4.4.0",
                 "//  Hardware Version: 1.1.0", "// Device settings: ", "//  Filter Profile: human(46.1)",
                 "//  Option Flags: Orientation Smoother Disabled, Position/Velocity Smoother Disabled, "
                 "Continuous Zero Rotation Update Disabled, AHS Disabled, ICC Disabled",
                 "// Coordinate system: ENU",
                 "\t".join(["PacketCounter", "SampleTimeFine", "Acc_X", "Acc_Y", "Acc_Z", "Gyr_X", "Gyr_Y", "Gyr_Z",
                            "Quat_q0", "Quat_q1", "Quat_q2", "Quat_q3"])]
        acc = truth.acc_g[:, k] * GRAVITY_MPS2
        for i in range(n):
            vals = [f"{(packet_start + i) % 65536}", f"{stf[i]}"] + [f"{v:.6f}" for v in acc[i]] + \
                   [f"{v:.6f}" for v in truth.gyro_rps[i, k]] + [f"{v:.6f}" for v in q[i, k]]
            lines.append("\t".join(vals))
        path = folder / f"MT_{dev}_000-000.txt"
        path.write_text("\n".join(lines) + "\n")
        paths.append(path)
    return paths


def standing_then_walking(stand_s: float = 3.0, walks: tuple[str | Motion, ...] = ("16_11", "16_16", "16_21"),
                          tpose_s: float = 0.0, fps: float = 100.0, seed: int = 3, bow_s: float = 0.0,
                          sit_s: float = 0.0, sway_deg: float = 1.0) -> Motion:
    """A take as a real one starts: the subject stands relaxed (the reference N-pose with a slow ``sway_deg`` sway
    of every joint), moves
    within 1 s into the first walking pose and walks (shipped CMU walks, or given Motions of one upright T-pose skeleton, joined end to start with
    continuous ground position and heading), optionally
    moving within 1 s into a held T-pose (the CMU zero pose, facing the last walking heading) for ``tpose_s``
    and then into a forward bow (``gateway.calibration.pose.reference_bow``) for ``bow_s`` and a long sit
    (``reference_long_sit``, legs out in front) for ``sit_s``; smoothed like
    :func:`clip`."""
    from engine.mocap import root_heading
    from gateway.calibration.pose import reference_npose

    rng = np.random.default_rng(seed)
    parts = [resample(c if isinstance(c, Motion) else load_clip(sample_clips()[c]), fps) for c in walks]
    skeleton = parts[0].skeleton
    rots, roots = [], []
    for part in parts:
        r, p = part.rotations.copy(), part.root_positions_m.copy()
        if roots:  # continue where the last clip ended: same ground point, same heading
            turn = float(root_heading(Motion(skeleton, fps, roots[-1][-2:], rots[-1][-2:]))[-1]
                         - root_heading(part)[0])
            yaw_m = quat.to_matrix(_yaw(turn))
            p = (p - p[0]) @ yaw_m.T + np.r_[roots[-1][-1][0], p[0, 1], roots[-1][-1][2]]
            r[:, 0] = quat.multiply(_yaw(turn)[None], r[:, 0])
        rots.append(r)
        roots.append(p)
    n_stand, n_t = int(stand_s * fps), int(tpose_s * fps)
    sway = quat.from_rotvec(np.radians(sway_deg) * np.sin(np.linspace(0, 3, n_stand))[:, None, None]
                            * rng.normal(size=(1, skeleton.n_joints, 3)))
    stand = quat.multiply(quat.from_matrix(reference_npose(skeleton)[0])[None], sway)
    stand[:, 0] = quat.multiply(_yaw(float(root_heading(parts[0])[0]))[None], stand[:, 0])
    n_start = int(fps)  # 1 s from the standing pose into the first walking frame (no teleport)
    start = quat.slerp(np.repeat(stand[-1:], n_start, 0), np.repeat(rots[0][:1], n_start, 0),
                       np.linspace(0.0, 1.0, n_start)[:, None])
    stand = np.concatenate([stand, start])
    n_stand += n_start
    heading = _yaw(float(root_heading(Motion(skeleton, fps, roots[-1][-2:], rots[-1][-2:]))[-1]))
    tails = []  # held end poses, each reached within 1 s from the previous frame
    if n_t:
        tpose = quat.identity((skeleton.n_joints,))
        tpose[0] = heading  # upright, facing the last walking heading
        tails.append((tpose, n_t))
    if bow_s:
        from gateway.calibration.pose import reference_bow

        bow = quat.from_matrix(_local_from_global(skeleton, reference_bow(skeleton)))
        bow[0] = quat.multiply(heading, bow[0])
        tails.append((bow, int(bow_s * fps)))
    if sit_s:
        from gateway.calibration.pose import reference_long_sit

        sit = quat.from_matrix(_local_from_global(skeleton, reference_long_sit(skeleton)))
        sit[0] = quat.multiply(heading, sit[0])
        tails.append((sit, int(sit_s * fps)))
    rot_parts, previous = [stand] + rots, rots[-1][-1]
    n_tail = 0
    for target, n_hold in tails:
        n_turn = int(fps)
        turn = quat.slerp(np.repeat(previous[None], n_turn, 0), np.repeat(target[None], n_turn, 0),
                          np.linspace(0.0, 1.0, n_turn)[:, None])
        rot_parts += [turn, np.repeat(target[None], n_hold, 0)]
        previous, n_tail = target, n_tail + n_turn + n_hold
    rot = np.concatenate(rot_parts)
    root = np.concatenate([np.tile(roots[0][:1], (n_stand, 1))] + roots + [np.tile(roots[-1][-1:], (n_tail, 1))])
    return smoothed(Motion(skeleton, fps, root, rot, "stand-walk"))


def mounted(placements: list[SensorPlacement], seed: int = 3, tilt_deg: tuple[float, float] = (20.0, 30.0),
            flip: tuple[str, ...] = ()) -> list[SensorPlacement]:
    """Placements strapped off nominal by a random rotation of 20-30° about a random axis (sensor frame);
    sensors named in ``flip`` are additionally strapped upside down (180° about their Y axis)."""
    from dataclasses import replace

    rng = np.random.default_rng(seed)
    out = []
    for p in placements:
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        m = quat.to_matrix(quat.from_rotvec(axis * np.radians(rng.uniform(*tilt_deg))))
        if p.name in flip:
            m = m @ np.diag([-1.0, 1.0, -1.0])
        out.append(replace(p, rotation=p.rotation @ m))
    return out

"""Calibrating orientation sensors from a take, whatever their strapping and whatever pose the athlete starts in
(issue 29): each sensor's earth-frame yaw and its strapping, as `OrientationCalibration`.

The model: a sensor's reading (Y-up world, `from_device_earth`) is ``Q(t) = yaw(δ) S(t) M``, with δ its earth
frame's unknown yaw, S(t) the orientation of its placement's nominal sensor frame and M its strapping (any
rotation: upside down and rolled straps included). Its up axis in its own frame is ``u(t) = Q⁻¹ŷ = M⁻¹ v(t)``,
``v(t) = S⁻¹ŷ`` the segment's up in the nominal frame.

What one still pose identifies: with the pose known (its nominal orientations P), ``u = M⁻¹ P⁻¹ŷ`` fixes two of
M's three angles; the turn of M about the pose's vertical cannot be told from a turn of the earth frame (δ), so a
pose alone leaves each sensor's strap **twist** θ about its vertical free: for a hanging forearm that is where
around the arm the sensor sits, which no still N-pose shows. Nor can one pose of unknown arm angle α tell α from
the strap: any tilt of the arm sensors' axes fits some strap. What makes both identifiable is the motion that
follows: the athlete's segments move relative to the pelvis as people move (the database's poses), and only the
right (α, θ) turns the measured orientations into relative rotations the database holds. So:

* **held pose** (N-pose, T-pose, or an A-pose of declared or unknown arm angle; the first still stretch of the
  take or a declared window): per sensor the pose gives M(α, θ) = twist(v_pose, θ) · minimal(u → v_pose) and
  δ(α, θ) exactly; α (shared by every arm sensor) is the angle whose best twists leave the arms' rotations
  relative to the pelvis sensor likeliest under the database's (`MotionPrior`), and each θ the one minimising
  that relative misfit plus how unlikely its up axes over the take are (`_Solver.combined_cost`); the pelvis
  sensor's own θ is the one whose whole solve (α and every other θ fitted to it) fits the database best
  (`HELD_REFERENCE_TWISTS`). The motion so judged leaves the hold out: the database need not hold the pose.
  Without a database θ = 0 (the smallest strap rotation, as the live wizard does) and α is the angle needing the
  smallest straps;
* **no held pose** (``pose none``, research-level, after TIC 2025): each sensor's M first from its own readings
  alone, the rotation that makes its up axes and its spin axes (the axes it turns about, in its own frame)
  likeliest under the database's distributions for that segment (`_Solver.strap_score`, a global search over
  all rotations); then its twist about that fit and δ on a grid from the relative rotations as above; then in
  a north per sensor a local refinement of all four angles, in one north a search over all rotations on the
  same cost, from there and from the best of uniform random straps (`_search_all_rotations`). The pelvis
  sensor's yaw is set to 0: the engines use yaws relative to it.
  In one earth frame (below) no north is solved at all: the pelvis strap's twist about its up is the one under
  which every other sensor's best strap fits likeliest (`_from_motion_one_north`).

**One north** (``north``): a magnetometer-aided filter (Xsens MTw, DOT; most 9-axis IMUs by default) reports
every sensor in one earth frame, δ the same for all. A held pose then fixes every strap but for ONE angle shared
by all sensors, the athlete's heading in that frame ε (M = P⁻¹ yaw(-ε) Q): (α, ε) is the pair whose straps
leave every sensor's rotations relative to the pelvis sensor, and their up axes, likeliest under the database
(`_shared_north`): six sensors' evidence on one angle instead of one sensor's on its own twist. ``auto``
solves each sensor's own north first and takes one north when they agree (`ONE_NORTH_DEG`), as they rarely do
on 6-axis filters whose norths are where each device booted, or when the one-north solve fits the database
nearly as well as the per-sensor one (`HELD_ONE_NORTH_FIT`: on a gesture the database lacks the per-sensor solves
miss and disagree though the north is one); it asks either only when the segments' horizontal turns follow the
pelvis's as in one earth frame (`turn_north_offset_deg`, `HELD_TURN_NORTH_DEG`), which no strap changes; without
a held pose it asks the turns first too (`TURN_NORTH_DEG`).

The engines refine the strapping further over the take (engine/graph/orientation_pose.py, the strap refinement),
so this only needs to land within its reach (tens of degrees would not; a few degrees do). Measured on held-out
Bandai gestures (docs/imu-import.md, docs/engine-evaluation.md): twists median 5.6 deg but 10-40 deg on segments
that move little, and from motion alone 3-172 deg with a north per sensor (docs/engine-evaluation.md has the
sessions' figures for each case)."""
from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from engine.mocap import quaternions as quat
from engine.mocap.orientation import from_device_earth, twist_yaw, yaw_about_up
from engine.mocap.calibration_poses import pose_rotations
from engine.mocap.orientation_calibration import OrientationCalibration, mean_orientation
from engine.mocap.rotations import minimal_rotation
from engine.mocap.sensors import standard_placements
from engine.mocap.skeleton import Skeleton

UP = np.array([0.0, 1.0, 0.0])
NO_TWIST_NOTE = ("the strap's twist about the pose's vertical is not observed without a database (give --graph): "
                 "the smallest strap rotation is assumed")
REFERENCE_SENSOR = "lower_back"  # the engines' yaw reference (engine/graph/orientation_term.py)
ARM_SENSORS = ("left_forearm", "right_forearm", "left_wrist", "right_wrist")  # moved by an A-pose's arm angle
POSE_NAMES = ("npose", "tpose", "apose", "none")
NORTHS = ("auto", "shared", "own")  # the sensors' earth frames: found, one for all (9-axis), one each (6-axis)
ONE_NORTH_DEG = 35.0  # auto: one north when all but one in six of at least 4 sensors' own solved norths lie this
# close to their circular mean. Measured (bench/bench_one_north.py): on one north the own solves of 6 sensors lay
# within 32 deg of it (a twist fit on a still segment is 10-40 deg off), on a north each 100-177 deg; uniform
# random norths pass 1.8 / 0.3 / 1.2 % of the time for 4 / 5 / 6 sensors, and then within this angle of one north.
TURN_NORTH_DEG = 60.0  # pose none, auto: one north when the sensors' turns follow the pelvis's as the
#                       database's do to within this (`_turns_say_one_north`)
ONE_NORTH_MISFIT = 0.17  # pose none, auto: how much worse (mean log k-NN distance per sensor) the one-north solve
#                         may fit than the per-sensor one; on 12 held-out Bandai takes one north fit 0.15 worse at
#                         most, a north per sensor 0.19 at least; in the evaluation's sessions one 9-axis content
#                         of six failed it and one 6-axis content passed it (docs/imu-import.md)
HELD_ONE_NORTH_FIT = 0.31  # held pose, auto, when the sensors' turns allow one north: how much worse (relative
#   misfit plus own-reading unlikeliness, each a mean per sensor: `_fit_gap`) the one-north solve may fit than the
#   per-sensor one. Measured (bench/bench_held_north.py --seeds 12: 12 draws x 6 held-out Bandai contents x 2
#   filters, a 70-deg A-pose held 2 s, uniform straps): on the 9-axis takes whose own norths disagreed one north
#   fit -0.03-0.29 worse; on the 6-axis takes that pass the turn test, 0.49 and more, and 0.33 on one "bye" take
#   of 39 draws (tests/engine/mocap/test_take_calibration.py's setup). Still a thin margin on the 9-axis side;
#   without the turn test the two overlapped (a 6-axis "call" take at 0.20)
HELD_TURN_NORTH_DEG = 45.0  # held pose, auto: one north only when the sensors' turns follow the pelvis's as the
#   database's do within this (`turn_north_offset_deg`): 0-35 deg on all 72 9-axis takes of that bench, 1-179 on
#   the 6-axis ones
HELD_REFERENCE_TWISTS = 12  # held pose, a north per sensor: the reference (pelvis) sensor's strap twists tried, each
#   with the whole solve that follows, keeping the one that fits the database best (`_total_misfit`). Its own up
#   axes alone cannot tell a pelvis facing forward from one facing back on a take with little bending: on 4-s
#   held-out "respond" takes (6-axis, uniform straps, a 70-deg A-pose; a diagnostic run) they turned it 157-180 deg
#   in 5 of 6 draws, the arm angle 10 deg for 70; sessions 5.90 -> 5.65 cm (docs/engine-evaluation.md)
HELD_SCREEN_FRAMES = 50  # ... screened on about this many of the solver's frames, the arms' twists every 30 deg
HELD_SCREEN_ARM_TWIST_STEP = 3  # (every 3rd of the 10-deg grid); the best then solved on every frame, its arm angle
HELD_ARM_REFINE_DEG = 10.0  # within this of the screened one
MIN_MOTION_FRAMES = 10  # held pose: a take with fewer samples outside the hold is judged with the hold in it
SPIN_INTERVAL_S = 1.0 / 15.0  # the turn whose axis is a segment's spin: long enough to rise above a filter's
#                                sample-to-sample noise, short enough that the axis is still one axis
SPIN_KERNEL_DEG = 15.0
MOTION_CANDIDATES = 2000  # pose none: uniform random straps a sensor's search over all rotations starts from,
MOTION_SCREEN_STEP = 4  # screened on every 4th of the take's frames,
MOTION_KEEP = 4  # the best 4 refined
_POSE_TEXT = re.compile(r"^(npose|tpose|apose|none)(?::([0-9.]+))?(?:@([0-9.]+):([0-9.]+))?$")


@dataclass(frozen=True)
class PoseSpec:
    """The pose the take starts with: ``name`` (npose, tpose, apose, or none: no held pose, calibrate from the
    motion), ``arm_deg`` (apose: the arms' angle out from hanging, 0-90; None: fit it) and ``window_s`` (start,
    end) where it is held (None: the first still stretch)."""

    name: str = "npose"
    arm_deg: float | None = None
    window_s: tuple[float, float] | None = None

    @classmethod
    def parse(cls, text: str) -> "PoseSpec":
        """``npose``, ``tpose``, ``apose``, ``apose:20``, any of them ``@START:END`` (seconds), or ``none``."""
        m = _POSE_TEXT.match(text.strip().lower())
        if m is None:
            raise ValueError(f"pose {text!r}: expected npose|tpose|apose[:DEG][@START:END] or none")
        name, deg, start, end = m.groups()
        if deg is not None and name != "apose":
            raise ValueError(f"pose {text!r}: only an A-pose takes an arm angle")
        if name == "none" and start is not None:
            raise ValueError(f"pose {text!r}: no held pose has no window")
        window = None if start is None else (float(start), float(end))
        if window is not None and not window[1] > window[0]:
            raise ValueError(f"pose {text!r}: the window must end after it starts")
        arm = None if deg is None else float(deg)
        if arm is not None and not 0.0 <= arm <= 90.0:
            raise ValueError(f"pose {text!r}: arm angle {arm:g} deg outside 0 (arms down) - 90 (horizontal)")
        return cls(name, arm, window)

    def text(self) -> str:
        out = self.name + ("" if self.arm_deg is None else f":{self.arm_deg:g}")
        return out + ("" if self.window_s is None else f"@{self.window_s[0]:g}:{self.window_s[1]:g}")


@dataclass(frozen=True)
class StillnessConfig:
    """A held pose: every sensor's orientation within ``still_deg`` of its mean over each ``window_s`` window,
    for at least ``min_s`` seconds (orientation filters' tilt noise wanders ~1 degree in a quarter second)."""

    window_s: float = 0.25
    still_deg: float = 3.0
    min_s: float = 1.0


def check_orientations(quat_wxyz: np.ndarray, sensor_names: list[str] | tuple[str, ...]) -> None:
    """ValueError naming the sensor when a reading is not a unit quaternion (all-zero rows are not orientations,
    and nothing is invented for them); NaN rows are missing readings and allowed, but not a take with none."""
    q = np.asarray(quat_wxyz, float)
    finite = np.isfinite(q).all(axis=-1)
    if not finite.any():
        raise ValueError("quat_wxyz holds no orientation (every reading is NaN)")
    norms = np.linalg.norm(np.where(finite[..., None], q, 1.0), axis=-1)
    bad = finite & (np.abs(norms - 1.0) > 0.05)
    for k in np.flatnonzero(bad.any(axis=0)):
        frames = np.flatnonzero(bad[:, k])
        raise ValueError(f"sensor {sensor_names[k]}: {len(frames)} orientation(s) are not unit quaternions (norm "
                         f"{norms[frames[0], k]:.3g} at sample {frames[0]}; all-zero rows are not orientations)")


def still_stretch(quat_wxyz: np.ndarray, fps: float, config: StillnessConfig = StillnessConfig()
                  ) -> tuple[float, float] | None:
    """(start, end) s of the take's first stretch in which every sensor holds still (`StillnessConfig`), or None."""
    q = from_device_earth(np.asarray(quat_wxyz, float))
    n = max(2, int(round(config.window_s * fps)))
    w = len(q) // n
    if not w:
        return None
    blocks = q[: w * n].reshape(w, n, *q.shape[1:])
    mean = quat.normalize(np.sum(blocks * np.sign(np.sum(blocks * blocks[:, :1], axis=-1, keepdims=True)), axis=1))
    dots = np.abs(np.sum(blocks * mean[:, None], axis=-1))
    angle = np.degrees(2.0 * np.arccos(np.clip(dots, 0.0, 1.0)))
    still = np.all(np.nan_to_num(angle, nan=180.0) <= config.still_deg, axis=(1, 2))
    need = int(np.ceil(config.min_s * fps / n))
    run = 0
    for i, s in enumerate(np.append(still, False)):  # a moving sentinel ends the last run
        if s:
            run += 1
            continue
        if run >= need:  # a window at each end dropped when the stretch is long enough: it may hold the move
            edge = 1 if run - 2 >= need else 0  # into or out of the pose
            return ((i - run + edge) * n / fps, (i - edge) * n / fps)
        run = 0
    return None


def _chordal(quaternion_distance: np.ndarray) -> np.ndarray:
    """The matrices' chordal (Frobenius) distance of two rotations from their unit quaternions' nearer distance
    ``2 sin(θ/4)`` (θ the angle between them): ``2√2 sin(θ/2)``. Both grow with θ, so the nearest neighbours are
    the same, and a kd-tree of quaternions (4-D, each rotation stored as q and -q) finds them several times faster
    than one of 9-D matrices."""
    theta = 4.0 * np.arcsin(np.clip(quaternion_distance / 2.0, 0.0, 1.0))
    return 2.0 * np.sqrt(2.0) * np.sin(theta / 2.0)


def _fibonacci_sphere(n: int) -> np.ndarray:
    k = np.arange(n) + 0.5
    z = 1.0 - 2.0 * k / n
    r = np.sqrt(1.0 - z**2)
    phi = np.pi * (1.0 + 5**0.5) * k
    return np.column_stack([r * np.cos(phi), r * np.sin(phi), z])


def _rotations_about(axis: np.ndarray, angles_rad: np.ndarray) -> np.ndarray:
    """(A, 3, 3) rotations by `angles_rad` about the unit `axis`."""
    return quat.to_matrix(quat.from_rotvec(np.outer(angles_rad, axis / np.linalg.norm(axis))))


class _SphereDensity:
    """A kernel density of weighted unit directions (N, 3) on a sphere grid, read as its log (floored: a
    direction the data never shows costs a bounded amount, not infinity)."""

    def __init__(self, dirs: np.ndarray, weights: np.ndarray, kernel_deg: float) -> None:
        grid = _fibonacci_sphere(4000)
        kappa = 1.0 / np.radians(kernel_deg) ** 2
        dens = np.zeros(len(grid))
        chunks = max(1, len(dirs) // 2000)
        for d, w in zip(np.array_split(dirs, chunks), np.array_split(weights, chunks)):
            dens += np.exp(kappa * (grid @ d.T - 1.0)) @ w
        self.tree, self.log_density = cKDTree(grid), np.log(dens / max(dens.max(), 1e-300) + 1e-4)

    def __call__(self, dirs: np.ndarray) -> np.ndarray:
        return self.log_density[self.tree.query(dirs.reshape(-1, 3))[1]].reshape(dirs.shape[:-1])


def body_spins(world_wxyz: np.ndarray, fps: float, min_rate_rad_s: float = 0.5, max_step_rad: float = 1.0
               ) -> tuple[np.ndarray, np.ndarray]:
    """Each sensor's spin axis in its own frame over `SPIN_INTERVAL_S` from consecutive orientations (T, S, 4):
    unit axes (T', S, 3) and weights (T', S), the turn in radians, 0 where the segment turned slower than
    `min_rate_rad_s` (the axis is then the filter's noise), more than `max_step_rad` (a jump: a lost sample, the
    seam between two database clips) or a reading is missing. The frame is the sensor's, so no earth frame,
    north or yaw enters: M maps these axes to the segment's frame as it maps the up axes."""
    q = np.asarray(world_wxyz, float)
    stride = max(1, int(round(fps * SPIN_INTERVAL_S)))
    steps = quat.to_rotvec(quat.multiply(quat.conjugate(q[:-stride]), q[stride:]))  # body frame: Q(t)⁻¹ Q(t+Δ)
    angle = np.linalg.norm(steps, axis=-1)
    ok = np.isfinite(angle) & (angle > min_rate_rad_s * stride / fps) & (angle < max_step_rad)
    dirs = np.where(ok[..., None], steps / np.where(ok, angle, 1.0)[..., None], 0.0)
    return dirs, np.where(ok, angle, 0.0)


@dataclass
class MotionPrior:
    """What the database says about the worn segments: its poses' nominal sensor orientations ``world_wxyz``
    (N, S, 4) in the engine world (a motion graph's nodes, consecutive within a clip, at ``fps``), by
    ``sensor_names``. Lazily: each segment's distributions of up directions and of spin axes in its nominal frame
    (kernel densities on a sphere grid), per sensor a kd-tree of its rotations relative to the reference
    sensor's, and how its turns follow the reference's."""

    world_wxyz: np.ndarray
    sensor_names: tuple[str, ...]
    max_poses: int = 12000
    kernel_deg: float = 10.0
    fps: float = 30.0
    _density: dict = field(default_factory=dict, repr=False)
    _relative: dict = field(default_factory=dict, repr=False)
    _turns: dict = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        q = np.asarray(self.world_wxyz, float)
        step = max(1, len(q) // self.max_poses)
        self._mats = quat.to_matrix(q[::step])  # (N', S, 3, 3)
        self.sensor_names = tuple(self.sensor_names)

    @classmethod
    def from_graph(cls, graph) -> "MotionPrior":
        """The prior of a motion graph's nodes (engine.graph.orientation_term.node_sensor_orientations)."""
        from engine.graph.orientation_term import node_sensor_orientations  # the graph sits above engine.mocap

        return cls(node_sensor_orientations(graph), tuple(graph.config.sensor_names), fps=graph.config.fps)

    def turn_coupling(self, reference: str) -> tuple[np.ndarray, np.ndarray]:
        """`horizontal_turn_coupling` of the database's poses against `reference` (its nodes in order: a clip's
        frames are consecutive)."""
        if reference not in self._turns:
            self._turns[reference] = horizontal_turn_coupling(np.asarray(self.world_wxyz, float),
                                                              self.index(reference))
        return self._turns[reference]

    def index(self, name: str) -> int:
        if name not in self.sensor_names:
            raise ValueError(f"the database has no {name} sensor (its sensors: {', '.join(self.sensor_names)})")
        return self.sensor_names.index(name)

    def up_log_density(self, name: str, up_nominal: np.ndarray) -> np.ndarray:
        """(...,) log density of unit up directions (..., 3) in `name`'s nominal frame under the database's."""
        if name not in self._density:
            ups = self._mats[:, self.index(name), 1, :]  # row 1 of S = S⁻¹ŷ
            self._density[name] = _SphereDensity(ups, np.ones(len(ups)), self.kernel_deg)
        return self._density[name](up_nominal)

    def spin_log_density(self, name: str, spin_nominal: np.ndarray) -> np.ndarray:
        """(...,) log density of unit spin axes (..., 3) in `name`'s nominal frame under the database's
        (`body_spins` of its consecutive poses at `fps`, weighted by rate): where a segment's turning axes lie in
        its own frame (a shin's about its knee's axis, a forearm's about its elbow's and along itself) fixes the
        twist about its up that its up axes leave open; the jumps between clips are left out as fast turns."""
        key = ("spin", name)
        if key not in self._density:
            dirs, weights = body_spins(np.asarray(self.world_wxyz, float)[:, self.index(name):self.index(name) + 1],
                                       self.fps)
            ok = weights[:, 0] > 0
            step = max(1, int(ok.sum()) // self.max_poses)
            self._density[key] = _SphereDensity(dirs[ok, 0][::step], weights[ok, 0][::step], SPIN_KERNEL_DEG)
        return self._density[key](spin_nominal)

    def relative_cost(self, name: str, reference: str, relative: np.ndarray, neighbours: int = 20) -> np.ndarray:
        """(...,) minus the mean log density, over frames, of the relative rotations ``W_ref⁻¹ W`` (..., F, 3, 3)
        under the database's for (reference, name): the log of the chordal distance to the `neighbours`-th
        nearest database rotation (a k-nearest-neighbour density; the nearest alone is near for almost any
        strap, since a broad database holds a rotation near almost anything)."""
        key = (name, reference)
        if key not in self._relative:
            rel = quat.from_matrix(np.swapaxes(self._mats[:, self.index(reference)], -1, -2)
                                   @ self._mats[:, self.index(name)])
            self._relative[key] = cKDTree(np.concatenate([rel, -rel]))  # q and -q: one rotation
        d, _ = self._relative[key].query(quat.from_matrix(relative.reshape(-1, 3, 3)), k=[neighbours], workers=-1)
        return np.log(_chordal(d[:, 0]) + 1e-3).reshape(relative.shape[:-2]).mean(axis=-1)


@dataclass(frozen=True)
class TakeCalibration:
    """The result: ``orientation`` (the calibrated sensors, in ``sensors`` order: indices into the take's
    columns), the pose as found (``pose``: name and arm angle, the window held), whether the sensors were solved
    in one earth frame (``north`` "shared") or each in its own ("own") and on what basis, and whether the straps'
    twists were observed (per sensor a note when not)."""

    orientation: OrientationCalibration
    sensors: tuple[int, ...]
    pose: PoseSpec
    north: str = "own"
    twist_observed: bool = True  # False: no database, each strap's twist about the pose's up a guess (in one north
    #                               all of them turn with the reference's)
    north_basis: str = ""  # north auto: what decided it (the turn and fit tests' numbers); "" when declared

    @property
    def notes(self) -> tuple[str, ...]:
        """Per sensor, what the user should know of its solve ("" for nothing)."""
        return tuple("" if self.twist_observed else NO_TWIST_NOTE for _ in self.sensors)


def _random_rotations(rng: np.random.Generator, n: int) -> np.ndarray:
    """(n, 3, 3) rotations uniform over all rotations."""
    return quat.to_matrix(quat.normalize(rng.normal(size=(n, 4))))


def _frames(world: np.ndarray, max_frames: int) -> np.ndarray:
    """(F', S, 3, 3) matrices of up to `max_frames` evenly spread samples with every sensor's reading."""
    ok = np.flatnonzero(np.isfinite(world).all(axis=(1, 2)))
    pick = ok[np.linspace(0, len(ok) - 1, min(max_frames, len(ok))).astype(int)] if len(ok) else ok
    return quat.to_matrix(world[pick])


def _spread_spins(world: np.ndarray, fps: float, max_frames: int) -> tuple[np.ndarray, np.ndarray]:
    """`body_spins` of the take at up to `max_frames` evenly spread samples."""
    dirs, weights = body_spins(world, fps)
    pick = np.linspace(0, len(dirs) - 1, min(max_frames, len(dirs))).astype(int) if len(dirs) else []
    return dirs[pick], weights[pick]


@dataclass(frozen=True)
class _Solution:
    mount: np.ndarray  # (3, 3) sensor -> nominal
    yaw_rad: float


def _held_family(u: np.ndarray, v: np.ndarray, held: np.ndarray, pose: np.ndarray, thetas: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Straps (A, 3, 3) twist(v, θ) · minimal(u → v) for each θ, and the yaws (A,) that make each explain the
    held reading `held` (3, 3) of the pose `pose` (3, 3): δ = twist of Q M⁻¹ P⁻¹ (a pure yaw: it keeps ŷ)."""
    mounts = _rotations_about(v, thetas) @ minimal_rotation(u, v)
    turn = held[None] @ np.swapaxes(mounts, -1, -2) @ pose.T[None]
    return mounts, twist_yaw(quat.from_matrix(turn))


def _world(frames: np.ndarray, mount: np.ndarray, yaw_rad: np.ndarray) -> np.ndarray:
    """W = yaw(-δ) Q M⁻¹ for frames (F, 3, 3) and candidates mount (..., 3, 3), yaw (...): (..., F, 3, 3)."""
    turn = quat.to_matrix(yaw_about_up(-np.asarray(yaw_rad, float)))
    return turn[..., None, :, :] @ frames @ np.swapaxes(mount, -1, -2)[..., None, :, :]


class _Solver:
    """Fits the sensors of one take against a prior (module docstring)."""

    def __init__(self, frames: np.ndarray, spins: tuple[np.ndarray, np.ndarray], names: list[str],
                 prior: MotionPrior | None, ref: int | None) -> None:
        self.frames, self.names, self.prior, self.ref = frames, names, prior, ref
        self.spin_dirs, self.spin_weights = spins

    def strap_score(self, k: int, mounts: np.ndarray) -> np.ndarray:
        """(A,) how likely sensor k's strap is from its own readings alone, strapped by each of `mounts`
        (A, 3, 3): the mean log density of its up axes over the frames plus the rate-weighted one of its spin
        axes (`body_spins`). The up axes fix a strap's tilt; the spin axes its twist about the segment's up, which
        the up axes leave open on a segment that mostly hangs. Measured on held-out Bandai gesture takes (straps
        uniform over all rotations, 9-axis filters; a diagnostic run, not a repo command), the twist each
        picks alone: the spin axes put a forearm's within 30 deg in 9 of 12 takes (the up axes alone in 10,
        but up to 100 deg off); on shins and trunk the spin axes leave a turn by 180 deg open (a hinge swings
        both ways). Only without a held pose: with one (which fixes the tilts) they moved the one heading off on a session of six ("bye", 4.58 -> 7.80 cm,
        the magnetometer sessions), and in a north per sensor (6-axis sessions from the take) they took "bye"
        from 5.73 to 7.92 cm (6.10 -> 6.48 over six), so a held pose's solver gets none."""
        ups = self.frames[:, k, 1, :]  # row 1 of Q = Q⁻¹ŷ, the sensor-frame up
        name = self.names[k]
        score = self.prior.up_log_density(name, np.einsum("aij,fj->afi", mounts, ups)).mean(axis=-1)
        weights = self.spin_weights[:, k]
        if weights.sum() > 0:
            used = weights > 0
            axes = np.einsum("aij,fj->afi", mounts, self.spin_dirs[used, k])
            score = score + self.prior.spin_log_density(name, axes) @ weights[used] / weights[used].sum()
        return score

    def relative_cost(self, k: int, mounts: np.ndarray, yaws: np.ndarray, ref_mount: np.ndarray,
                      ref_yaw: float | np.ndarray) -> np.ndarray:
        """(...) the database misfit of sensor k's rotations relative to the reference sensor, per candidate
        (`mounts` (..., 3, 3), `yaws` (...)); the reference strapped by `ref_mount` at `ref_yaw`, one solution or
        one per candidate (`_shared_north`, where every strap moves with the one heading)."""
        w_ref = _world(self.frames[:, self.ref], ref_mount, np.asarray(ref_yaw, float))
        w = _world(self.frames[:, k], mounts, yaws)
        return self.prior.relative_cost(self.names[k], self.names[self.ref], np.swapaxes(w_ref, -1, -2) @ w)

    def combined_cost(self, k: int, mounts: np.ndarray, yaws: np.ndarray, ref: _Solution,
                      screen: "_Solver | None" = None):
        """The cost that picks a strap's twist: the relative misfit plus minus the up axis' log density, each in
        units of its spread over the candidates (`mounts`, `yaws`: a grid of twists) so neither drowns the other.
        Returns the cost (a function of mounts (A, 3, 3) and yaws (A,)) and the candidates' costs in those units,
        both from one pass over the candidates (on `screen`, a thinned solver, when given: a screening of many).
        Measured on held-out Bandai gesture takes (a held N-pose, straps uniform over all rotations): twist error
        median 5.6 deg, 95 % within 20 deg; the relative misfit alone 7.8 / 80 %, the up density alone 9.5 /
        80 %: a broad database holds a near relative rotation for many wrong twists, and an up direction alone
        says little about a segment that seldom tilts."""
        on = self if screen is None else screen
        rel = on.relative_cost(k, mounts, yaws, ref.mount, ref.yaw_rad)
        own = -on.strap_score(k, mounts)
        (rel_mean, rel_sd), (own_mean, own_sd) = _scales(rel), _scales(own)

        def cost(m: np.ndarray, y: np.ndarray) -> np.ndarray:
            return ((self.relative_cost(k, m, y, ref.mount, ref.yaw_rad) - rel_mean) / rel_sd
                    + (-self.strap_score(k, m) - own_mean) / own_sd)

        return cost, _spread_units(rel) + _spread_units(own)

    def thinned(self, step: int) -> "_Solver":
        """This solver on every `step`-th frame: a screening of many candidates at a fraction of the cost."""
        return _Solver(self.frames[::step], (self.spin_dirs[::step], self.spin_weights[::step]), self.names,
                       self.prior, self.ref)

    def global_up_fit(self, k: int, rng: np.random.Generator, n_candidates: int = 3000) -> np.ndarray:
        """M (3, 3) maximising `strap_score` over all rotations."""
        candidates = _random_rotations(rng, n_candidates)
        scores = self.strap_score(k, candidates)
        refined = [self.refine(lambda m: -self.strap_score(k, m), m) for m in candidates[np.argsort(scores)[-8:]]]
        return min(refined, key=lambda mc: mc[1])[0]


    def up_fits(self, rng: np.random.Generator) -> list[np.ndarray]:
        """Every sensor's `global_up_fit` (the reference's drawn first), computed once for both motion-only
        solves."""
        order = [self.ref] + [k for k in range(len(self.names)) if k != self.ref]
        fits = {k: self.global_up_fit(k, rng) for k in order}
        return [fits[k] for k in range(len(self.names))]

    def up_fit_twists(self, k: int, fit: np.ndarray, angles_rad: np.ndarray) -> np.ndarray:
        """(Θ, 3, 3) sensor k's up fit `fit` turned about the segment's usual up (the database's mean) by each
        angle: what the up axes leave open, most of all on a limb that mostly hangs."""
        mode = self.prior._mats[:, self.prior.index(self.names[k]), 1, :].mean(axis=0)
        return _rotations_about(mode, angles_rad) @ fit[None]

    @staticmethod
    def refine(cost, mount: np.ndarray, steps_deg: tuple[float, ...] = (8.0, 4.0, 2.0, 1.0, 0.5)
                ) -> tuple[np.ndarray, float]:
        """Pattern search of `cost` (over (A, 3, 3) candidates) by small rotations about the frame's axes."""
        best = float(cost(mount[None])[0])
        for step in steps_deg:
            for _ in range(20):
                moves = quat.to_matrix(quat.from_rotvec(np.radians(step) * np.vstack([np.eye(3), -np.eye(3)])))
                trial = moves @ mount[None]
                c = cost(trial)
                if c.min() >= best:
                    break
                best, mount = float(c.min()), trial[int(np.argmin(c))]
        return mount, best

    @staticmethod
    def refine_pair(sol: _Solution, cost) -> _Solution:
        """Local search of all four angles (M and δ) of a sensor on `cost` (mounts (A, 3, 3), yaws (A,))."""
        mount, yaw = sol.mount, sol.yaw_rad
        best = float(cost(mount[None], np.array([yaw]))[0])
        for step in np.radians([8.0, 4.0, 2.0, 1.0]):
            for _ in range(20):
                rot = quat.to_matrix(quat.from_rotvec(step * np.vstack([np.eye(3), -np.eye(3)])))
                mounts = np.concatenate([rot @ mount[None], mount[None], mount[None]])
                yaws = np.concatenate([np.full(6, yaw), [yaw + step, yaw - step]])
                c = cost(mounts, yaws)
                if c.min() >= best:
                    break
                i = int(np.argmin(c))
                best, mount, yaw = float(c[i]), mounts[i], float(yaws[i])
        return _Solution(mount, yaw)


def _held_pose_orientations(skeleton: Skeleton, names: list[str], spec: PoseSpec, arm_deg: float) -> np.ndarray:
    """(S, 3, 3) nominal sensor orientations ``G_j N`` of the held pose at arm angle `arm_deg` (apose), facing +Z,
    the pose built in the skeleton's own joint frames: the template the live wizard and the accelerometers'
    expected up use (on the shipped CMU skeleton the chest differs by its zero pose's 2.7-degree trunk lean from
    the T-pose re-based `pose_sensor_orientations`; on a skeleton that is not upright they are the same)."""
    glob = pose_rotations(skeleton, spec.name, arm_deg if spec.name == "apose" else None)
    return np.stack([glob[p.joint] @ p.rotation for p in standard_placements(skeleton, names)])


def calibrate_take(quat_device: np.ndarray, fps: float, sensor_names: list[str] | tuple[str, ...],
                   skeleton: Skeleton, pose: PoseSpec = PoseSpec(), prior: MotionPrior | None = None,
                   stillness: StillnessConfig = StillnessConfig(), max_frames: int = 300,
                   seed: int = 0, north: str = "auto") -> TakeCalibration:
    """Calibrate every sensor of a take whose orientations ``quat_device`` (T, S, 4, device earth; a sensor
    with no reading at all is left out) at ``fps`` start with ``pose`` (module docstring), against the
    reference poses built on ``skeleton`` and the database ``prior`` (needed for any strap twist, a fitted arm
    angle with straps far from nominal, and ``pose none``); ``north`` says whether the sensors share one earth
    frame (module docstring: auto, shared, own). ValueError with the reason when it cannot."""
    if north not in NORTHS:
        raise ValueError(f"north {north!r}: expected one of {', '.join(NORTHS)}")
    names = list(sensor_names)
    q = np.asarray(quat_device, float)
    check_orientations(q, names)
    sensors = [k for k in range(len(names)) if np.isfinite(q[:, k]).all(axis=-1).any()]
    q, names = q[:, sensors], [names[k] for k in sensors]
    world = from_device_earth(q)
    if pose.name == "none":
        if prior is None:
            raise ValueError("calibration from motion (pose none) needs the database: give the graph (--graph)")
        solver = _take_solver(world, fps, names, prior, max_frames, spins=True)
        solutions, one_north, basis = _from_motion_any_north(solver, world, north, seed)
        return TakeCalibration(_calibration(solutions), tuple(sensors), pose, "shared" if one_north else "own",
                               north_basis=basis)
    window = pose.window_s or still_stretch(q, fps, stillness)
    if window is None:
        raise ValueError(f"no still stretch: no {stillness.min_s:g} s in which every sensor's orientation stays "
                         f"within {stillness.still_deg:g} deg; declare the held pose's window (--pose "
                         "apose@START:END) or calibrate from the motion (--pose none)")
    i0, i1 = int(round(window[0] * fps)), int(round(window[1] * fps))
    held_q = q[max(0, i0):min(len(q), i1)]
    held_q = held_q[np.isfinite(held_q).all(axis=(1, 2))]
    if len(held_q) < 2:
        raise ValueError(f"the pose window {window[0]:g}-{window[1]:g} s holds no sample with every sensor's "
                         f"orientation (take: 0-{len(q) / fps:.1f} s)")
    held = quat.to_matrix(from_device_earth(mean_orientation(held_q)))  # (S, 3, 3)
    # the motion is judged against the database without the hold, which the database need not hold (an A-pose
    # scored as poses turned it towards arms down); a held pose fixes the tilts, and the spin axes moved one
    # session's heading off (strap_score)
    motion = np.delete(world, np.arange(max(0, i0), min(len(world), i1)), axis=0)
    solver = _take_solver(motion if len(motion) >= MIN_MOTION_FRAMES else world, fps, names, prior, max_frames,
                          spins=False)
    basis = ""
    if north == "shared":
        (solutions, arm_deg), one_north = _shared_north(solver, held, skeleton, pose), True
    elif north == "own" or prior is None:  # without a database there is nothing to tell one north by
        (solutions, arm_deg), one_north = _from_held_pose(solver, held, skeleton, pose), False
    else:
        (solutions, arm_deg), one_north, basis = _held_pose_any_north(solver, held, skeleton, pose, world)
    found = PoseSpec(pose.name, arm_deg if pose.name == "apose" else None, window)
    # in one north without a database the one heading is the reference sensor's guess
    return TakeCalibration(_calibration(solutions), tuple(sensors), found, "shared" if one_north else "own",
                           twist_observed=prior is not None, north_basis=basis)


def _take_solver(world: np.ndarray, fps: float, names: list[str], prior: MotionPrior | None, max_frames: int,
                 spins: bool) -> _Solver:
    """The solver of a take's world-frame orientations (T, S, 4) against `prior`: up to `max_frames` spread
    frames, the pelvis sensor as reference (else the first), and the take's spin axes when `spins`."""
    ref = names.index(REFERENCE_SENSOR) if REFERENCE_SENSOR in names else 0
    no_spins = (np.zeros((0, len(names), 3)), np.zeros((0, len(names))))
    return _Solver(_frames(world, max_frames), _spread_spins(world, fps, max_frames) if spins else no_spins,
                   names, prior, ref)


def horizontal_turn_coupling(world_wxyz: np.ndarray, ref: int, max_step_rad: float = 0.35
                             ) -> tuple[np.ndarray, np.ndarray]:
    """How each sensor's horizontal turning follows the reference's in the world frame, from consecutive
    orientations (T, S, 4; Y up): the angle (S,) between their horizontal angular steps, summed over the take,
    and its coherence (S,), 0-1 (1: always the same turn). The strapping (right of Q) never enters a world-frame
    step, so this is seen before any calibration; steps over `max_step_rad` (missing samples, the jump between
    two database clips) are left out."""
    steps = quat.to_rotvec(quat.multiply(world_wxyz[1:], quat.conjugate(world_wxyz[:-1])))  # (T-1, S, 3)
    ok = np.isfinite(steps).all(axis=(1, 2)) & (np.linalg.norm(steps, axis=-1) < max_step_rad).all(axis=1)
    h = steps[ok][..., 2] + 1j * steps[ok][..., 0]  # the horizontal (Z, X) step as a complex number
    cross = np.sum(np.conj(h[:, ref:ref + 1]) * h, axis=0)
    power = np.sum(np.abs(h) ** 2, axis=0)
    return np.angle(cross), np.abs(cross) / np.sqrt(power[ref] * power + 1e-30)


def turn_north_offset_deg(world: np.ndarray, names: list[str], ref: int, prior: MotionPrior) -> float:
    """How far (degrees, 0-180) the sensors' horizontal turns lie from following the pelvis's as the database's
    do (`horizontal_turn_coupling`): in one earth frame each segment turns with the pelvis at the angle the
    database's motion shows (the shins about 180 degrees: they tilt back as the pelvis tilts forward; the chest
    about 0); in a frame of its own at that angle plus the difference of the two norths. The mean of the take's
    angle minus the database's, weighted by the database's coherence per sensor (the segments whose turns follow
    the pelvis's at all)."""
    angle, _ = horizontal_turn_coupling(world, ref)
    db_angle, db_coherence = prior.turn_coupling(names[ref])
    others = [k for k in range(len(names)) if k != ref]
    db = [prior.index(names[k]) for k in others]
    mean = np.sum(db_coherence[db] * np.exp(1j * (angle[others] - db_angle[db])))
    return float(np.degrees(abs(np.angle(mean))))


def _turns_say_one_north(world: np.ndarray, names: list[str], ref: int, prior: MotionPrior,
                         limit_deg: float = TURN_NORTH_DEG) -> tuple[bool, str]:
    """North auto: one north when `turn_north_offset_deg` is within `limit_deg` (pose none: `TURN_NORTH_DEG`; a
    held pose: `HELD_TURN_NORTH_DEG`, `_held_pose_any_north`). Measured on
    held-out Bandai contents (`bench/bench_pose_free.py`, docs/imu-import.md): one north within 35 degrees in 18
    of 18 takes; a north per sensor (three draws, six contents) beyond 60 in 12 of 18. A miss is not cheap (a
    6-axis session at 17.9 cm against 10.5), hence the fit test after it (`_from_motion_any_north`). Also the
    phrase that says it, for the decision's basis (`TakeCalibration.north_basis`)."""
    offset = turn_north_offset_deg(world, names, ref, prior)
    return offset <= limit_deg, (f"the segments' turns lie {offset:.0f} deg from following the pelvis's as in one "
                                 f"earth frame (one north: <= {limit_deg:g})")


def _held_pose_any_north(solver: _Solver, held: np.ndarray, skeleton: Skeleton, spec: PoseSpec, world: np.ndarray
                         ) -> tuple[tuple[list[_Solution], float | None], bool, str]:
    """Held pose, north auto: the solve to keep (the per-sensor one, `_from_held_pose`, or the one-north one,
    `_shared_north`), whether in one north, and on what basis (a phrase: `TakeCalibration.north_basis`). One north
    when the sensors' horizontal turns (in `world`, the take's readings) follow the pelvis's as in one earth frame
    (`HELD_TURN_NORTH_DEG`), which no strap changes, AND either their own solved norths agree (`_norths_agree`) or
    the one-north solve fits the database within `HELD_ONE_NORTH_FIT` of the per-sensor solve (`_fit_gap`). Why the
    fit: on a gesture the database lacks, the per-sensor solves miss (a waving forearm's twist 120 deg off) and no
    longer agree though the sensors share one north, and the one-north solve, whose straps the held pose forces,
    then still fits about as well; in a north each it forces straps 60-110 deg off and mostly fits far worse. Why
    the turns too: not always (a 6-axis take's gap can be as small as a 9-axis one's, and its norths can agree by
    chance), and the turns tell those apart. The fit test also decides for fewer than the four sensors the agreement
    test needs."""
    own = _from_held_pose(solver, held, skeleton, spec)
    turns_allow, turns = _turns_say_one_north(world, solver.names, solver.ref, solver.prior, HELD_TURN_NORTH_DEG)
    if not turns_allow:
        return own, False, turns
    shared = _shared_north(solver, held, skeleton, spec)
    if _norths_agree([s.yaw_rad for s in own[0]]):
        return shared, True, f"{turns}, and the per-sensor solves' norths agree"
    gap = _fit_gap(solver, shared[0], own[0])
    fit = _fit_phrase(turns, gap, HELD_ONE_NORTH_FIT)
    return (shared, True, fit) if gap <= HELD_ONE_NORTH_FIT else (own, False, fit)


def _fit_phrase(turns: str, gap: float, limit: float) -> str:
    """The basis of a north decided by the fit test after the turns (`TakeCalibration.north_basis`)."""
    return f"{turns}; one north fits the database {gap:.2f} worse than a north each (one north: <= {limit:g})"


def _fit_gap(solver: _Solver, shared: list[_Solution], own: list[_Solution]) -> float:
    """How much worse the one-north solve `shared` fits the database than the per-sensor `own`
    (`_total_misfit`)."""
    return _total_misfit(solver, shared) - _total_misfit(solver, own)


def _total_misfit(solver: _Solver, solutions: list[_Solution]) -> float:
    """How badly a whole solve fits the database: its relative misfit (`_relative_misfit`) plus its straps'
    own-reading unlikeliness (minus `_Solver.strap_score`, the mean over sensors)."""
    unlikeliness = np.mean([-solver.strap_score(k, s.mount[None])[0] for k, s in enumerate(solutions)])
    return _relative_misfit(solver, solutions) + float(unlikeliness)


def _norths_agree(yaws_rad: list[float]) -> bool:
    """Do the sensors' own solved earth yaws say one north (`ONE_NORTH_DEG`)? Four sensors at least."""
    if len(yaws_rad) < 4:
        return False
    z = np.exp(1j * np.asarray(yaws_rad))
    off = np.degrees(np.abs(np.angle(z * np.conj(z.mean()))))
    return int(np.sum(off <= ONE_NORTH_DEG)) >= len(z) - len(z) // 6


def _calibration(solutions: list[_Solution]) -> OrientationCalibration:
    yaws = np.angle(np.exp(1j * np.array([s.yaw_rad for s in solutions])))
    mounts = quat.from_matrix(np.stack([s.mount for s in solutions]))
    return OrientationCalibration(yaws, np.where(mounts[:, :1] < 0, -mounts, mounts))


def _from_held_pose(solver: _Solver, held: np.ndarray, skeleton: Skeleton, spec: PoseSpec
                    ) -> tuple[list[_Solution], float | None]:
    """Every sensor's (M, δ) from the held pose, its twist θ and the arm angle α fitted (module docstring)."""
    names, ref = solver.names, solver.ref
    arms = [k for k, n in enumerate(names) if n in ARM_SENSORS]
    fit_arm, angles = _arm_angles(spec)
    poses = {a: _held_pose_orientations(skeleton, names, spec, a) for a in angles}
    ups = held[:, 1, :]  # (S, 3) sensor-frame up in the pose
    thetas = np.radians(np.arange(0.0, 360.0, 10.0)) if solver.prior is not None else np.zeros(1)

    def family(k: int, a: float, th: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        pose = poses[a][k]
        return _held_family(ups[k], pose[1], held[k], pose, th)

    def fine(k: int, a: float, theta: float, cost) -> _Solution:
        th = theta + np.radians(np.arange(-9.0, 9.5, 1.0))
        mounts, yaws = family(k, a, th)
        i = int(np.argmin(cost(mounts, yaws)))
        return _Solution(mounts[i], float(yaws[i]))

    a0 = angles[0]
    if solver.prior is None:  # no database: the smallest straps, and the arm angle that needs the smallest
        if fit_arm and arms:
            need = [sum(_angle_deg(family(k, a, thetas)[0][0]) for k in arms) for a in angles]
            a0 = angles[int(np.argmin(need))]
        smallest = [family(k, a0 if k in arms else angles[0], thetas) for k in range(len(names))]
        return [_Solution(m[0], float(y[0])) for m, y in smallest], (float(a0) if spec.name == "apose" else None)

    def solve(on: _Solver, reference_twist: float, arm_angles: np.ndarray, arm_twists: np.ndarray
              ) -> tuple[list[_Solution], float]:
        """Every sensor's solution on `on` with the reference's twist near `reference_twist` (its own up axes
        pick it within 9 degrees), the arm angle among `arm_angles` judged on the arms' twists `arm_twists`."""
        reference = fine(ref, a0, reference_twist, lambda m, y: -on.strap_score(ref, m))
        out: list[_Solution] = [reference] * len(names)
        arm = a0
        if fit_arm and arms:  # the arm angle whose best twists leave the arms' relative rotations likeliest
            misfit = np.zeros(len(arm_angles))
            for k in arms:  # every arm angle's twists in one query
                mounts, yaws = (np.stack(f) for f in zip(*(family(k, a, arm_twists) for a in arm_angles)))
                misfit += on.relative_cost(k, mounts, yaws, reference.mount, reference.yaw_rad).min(axis=1)
            arm = float(arm_angles[int(np.argmin(misfit))])
        for k in range(len(names)):
            if k != ref:
                a = arm if k in arms else angles[0]
                cost, grid = on.combined_cost(k, *family(k, a, thetas), reference)
                out[k] = fine(k, a, float(thetas[int(np.argmin(grid))]), cost)
        return out, arm

    # the reference's twist: the one whose whole solve fits the database best, screened on a thinned take
    screen = solver.thinned(max(1, len(solver.frames) // HELD_SCREEN_FRAMES))
    twists = thetas[::len(thetas) // HELD_REFERENCE_TWISTS]
    screened = [solve(screen, t, angles, thetas[::HELD_SCREEN_ARM_TWIST_STEP]) for t in twists]
    best = int(np.argmin([_total_misfit(screen, out) for out, _ in screened]))
    near = angles[np.abs(angles - screened[best][1]) <= HELD_ARM_REFINE_DEG]
    out, arm = solve(solver, float(twists[best]), near, thetas)
    return out, (arm if spec.name == "apose" else None)


def _arm_angles(spec: PoseSpec) -> tuple[bool, np.ndarray]:
    """Is the arm angle fitted, and the candidates (degrees; a 5-degree grid from arms down to horizontal)."""
    fit_arm = spec.name == "apose" and spec.arm_deg is None
    return fit_arm, (np.arange(0.0, 90.1, 5.0) if fit_arm else np.array([spec.arm_deg or 0.0]))


def _shared_north(solver: _Solver, held: np.ndarray, skeleton: Skeleton, spec: PoseSpec
                  ) -> tuple[list[_Solution], float | None]:
    """Every sensor's (M, δ) in one earth frame (module docstring): M = P(α)⁻¹ yaw(-ε) Q_held, δ = ε, with (α, ε)
    minimising the sum over sensors of their relative-rotation misfit and minus their up axes' log density, each
    in units of its spread over the grid (as `_Solver.combined_cost`); ε on a 10-degree grid, then 1 degree.
    Without a database (α, ε) are the reference sensor's own as `_from_held_pose` finds them (its smallest
    strap, the arm angle needing the smallest straps)."""
    names, ref = solver.names, solver.ref
    arms = [k for k, n in enumerate(names) if n in ARM_SENSORS]
    _, angles = _arm_angles(spec)
    poses = np.stack([_held_pose_orientations(skeleton, names, spec, a) for a in angles])  # (Aα, S, 3, 3)

    def straps(eps: np.ndarray) -> np.ndarray:
        """(Aα, E, S, 3, 3) M = P⁻¹ yaw(-ε) Q_held for every arm angle and heading."""
        turn = quat.to_matrix(yaw_about_up(-eps))  # (E, 3, 3)
        return np.swapaxes(poses, -1, -2)[:, None] @ (turn[:, None] @ held[None])[None]

    def cost(eps: np.ndarray) -> np.ndarray:
        """(Aα, E) the summed, spread-scaled misfit of every sensor (one arm-angle row for the sensors the arm
        angle does not move)."""
        mounts = straps(eps)
        total = np.zeros(mounts.shape[:2])
        for k in range(len(names)):
            rows = slice(None) if k in arms or ref in arms else slice(0, 1)
            m, grid = mounts[rows], mounts[rows].shape[:2]
            terms = [-solver.strap_score(k, m[:, :, k].reshape(-1, 3, 3)).reshape(grid)]
            if k != ref:
                yaws = np.broadcast_to(eps, grid)
                terms.append(solver.relative_cost(k, m[:, :, k], yaws, m[:, :, ref], yaws))
            for t in terms:
                total += _spread_units(t)
        return total

    if solver.prior is None:
        own, arm = _from_held_pose(solver, held, skeleton, spec)
        ia, eps = int(np.argmin(np.abs(angles - (arm or angles[0])))), own[ref].yaw_rad
    else:
        coarse = np.radians(np.arange(0.0, 360.0, 10.0))
        c = cost(coarse)
        ia, ie = np.unravel_index(int(np.argmin(c)), c.shape)
        fine = coarse[ie] + np.radians(np.arange(-9.0, 9.5, 1.0))
        eps = float(fine[int(np.argmin(cost(fine)[ia]))])
    mounts = straps(np.array([eps]))[ia, 0]
    return [_Solution(m, float(eps)) for m in mounts], (float(angles[ia]) if spec.name == "apose" else None)


def _from_motion_any_north(solver: _Solver, world: np.ndarray, north: str, seed: int
                           ) -> tuple[list[_Solution], bool, str]:
    """Pose none: the straps, whether in one north, and (north auto) on what basis. `auto` takes one north only
    when both tests say so: the segments' turns follow the pelvis's as the database's do (`_turns_say_one_north`),
    and the one-north solve's relative rotations fit the database within `ONE_NORTH_MISFIT` per sensor of the
    per-sensor solve's (which, freer, always fits at least as well)."""
    rng = np.random.default_rng(seed)
    fits = solver.up_fits(rng)
    if north == "own":
        return _from_motion(solver, fits), False, ""
    if north == "shared":
        return _from_motion_one_north(solver, fits, rng), True, ""
    turns_allow, turns = _turns_say_one_north(world, solver.names, solver.ref, solver.prior)
    if not turns_allow:
        return _from_motion(solver, fits), False, turns
    shared = _from_motion_one_north(solver, fits, rng)
    own = _from_motion(solver, fits)
    gap = _relative_misfit(solver, shared) - _relative_misfit(solver, own)
    fit = _fit_phrase(turns, gap, ONE_NORTH_MISFIT)
    return (shared, True, fit) if gap <= ONE_NORTH_MISFIT else (own, False, fit)


def _relative_misfit(solver: _Solver, solutions: list[_Solution]) -> float:
    """The mean over the non-reference sensors of their relative rotations' database misfit."""
    ref = solutions[solver.ref]
    return float(np.mean([solver.relative_cost(k, s.mount[None], np.array([s.yaw_rad]), ref.mount, ref.yaw_rad)[0]
                          for k, s in enumerate(solutions) if k != solver.ref]))


def _from_motion(solver: _Solver, fits: list[np.ndarray]) -> list[_Solution]:
    """Every sensor's (M, δ) from the motion alone (module docstring), from its up fit `fits[k]`: its best twist
    about that fit and yaw on a grid, refined locally."""
    names, ref = solver.names, solver.ref
    reference = _Solution(fits[ref], 0.0)
    out: list[_Solution] = []
    thetas = np.radians(np.arange(0.0, 360.0, 15.0))
    for k in range(len(names)):
        if k == ref:
            out.append(reference)
            continue
        mounts = np.repeat(solver.up_fit_twists(k, fits[k], thetas), len(thetas), axis=0)
        yaws = np.tile(thetas, len(thetas))
        cost, grid = solver.combined_cost(k, mounts, yaws, reference)
        i = int(np.argmin(grid))
        out.append(solver.refine_pair(_Solution(mounts[i], float(yaws[i])), cost))
    return out


def _search_all_rotations(solver: _Solver, k: int, reference: _Solution, start: np.ndarray,
                          rng: np.random.Generator) -> _Solution:
    """Sensor k's strap in one north searched over all rotations on the relative misfit plus its own readings'
    unlikeliness (`_Solver.combined_cost`, in units of their spread over uniform random candidates): the best
    `MOTION_KEEP` candidates, screened on every `MOTION_SCREEN_STEP`-th frame, and `start` (its best twist about
    its up fit), each refined locally. Why not the twists alone: a segment whose motion the database lacks (a
    forearm waving) can be likeliest on its own readings at a tilt well off its true one, which no twist about
    that tilt reaches, while its rotations relative to the pelvis still find the true one."""
    mounts = _random_rotations(rng, MOTION_CANDIDATES)
    cost, screened = _all_rotations_cost(solver, k, reference, mounts)
    seeds = list(mounts[np.argsort(screened)[:MOTION_KEEP]]) + [start]
    found = [solver.refine(cost, seed) for seed in seeds]
    return _Solution(min(found, key=lambda mc: mc[1])[0], 0.0)


def _all_rotations_cost(solver: _Solver, k: int, reference: _Solution, candidates: np.ndarray):
    """`_search_all_rotations`' cost of sensor k's strap (a function of mounts (A, 3, 3), one north), in units of
    its two terms' spread over `candidates` (uniform random straps) screened on every `MOTION_SCREEN_STEP`-th
    frame, and the candidates' screened costs in those units (one pass gives both)."""
    cost, screened = solver.combined_cost(k, candidates, np.zeros(len(candidates)), reference,
                                          screen=solver.thinned(MOTION_SCREEN_STEP))
    return (lambda m: cost(m, np.zeros(len(m)))), screened


def one_north_strap_costs(quat_device: np.ndarray, fps: float, sensor_names: list[str] | tuple[str, ...],
                          prior: MotionPrior, mount_wxyz: np.ndarray, max_frames: int = 300, seed: int = 0
                          ) -> np.ndarray:
    """(S,) the cost the pose-free one-north search minimises (`_search_all_rotations`) at the straps `mount_wxyz`
    (S, 4; sensor -> nominal, in `sensor_names` order) of a take with every sensor's orientation, each strap
    against the reference sensor's strap in those straps; NaN at the reference. A diagnostic (bench/
    bench_pose_free.py --cost-at-truth): where the true straps cost more than the solved ones, no better search
    finds them -- the database, not the search, decides."""
    names = list(sensor_names)
    solver = _take_solver(from_device_earth(np.asarray(quat_device, float)), fps, names, prior, max_frames, spins=True)
    ref = solver.ref
    mounts = quat.to_matrix(np.asarray(mount_wxyz, float))
    reference = _Solution(mounts[ref], 0.0)
    candidates = _random_rotations(np.random.default_rng(seed), MOTION_CANDIDATES)
    costs = [_all_rotations_cost(solver, k, reference, candidates)[0](mounts[k:k + 1])[0] if k != ref else np.nan
             for k in range(len(names))]
    return np.array(costs, float)


def _from_motion_one_north(solver: _Solver, fits: list[np.ndarray], rng: np.random.Generator) -> list[_Solution]:
    """Every sensor's M from the motion alone, all in one earth frame (δ = 0 for every sensor: a shared north
    cancels from the relative rotations and never touches an up axis, so it is neither seen nor needed). Each
    strap's tilt from its own readings (`global_up_fit`) leaves a twist about its segment's usual up; the
    reference's twist ψ is the one under which every other sensor's best twist θ leaves its rotations relative to
    the reference, and its own readings, likeliest (the sum over sensors, each term in units of its spread over
    the (ψ, θ) grid), which a per-sensor north cannot do: there each sensor's own north absorbs the reference's
    twist. Then each other strap is searched over all rotations from its best twist (`_search_all_rotations`)."""
    names, ref = solver.names, solver.ref
    grid = np.radians(np.arange(0.0, 360.0, 10.0))
    ref_mounts = solver.up_fit_twists(ref, fits[ref], grid)  # (Ψ, 3, 3)
    total = _spread_units(-solver.strap_score(ref, ref_mounts))
    zero = np.zeros((len(grid), len(grid)))
    costs = {}
    for k in range(len(names)):
        if k == ref:
            continue
        mounts = solver.up_fit_twists(k, fits[k], grid)
        rel = solver.relative_cost(k, np.broadcast_to(mounts, zero.shape + (3, 3)), zero, ref_mounts[:, None], zero)
        up = np.broadcast_to(-solver.strap_score(k, mounts), zero.shape)
        costs[k] = (mounts, _spread_units(rel) + _spread_units(up))
        total = total + costs[k][1].min(axis=1)
    ip = int(np.argmin(total))
    reference = _Solution(ref_mounts[ip], 0.0)
    out: list[_Solution] = []
    for k in range(len(names)):
        if k == ref:
            out.append(reference)
            continue
        mounts, cost_grid = costs[k]
        out.append(_search_all_rotations(solver, k, reference, mounts[int(np.argmin(cost_grid[ip]))], rng))
    return out


def _scales(cost: np.ndarray) -> tuple[float, float]:
    """The mean and spread of a cost over a grid of candidates: the units in which unlike costs are summed."""
    return float(cost.mean()), float(cost.std() + 1e-9)


def _spread_units(cost: np.ndarray) -> np.ndarray:
    """`cost` in units of its spread over the grid (`_scales`), about its mean."""
    mean, sd = _scales(cost)
    return (cost - mean) / sd


def _angle_deg(r: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(r) - 1.0) / 2.0, -1.0, 1.0))))

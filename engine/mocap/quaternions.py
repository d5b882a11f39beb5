"""Vectorised unit-quaternion helpers, (w, x, y, z) order, acting on column vectors.

Everything works on arrays of any leading shape `(..., 4)` so forward kinematics, resampling and mirroring
run over all frames at once. Euler conversions go through scipy's `Rotation` (well tested, all 12 orders)
with the order given as an upper-case *intrinsic* axis string, which is exactly BVH channel order:
channels "Zrotation Xrotation Yrotation" mean R = Rz @ Rx @ Ry, i.e. order "ZXY"."""
from __future__ import annotations

import warnings

import numpy as np
from scipy.spatial.transform import Rotation

_AXES = {"X": 0, "Y": 1, "Z": 2}


def identity(shape: tuple[int, ...] = ()) -> np.ndarray:
    """Identity quaternions of the given leading shape."""
    q = np.zeros(shape + (4,))
    q[..., 0] = 1.0
    return q


def normalize(q: np.ndarray) -> np.ndarray:
    """Unit quaternions (zero-length input becomes identity rather than NaN)."""
    q = np.asarray(q, dtype=float)
    n = np.linalg.norm(q, axis=-1, keepdims=True)
    out = np.where(n > 0, q / np.where(n > 0, n, 1.0), identity(q.shape[:-1]))
    return out


def multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product a*b (apply b first, then a). Components by basic slicing into one preallocated output:
    a live frame calls this on a few dozen quaternions, where moving axes and stacking cost more than the sums."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    aw, ax, ay, az = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    bw, bx, by, bz = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = aw * bw - ax * bx - ay * by - az * bz
    out[..., 1] = aw * bx + ax * bw + ay * bz - az * by
    out[..., 2] = aw * by - ax * bz + ay * bw + az * bx
    out[..., 3] = aw * bz + ax * by - ay * bx + az * bw
    return out


def conjugate(q: np.ndarray) -> np.ndarray:
    """Inverse of a unit quaternion."""
    return np.asarray(q, float) * np.array([1.0, -1.0, -1.0, -1.0])


def to_matrix(q: np.ndarray) -> np.ndarray:
    """(..., 4) unit quaternions -> (..., 3, 3) rotation matrices."""
    q = normalize(q)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    m = np.empty(np.shape(w) + (3, 3))
    m[..., 0, 0] = 1 - 2 * (y * y + z * z)
    m[..., 0, 1] = 2 * (x * y - w * z)
    m[..., 0, 2] = 2 * (x * z + w * y)
    m[..., 1, 0] = 2 * (x * y + w * z)
    m[..., 1, 1] = 1 - 2 * (x * x + z * z)
    m[..., 1, 2] = 2 * (y * z - w * x)
    m[..., 2, 0] = 2 * (x * z - w * y)
    m[..., 2, 1] = 2 * (y * z + w * x)
    m[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return m


def _from_scipy(r: Rotation, shape: tuple[int, ...]) -> np.ndarray:
    xyzw = r.as_quat().reshape(shape + (4,))
    return np.concatenate([xyzw[..., 3:], xyzw[..., :3]], axis=-1)


def _to_scipy(q: np.ndarray) -> Rotation:
    q = normalize(q).reshape(-1, 4)
    return Rotation.from_quat(np.concatenate([q[:, 1:], q[:, :1]], axis=1))


def from_matrix(m: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation matrices -> (..., 4) unit quaternions with w >= 0."""
    m = np.asarray(m, float)
    shape = m.shape[:-2]
    q = _from_scipy(Rotation.from_matrix(m.reshape(-1, 3, 3)), shape)
    return np.where(q[..., :1] < 0, -q, q)


def from_euler(angles_rad: np.ndarray, order: str) -> np.ndarray:
    """Intrinsic Euler angles (..., k) about the upper-case axes in `order` (e.g. "ZXY": R = Rz Rx Ry).

    Orders with fewer than three axes (ASF bones with 1 or 2 dofs) are composed axis by axis."""
    angles = np.asarray(angles_rad, float)
    if angles.shape[-1] != len(order):
        raise ValueError(f"{angles.shape[-1]} angles for rotation order {order!r}")
    q = identity(angles.shape[:-1])
    for i, axis in enumerate(order):
        half = 0.5 * angles[..., i]
        step = np.zeros(angles.shape[:-1] + (4,))
        step[..., 0] = np.cos(half)
        step[..., 1 + _AXES[axis]] = np.sin(half)
        q = multiply(q, step)
    return q


def to_euler(q: np.ndarray, order: str) -> np.ndarray:
    """Inverse of `from_euler` for three-axis intrinsic orders (radians, (..., 3))."""
    q = np.asarray(q, float)
    shape = q.shape[:-1]
    with warnings.catch_warnings():
        # At gimbal lock scipy picks one of the equivalent angle sets and warns; any of them is the same
        # rotation (the BVH round-trip test covers it), so the warning is noise here.
        warnings.filterwarnings("ignore", message="Gimbal lock detected")
        return _to_scipy(q).as_euler(order.upper()).reshape(shape + (3,))


def rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vectors (..., 3) by quaternions (..., 4) (broadcasting)."""
    return np.einsum("...ij,...j->...i", to_matrix(q), np.asarray(v, float))


def slerp(a: np.ndarray, b: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Spherical interpolation from a (t=0) to b (t=1) along the short arc; t broadcasts over (...)."""
    a = normalize(a)
    b = normalize(b)
    t = np.asarray(t, float)[..., None]
    dot = np.sum(a * b, axis=-1, keepdims=True)
    b = np.where(dot < 0, -b, b)
    dot = np.abs(dot)
    theta = np.arccos(np.clip(dot, -1.0, 1.0))
    sin_theta = np.sin(theta)
    close = sin_theta < 1e-8  # nearly equal: linear interpolation is exact enough and avoids 0/0
    safe = np.where(close, 1.0, sin_theta)
    wa = np.where(close, 1.0 - t, np.sin((1.0 - t) * theta) / safe)
    wb = np.where(close, t, np.sin(t * theta) / safe)
    return normalize(wa * a + wb * b)


def log_matrix(m: np.ndarray) -> np.ndarray:
    """Rotation vectors (axis * angle, radians) of rotation matrices (..., 3, 3)."""
    m = np.asarray(m, float)
    return Rotation.from_matrix(m.reshape(-1, 3, 3)).as_rotvec().reshape(m.shape[:-2] + (3,))


def to_rotvec(q: np.ndarray) -> np.ndarray:
    """(..., 4) unit quaternions -> (..., 3) rotation vectors (radians), taking the short way round (w >= 0).

    Closed form rather than scipy: it runs per frame inside the OLNG energy and the graph's transition blending,
    where scipy's object overhead dominates for small batches."""
    q = np.asarray(q, float)
    q = np.where(q[..., :1] < 0, -q, q)
    sin_half = np.linalg.norm(q[..., 1:], axis=-1)
    angle = 2.0 * np.arctan2(sin_half, q[..., 0])
    scale = np.where(sin_half > 1e-12, angle / np.maximum(sin_half, 1e-12), 2.0)
    return q[..., 1:] * scale[..., None]


def from_rotvec(v: np.ndarray) -> np.ndarray:
    """Quaternions from rotation vectors (axis * angle, radians)."""
    v = np.asarray(v, float)
    return _from_scipy(Rotation.from_rotvec(v.reshape(-1, 3)), v.shape[:-1])


def canonical_sign(q: np.ndarray) -> np.ndarray:
    """Make consecutive quaternions along axis 0 lie in the same hemisphere (q and -q are the same rotation),
    so per-frame interpolation and finite differences never take the long way round."""
    q = np.array(q, float)
    if q.shape[0] < 2:
        return q
    dots = np.sum(q[1:] * q[:-1], axis=-1)
    flips = np.cumprod(np.where(dots < 0, -1.0, 1.0), axis=0)
    q[1:] *= flips[..., None]
    return q

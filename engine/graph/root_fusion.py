"""The output root from the camera: a fixed-lag smoother of the camera fixes (issue 11).

Why: with the root warp (warp.py) the output root is the chosen path's own steps pulled towards the camera, so it
depends on *which* motion the search picked. Adding accelerometers changes the pick (for a better pose) and with
it the root: on Bandai-1 chained takes the heading came out 0.01-0.3 deg worse than the camera-only search. The
camera measures the root; the database only guesses it. So whenever the camera is present the output root's
ground position and heading are a function of the camera fixes alone -- a constant-velocity Kalman filter per
coordinate (x, z: white-noise acceleration `position_process`; heading: white-noise angular acceleration
`heading_process`, innovations wrapped) and a Rauch-Tung-Striebel pass back over the last `lag` frames -- and
the database motion supplies only the root-relative pose. Adding accelerometers then cannot change the root at
all (equal by construction), and the smoother averages ~a second of fixes instead of the warp's ~3 frames
(measured on the chained takes: 2.1 cm / 2.7 deg against the warp's 3.9 cm / 4.3 deg, 5 cm / 10 deg camera).

Where a coordinate has had no fix for more than `max_gap_s` (a camera dropout, a camera without heading) the root
follows the path's own steps from the last output (dead reckoning: what the database knows), and when fixes
return it rejoins the smoothed track at most `max_speed_mps` / `max_turn_rps` faster than the track itself, so a
camera coming back never teleports the skeleton. With fixes on every frame from the first, the output is the
smoothed track exactly.

`RootFuser` is incremental (push one frame's fix, decide frames up to `lag` behind the newest), so the fixed-lag
decoder (live) and a batch search (lag = the whole take) run the same code; the smoothed estimate of frame s
given fixes up to s + lag is the exact RTS estimate over that window (tested against the batch least-squares
solution).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .geometry import wrap_angle


@dataclass(frozen=True)
class RootFusion:
    """Camera noise (sd per fix) and process noise of the root smoother, and the dropout rule (module doc).

    Process noise measured on Bandai-1 chained held-out takes with the 5 cm / 10 deg, 30 Hz camera
    (docs/engine-graph.md): position 1 m^2/s^3 (0.3-1 best; 0.1 -> 2.3 cm, 3 -> 2.3 cm, 10 -> 2.6 cm), heading
    10 rad^2/s^3 (3 -> 2.7 deg, 30 -> 2.8, 1 -> 3.0, 1000 -> 4.2)."""

    position_noise_m: float = 0.05
    heading_noise_rad: float = float(np.radians(10.0))
    position_process: float = 1.0  # m^2/s^3: spectral density of the white-noise acceleration
    heading_process: float = 10.0  # rad^2/s^3
    max_gap_s: float = 0.5  # a coordinate without a fix for longer follows the path's own steps
    max_speed_mps: float = 8.0  # rejoining the camera track after a dropout: at most this much faster ...
    max_turn_rps: float = 6.0  # ... or turning faster than the track
    enabled: bool = True

    @classmethod
    def off(cls) -> "RootFusion":
        """The output root is the search's own (warped) path track, as before issue 11's fusion."""
        return cls(enabled=False)


class _ConstantVelocity:
    """Kalman filter of C channels sharing one constant-velocity model and one fix schedule, keeping per frame
    (from `first` on) what the RTS backward pass needs, as plain floats: the 2-state recursions run ~20x faster
    so than on tiny numpy arrays, and a live decoder runs one backward pass per decided frame."""

    def __init__(self, channels: int, process: float, noise_sd: float, dt: float, angle: bool) -> None:
        self.F = np.array([[1.0, dt], [0.0, 1.0]])
        self.Q = process * np.array([[dt ** 3 / 3, dt ** 2 / 2], [dt ** 2 / 2, dt]])
        self.R = noise_sd ** 2
        self.angle = angle
        self.channels = channels
        self.x: np.ndarray | None = None  # (C, 2) filtered mean: value, rate
        self.P: np.ndarray | None = None  # (2, 2) filtered covariance (shared by the channels)
        self.first = 0  # frame of the oldest kept entry
        self.filtered: list[list[list[float]] | None] = []  # per frame [[value, rate]] * C; None before a fix
        self.predicted: list[list[list[float]] | None] = []  # per frame: the prediction into it
        self.gain: list[list[list[float]]] = []  # per frame s: RTS gain P_s|s F^T P_s+1|s^-1 (once s+1 is in)
        self.last_fix = -1  # frame of the newest fix

    def push(self, z: np.ndarray | None) -> None:
        """One frame: predict, then update with fix `z` (C,) if given. Before the first fix nothing is estimated."""
        t = self.first + len(self.filtered)
        if self.x is None:
            xp = None
            if z is not None:  # diffuse start: the first fix, rate unknown (variance large against any body's)
                self.x = np.stack([np.asarray(z, float), np.zeros(self.channels)], axis=1)
                self.P = np.diag([self.R, 1e4])
                xp = self.x.tolist()
                self.last_fix = t
            self.predicted.append(xp)
            self.filtered.append(xp)
            self.gain.append([[0.0, 0.0], [0.0, 0.0]])
            return
        xp = self.x @ self.F.T
        Pp = self.F @ self.P @ self.F.T + self.Q
        self.gain[-1] = (self.P @ self.F.T @ np.linalg.inv(Pp)).tolist()
        x, P = xp, Pp
        if z is not None:
            innovation = np.asarray(z, float) - xp[:, 0]
            if self.angle:
                innovation = wrap_angle(innovation)
            k = Pp[:, 0] / (Pp[0, 0] + self.R)
            x = xp + innovation[:, None] * k[None, :]
            P = Pp - np.outer(k, Pp[0])
            self.last_fix = t
        self.x, self.P = x, P
        self.predicted.append(xp.tolist())
        self.filtered.append(x.tolist())
        self.gain.append([[0.0, 0.0], [0.0, 0.0]])

    def smoothed(self, first: int, last: int) -> np.ndarray:
        """(last - first + 1, C) values of frames first..last given every fix pushed so far (RTS from the
        newest frame back); NaN before the first fix."""
        newest = self.first + len(self.filtered) - 1
        out = np.full((last - first + 1, self.channels), np.nan)
        s = self.filtered[newest - self.first]
        for u in range(newest, first - 1, -1):
            k = u - self.first
            xf = self.filtered[k]
            if xf is None:
                break  # before the first fix: NaN
            if u < newest:
                (g00, g01), (g10, g11) = self.gain[k]
                xp = self.predicted[k + 1]
                s = [[f[0] + g00 * (a[0] - p[0]) + g01 * (a[1] - p[1]),
                      f[1] + g10 * (a[0] - p[0]) + g11 * (a[1] - p[1])] for f, a, p in zip(xf, s, xp)]
            if u <= last:
                out[u - first] = [v[0] for v in s]
        return out

    def drop_before(self, frame: int) -> None:
        n = max(0, min(len(self.filtered), frame - self.first))
        del self.filtered[:n], self.predicted[:n], self.gain[:n]
        self.first += n


class RootFuser:
    """One take's output root: push every frame's camera fix (`push`), then decide frames in order (`decide`)
    given the chosen path's own track for them. `lag` frames of fixes after a frame are used when it is decided
    (the caller decides frame t - lag after pushing frame t; a batch search decides everything at the end)."""

    def __init__(self, fusion: RootFusion, fps: float) -> None:
        self.fusion = fusion
        dt = 1.0 / fps
        self._pos = _ConstantVelocity(2, fusion.position_process, fusion.position_noise_m, dt, angle=False)
        self._head = _ConstantVelocity(1, fusion.heading_process, fusion.heading_noise_rad, dt, angle=True)
        self._max_gap = int(round(fusion.max_gap_s * fps))
        self._catch_up = (fusion.max_speed_mps * dt, fusion.max_turn_rps * dt)
        self._pushed = 0
        self._last_fix: list[tuple[int, int]] = []  # per undecided frame: newest position / heading fix so far
        self._decided = 0
        self._out: tuple[complex, float] | None = None  # output root of the last decided frame
        self._path: tuple[complex, float] | None = None  # the path's own root at the last decided frame
        self._offset: tuple[complex | None, float | None] = (None, None)  # output - smoothed while rejoining
        self._was_covered = (False, False)  # did the camera cover the last decided frame (position, heading)

    def push(self, position_m: np.ndarray | None, heading_rad: float | None) -> None:
        pos = None if position_m is None or np.any(np.isnan(position_m)) else np.asarray(position_m, float)
        head = None if heading_rad is None or np.isnan(heading_rad) else np.array([float(heading_rad)])
        self._pos.push(pos)
        self._head.push(head)
        self._last_fix.append((self._pos.last_fix, self._head.last_fix))
        self._pushed += 1

    def decide(self, path_ground_m: np.ndarray, path_heading_rad: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Output ground (K, 2) and heading (K,) of the next K undecided frames, whose chosen path places the root
        at `path_ground_m` / `path_heading_rad` (the search's own track: used only where the camera is absent)."""
        k = len(path_heading_rad)
        first, last = self._decided, self._decided + k - 1
        if last >= self._pushed:
            raise ValueError(f"frame {last} decided before its fix was pushed ({self._pushed} pushed)")
        if not self.fusion.enabled:  # the path's own track, untouched
            out_g, out_h = np.asarray(path_ground_m, float), np.asarray(path_heading_rad, float)
        else:
            sp = self._pos.smoothed(first, last)
            sh = self._head.smoothed(first, last)[:, 0]
            out_g, out_h = np.empty((k, 2)), np.empty(k)
            for i in range(k):
                g, h = self._one(first + i, complex(*path_ground_m[i]), float(path_heading_rad[i]),
                                 complex(*sp[i]), float(sh[i]))
                out_g[i], out_h[i] = (g.real, g.imag), h
            out_h = wrap_angle(out_h)
        self._decided = last + 1
        del self._last_fix[:k]
        for f in (self._pos, self._head):  # the newest frame stays: the next prediction's RTS gain is set on it
            f.drop_before(min(self._decided, self._pushed - 1))
        return out_g, out_h

    def _one(self, frame: int, path_g: complex, path_h: float, smooth_g: complex, smooth_h: float
             ) -> tuple[complex, float]:
        """Output root of one frame (module doc): the smoothed fix where the camera covers the frame (rejoined
        at a bounded rate after a dropout), else the last output moved by the path's own step."""
        pos_fix, head_fix = self._last_fix[frame - self._decided]
        covered = tuple(fix >= 0 and frame - fix <= self._max_gap for fix in (pos_fix, head_fix))
        if self._out is None:  # the first frame: the smoothed fix, else the path's own placement
            g = smooth_g if covered[0] else path_g
            h = smooth_h if covered[1] else path_h
        else:
            (prev_g, prev_h), (ppath_g, ppath_h) = self._out, self._path
            step = (path_g - ppath_g) * np.exp(1j * ppath_h)  # the path's step in its own previous root frame
            dead_h = prev_h + float(wrap_angle(path_h - ppath_h))
            dead_g = prev_g + step * np.exp(-1j * prev_h)
            off_g, off_h = self._offset
            if covered[1]:
                if off_h is None and not self._was_covered[1]:
                    off_h = float(wrap_angle(dead_h - smooth_h))
                off_h = None if off_h is None else float(np.sign(off_h) * max(0.0, abs(off_h) - self._catch_up[1]))
                h = smooth_h + (off_h or 0.0)
                off_h = off_h or None
            else:
                h, off_h = dead_h, None
            if covered[0]:
                if off_g is None and not self._was_covered[0]:
                    off_g = dead_g - smooth_g
                if off_g is not None:
                    d = abs(off_g)
                    off_g = off_g * max(0.0, d - self._catch_up[0]) / d if d > 0 else 0j
                g = smooth_g + (off_g or 0j)
                off_g = off_g or None
            else:
                g, off_g = dead_g, None
            self._offset = (off_g, off_h)
        self._was_covered = covered
        self._out, self._path = (g, h), (path_g, path_h)
        return g, h


def fuse_track(fusion: RootFusion, fps: float, position_m: np.ndarray | None, heading_rad: np.ndarray | None,
               path_ground_m: np.ndarray, path_heading_rad: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A whole take at once (a batch search): fixes (T, 2) / (T,) with NaN where missing (None: no camera),
    the chosen path's track (T, 2) / (T,) -> the output root (T, 2) / (T,)."""
    n = len(path_heading_rad)
    fuser = RootFuser(fusion, fps)
    for t in range(n):
        fuser.push(None if position_m is None else position_m[t], None if heading_rad is None else heading_rad[t])
    return fuser.decide(path_ground_m, path_heading_rad)

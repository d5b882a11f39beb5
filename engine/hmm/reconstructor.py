"""Streaming reconstruction from one (or two) IMUs with the hierarchical HMM (spec B2.4-B2.5).

Per frame: the forward algorithm over the last W frames (uniform start, so wrong hypotheses recover fast)
gives the phase posterior; in the winning phase the K segment chains that best explain the frames since the
phase was entered are interpolated (weights = softmax of their forward log-likelihoods), and the output is the
posterior-weighted Gaussian conditional mean over the phase's frames. Phase switches are hidden by
inertialisation (the previous velocity carried forward, decaying with a smoothstep over `blend_frames`).
"""
from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass

import numpy as np

from engine.hmm.features import IMU_CHANNELS, channel_set, stack_imu
from engine.olng.channels import tilt_from_device_earth
from engine.hmm.forward import chain_forward, forward
from engine.hmm.model import HierarchicalHMM, conditional_mean


@dataclass(frozen=True)
class HMMFrame:
    body: np.ndarray     # (dx,) reconstructed body features
    phase: int           # index into model.phases
    progress: float      # expected frame within the phase
    compute_s: float     # wall time of this push


class HMMReconstructor:
    def __init__(self, model: HierarchicalHMM) -> None:
        self.model = model
        cfg = model.config
        self._log_b: deque[np.ndarray] = deque(maxlen=cfg.window)
        self._imu_z: deque[np.ndarray | None] = deque(maxlen=cfg.window)   # None = dropped frame
        self._phase = -1
        self._since_entry = 0
        self._history: list[np.ndarray] = []
        self._blend_offset: np.ndarray | None = None
        self._blend_step = 0
        self._uniform = np.full(model.n_states, 1.0 / model.n_states)
        self._alpha: np.ndarray | None = None
        self.dropped_frames = 0   # frames whose IMU sample was missing (NaN)
        if model.config.forward_mode not in {"window", "recursive"}:
            raise ValueError(f"forward_mode must be 'window' or 'recursive', not {model.config.forward_mode!r}")

    def _emission(self, y_z: np.ndarray) -> np.ndarray:
        d = self.model.state_imu_z - y_z
        return -0.5 * np.einsum("sk,sk->s", d, d) / self.model.config.sigma**2

    def posterior(self) -> np.ndarray:
        """Forward variable over all template states: from a uniform start over the last W frames (window mode),
        or one recursive step from the previous frame's alpha floored towards uniform (recursive mode)."""
        cfg = self.model.config
        if cfg.forward_mode == "window" or self._alpha is None:
            frames = np.stack(self._log_b) if cfg.forward_mode == "window" else self._log_b[-1][None]
            alpha, _ = forward(frames, self.model.transitions, self._uniform)
        else:
            prior = self.model.transitions.T @ ((1.0 - cfg.epsilon) * self._alpha + cfg.epsilon * self._uniform)
            alpha, _ = forward(self._log_b[-1][None], self.model.transitions, prior)
        self._alpha = alpha
        return alpha

    def push(self, acc_g: np.ndarray, gyro_rps: np.ndarray | None = None,
             quat_wxyz: np.ndarray | None = None) -> HMMFrame:
        """One IMU frame: acc (S, 3) g, gyro (S, 3) rad/s and orientation (S, 4) sensor -> device earth (Z up,
        any yaw: only the tilt is used) in the model's IMU order; channels the model was not trained on
        (``config.imu_channels``) are ignored and may be None. A NaN channel is a dropped frame."""
        t0 = time.perf_counter()
        m, cfg = self.model, self.model.config
        use_gyro, use_tilt = channel_set(cfg.imu_channels)
        if (use_gyro and gyro_rps is None) or (use_tilt and quat_wxyz is None):
            raise ValueError(f"this model was trained on {cfg.imu_channels}: give "
                             f"{'gyro_rps' if use_gyro and gyro_rps is None else 'quat_wxyz'}")
        acc = np.asarray(acc_g, float)
        tilt = tilt_from_device_earth(np.asarray(quat_wxyz, float).reshape(len(acc), 4)) if use_tilt else None
        y = stack_imu(acc[None], np.asarray(gyro_rps, float)[None] if use_gyro else None,
                      None if tilt is None else tilt[None])[0]
        if y.shape != m.imu_mean.shape:
            width = IMU_CHANNELS[cfg.imu_channels]
            raise ValueError(f"expected {m.imu_mean.shape[0] // width} IMU(s) of {cfg.imu_channels}, "
                             f"got {y.shape[0] // width}")
        dropped = not np.all(np.isfinite(y))
        y_z = m.zscore(y)
        # sensor drop-out (paper §6): no evidence, so the chains keep moving on their transitions alone
        self._log_b.append(np.zeros(m.n_states) if dropped else self._emission(y_z))
        self._imu_z.append(None if dropped else y_z)
        self.dropped_frames += dropped
        alpha = self.posterior()
        mass = np.add.reduceat(alpha, m.offsets[:-1])
        phase = int(np.argmax(mass))
        switched = phase != self._phase and self._phase >= 0
        self._since_entry = 1 if phase != self._phase else self._since_entry + 1
        self._phase = phase
        pm = m.phases[phase]
        progress = alpha[m.offsets[phase]: m.offsets[phase + 1]]
        progress = progress / progress.sum()

        # reactive interpolation: score each segment chain of the phase on the frames since entry
        recent = list(self._imu_z)[-self._since_entry:]
        log_b = np.zeros((len(recent),) + pm.seg_imu.shape[:2])                            # (T, H, L)
        seen = [i for i, r in enumerate(recent) if r is not None]
        if seen:
            diff = pm.seg_imu[None] - np.stack([recent[i] for i in seen])[:, None, None, :]
            log_b[seen] = -0.5 * np.einsum("thlk,thlk->thl", diff, diff) / cfg.sigma**2
        _, loglik = chain_forward(log_b, cfg.p_self, cfg.p_next, cfg.p_skip)
        k = min(cfg.k_interpolate, len(loglik))
        top = np.argsort(loglik)[::-1][:k]
        weights = np.exp(loglik[top] - loglik[top].max())
        weights /= weights.sum()
        mean_body = np.einsum("k,kld->ld", weights, pm.seg_body[top])
        mean_imu = np.einsum("k,kld->ld", weights, pm.seg_imu[top])
        per_state = mean_body if dropped else conditional_mean(mean_body, mean_imu, pm.gain, y_z)
        if cfg.output == "argmax":
            body = per_state[int(np.argmax(progress))]
        else:
            body = progress @ per_state
        body = self._blend(body, switched)
        self._history = (self._history + [body])[-2:]
        return HMMFrame(body=body, phase=phase, progress=float(progress @ np.arange(len(progress))),
                        compute_s=time.perf_counter() - t0)

    def _blend(self, body: np.ndarray, switched: bool) -> np.ndarray:
        """Inertialisation: at a phase switch, start from where the previous output was heading and decay the
        offset to the new estimate with a smoothstep (Levine et al. style velocity blending)."""
        n = self.model.config.blend_frames
        if switched and len(self._history) == 2 and n > 0:
            predicted = 2 * self._history[-1] - self._history[-2]
            self._blend_offset = predicted - body
            self._blend_step = 0
        if self._blend_offset is None:
            return body
        self._blend_step += 1
        s = min(self._blend_step / n, 1.0)
        out = body + self._blend_offset * (1.0 - (3 * s * s - 2 * s * s * s))
        if s >= 1.0:
            self._blend_offset = None
        return out

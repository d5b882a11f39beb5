"""Online multi-subject marker labeling (paper 001, Yu, Li & Deng 2007), one unlabelled point cloud per frame.

Per frame: predict every label with its Kalman filter; gate observed points (Mahalanobis ≤ γ, K nearest);
fit every rigid body by exhaustive search of Eq. 5; commit bodies greedily best-score-first across all subjects,
removing committed points from the others' candidates and re-searching those (Algorithm 1); recover missing
markers from their body's observed markers (§3.3); update the Kalman filters and the sliding-window distance
model, from truly observed markers only.

Why it beats closest-point tracking: each body is scored against the learned distance model, not against the
previous frame's labels, so one wrong frame does not propagate and a swap between people breaks the within-body
distances and scores low.

Internally labels are reordered so that each rigid body is a contiguous run; the public API uses the caller's
label order throughout.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass
from itertools import combinations, permutations

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.spatial import cKDTree

from engine.mocap.rotations import best_rotation

from .config import LabelingConfig
from .kalman import KalmanBank
from .reacquire import reacquire_body
from .search import search_body
from .structure import DistanceWindow, choose_cluster_tau, cluster_rigid_bodies, pair_distances

OBSERVED, RECOVERED, LOST = 0, 1, 2


@dataclass
class FrameLabels:
    """One frame's result, in the caller's label order.

    label_point (L,): index of the observed point given to each label, −1 if none.
    point_label (m,): label index of each observed point, −1 for points left unlabelled (ghosts/noise).
    positions_m (L,3): observed position, or the recovered one, or the Kalman prediction when lost.
    status (L,): OBSERVED, RECOVERED or LOST.
    mean_candidates: average number of gated candidates per label this frame (paper: 2-4)."""

    label_point: np.ndarray
    point_label: np.ndarray
    positions_m: np.ndarray
    status: np.ndarray
    mean_candidates: float


def _kabsch(src: np.ndarray, dst: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation R and translation t minimising |R src + t − dst| (rows are points)."""
    cs, cd = src.mean(0), dst.mean(0)
    rot = best_rotation(src - cs, dst - cd)
    return rot, cd - rot @ cs


class OnlineLabeler:
    """Learns the structure and motion models from labelled training frames, then labels frames one at a time."""

    def __init__(self, config: LabelingConfig = LabelingConfig()):
        self.config = config
        self.bodies: list[np.ndarray] = []  # rigid bodies as arrays of caller label indices

    # ---------------------------------------------------------------- training
    def train(
        self,
        training_m: np.ndarray,
        subjects: np.ndarray,
        fps: float,
        bodies: list[np.ndarray] | None = None,
    ) -> None:
        """Learn from labelled frames (T0, L, 3) in metres (NaN = missing); subjects (L,) subject id per label.

        bodies: optional user-supplied rigid-body partition (the paper's validation override)."""
        cfg = self.config
        training_m = np.asarray(training_m, dtype=float)
        subjects = np.asarray(subjects)
        n_frames, n_labels = training_m.shape[:2]
        if n_frames < 3:
            raise ValueError(f"training needs at least 3 labelled frames, got {n_frames}")
        if len(subjects) != n_labels:
            raise ValueError(f"{len(subjects)} subject ids for {n_labels} labels")
        self.n_labels, self.dt = n_labels, 1.0 / fps
        if bodies is None:
            dist = pair_distances(training_m)
            bodies = []
            for s in np.unique(subjects):
                members = np.flatnonzero(subjects == s)
                pair = dist[:, members][:, :, members]
                with np.errstate(invalid="ignore"), warnings.catch_warnings():
                    warnings.simplefilter("ignore", RuntimeWarning)  # pairs never seen together stay NaN
                    std = np.nanstd(pair, axis=0) + cfg.cluster_proximity * np.nanmean(pair, axis=0)
                tau = cfg.cluster_tau_m
                if cfg.cluster_tau_max_m > tau:
                    taus = np.geomspace(tau, cfg.cluster_tau_max_m, 12)
                    tau = choose_cluster_tau(std, taus, cfg.min_body, cfg.max_body)
                bodies += [members[g] for g in cluster_rigid_bodies(std, tau, cfg.min_body, cfg.max_body)]
        self._set_bodies([np.asarray(b) for b in bodies])
        order = self._order
        train = training_m[:, order]

        # Motion models: per-marker process noise from training accelerations, then warm up over the frames.
        acc = (train[2:] - 2 * train[1:-1] + train[:-2]) / self.dt**2
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # labels seen in < 3 consecutive frames: no estimate
            acc_std = np.sqrt(np.nanmean(np.nanvar(acc, axis=0), axis=1))
        acc_std = np.nan_to_num(acc_std, nan=0.0) * cfg.accel_std_scale
        accel_var = np.maximum(acc_std, cfg.accel_std_floor_mps2) ** 2
        # A label missing from some training frames starts where it is first seen and is held at its last seen
        # position (velocity zeroed) while missing; a label never seen in training cannot be learned: it stays
        # out of gating and re-acquisition (it is reported LOST) and starts at its subject's mean position.
        seen_any = ~np.isnan(train).any(axis=2)  # (T0, L)
        self.trained = seen_any.any(axis=0)
        first_seen = np.argmax(seen_any, axis=0)
        first = train[first_seen, np.arange(n_labels)]
        subject_mean = {s: np.nanmean(training_m[:, subjects == s], axis=(0, 1)) for s in np.unique(subjects)}
        for i in np.flatnonzero(~self.trained):
            first[i] = np.nan_to_num(subject_mean[subjects[order[i]]])
        self.kf = KalmanBank(first, np.zeros_like(first), accel_var, cfg.meas_noise_m, self.dt)
        for t in range(1, n_frames):
            self.kf.predict()
            seen = np.flatnonzero(seen_any[t] & (t > first_seen))
            self.kf.update(seen, train[t, seen])
            self.kf.vel[~seen_any[t]] = 0.0
        self._learn_neighbours(train, subjects[order])
        self._reliable = seen_any[-1].copy()  # observed in the previous frame: its prediction can anchor others
        self._recovered_frames = np.zeros(n_labels, int)
        self._max_recovered = max(int(round(cfg.max_recovered_s * fps)), 1)

        # Structure model and recovery state, from the training frames.
        self.window = DistanceWindow(len(self.bodies), self._n_max, cfg.window_frames, cfg.sigma_min_m)
        self._disp = np.full((len(self.bodies), self._n_max, self._n_max, 3), np.nan)
        self._template = np.full((len(self.bodies), self._n_max, 3), np.nan)
        self._template_age = np.zeros(len(self.bodies), int)  # frames since the body was last complete
        for t in range(max(0, n_frames - cfg.window_frames), n_frames):
            self._update_structure(train[t], ~np.isnan(train[t]).any(axis=1))
        self._train_template = self._template.copy()
        self._rigid_tol = np.zeros(len(self.bodies))  # 95th-percentile rigid-fit RMS of each body in training
        for b in range(len(self.bodies)):
            rows = self._pad[b, : self._sizes[b]]
            if np.isnan(self._train_template[b, : self._sizes[b]]).all():  # never complete in the window
                self._train_template[b, : self._sizes[b]] = _last_seen_positions(train[:, rows])
            tmpl = self._train_template[b, : self._sizes[b]]
            known = ~np.isnan(tmpl).any(axis=1)
            frames = train[:, rows][:, known]
            full = ~np.isnan(frames).any(axis=(1, 2))
            if known.sum() >= 3 and full.any():
                self._rigid_tol[b] = np.percentile([_rigid_rms(tmpl[known], f) for f in frames[full][::5]], 95)

    def _learn_neighbours(self, train: np.ndarray, subjects: np.ndarray) -> None:
        """Per label, up to max_neighbours markers of the same subject in *other* bodies whose training distance
        to it varied least (std ≤ neighbour_std_m): markers across one joint. Their (D, A) are fixed."""
        cfg = self.config
        with np.errstate(invalid="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            dist = pair_distances(train)
            mean, std = np.nanmean(dist, axis=0), np.nanstd(dist, axis=0)
        eligible = (subjects[:, None] == subjects[None, :]) & (self._body_of[:, None] != self._body_of[None, :])
        eligible &= np.isfinite(std) & (std <= cfg.neighbour_std_m)
        ranked = np.argsort(np.where(eligible, std, np.inf), axis=1)[:, : cfg.max_neighbours]
        ok = np.take_along_axis(eligible, ranked, axis=1)
        self._nb = np.where(ok, ranked, -1)
        self._nb_mean = np.where(ok, np.take_along_axis(mean, ranked, axis=1), np.nan)
        self._nb_std = np.maximum(np.where(ok, np.take_along_axis(std, ranked, axis=1), np.nan),
                                  cfg.neighbour_sigma_min_m)

    def _unary(self, labels: np.ndarray, option_pos: np.ndarray) -> tuple[np.ndarray, int]:
        """Neighbour link terms of each option (n, K) of ``labels`` against the predicted positions of their
        neighbours that were observed last frame, and the number of such links (see search_body)."""
        nb = self._nb[labels]
        valid = (nb >= 0) & self._reliable[np.maximum(nb, 0)]
        if not valid.any():
            return np.zeros(option_pos.shape[:2]), 0
        anchor = self.kf.pos[np.maximum(nb, 0)]  # (n, J, 3)
        d = np.linalg.norm(option_pos[:, :, None, :] - anchor[:, None, :, :], axis=-1)  # (n, K, J)
        with np.errstate(invalid="ignore"):
            z = (d - self._nb_mean[labels][:, None, :]) / self._nb_std[labels][:, None, :]
            terms = np.where(valid[:, None, :], np.nan_to_num(np.exp(-0.5 * z * z), nan=0.0), 0.0)
        return terms.sum(axis=2), int(valid.sum())

    def _prior(self, labels: np.ndarray, option_pos: np.ndarray, neighbours: bool = True) -> tuple[np.ndarray, float]:
        """Terms that join Eq. 5 in the body search (search_body's ``unary``): neighbour links (see _unary; only
        in the second-chance pass, whose wide gate can offer the other hand's points — in Algorithm 1 they
        raised swaps between the two tennis players tenfold where their arms interleave) plus
        motion_weight · exp(−½ Mahalanobis²) of each option against its label's Kalman prediction.

        Why the motion term: when a marker hides, its gate may hold a body-mate's point (toe and fifth metatarsal
        are 5 cm apart), and Eq. 5 alone scores "toe takes it" and "metatarsal keeps it" alike on a body that is
        not quite rigid. The first swap then persists and the window learns it. The prediction breaks the tie."""
        terms, count = self._unary(labels, option_pos) if neighbours else (np.zeros(option_pos.shape[:2]), 0)
        weight = self.config.motion_weight
        if weight <= 0:
            return terms, float(count)
        diff = option_pos - self.kf.pos[labels][:, None, :]
        with np.errstate(invalid="ignore"):
            m2 = np.einsum("nki,nki->nk", diff, diff) / self.kf.innovation_var()[labels][:, None]
        return terms + weight * np.nan_to_num(np.exp(-0.5 * m2), nan=0.0), count + weight * len(labels)

    def _set_bodies(self, bodies: list[np.ndarray]) -> None:
        labels = np.concatenate(bodies)
        if len(labels) != self.n_labels or len(np.unique(labels)) != self.n_labels:
            raise ValueError("rigid bodies must partition the labels: every label in exactly one body")
        self.bodies = bodies
        self._order = labels  # internal index → caller label
        sizes = np.array([len(b) for b in bodies])
        self._starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
        self._sizes = sizes
        self._n_max = int(sizes.max())
        self._pad = np.full((len(bodies), self._n_max), -1)  # internal label index per body slot, −1 padding
        for b, (start, size) in enumerate(zip(self._starts, sizes)):
            self._pad[b, :size] = np.arange(start, start + size)
        self._body_of = np.repeat(np.arange(len(bodies)), sizes)

    def _padded(self, per_label: np.ndarray) -> np.ndarray:
        """Internal per-label float array (L, ...) → per-body padded (B, n_max, ...), NaN in the padding."""
        ext = np.concatenate([per_label, np.full((1,) + per_label.shape[1:], np.nan)])
        return ext[self._pad]

    def _update_structure(self, pos: np.ndarray, observed: np.ndarray) -> None:
        """Window distances, offset vectors and complete-body templates from observed markers (internal order)."""
        obs_pos = np.where(observed[:, None], pos, np.nan)
        body_pos = self._padded(obs_pos)  # (B, n_max, 3)
        self.window.push(pair_distances(body_pos))
        disp = body_pos[:, None, :, :] - body_pos[:, :, None, :]  # disp[b, k, m] = M_m − M_k
        both = ~np.isnan(disp).any(axis=-1)
        self._disp[both] = disp[both]
        untrained = self._padded(np.where(self.trained, 0.0, 1.0)[:, None])[..., 0] == 1.0
        complete = (~np.isnan(body_pos).any(axis=-1) | (self._pad < 0) | untrained).all(axis=1)
        self._template[complete] = body_pos[complete]
        self._template_age = np.where(complete, 0, self._template_age + 1)

    # ---------------------------------------------------------------- online step
    def step(self, points_m: np.ndarray) -> FrameLabels:
        """Label one frame's unordered points (m, 3) metres. Returns labels in the caller's order."""
        cfg = self.config
        points = np.asarray(points_m, dtype=float).reshape(-1, 3)
        finite = np.flatnonzero(np.isfinite(points).all(axis=1))  # NaN rows (missing) are never candidates
        n_points = len(points)
        self.kf.predict()
        pred, s_var = self.kf.pos, self.kf.innovation_var()

        # Gating: K nearest points, kept if |p − ẑ|²/S ≤ γ (isotropic S, see kalman.py).
        cand = np.full((self.n_labels, cfg.max_candidates), -1)
        k = min(cfg.max_candidates, len(finite))
        if k:
            dist, idx = cKDTree(points[finite]).query(pred, k=k)
            dist, idx = dist.reshape(self.n_labels, k), idx.reshape(self.n_labels, k)
            ok = dist * dist <= cfg.gate_chi2 * s_var[:, None]
            cand[:, :k] = np.where(ok, finite[np.minimum(idx, len(finite) - 1)], -1)
            cand[~self.trained] = -1
        mean_candidates = float((cand >= 0).sum() / self.n_labels)
        ext_points = np.vstack([points, np.full((1, 3), np.nan)])

        # Algorithm 1: greedy best-body-first over all subjects' bodies.
        mean, std = self.window.stats()
        n_bodies = len(self.bodies)
        best_pid = [np.empty(0, int)] * n_bodies
        best_score = np.full(n_bodies, -np.inf)
        need = np.ones(n_bodies, bool)
        open_ = np.ones(n_bodies, bool)
        assigned = np.full(self.n_labels, -1)
        used = np.zeros(n_points + 1, bool)  # last slot: the −1 "no candidate" sentinel, never used
        while open_.any():
            for b in np.flatnonzero(open_ & need):
                sl, n = slice(self._starts[b], self._starts[b] + self._sizes[b]), self._sizes[b]
                pos_b = ext_points[cand[sl]]
                pid, score, _ = search_body(cand[sl], pos_b, mean[b, :n, :n], std[b, :n, :n], cfg.max_combinations,
                                            self._prior(np.arange(sl.start, sl.stop), pos_b, neighbours=False))
                best_pid[b], best_score[b], need[b] = pid, score, False
            b = int(np.flatnonzero(open_)[np.argmax(best_score[open_])])
            open_[b] = False
            sl = slice(self._starts[b], self._starts[b] + self._sizes[b])
            assigned[sl] = best_pid[b]
            taken = best_pid[b][best_pid[b] >= 0]
            if len(taken) == 0:
                continue
            used[taken] = True
            hit = used[cand] & (cand >= 0)  # (L, K): candidates now taken by a committed body
            hit_label = hit.any(axis=1) & open_[self._body_of]
            if hit_label.any():
                rows = np.flatnonzero(hit_label)
                cand[rows] = _valid_first(np.where(hit[rows], -1, cand[rows]))
                # Exact shortcut: removing candidates a body's best assignment does not use leaves that
                # assignment optimal, so only bodies whose best used a taken point are searched again.
                for r in np.unique(self._body_of[rows]):
                    need[r] = bool(used[best_pid[r]].any())

        self._second_chance(points, finite, assigned, used, best_score, mean, std)
        if cfg.shape_reacquire:
            self._reacquire_by_shape(points, finite, assigned, mean, std)
        self._orient_reentering_bodies(points, assigned)
        if cfg.repair_swaps:
            self._repair_swaps(points, assigned)
        return self._finish(points, assigned, mean_candidates)

    def _repair_swaps(self, points: np.ndarray, assigned: np.ndarray) -> None:
        """Undo swaps inside a body by its training template (rigid fit + one-to-one nearest, i.e. Hungarian).

        Why: a swap between body-mates (a hidden toe taking the metatarsal's point) passes Eq. 5 on a body that
        is not quite rigid; the Kalman gates then follow the swapped points and the sliding window learns the
        swapped distances, so nothing in the paper's loop ever undoes it. The training template is known to be
        correctly labelled. When a body fits it worse than it ever did in training (RMS above repair_tol_scale x
        its training 95th percentile), a body with three labelled markers tries the other permutations of its
        points; a larger one has the template fitted rigidly to its points on all of them and,
        since the swapped ones pull that fit off, on every subset leaving two out (one for a 4-marker body);
        each fit gives every point to the label whose template position lands nearest; the best relabelling is
        kept if its RMS is below repair_ratio x the current one. Modifies ``assigned``."""
        cfg = self.config
        for b in range(len(self.bodies)):
            sl, n = slice(self._starts[b], self._starts[b] + self._sizes[b]), self._sizes[b]
            current = assigned[sl]
            tmpl = self._train_template[b, :n]
            known = ~np.isnan(tmpl).any(axis=1)
            usable = np.flatnonzero((current >= 0) & known)
            if len(usable) < 3:
                continue
            pts = points[current[usable]]
            old_rms = _rigid_rms(tmpl[usable], pts)
            if old_rms < max(cfg.repair_min_rms_m, cfg.repair_tol_scale * self._rigid_tol[b]):
                continue  # fits as well as in training: nothing to repair (the common case, one SVD)
            best, best_rms = None, cfg.repair_ratio * old_rms
            if len(usable) == 3:  # three points: no subset to fit on, so try their 5 other permutations
                for perm in permutations(range(len(usable))):
                    if list(perm) == list(range(len(usable))):
                        continue
                    rms = _rigid_rms(tmpl[usable], pts[list(perm)])
                    if rms < best_rms:
                        best, best_rms = current.copy(), rms
                        best[usable] = current[usable][list(perm)]
                if best is not None:
                    assigned[sl] = best
                continue
            rows = np.flatnonzero(known)
            drop = min(len(usable) - 3, 2)  # leave out up to two markers (one of four), keeping three to fit
            subsets = [np.arange(len(usable))]
            subsets += [np.delete(np.arange(len(usable)), out) for out in combinations(range(len(usable)), drop)]
            for subset in subsets:
                rot, shift = _kabsch(tmpl[usable[subset]], pts[subset])
                cost = np.linalg.norm((tmpl[rows] @ rot.T + shift)[:, None] - pts[None], axis=2)
                r, c = linear_sum_assignment(cost)
                proposal = current.copy()
                proposal[usable] = -1
                proposal[rows[r]] = current[usable][c]
                if np.array_equal(proposal, current):
                    continue
                use = np.flatnonzero((proposal >= 0) & known)
                rms = _rigid_rms(tmpl[use], points[proposal[use]])
                if rms < best_rms:
                    best, best_rms = proposal, rms
            if best is not None:
                assigned[sl] = best

    def _orient_reentering_bodies(self, points: np.ndarray, assigned: np.ndarray) -> None:
        """Undo a mirrored or flipped re-acquisition of a symmetric body by its last complete pose.

        Why: pair distances, the only thing Eq. 5 and the shape search score, are blind to mirror images and to
        the symmetries of a body (a head's four markers form a near-planar rectangle: left/right swapped is the
        same rectangle turned upside down). A body that comes back after a loss is gated around stale
        predictions, so nothing picks the right one of those twins, and a head re-acquired mirrored stayed
        mirrored for the rest of the take (cmu_135_02, --degrade 2). For a body coming back (< 3 markers observed
        last frame, ≥ 3 now, complete within the last second), its points are relabelled one-to-one (Hungarian)
        against its last complete configuration moved by translation only. The relabelling is kept only when it
        is a twin of the current labels (proper rigid fits within repair_min_rms_m of each other) and the
        current labels imply the body turned by more than 120° while the relabelling implies less than 60°.
        Shape alone is not trusted to decide: on the tennis serve the trunk changes shape as the arm rises, and
        a relabelling that merely fitted the older template better flipped a correctly labelled trunk.
        Modifies ``assigned``."""
        cfg = self.config
        for b in range(len(self.bodies)):
            sl, n = slice(self._starts[b], self._starts[b] + self._sizes[b]), self._sizes[b]
            if self._reliable[sl].sum() >= 3 or self._template_age[b] * self.dt > cfg.reentry_max_age_s:
                continue
            current, tmpl = assigned[sl], self._template[b, :n]
            usable = np.flatnonzero((current >= 0) & ~np.isnan(tmpl).any(axis=1))
            if len(usable) < 3:
                continue
            src, pts = tmpl[usable], points[current[usable]]
            cost = np.square((src - src.mean(0))[:, None] - (pts - pts.mean(0))[None]).sum(axis=2)
            _, perm = linear_sum_assignment(cost)
            if np.array_equal(perm, np.arange(len(usable))):
                continue
            (old_turn, old_rms), (new_turn, new_rms) = _turn_and_rms(src, pts), _turn_and_rms(src, pts[perm])
            twin = abs(new_rms - old_rms) <= cfg.repair_min_rms_m
            if twin and old_turn > cfg.reentry_turn_rad and new_turn < cfg.reentry_settled_rad:
                assigned[sl.start + usable] = current[usable][perm]

    def _reacquire_by_shape(self, points: np.ndarray, finite: np.ndarray, assigned: np.ndarray, mean: np.ndarray,
                            std: np.ndarray) -> None:
        """Give missing labels leftover points that fit their body's shape, wherever the filters predict them.

        Bodies are tried most-labelled first (their anchors make the match the least ambiguous). A label found
        this way restarts its Kalman filter at the point: the old state is what lost it. Modifies ``assigned``."""
        cfg = self.config
        free = np.ones(len(points), bool)
        free[assigned[assigned >= 0]] = False
        leftover = finite[free[finite]]
        missing = (assigned < 0) & self.trained
        if len(leftover) == 0 or not missing.any():
            return
        bodies = np.unique(self._body_of[missing])
        labelled_count = np.array([np.sum(assigned[self._pad[b, : self._sizes[b]]] >= 0) for b in bodies])
        std_shape = np.maximum(std, cfg.shape_sigma_min_m)
        restart = []
        for b in bodies[np.argsort(-labelled_count, kind="stable")]:
            if len(leftover) == 0:
                break
            sl, n = slice(self._starts[b], self._starts[b] + self._sizes[b]), self._sizes[b]
            body_pos = np.full((n, 3), np.nan)
            have = assigned[sl] >= 0
            body_pos[have] = points[assigned[sl][have]]
            pick = reacquire_body(points[leftover], body_pos, mean[b, :n, :n], std_shape[b, :n, :n],
                                  cfg.shape_min_support)
            if have.sum() == 1:
                # One labelled marker carries no shape evidence: after a loss a stale gate hands it another
                # marker's point (cmu_135_02: RSHO took CLAV's), and anchored on it the rest is never found. So
                # the body is also searched from scratch with that point back in the pool; a search finding 4 or
                # more markers, more than the anchored one, wins (3 points match some body by chance: along an
                # arm the upper-arm triangle was found in forearm points, cmu_85_02 --degrade 1).
                lone = sl.start + int(np.flatnonzero(have)[0])
                pool = np.append(leftover, assigned[lone])
                alone = reacquire_body(points[pool], np.full((n, 3), np.nan), mean[b, :n, :n],
                                       std_shape[b, :n, :n], cfg.shape_min_support)
                found = int(np.sum(alone >= 0))
                if found >= 4 and found > np.sum(pick >= 0) + 1:
                    assigned[lone], leftover, pick = -1, pool, alone
            pick[~self.trained[sl]] = -1
            got = np.flatnonzero(pick >= 0)
            if len(got):  # a shape twin (the other hand) fits the body's own links: its neighbours must agree too
                labels = self._starts[b] + got
                terms, _ = self._unary(labels, points[leftover[pick[got]]][:, None, :])
                nb = self._nb[labels]
                n_links = ((nb >= 0) & self._reliable[np.maximum(nb, 0)]).sum(axis=1)
                bad = (n_links > 0) & (terms[:, 0] < cfg.neighbour_min_support * n_links)
                pick[got[bad]] = -1
                got = got[~bad]
            if len(got) == 0:
                continue
            assigned[self._starts[b] + got] = leftover[pick[got]]
            restart.extend(self._starts[b] + got)
            leftover = np.delete(leftover, pick[got])
        if restart:
            self.kf.restart(np.asarray(restart), points[assigned[restart]])

    def _second_chance(
        self,
        points: np.ndarray,
        finite: np.ndarray,
        assigned: np.ndarray,
        used: np.ndarray,
        best_score: np.ndarray,
        mean: np.ndarray,
        std: np.ndarray,
    ) -> None:
        """Re-acquire missing labels from the points no body took, with a wider gate (a deviation from paper 001).

        Why: when a fast limb leaves every marker's gate at once (a 50 Hz tennis serve), the whole body is
        missing, its Kalman filters coast, and the paper's loop never offers it the right points again. After
        Algorithm 1 the leftover points are few (that limb's markers plus ghosts), so each body with missing labels
        is searched once more with its observed labels fixed and its missing labels offered the leftovers within
        reacquire_gate_scale·γ; the new assignment is kept only if it scores higher. Modifies ``assigned``."""
        cfg = self.config
        leftover = finite[~used[finite]]
        missing = (assigned < 0) & self.trained
        if len(leftover) == 0 or not missing.any():
            return
        k = min(cfg.max_candidates, len(leftover))
        dist, idx = cKDTree(points[leftover]).query(self.kf.pos[missing], k=k)
        dist, idx = dist.reshape(-1, k), idx.reshape(-1, k)
        m2 = dist * dist / self.kf.innovation_var()[missing, None]
        ok = m2 <= cfg.reacquire_gate_scale * cfg.gate_chi2
        # Competitive gate: in the wide gate a point is offered only to the missing label whose prediction it is
        # nearest to (Mahalanobis), else a hidden toe takes its visible neighbour's point and the swap persists.
        pid = np.where(ok, leftover[np.minimum(idx, len(leftover) - 1)], -1)
        nearest = np.full(len(points), np.inf)
        np.minimum.at(nearest, pid[ok], m2[ok])
        ok &= m2 <= nearest[np.maximum(pid, 0)]
        cand = np.full((self.n_labels, cfg.max_candidates), -1)
        cand[missing, :k] = _valid_first(np.where(ok, pid, -1))
        cand[~missing, 0] = assigned[~missing]
        ext_points = np.vstack([points, np.full((1, 3), np.nan)])
        taken = np.zeros(len(points) + 1, bool)
        for b in np.unique(self._body_of[missing & (cand[:, 0] >= 0)]):
            sl, n = slice(self._starts[b], self._starts[b] + self._sizes[b]), self._sizes[b]
            body_cand = _valid_first(np.where(taken[cand[sl]], -1, cand[sl]))
            pos_b = ext_points[body_cand]
            pid, score, _ = search_body(body_cand, pos_b, mean[b, :n, :n], std[b, :n, :n], cfg.max_combinations,
                                        self._prior(np.arange(sl.start, sl.stop), pos_b))
            if score <= best_score[b]:
                continue
            new = np.flatnonzero((pid >= 0) & (assigned[sl] < 0))
            support = _link_support(points, pid, new, mean[b, :n, :n], std[b, :n, :n])
            pid[new[support < cfg.reacquire_min_support]] = -1  # a re-acquired point must fit its body
            assigned[sl] = pid
            taken[pid[pid >= 0]] = True

    def _finish(self, points: np.ndarray, assigned: np.ndarray, mean_candidates: float) -> FrameLabels:
        """Recovery of missing markers, model updates, and the result in caller order."""
        cfg = self.config
        observed = assigned >= 0
        pos = np.full((self.n_labels, 3), np.nan)
        pos[observed] = points[assigned[observed]]
        status = np.where(observed, OBSERVED, LOST)
        recovered = self._recover(pos, observed)
        rec = ~np.isnan(recovered).any(axis=1) & ~observed
        self._recovered_frames = np.where(rec, self._recovered_frames + 1, 0)
        rec &= self._recovered_frames <= self._max_recovered  # a long-recovered marker counts as lost
        pos[rec] = recovered[rec]
        status[rec] = RECOVERED

        self.kf.update(np.flatnonzero(observed), pos[observed])
        self.kf.update(np.flatnonzero(rec), pos[rec], cfg.recovered_noise_scale)
        lost = status == LOST
        self.kf.vel[lost] = 0.0
        pos[lost] = self.kf.pos[lost]
        self._update_structure(pos, observed)
        self._reliable = observed

        label_point = np.full(self.n_labels, -1)
        label_point[self._order] = assigned
        point_label = np.full(len(points), -1)
        point_label[assigned[observed]] = self._order[observed]
        out_pos = np.empty_like(pos)
        out_pos[self._order] = pos
        out_status = np.empty_like(status)
        out_status[self._order] = status
        return FrameLabels(label_point, point_label, out_pos, out_status, mean_candidates)

    def _recover(self, pos: np.ndarray, observed: np.ndarray) -> np.ndarray:
        """Positions of unobserved labels from their body's observed markers (internal order; NaN if not possible).

        offsets (paper §3.3): mean over observed k of M_k + d_{k→m}, d from the last frame both were seen.
        kabsch: rigid fit of the body's last complete configuration to its observed markers (needs ≥ 3)."""
        cfg = self.config
        body_pos = self._padded(np.where(observed[:, None], pos, np.nan))  # (B, n_max, 3)
        obs = ~np.isnan(body_pos).any(axis=-1)
        # offsets: est[b, m] = mean_k (M_k + disp[b, k, m]) over observed k with a known offset
        est = body_pos[:, :, None, :] + self._disp  # (B, k, m, 3)
        usable = ~np.isnan(est).any(axis=-1)
        count = usable.sum(axis=1)  # (B, m)
        with np.errstate(invalid="ignore"):
            offsets = np.nansum(np.where(usable[..., None], est, 0.0), axis=1) / count[..., None]
        n_obs = obs.sum(axis=1)
        ok = (count >= 1) & (n_obs[:, None] >= cfg.min_observed_for_recovery) & ~obs
        result = np.where(ok[..., None], offsets, np.nan)
        if cfg.recovery == "kabsch":
            for b in np.flatnonzero((n_obs >= 3) & (n_obs < self._sizes)):
                tmpl, seen = self._template[b], obs[b]
                if np.isnan(tmpl[: self._sizes[b]]).any():
                    continue
                rot, shift = _kabsch(tmpl[seen], body_pos[b, seen])
                miss = ~seen & (self._pad[b] >= 0)
                result[b, miss] = tmpl[miss] @ rot.T + shift
        out = np.full((self.n_labels, 3), np.nan)
        valid = self._pad >= 0
        out[self._pad[valid]] = result[valid]
        return out


def _turn_and_rms(src: np.ndarray, dst: np.ndarray) -> tuple[float, float]:
    """Rotation angle (rad) and RMS distance of the best rigid fit of src onto dst (paired rows)."""
    rot, shift = _kabsch(src, dst)
    angle = float(np.arccos(np.clip((np.trace(rot) - 1.0) / 2.0, -1.0, 1.0)))
    return angle, float(np.sqrt(np.mean(np.sum((src @ rot.T + shift - dst) ** 2, axis=1))))


def _rigid_rms(src: np.ndarray, dst: np.ndarray) -> float:
    """RMS distance after the best rigid fit of src onto dst (paired rows)."""
    return _turn_and_rms(src, dst)[1]


def _link_support(points: np.ndarray, pid: np.ndarray, which: np.ndarray, mean: np.ndarray, std: np.ndarray) -> np.ndarray:
    """Mean Eq. 5 link term of each marker in ``which`` with the body's other assigned markers (0 if none)."""
    others = np.flatnonzero(pid >= 0)
    if len(which) == 0 or len(others) < 2:
        return np.zeros(len(which))
    d = np.linalg.norm(points[pid[which]][:, None] - points[pid[others]][None], axis=2)
    z = (d - mean[np.ix_(which, others)]) / std[np.ix_(which, others)]
    is_other = others[None] != which[:, None]
    terms = np.where(is_other, np.nan_to_num(np.exp(-0.5 * z * z), nan=0.0), 0.0)
    return terms.sum(axis=1) / np.maximum(is_other.sum(axis=1), 1)


def _last_seen_positions(frames: np.ndarray) -> np.ndarray:
    """(T, n, 3) → (n, 3): each marker's position in the last frame where the whole set of markers seen in that
    frame is largest; markers not seen there are NaN (a template must be one rigid configuration)."""
    seen = ~np.isnan(frames).any(axis=2)
    best = len(frames) - 1 - int(np.argmax(seen.sum(axis=1)[::-1]))
    return frames[best].copy()


def _valid_first(rows: np.ndarray) -> np.ndarray:
    """Move the −1 entries of each row to the end, keeping the order (nearest first) of the valid ones."""
    order = np.argsort(rows < 0, axis=1, kind="stable")
    return np.take_along_axis(rows, order, axis=1)

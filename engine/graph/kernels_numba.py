"""Compiled (numba) passes of one Viterbi search step; `viterbi.ViterbiLattice` calls them. `kernels_numpy` has
the same functions with the same signatures (the lattice picks one module when it is built).

Per step, in this order (the numpy reference, `kernels_numpy`, computes the same numbers with whole-array ops):

1. `node_terms`: per node, cos/sin of the path's heading (`trig32`) and the source-side parts of the position
   and heading costs, u = R(-O)(P - M) and wrap(O - M_h) -- contiguous, vectorised;
2. `runs_fold`: the edges of the long diagonal runs (`edge_runs.EdgeRuns`): cost, best-so-far per destination
   and (with global state) the best edge's new ground position and heading (eq. 5), over contiguous slices (a
   run's metadata rows are consecutive too, so even its accelerometer costs are a slice of `acc_rows`' output)
   -- SIMD without gathers, which is where the speed comes from;
3. `scattered_fold`: the remaining edges: their costs in one pass with gathers, then the minimum per
   destination in search order, and the new state of destinations a scattered edge won.

Measured per step on the 483k-edge Bandai graph (acc + position + heading): see bench/bench_viterbi.py.
The state is float32 (Px, Pz, O) with cos/sin of O recomputed per step: with the earlier five-array state
(cos/sin carried by rotation) the fused run loop touched ~20 arrays, which defeated LLVM's vectoriser (too many
run-time alias checks) and measured 2-4x slower than separate passes.

Everything is float32 and written operation for operation as the reference computes it (numba does not contract
a*b + c into an fma without fastmath; error_model="numpy" gives inf/nan instead of raising), so the compiled and
numpy searches give bit-identical costs, states and paths (tests/engine/graph/test_kernels.py).
"""
from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit

from .trig32 import cos_sin

PI32 = np.float32(np.pi)
TWO_PI32 = np.float32(2.0 * np.pi)
ROW_CHUNK = 1024  # metadata rows per cache-resident chunk in acc_rows


@njit(cache=True, nogil=True, error_model="numpy")
def acc_rows(meta_acc_t, meta_acc_sq, m32, mm32, scale32, out):
    """W_A C_A per metadata row for B samples at once: ((sum_i E_i m_i) * -2 + ||E||^2 + ||m||^2) * W_A / S in
    float32, summed in sensor-axis order (= the reference's row-axpys, so the rows are bit-identical whether a
    sample comes alone or in a batch). meta_acc_t: (3S, M) float32; m32: (B, 3S); mm32: (B,); out: (B, M).
    The (3S, M) metadata (27 MB on the 483k-edge graph) is read once per batch, chunk by chunk; the running sum
    goes through memory once per sensor (three axes per loop body), not once per axis: 2.3x faster."""
    k, n = meta_acc_t.shape
    for r0 in range(0, n, ROW_CHUNK):  # slices (not 2-D indexing) so the inner loops vectorise
        r1 = min(n, r0 + ROW_CHUNK)
        w = r1 - r0
        sq = meta_acc_sq[r0:r1]
        for b in range(m32.shape[0]):
            o = out[b, r0:r1]
            for a in range(0, k, 3):
                x, y, z = meta_acc_t[a, r0:r1], meta_acc_t[a + 1, r0:r1], meta_acc_t[a + 2, r0:r1]
                mx, my, mz = m32[b, a], m32[b, a + 1], m32[b, a + 2]
                if a == 0:
                    for j in range(w):
                        o[j] = (x[j] * mx + y[j] * my) + z[j] * mz
                else:
                    for j in range(w):
                        o[j] = ((o[j] + x[j] * mx) + y[j] * my) + z[j] * mz
            mm = mm32[b]
            sc = scale32[b]
            for j in range(w):
                o[j] = ((o[j] * np.float32(-2.0) + sq[j]) + mm) * sc


@njit(inline="always")
def _wrap(h):
    """An angle in [-3pi, 3pi) into [-pi, pi] (one 2pi step each way is all the callers need)."""
    h = h - TWO_PI32 if h > PI32 else h
    return h + TWO_PI32 if h < -PI32 else h


_cos_sin = njit(inline="always")(cos_sin)


@njit(cache=True, nogil=True, error_model="numpy")
def node_terms(Px, Pz, O, mx, mz, mh, C, Sn, ux, uz, th):
    """Per node: (C, Sn) = (cos O, sin O); (ux, uz) = R(-O)(P - M), the path's offset from the camera fix in
    its own heading frame; th = wrap(O - M_h). M = (mx, mz) m, M_h in [-pi, pi] rad, all float32."""
    for i in range(len(Px)):
        c, s = _cos_sin(O[i])
        C[i] = c
        Sn[i] = s
        ax = Px[i] - mx
        az = Pz[i] - mz
        ux[i] = ax * c - az * s
        uz[i] = ax * s + az * c
        th[i] = _wrap(O[i] - mh)


@njit(inline="always")
def _edge_cost(g, ra, ux, uz, th, dx, dz, dh, wp, wh):
    """G(src) + W_A C_A + W_P |u + d| + W_O |wrap(th + dh)| in float32, in the reference's order."""
    x = ux + dx
    y = uz + dz
    c = (g + ra) + np.sqrt(x * x + y * y) * wp
    h = abs(th + dh)
    h = min(h, TWO_PI32 - h)
    return c + h * wh


@njit(inline="always")
def _advance(px, pz, o, c, s, dx, dz, dh):
    """Eq. 5 for one edge: P + R(O) d and O + dh (wrapped); c, s = cos O, sin O."""
    return px + (dx * c + dz * s), pz + (dz * c - dx * s), _wrap(o + dh)


@njit(cache=True, nogil=True, error_model="numpy")
def runs_fold(run_src0, run_dst0, run_edge0, run_row0, run_len, rows, G, ux, uz, th, Px, Pz, O, C, Sn, dx, dz, dh,
              wp, wh, use_terms, track, best, win, nPx, nPz, nO):
    """Fold the run edges into the per-destination best cost / winning search index (strict <: ties keep the
    earlier edge) and, if `track`, into the new global state (eq. 5 of the best run edge so far; a scattered
    winner overwrites it later). A run's accelerometer costs are rows[row0:row0 + n]. Without position/heading
    terms the cost is G(src) + W_A C_A alone. (The branches are loop-invariant: LLVM unswitches them.)"""
    for r in range(len(run_len)):
        s0, d0, e0, n = run_src0[r], run_dst0[r], run_edge0[r], run_len[r]
        b_ = best[d0:d0 + n]  # slices, so the loop below vectorises
        w_ = win[d0:d0 + n]
        g_ = G[s0:s0 + n]
        ra_ = rows[run_row0[r]:run_row0[r] + n]
        ux_, uz_, th_ = ux[s0:s0 + n], uz[s0:s0 + n], th[s0:s0 + n]
        px_, pz_, o_, c_, sn_ = Px[s0:s0 + n], Pz[s0:s0 + n], O[s0:s0 + n], C[s0:s0 + n], Sn[s0:s0 + n]
        dx_, dz_, dh_ = dx[e0:e0 + n], dz[e0:e0 + n], dh[e0:e0 + n]
        npx, npz, no = nPx[d0:d0 + n], nPz[d0:d0 + n], nO[d0:d0 + n]
        for i in range(n):
            if use_terms:
                c = _edge_cost(g_[i], ra_[i], ux_[i], uz_[i], th_[i], dx_[i], dz_[i], dh_[i], wp, wh)
            else:
                c = g_[i] + ra_[i]
            lt = c < b_[i]
            b_[i] = c if lt else b_[i]
            w_[i] = np.int32(e0 + i) if lt else w_[i]
            if track:
                a, b, o = _advance(px_[i], pz_[i], o_[i], c_[i], sn_[i], dx_[i], dz_[i], dh_[i])
                npx[i] = a if lt else npx[i]
                npz[i] = b if lt else npz[i]
                no[i] = o if lt else no[i]


@njit(cache=True, nogil=True, error_model="numpy")
def scattered_fold(sc_nodes, sc_indptr, src, row, rows, G, ux, uz, th, Px, Pz, O, C, Sn, dx, dz, dh, wp, wh,
                   use_terms, track, best, win, nPx, nPz, nO, cost):
    """Fold the scattered edges (after the runs, in search order) into best / win: every edge's cost in one
    vectorised pass (gathers; edge e's accelerometer cost is rows[row[e]]), then the minimum per destination,
    and (if `track`) the new global state where a scattered edge won."""
    first = sc_indptr[0]
    m = len(src) - first
    s_ = src[first:]
    r_ = row[first:]
    if use_terms:
        dx_, dz_, dh_ = dx[first:], dz[first:], dh[first:]
        for i in range(m):
            s = s_[i]
            cost[i] = _edge_cost(G[s], rows[r_[i]], ux[s], uz[s], th[s], dx_[i], dz_[i], dh_[i], wp, wh)
    else:
        for i in range(m):
            cost[i] = G[s_[i]] + rows[r_[i]]
    for j in range(len(sc_nodes)):
        n = sc_nodes[j]
        b = best[n]
        w = win[n]
        for e in range(sc_indptr[j], sc_indptr[j + 1]):
            c = cost[e - first]
            lt = c < b
            b = c if lt else b
            w = np.int32(e) if lt else w
        best[n] = b
        win[n] = w
        if track and w >= first:
            s = src[w]
            nPx[n], nPz[n], nO[n] = _advance(Px[s], Pz[s], O[s], C[s], Sn[s], dx[w], dz[w], dh[w])


@njit(cache=True, nogil=True)
def survivor_column(col_nodes, col_edges, full, alive, src, mark):
    """One column of survivor-path pruning: the arriving edge (search index) of each node in `alive` (sorted)
    -- col_edges[alive] for a full column, else a merge with the column's sorted `col_nodes` (alive is a subset)
    -- and the distinct sources of those edges, ascending (the alive set one column earlier). `mark` is an
    all-False (N,) scratch array, left all-False."""
    k = len(alive)
    kept = np.empty(k, dtype=np.int32)
    if full:
        for i in range(k):
            kept[i] = col_edges[alive[i]]
    else:
        j = 0
        for i in range(k):
            while col_nodes[j] < alive[i]:
                j += 1
            kept[i] = col_edges[j]
    found = np.empty(k, dtype=np.int64)
    m = 0
    for i in range(k):
        s = src[kept[i]]
        if not mark[s]:
            mark[s] = True
            found[m] = s
            m += 1
    if m * 32 > len(mark):  # many: one scan of the marks gives them sorted
        out = np.empty(m, dtype=np.int64)
        j = 0
        for s in range(len(mark)):
            if mark[s]:
                out[j] = s
                j += 1
                mark[s] = False
        return kept, out
    for i in range(m):
        mark[found[i]] = False
    return kept, np.sort(found[:m])


@njit(cache=True, nogil=True, error_model="numpy")
def warp_state(Px, Pz, O, mx, mz, mh, gp, maxp, gh, maxh):
    """Root warping (engine/graph/warp.py), in place for every node: move the path's ground position towards the
    camera fix (mx, mz) by gp x the distance, at most maxp metres, and turn its heading towards mh by gh x the
    wrapped difference, at most maxh radians. gp = 0 / gh = 0 leave a component untouched. float32, in the order
    of kernels_numpy.warp_state."""
    for i in range(len(Px)):
        ex = mx - Px[i]
        ez = mz - Pz[i]
        d = np.sqrt(ex * ex + ez * ez)
        s = min(d * gp, maxp)
        k = s / d if d > np.float32(0.0) else np.float32(0.0)
        Px[i] = Px[i] + ex * k
        Pz[i] = Pz[i] + ez * k
        c = _wrap(mh - O[i]) * gh
        c = max(-maxh, min(c, maxh))
        O[i] = _wrap(O[i] + c)


def fold(lat: Any, rows, ra, terms, wp, wh, best, win) -> None:
    """Best cost and winning search index per node -- runs (SIMD), then the scattered edges -- and, with global
    state, the winners' new position/heading into the lattice's spare state. The accelerometer costs come by
    metadata row from `rows`, or by search index from `ra` if constraints have masked it."""
    r = lat.runs
    ux, uz, th = lat._terms[2:] if lat.track_global else (lat._none32,) * 3
    use = terms is not None
    if ra is None:
        table, run_row0, row = rows, r.run_meta0, lat._meta32
    else:
        table, run_row0, row = ra, r.run_edge0, lat._search_index32
    now = (*lat._state, *lat._terms[:2]) if lat.track_global else (lat._none32,) * 5  # Px, Pz, O, C, Sn
    new = lat._spare_state if lat.track_global else (lat._none32,) * 3
    edge = (lat._dx, lat._dz, lat._dh)
    runs_fold(r.run_src0, r.run_dst0, r.run_edge0, run_row0, r.run_len, table, lat._G, ux, uz, th, *now,
              *edge, wp, wh, use, lat.track_global, best, win, *new)
    scattered_fold(r.sc_nodes, r.sc_indptr, lat._src32, row, table, lat._G, ux, uz, th, *now, *edge,
                   wp, wh, use, lat.track_global, best, win, *new, lat._sc_cost)

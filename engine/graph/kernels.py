"""Compiled (numba) per-sample kernels of the Viterbi search; `viterbi.ViterbiLattice` calls them.

One search step in numpy is ~20 whole-array passes, most of them gathers through the edge index arrays (per
step on a 483k-edge graph: C_A rows 2 ms, edge costs 7 ms, min/argmin 2 ms, per-node state update 4 ms). Here
a step is four compiled passes without temporaries: per-node position/heading terms, branch-free edge costs
(vectorised), the per-node min/argmin (selects, no branches) fused with the winners' state update; batch search
computes the C_A rows of 16 samples per pass over the (3S, M) metadata. Measured per step (483k edges, acc +
position + heading): argmin + update ~4 ms, edge costs ~2.5 ms, C_A rows ~0.6 ms batched (2 ms alone).

The arithmetic is the numpy reference's, operation for operation and in the same precision, so the two give
bit-identical costs, states and paths (tests/engine/graph/test_kernels.py checks it): float32 edge costs added
in the same order, float64 heading wrap, complex products as numpy's SIMD loops compute them
(re = fma(ar, br, -(ai bi)), im = fma(ar, bi, ai br)) and |z| of a complex64 as numpy does
(large sqrt(fma(r, r, 1)), r = small/large). numba never contracts a*b + c into an fma on its own (no fastmath),
so every other expression rounds like numpy's separate ufuncs; error_model="numpy": x / 0 gives inf/nan (then
selected away), as in numpy, instead of raising.
"""
from __future__ import annotations

import numpy as np
from numba import njit
from numba.extending import intrinsic

TWO_PI = 2.0 * np.pi


@intrinsic
def _fma(typingctx, a, b, c):
    """a * b + c with one rounding (LLVM llvm.fma), operands of one float type."""
    def codegen(context, builder, sig, args):
        return builder.fma(*args)
    return a(a, a, a), codegen


@njit(inline="always")
def _cmul(a, b):
    """Complex product rounded as numpy's SIMD complex multiply."""
    ar, ai, br, bi = a.real, a.imag, b.real, b.imag
    return complex(_fma(ar, br, -(ai * bi)), _fma(ar, bi, ai * br))


ROW_CHUNK = 1024  # metadata rows per cache-resident chunk in acc_rows


@njit(cache=True, nogil=True, error_model="numpy")
def acc_rows(meta_acc_t, meta_acc_sq, m32, mm32, scale32, out):
    """W_A C_A per metadata row for B samples at once: ((sum_i E_i m_i) * -2 + ||E||^2 + ||m||^2) * W_A / S in
    float32, summed in sensor-axis order (= the reference's row-axpys, so the rows are bit-identical whether a
    sample comes alone or in a batch). meta_acc_t: (3S, M) float32; m32: (B, 3S); mm32: (B,); out: (B, M).
    The (3S, M) metadata (27 MB on the 483k-edge graph) is read once per batch, chunk by chunk, not per sample."""
    k, n = meta_acc_t.shape
    acc = np.empty(ROW_CHUNK, dtype=np.float32)
    for r0 in range(0, n, ROW_CHUNK):  # slices (not 2-D indexing) so the inner loops vectorise
        r1 = min(n, r0 + ROW_CHUNK)
        w = r1 - r0
        sq = meta_acc_sq[r0:r1]
        for b in range(m32.shape[0]):
            row = meta_acc_t[0, r0:r1]
            m0 = m32[b, 0]
            for j in range(w):
                acc[j] = row[j] * m0
            for i in range(1, k):
                row = meta_acc_t[i, r0:r1]
                mi = m32[b, i]
                for j in range(w):
                    acc[j] = acc[j] + row[j] * mi
            o = out[b, r0:r1]
            mm = mm32[b]
            sc = scale32[b]
            for j in range(w):
                o[j] = ((acc[j] * np.float32(-2.0) + sq[j]) + mm) * sc


@njit(cache=True, nogil=True, error_model="numpy")
def node_terms(P, rot, mpos, O, mhead, use_pos, use_head, u32, hd32):
    """Per node: u = complex64(R(-O)(P - M)) (the position term in the source's frame) and
    hd = float32(wrap(O - M_h)); zeros for a term not in use (so the edge loop adds exactly 0 for it)."""
    for i in range(len(u32)):
        if use_pos:
            a = P[i] - mpos
            u32[i] = np.complex64(_cmul(a, complex(rot[i].real, -rot[i].imag)))
        else:
            u32[i] = 0
        if use_head:
            h = O[i] - mhead
            h = h - TWO_PI * np.rint(h / TWO_PI)
            hd32[i] = np.float32(h)
        else:
            hd32[i] = 0


@njit(cache=True, nogil=True, error_model="numpy")
def edge_costs_acc(src, meta, G, rows, cost):
    """Accelerometer-only edge costs: G[src] + rows[meta]."""
    for e in range(len(src)):
        cost[e] = G[src[e]] + rows[meta[e]]


@njit(cache=True, nogil=True, error_model="numpy")
def edge_costs_global(src, meta, d32, dh32, G, rows, u32, hd32, wp32, wh32, cost):
    """Edge costs with position and heading: G[s] + rows[meta] + W_P |u[s] + d| + W_O min(|h|, 2pi - |h|),
    h = hd[s] + dh. Branch-free so it vectorises; a weight of 0 with a zero node term adds exactly +0 (the
    reference skips the term: same bits), a weight of 1 multiplies exactly (the reference skips the multiply)."""
    two_pi32 = np.float32(TWO_PI)
    one = np.float32(1.0)
    for e in range(len(src)):
        s = src[e]
        c = G[s] + rows[meta[e]]
        z = u32[s]
        dz = d32[e]
        x = abs(z.real + dz.real)
        y = abs(z.imag + dz.imag)
        large = max(x, y)
        small = min(x, y)
        r = small / large
        r = np.float32(0.0) if large == 0 else r
        c = c + (np.sqrt(_fma(r, r, one)) * large) * wp32
        h = abs(hd32[s] + dh32[e])
        h = min(h, two_pi32 - h)
        cost[e] = c + h * wh32


@njit(cache=True, nogil=True, error_model="numpy")
def mask_constraints(b_off, b_deg, b_cnt, b_node0, src, Gr, grmin, cost):
    """Eq. 8: only edges whose source has the fewest broken constraints among a node's sources compete."""
    for b in range(len(b_off)):
        off, deg, cnt, n0 = b_off[b], b_deg[b], b_cnt[b], b_node0[b]
        for j in range(cnt):
            grmin[n0 + j] = Gr[src[off + j]]
        for k in range(1, deg):
            base = off + k * cnt
            for j in range(cnt):
                g = Gr[src[base + j]]
                if g < grmin[n0 + j]:
                    grmin[n0 + j] = g
        for k in range(deg):
            base = off + k * cnt
            for j in range(cnt):
                if Gr[src[base + j]] > grmin[n0 + j]:
                    cost[base + j] = np.inf


@njit(cache=True, nogil=True, error_model="numpy")
def argmin_update(b_off, b_deg, b_cnt, b_node0, cost, src, edge_id, d, dh, rot_dh, P, O, rot, track,
                  Gr, constrained, G_new, P_new, O_new, rot_new, Gr_new, win, col):
    """Per node (layout order) the cheapest incoming edge, ties to the lowest slot (= the reference's strict-<
    row scan and first-index argmin); then the winners' new state: G_new, eq. 5 for P/O/rot (if track), the
    source's Gr (if constrained), col = graph edge ids."""
    for b in range(len(b_off)):
        off, deg, cnt, n0 = b_off[b], b_deg[b], b_cnt[b], b_node0[b]
        for j in range(cnt):
            G_new[n0 + j] = cost[off + j]
            win[n0 + j] = off + j
        gb = G_new[n0:n0 + cnt]  # slices + selects (no branches): the compare loop vectorises
        wb = win[n0:n0 + cnt]
        for k in range(1, deg):
            base = off + k * cnt
            cb = cost[base:base + cnt]
            for j in range(cnt):
                c = cb[j]
                cur = gb[j]
                lt = c < cur
                gb[j] = c if lt else cur
                wb[j] = base + j if lt else wb[j]
    for n in range(len(col)):
        e = win[n]
        s = src[e]
        col[n] = edge_id[e]
        if constrained:
            Gr_new[n] = Gr[s]
        if track:
            r = rot[s]
            P_new[n] = P[s] + _cmul(d[e], r)
            O_new[n] = O[s] + dh[e]
            rot_new[n] = _cmul(r, rot_dh[e])

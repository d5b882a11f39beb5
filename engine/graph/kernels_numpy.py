"""The numpy reference of one Viterbi search step: the same functions, with the same signatures, as the
compiled `kernels_numba` — `viterbi.ViterbiLattice` picks one of the two modules when it is built and calls it
without asking again. Whole-array float32 operations in the order the compiled loops use, so the two give
bit-identical costs, states and paths (tests/engine/graph/test_kernels.py); this one needs no compiler (the
headless gateway install has no numba) and is the one to read."""
from __future__ import annotations

from typing import Any

import numpy as np

from .trig32 import cos_sin

PI32 = np.float32(np.pi)
TWO_PI32 = np.float32(2.0 * np.pi)


def wrap32(h: np.ndarray) -> np.ndarray:
    """float32 angles in [-3pi, 3pi) into [-pi, pi] by one 2pi step (as kernels_numba._wrap)."""
    h = np.where(h > PI32, h - TWO_PI32, h)
    return np.where(h < -PI32, h + TWO_PI32, h)


def acc_rows(meta_acc_t, meta_acc_sq, m32, mm32, scale32, out) -> None:
    """W_A C_A per metadata row for B samples (kernels_numba.acc_rows): per sample, 3S row-axpys over the
    transposed float32 metadata, then ((. * -2 + ||E||^2) + ||m||^2) * W_A / S."""
    tmp = np.empty(meta_acc_t.shape[1], dtype=np.float32)
    for b in range(len(m32)):
        dots = out[b]
        np.multiply(meta_acc_t[0], m32[b, 0], out=dots)
        for i in range(1, m32.shape[1]):
            np.multiply(meta_acc_t[i], m32[b, i], out=tmp)
            dots += tmp
        dots *= np.float32(-2.0)
        dots += meta_acc_sq
        dots += mm32[b]
        dots *= scale32[b]


def node_terms(Px, Pz, O, mx, mz, mh, C, Sn, ux, uz, th) -> None:
    """Per node (kernels_numba.node_terms): C, Sn = cos O, sin O; (ux, uz) = R(-O)(P - M); th = wrap(O - M_h)."""
    C[:], Sn[:] = cos_sin(O)
    ax, az = Px - mx, Pz - mz
    np.subtract(ax * C, az * Sn, out=ux)
    np.add(ax * Sn, az * C, out=uz)
    th[:] = wrap32(O - mh)


def warp_state(Px, Pz, O, mx, mz, mh, gp, maxp, gh, maxh) -> None:
    """Root warping of every path (kernels_numba.warp_state), in place."""
    ex = mx - Px
    ez = mz - Pz
    d = np.sqrt(ex * ex + ez * ez)
    step = np.minimum(d * gp, maxp)
    k = np.zeros_like(d)
    np.divide(step, d, out=k, where=d > np.float32(0.0))
    Px[:] = Px + ex * k
    Pz[:] = Pz + ez * k
    c = wrap32(mh - O) * gh
    c = np.maximum(-maxh, np.minimum(c, maxh))
    O[:] = wrap32(O + c)


def survivor_column(col_nodes, col_edges, full, alive, src, mark) -> tuple[np.ndarray, np.ndarray]:
    """One column of survivor-path pruning (kernels_numba.survivor_column): the arriving edge of each node in
    `alive` and the distinct sources of those edges, ascending."""
    idx = alive if full else np.searchsorted(col_nodes, alive)
    edges = col_edges[idx].astype(np.int32)
    mark[src[edges]] = True
    sources = np.flatnonzero(mark)  # sorted and distinct (np.unique's hashing was 20x slower)
    mark[sources] = False
    return edges, sources


def fold(lat: Any, rows, ra, terms, wp, wh, best, win) -> None:
    """Best cost and winning search index per node into `best`/`win`: every edge's cost in whole-array float32
    ops (the order of kernels_numba._edge_cost; ``ra`` = the per-edge accelerometer costs, from ``rows`` if not
    given), then one comparison per rank layer, so ties go to the lowest search index as in the compiled passes;
    with global state, eq. 5 of every node's winning edge into the lattice's spare state."""
    src, cost = lat._src, lat._cost
    ra = lat._edge_rows(rows) if ra is None else ra
    np.take(lat._G, src, out=cost)
    cost += ra
    if terms is not None:
        ux, uz, th = terms
        x = ux[src] + lat._dx
        y = uz[src] + lat._dz
        cost += np.sqrt(x * x + y * y) * wp
        h = np.abs(th[src] + lat._dh)
        cost += np.minimum(h, TWO_PI32 - h) * wh
    for idx, d in lat.runs.layers:
        c = cost[idx]
        lt = c < best[d]
        best[d] = np.where(lt, c, best[d])
        win[d] = np.where(lt, idx, win[d])
    if lat.track_global:
        _advance(lat, win, lat._spare_state)


def _advance(lat: Any, win, new_state) -> None:
    """Eq. 5 for every node's winning edge into `new_state` (nodes nothing reached keep stale values), in the
    order of kernels_numba._advance."""
    nodes = np.flatnonzero(win >= 0)
    e = win[nodes]
    s = lat._src[e]
    Px, Pz, O, C, Sn = (a[s] for a in (*lat._state, *lat._terms[:2]))
    dx, dz, dh = (a[e] for a in (lat._dx, lat._dz, lat._dh))
    nPx, nPz, nO = new_state
    nPx[nodes] = Px + (dx * C + dz * Sn)
    nPz[nodes] = Pz + (dz * C - dx * Sn)
    nO[nodes] = wrap32(O + dh)

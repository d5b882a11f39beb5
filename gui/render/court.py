"""Tennis court line geometry (ITF dimensions) in the court frame, as ground-plane segments.

Court frame (docs/CONTRACTS.md): origin at the court centre, x along the net, y towards the far baseline,
metres. Engine world: (X, Z) = (court x, court y). Shared by the 3-D view and the camera/minimap overlays."""
from __future__ import annotations

import numpy as np

COURT_LENGTH_M = 23.77
DOUBLES_WIDTH_M = 10.97
SINGLES_WIDTH_M = 8.23
SERVICE_LINE_FROM_NET_M = 6.40
CENTRE_MARK_M = 0.10
LINE_WIDTH_M = 0.05
NET_HEIGHT_M = 0.914


def court_line_segments() -> np.ndarray:
    """All court lines as (N, 2, 2) segments ``[[x0, y0], [x1, y1]]`` in court metres."""
    hl, hd, hs, sv = COURT_LENGTH_M / 2, DOUBLES_WIDTH_M / 2, SINGLES_WIDTH_M / 2, SERVICE_LINE_FROM_NET_M
    segs = [
        [[-hd, -hl], [hd, -hl]], [[-hd, hl], [hd, hl]],            # baselines
        [[-hd, -hl], [-hd, hl]], [[hd, -hl], [hd, hl]],            # doubles sidelines
        [[-hs, -hl], [-hs, hl]], [[hs, -hl], [hs, hl]],            # singles sidelines
        [[-hs, -sv], [hs, -sv]], [[-hs, sv], [hs, sv]],            # service lines
        [[0.0, -sv], [0.0, sv]],                                   # centre service line
        [[0.0, -hl], [0.0, -hl + CENTRE_MARK_M]], [[0.0, hl], [0.0, hl - CENTRE_MARK_M]],  # centre marks
    ]
    return np.array(segs, dtype=float)


def net_segment() -> np.ndarray:
    """The net line (posts 0.914 m outside the doubles sidelines), court metres, shape (2, 2)."""
    hp = DOUBLES_WIDTH_M / 2 + 0.914
    return np.array([[-hp, 0.0], [hp, 0.0]])


def segments_to_quads(segments: np.ndarray, width_m: float = LINE_WIDTH_M) -> np.ndarray:
    """Thicken (N,2,2) segments into two triangles each: returns (N*6, 2) vertices (vectorised)."""
    a, b = segments[:, 0], segments[:, 1]
    d = b - a
    n = np.c_[-d[:, 1], d[:, 0]] / np.linalg.norm(d, axis=1, keepdims=True) * (width_m / 2)
    p0, p1, p2, p3 = a - n, a + n, b + n, b - n
    return np.stack([p0, p1, p2, p0, p2, p3], axis=1).reshape(-1, 2)

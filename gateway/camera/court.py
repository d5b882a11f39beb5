"""ITF tennis-court model in the court frame (metres).

Court frame (docs/CONTRACTS.md): origin at the court centre on the ground, ``x`` along the net, ``y`` towards the
far baseline, ``z`` up. "near" means ``y < 0``, "left" means ``x < 0``.

Why a table of named keypoints: the console's calibration wizard asks the operator to click named line
intersections, and the homography fit pairs clicks with these metric coordinates by name.
"""
from __future__ import annotations

import numpy as np

COURT_LENGTH_M = 23.77
DOUBLES_WIDTH_M = 10.97
SINGLES_WIDTH_M = 8.23
SERVICE_LINE_FROM_NET_M = 6.40
CENTRE_MARK_LENGTH_M = 0.10
LINE_WIDTH_M = 0.05

HALF_LENGTH_M = COURT_LENGTH_M / 2.0
HALF_DOUBLES_M = DOUBLES_WIDTH_M / 2.0
HALF_SINGLES_M = SINGLES_WIDTH_M / 2.0


def _build_lines() -> dict[str, np.ndarray]:
    lines: dict[str, np.ndarray] = {}
    for side, sy in (("near", -1.0), ("far", 1.0)):
        lines[f"{side}_baseline"] = np.array([[-HALF_DOUBLES_M, sy * HALF_LENGTH_M], [HALF_DOUBLES_M, sy * HALF_LENGTH_M]])
        lines[f"{side}_service_line"] = np.array(
            [[-HALF_SINGLES_M, sy * SERVICE_LINE_FROM_NET_M], [HALF_SINGLES_M, sy * SERVICE_LINE_FROM_NET_M]]
        )
        lines[f"{side}_centre_mark"] = np.array(
            [[0.0, sy * HALF_LENGTH_M], [0.0, sy * (HALF_LENGTH_M - CENTRE_MARK_LENGTH_M)]]
        )
    for hand, sx in (("left", -1.0), ("right", 1.0)):
        for kind, half_width in (("doubles", HALF_DOUBLES_M), ("singles", HALF_SINGLES_M)):
            x = sx * half_width
            lines[f"{hand}_{kind}_sideline"] = np.array([[x, -HALF_LENGTH_M], [x, HALF_LENGTH_M]])
    lines["centre_service_line"] = np.array([[0.0, -SERVICE_LINE_FROM_NET_M], [0.0, SERVICE_LINE_FROM_NET_M]])
    return lines


def _build_keypoints() -> dict[str, tuple[float, float]]:
    points: dict[str, tuple[float, float]] = {}
    for side, sy in (("near", -1.0), ("far", 1.0)):
        for hand, sx in (("left", -1.0), ("right", 1.0)):
            points[f"{side}_baseline_{hand}_doubles"] = (sx * HALF_DOUBLES_M, sy * HALF_LENGTH_M)
            points[f"{side}_baseline_{hand}_singles"] = (sx * HALF_SINGLES_M, sy * HALF_LENGTH_M)
            points[f"{side}_service_{hand}_singles"] = (sx * HALF_SINGLES_M, sy * SERVICE_LINE_FROM_NET_M)
        points[f"{side}_service_centre"] = (0.0, sy * SERVICE_LINE_FROM_NET_M)
        points[f"{side}_baseline_centre"] = (0.0, sy * HALF_LENGTH_M)
    return points


#: Painted lines as (2, 2) arrays of endpoints ``[[x0, y0], [x1, y1]]`` in metres (line centre lines).
COURT_LINES_M: dict[str, np.ndarray] = _build_lines()
#: All 16 line intersections / T-junctions an operator can click, in metres.
COURT_KEYPOINTS_M: dict[str, tuple[float, float]] = _build_keypoints()


def keypoints_array(names: list[str] | tuple[str, ...]) -> np.ndarray:
    """Court coordinates (N, 2) m of the named keypoints; KeyError names the unknown one."""
    try:
        return np.array([COURT_KEYPOINTS_M[name] for name in names], dtype=float)
    except KeyError as exc:
        raise KeyError(f"unknown court keypoint {exc.args[0]!r}; known: {sorted(COURT_KEYPOINTS_M)}") from None


def court_outline_m(margin_m: float = 0.0) -> np.ndarray:
    """Corners (4, 2) m of the doubles court grown by ``margin_m`` (the region where a player is tracked)."""
    hx, hy = HALF_DOUBLES_M + margin_m, HALF_LENGTH_M + margin_m
    return np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]], dtype=float)


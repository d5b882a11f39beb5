"""The printed tables: one line per row, mean over every frame of every take, with the mean-pose skill."""
from __future__ import annotations

import numpy as np

from .metrics import per_second, summary
from .protocols import CAMERA_ON, Row, RowScores

HEADER = (f"{'engine':<34}{'sensors':>7} {'camera':<10}{'global cm':>10}{'root-rel cm':>12}{'skill':>7}"
          f"{'pos cm':>8}{'head deg':>9}{'worst s cm':>11}{'clips':>6}{'1-clip s':>9}{'run s':>7}{'BVH rr cm':>10}")


def skill_reference(results: dict[Row, RowScores]) -> float:
    """Root-relative error of the mean pose (placement does not change it), the skill's denominator."""
    for row, scores in results.items():
        if row.engine == "mean pose" and row.camera == CAMERA_ON:
            return summary(scores.errors)["root_relative_cm"]
    return float("nan")


def format_rows(results: dict[Row, RowScores], fps: float, prefix: str = "") -> list[str]:
    """Lines of the table body. BVH rr = the root-relative error of the BVH written from the same decided poses
    and read back (engines that decide rotations; '-' for the others); skill = 1 - root-relative error / the mean
    pose's; worst s = the worst
    one-second global joint error of any take; clips / 1-clip s = distinct database clips played and the
    longest stretch from one clip (mean over takes), for engines that play database frames."""
    ref = skill_reference(results)
    lines = []
    for row, scores in results.items():
        s = summary(scores.errors)
        worst = max(per_second(e.global_cm, fps).max() for e in scores.errors)
        used = np.mean(scores.clips_used) if any(scores.clips_used) else float("nan")
        longest = np.nanmean(scores.longest_run_s) if any(scores.clips_used) else float("nan")
        clips = f"{used:6.1f}" if np.isfinite(used) else f"{'-':>6}"
        run = f"{longest:9.1f}" if np.isfinite(longest) else f"{'-':>9}"
        bvh = f"{summary(scores.exported)['root_relative_cm']:10.2f}" if scores.exported else f"{'-':>10}"
        lines.append(f"{prefix + row.engine:<34}{row.sensors:>7} {row.camera:<10}{s['global_cm']:10.1f}"
                     f"{s['root_relative_cm']:12.2f}{1 - s['root_relative_cm'] / ref:7.2f}{s['position_cm']:8.1f}"
                     f"{s['heading_deg']:9.1f}{worst:11.1f}{clips}{run}{scores.seconds:7.1f}{bvh}")
    return lines


def format_table(results: dict[Row, RowScores], fps: float) -> str:
    return "\n".join([HEADER, "-" * len(HEADER), *format_rows(results, fps)])


def oracle_fractions(results: dict[Row, RowScores]) -> list[str]:
    """Per row with the camera: which fraction of the database oracle's gain over the mean pose (root-relative)
    it gets, and how far it is from the oracle (issue 18's "within 1.5 cm of the oracle")."""
    from .protocols import ORACLE

    ref = skill_reference(results)
    oracle = _find(results, ORACLE, "-", CAMERA_ON)
    if oracle is None or not np.isfinite(ref):
        return []
    gain = ref - oracle["root_relative_cm"]
    lines = [f"database oracle root-relative {oracle['root_relative_cm']:.1f} cm (mean pose {ref:.1f} cm): "
             "fraction of its gain per row, and the distance to it"]
    for row, scores in results.items():
        if row.camera != CAMERA_ON or row.engine in (ORACLE, "mean pose"):
            continue
        rr = summary(scores.errors)["root_relative_cm"]
        lines.append(f"  {row.engine}, {row.sensors} sensors: {(ref - rr) / gain:.2f} of the oracle's gain, "
                     f"{rr - oracle['root_relative_cm']:+.1f} cm from it")
    return lines


def format_trace(name: str, values: np.ndarray) -> str:
    """One take's per-second values as a compact line (integers)."""
    return f"{name}: " + " ".join(f"{v:.0f}" for v in values)


def _find(results: dict[Row, RowScores], engine: str, sensors: str, camera: str) -> dict[str, float] | None:
    scores = results.get(Row(engine, sensors, camera))
    return summary(scores.errors) if scores else None


# "Not worse" allows what the metric itself cannot resolve: with root fusion every row's output root is the same
# (engine/graph/root_fusion.py, equal to the bit), but the metric reads position and heading back from the placed
# database poses, stored in float32: the rows then differ by ~1e-7 cm and ~3e-5 deg.
EQUAL_CM, EQUAL_DEG = 1e-3, 1e-3


def chained_verdict(results: dict[Row, RowScores], camera_noise_m: float) -> list[str]:
    """Issue 11's "done when" for chained takes, judged on this table: the motion graph with 6 accelerometers
    + camera must reach global joint error <= 15 cm, mean root position error <= 2x the camera's noise (sd per
    axis) and root-relative error >= 30 % below the mean pose (skill >= 0.30); and with the camera, adding
    accelerometers must not make root position or heading worse than camera-only."""
    ref = skill_reference(results)
    main = _find(results, "motion graph", "6", CAMERA_ON)
    cam = _find(results, "camera only (W_A=0)", "0", CAMERA_ON)
    if main is None:
        return []
    limit_cm = 200 * camera_noise_m
    checks = [("global joint error <= 15 cm", main["global_cm"], main["global_cm"] <= 15.0),
              (f"root position error <= {limit_cm:.0f} cm (2x camera noise)", main["position_cm"],
               main["position_cm"] <= limit_cm),
              ("skill (root-relative vs mean pose) >= 0.30", 1 - main["root_relative_cm"] / ref,
               1 - main["root_relative_cm"] / ref >= 0.30)]
    lines = [f"done-when (motion graph, 6 sensors + camera): {name}: {value:.2f} -> {'PASS' if ok else 'FAIL'}"
             for name, value, ok in checks]
    if cam is not None:
        for row, scores in results.items():
            if row.engine == "motion graph" and row.camera == CAMERA_ON:
                s = summary(scores.errors)
                ok = (s["position_cm"] <= cam["position_cm"] + EQUAL_CM
                      and s["heading_deg"] <= cam["heading_deg"] + EQUAL_DEG)
                lines.append(f"done-when: {row.sensors} accelerometers + camera vs camera only: position "
                             f"{s['position_cm']:.2f} vs {cam['position_cm']:.2f} cm, heading {s['heading_deg']:.2f} "
                             f"vs {cam['heading_deg']:.2f} deg -> {'PASS' if ok else 'FAIL'}")
    return lines


def group_verdict(group: str, results: dict[Row, RowScores]) -> list[str]:
    """Issue 11's "done when" for leave-one-content-out turning walks: the motion graph with 6 accelerometers +
    camera within 10 deg heading and 15 cm position error."""
    main = _find(results, "motion graph", "6", CAMERA_ON)
    if main is None:
        return []
    ok = main["heading_deg"] <= 10.0 and main["position_cm"] <= 15.0
    return [f"done-when ({group}, motion graph, 6 sensors + camera): heading {main['heading_deg']:.1f} deg "
            f"(<= 10), position {main['position_cm']:.1f} cm (<= 15) -> {'PASS' if ok else 'FAIL'}"]


COMPARED = (("global_cm", "global cm"), ("root_relative_cm", "root-rel cm"), ("position_cm", "pos cm"),
            ("heading_deg", "head deg"))


def format_comparison(before: dict, after: dict) -> str:
    """Rows of two `--json` reports side by side (before -> after), matched by group, engine, sensors, camera;
    a row present in only one report shows '-' on the other side."""
    def rows(report: dict) -> dict[tuple[str, str, str, str], dict]:
        return {(g, r["engine"], r["sensors"], r["camera"]): r for g, rs in report["groups"].items() for r in rs}
    a, b = rows(before), rows(after)
    head = f"{'group':<12}{'engine':<30}{'sensors':>7} {'camera':<7}" + "".join(f"{name:>22}" for _, name in COMPARED)
    lines = [head, "-" * len(head)]
    for key in list(a) + [k for k in b if k not in a]:
        cells = []
        for field, _ in COMPARED:
            old = f"{a[key][field]:.1f}" if key in a else "-"
            new = f"{b[key][field]:.1f}" if key in b else "-"
            cells.append(f"{old + ' -> ' + new:>22}")
        lines.append(f"{key[0]:<12}{key[1]:<30}{key[2]:>7} {key[3]:<7}" + "".join(cells))
    return "\n".join(lines)

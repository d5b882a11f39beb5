"""The printed tables: one line per row, mean over every frame of every take, with the mean-pose skill."""
from __future__ import annotations

import numpy as np

from .metrics import per_second, summary
from .protocols import CAMERA_ON, Row, RowScores

HEADER = (f"{'engine':<34}{'sensors':>7} {'camera':<10}{'global cm':>10}{'root-rel cm':>12}{'skill':>7}"
          f"{'pos cm':>8}{'head deg':>9}{'worst s cm':>11}{'clips':>6}{'1-clip s':>9}{'run s':>7}")


def skill_reference(results: dict[Row, RowScores]) -> float:
    """Root-relative error of the mean pose (placement does not change it), the skill's denominator."""
    for row, scores in results.items():
        if row.engine == "mean pose" and row.camera == CAMERA_ON:
            return summary(scores.errors)["root_relative_cm"]
    return float("nan")


def format_rows(results: dict[Row, RowScores], fps: float, prefix: str = "") -> list[str]:
    """Lines of the table body. skill = 1 - root-relative error / the mean pose's; worst s = the worst
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
        lines.append(f"{prefix + row.engine:<34}{row.sensors:>7} {row.camera:<10}{s['global_cm']:10.1f}"
                     f"{s['root_relative_cm']:12.1f}{1 - s['root_relative_cm'] / ref:7.2f}{s['position_cm']:8.1f}"
                     f"{s['heading_deg']:9.1f}{worst:11.1f}{clips}{run}{scores.seconds:7.1f}")
    return lines


def format_table(results: dict[Row, RowScores], fps: float) -> str:
    return "\n".join([HEADER, "-" * len(HEADER), *format_rows(results, fps)])


def format_trace(name: str, values: np.ndarray) -> str:
    """One take's per-second values as a compact line (integers)."""
    return f"{name}: " + " ".join(f"{v:.0f}" for v in values)

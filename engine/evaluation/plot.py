"""`courtside evaluate --plot out.png`: one take's per-second global joint error of every row (each engine and
baseline at each sensor set, with and without the camera), and the table's mean global error as bars.

Why from the report dict (the structure `--json` writes) rather than from the live results: the picture and the
JSON then cannot disagree, and a saved report can be drawn again without re-running an evaluation.
Why `Figure` + the Agg canvas and not pyplot: no global figure state and no GUI backend is ever chosen, so it runs
on a headless CI machine or the gateway board, and matplotlib stays an optional extra (`courtside[plot]`).
"""
from __future__ import annotations

import importlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from engine.errors import CourtsideError

FIGURE_SIZE_IN = (12.0, 8.0)
DPI = 100


@dataclass
class Plotted:
    """What the picture shows, row by row (the tests compare it with the report and with the PNG's pixels)."""

    group: str
    take: int
    labels: list[str]
    colours_rgb: list[tuple[float, float, float]]
    traces_cm: list[list[float]]  # per row: the take's per-second global error (what the top panel draws)
    bars_cm: list[float]  # per row: mean global error over every take (the table's number)


def row_label(row: dict[str, Any]) -> str:
    sensors = f", {row['sensors']} sensors" if row["sensors"] not in ("-", "0") else ""
    return f"{row['engine']}{sensors}, {'camera' if row['camera'] == 'yes' else 'first fix'}"


def _colours(n: int) -> list[tuple[float, float, float]]:
    """n distinct colours: tab10 then tab20's lighter halves (an evaluation table has up to ~20 rows)."""
    from matplotlib import colormaps

    tab10, tab20 = colormaps["tab10"], colormaps["tab20"]
    palette = [tab10(i)[:3] for i in range(10)] + [tab20(2 * i + 1)[:3] for i in range(10)]
    return [tuple(float(c) for c in palette[i % len(palette)]) for i in range(n)]


def figure(report: dict[str, Any], group: str | None = None, take: int = 0):
    """(matplotlib Figure, Plotted) for one group of the report (default: its first) and one take of it."""
    from matplotlib.figure import Figure

    groups = report.get("groups") or {}
    if not groups:
        raise CourtsideError("--plot: the evaluation produced no rows to draw")
    group = group if group is not None else next(iter(groups))
    rows = groups[group]
    colours = _colours(len(rows))
    traces = [row["per_second"][take]["global_cm"] if take < len(row["per_second"]) else [] for row in rows]
    plotted = Plotted(group, take, [row_label(r) for r in rows], colours, traces, [float(r["global_cm"]) for r in rows])
    fig = Figure(figsize=FIGURE_SIZE_IN, dpi=DPI, layout="constrained")
    grid = fig.add_gridspec(2, 2, height_ratios=[3, 2])
    # rows with the camera stay within centimetres, rows with only the first fix drift by metres: one panel each
    panels = {"yes": fig.add_subplot(grid[0, 0]), "no": fig.add_subplot(grid[0, 1])}
    for row, label, colour, trace in zip(rows, plotted.labels, colours, traces):
        panels[row["camera"]].plot(np.arange(len(trace)) + 0.5, trace, color=colour, linewidth=1.4, label=label)
    for camera, ax in panels.items():
        ax.set_title(f"{group}, take {take + 1}: " + ("with the camera track" if camera == "yes"
                                                     else "camera's first fix only"), fontsize=10)
        ax.set_xlabel("time in the take (s)")
        ax.set_ylabel("global joint error per second (cm)")
        ax.set_ylim(bottom=0)
        ax.grid(alpha=0.3)
        if ax.get_lines():
            ax.legend(fontsize=7)
    bottom = fig.add_subplot(grid[1, :])
    x = np.arange(len(rows))
    bars = bottom.bar(x, plotted.bars_cm, color=colours)
    bottom.bar_label(bars, fmt="%.1f", fontsize=7)
    bottom.set_yscale("log")  # camera rows (centimetres) and first-fix rows (metres) on one readable axis
    bottom.set_xticks(x, plotted.labels, rotation=30, ha="right", fontsize=7)
    bottom.set_ylabel("mean global error (cm, log scale)")
    bottom.set_title("the table: mean global error over every frame of every take", fontsize=10)
    bottom.grid(axis="y", alpha=0.3)
    return fig, plotted


def save(report: dict[str, Any], path: str | Path, group: str | None = None, take: int = 0) -> Plotted:
    """Draw the report and write it as a PNG (Agg)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    fig, plotted = figure(report, group, take)
    FigureCanvasAgg(fig)
    fig.savefig(path, format="png", dpi=DPI)
    return plotted


def require_matplotlib() -> None:
    """Refuse --plot up front (before minutes of evaluation) when the plot extra is not installed."""
    try:
        importlib.import_module("matplotlib")  # only to check it is installed: figure() imports what it draws with
    except ImportError:
        raise CourtsideError("--plot needs matplotlib: pip install 'courtside[plot]'") from None

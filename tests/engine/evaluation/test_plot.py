"""`courtside evaluate --plot`: a real (small) chained evaluation on the shipped clips, its PNG checked against
the --json report of the same run: picture size, not blank, one trace and one bar per row in the row's colour, and
the drawn numbers equal to the report's."""
from __future__ import annotations

import json

import numpy as np
import pytest

from engine.errors import CourtsideError
from engine.evaluation import plot
from gateway.cli import main as courtside

matplotlib = pytest.importorskip("matplotlib")


@pytest.fixture(scope="module")
def evaluated(tmp_path_factory):
    out = tmp_path_factory.mktemp("plot")
    png, report = out / "eval.png", out / "eval.json"
    assert courtside(["evaluate", "--protocol", "chained", "--sample", "--takes", "1", "--take-seconds", "3",
                      "--engines", "motion-graph,baselines", "--sensor-sets", "6,1", "--json", str(report),
                      "--plot", str(png)]) == 0
    return png, json.loads(report.read_text())


def _pixels(png) -> np.ndarray:
    from matplotlib.image import imread

    return imread(png)[..., :3]  # (H, W, 3) floats in [0, 1]


def test_plot_is_a_full_size_non_blank_picture(evaluated):
    png, _ = evaluated
    rgb = _pixels(png)
    w_in, h_in = plot.FIGURE_SIZE_IN
    assert rgb.shape[:2] == (int(h_in * plot.DPI), int(w_in * plot.DPI))
    white = np.all(rgb > 0.98, axis=-1).mean()
    assert 0.3 < white < 0.97  # mostly background, but well drawn on


def test_plot_draws_every_row_of_the_report(evaluated):
    png, report = evaluated
    rows = report["groups"]["chained"]
    fig, drawn = plot.figure(report)
    assert drawn.labels == [plot.row_label(r) for r in rows] and len(rows) >= 6
    with_camera, first_fix, bars = fig.axes
    lines = {line.get_label(): line for ax in (with_camera, first_fix) for line in ax.get_lines()}
    assert len(lines) == len(rows)  # one trace per engine / baseline row
    for row in rows:
        line = lines[plot.row_label(row)]
        assert line in (with_camera if row["camera"] == "yes" else first_fix).get_lines()
        np.testing.assert_allclose(line.get_ydata(), row["per_second"][0]["global_cm"])
    heights = [patch.get_height() for patch in bars.patches]
    np.testing.assert_allclose(heights, [r["global_cm"] for r in rows])  # the table as bars
    # in the PNG the CLI wrote, every row's colour is present (its trace and its bar): the picture shows each row
    rgb = _pixels(png)
    for colour, label in zip(drawn.colours_rgb, drawn.labels):
        near = np.all(np.abs(rgb - np.asarray(colour)) < 0.02, axis=-1).sum()
        assert near > 200, (label, near)
    assert len(set(drawn.colours_rgb)) == len(rows)


def test_plot_refuses_the_leave_one_out_protocol(tmp_path):
    with pytest.raises(CourtsideError, match="--plot draws the chained"):
        from engine.evaluation.cli import main

        main(["--sample", "--plot", str(tmp_path / "x.png")])

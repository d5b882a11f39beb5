"""The done-when lines judge exactly the issue's thresholds on the table's numbers."""
from __future__ import annotations

import numpy as np

from engine.evaluation.metrics import FrameErrors
from engine.evaluation.protocols import CAMERA_ON, Row, RowScores
from engine.evaluation.table import chained_verdict, format_table, group_verdict


def scores(global_cm, rel_cm, pos_cm, head_deg, frames=60) -> RowScores:
    full = lambda v: np.full(frames, float(v))  # noqa: E731
    return RowScores([FrameErrors(full(global_cm), full(rel_cm), full(pos_cm), full(head_deg))], [3], [1.0])


def test_chained_verdict_thresholds():
    results = {Row("mean pose", "-", CAMERA_ON): scores(14, 10, 6, 8),
               Row("motion graph", "6", CAMERA_ON): scores(14.9, 6.9, 9.9, 7),
               Row("motion graph", "1", CAMERA_ON): scores(20, 8, 12, 7),
               Row("camera only (W_A=0)", "0", CAMERA_ON): scores(20, 11, 11, 7)}
    lines = chained_verdict(results, camera_noise_m=0.05)
    assert [ln.rsplit(" ", 1)[1] for ln in lines] == ["PASS", "PASS", "PASS", "PASS", "FAIL"]
    assert "skill" in lines[2] and "0.31" in lines[2]
    results[Row("motion graph", "6", CAMERA_ON)] = scores(15.1, 7.1, 10.1, 7)
    assert [ln.rsplit(" ", 1)[1] for ln in chained_verdict(results, 0.05)][:3] == ["FAIL", "FAIL", "FAIL"]
    assert "0.29" in format_table(results, 30.0).splitlines()[3]  # the skill column: 1 - 7.1 / 10


def test_accelerometers_vs_camera_only_tolerates_only_float32_pose_storage():
    """Rows on the same fused root differ by ~3e-5 deg in the metric (float32 database poses): not worse; a
    hundredth of a degree or of a centimetre worse is worse."""
    def verdict(pos, head):
        results = {Row("mean pose", "-", CAMERA_ON): scores(14, 10, 6, 8),
                   Row("motion graph", "6", CAMERA_ON): scores(11, 9, pos, head),
                   Row("camera only (W_A=0)", "0", CAMERA_ON): scores(15, 14, 2.146, 2.677)}
        return chained_verdict(results, 0.05)[-1].rsplit(" ", 1)[1]
    assert verdict(2.146, 2.677 + 3e-5) == "PASS"
    assert verdict(2.146, 2.687) == "FAIL" and verdict(2.156, 2.677) == "FAIL"


def test_group_verdict_thresholds():
    ok = {Row("motion graph", "6", CAMERA_ON): scores(10, 5, 15.0, 10.0)}
    bad = {Row("motion graph", "6", CAMERA_ON): scores(10, 5, 15.0, 10.5)}
    assert group_verdict("content walk-left", ok)[0].endswith("PASS")
    assert group_verdict("content walk-left", bad)[0].endswith("FAIL")


def test_comparison_matches_rows_by_group_engine_sensors_camera(tmp_path, capsys):
    import json

    from gateway.cli import main as courtside

    def report(pos):
        return {"groups": {"chained": [{"engine": "motion graph", "sensors": "6", "camera": "yes", "global_cm": 20.0,
                                        "root_relative_cm": 10.0, "position_cm": pos, "heading_deg": 5.0}]}}
    before, after = tmp_path / "a.json", tmp_path / "b.json"
    before.write_text(json.dumps(report(113.1)))
    after_report = report(7.25)
    after_report["groups"]["chained"].append({**after_report["groups"]["chained"][0], "camera": "no"})
    after.write_text(json.dumps(after_report))
    assert courtside(["evaluate", "--compare", str(before), str(after)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert "113.1 -> 7.2" in lines[2] and "20.0 -> 20.0" in lines[2]
    assert "- -> 7.2" in lines[3]
    assert courtside(["evaluate", "--compare", str(before), str(tmp_path / "missing.json")]) == 2

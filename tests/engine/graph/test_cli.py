"""The three CLIs end to end on the shipped CMU clips: build a graph, synthesise a held-out take, evaluate."""
from __future__ import annotations

import re

import numpy as np
import pytest

from engine.graph.cli import build_graph_main, evaluate_main, synthesize_main
from engine.graph.graph import MotionGraph
from engine.graph.inputs import heading_heuristic, load_take, read_take
from engine.mocap import (forward_kinematics, load_clip, read_bvh, resample, root_heading, sample_clips,
                          standard_placements, virtual_accelerometers)


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """A graph of all shipped subject-16 clips but 16_32, and 16_32 recorded at 120 Hz as a take."""
    tmp = tmp_path_factory.mktemp("cli")
    clips = sample_clips()
    held = "16_32"
    others = [str(p) for n, p in clips.items() if n.startswith("16_") and n != held]
    assert build_graph_main(others + ["-o", str(tmp / "g.npz"), "--msv"]) == 0
    motion = resample(load_clip(clips[held]), 120.0)
    pos, glob = forward_kinematics(motion)
    acc = virtual_accelerometers(motion, standard_placements(motion.skeleton), fk=(pos, glob))
    np.savez(tmp / "take.npz", acc_g=acc, fps=120.0, position_m=motion.root_positions_m[:, [0, 2]],
             heading_rad=root_heading(motion, pos))
    return tmp, motion


def test_build_graph_writes_a_loadable_graph(built):
    tmp, _ = built
    g = MotionGraph.load(tmp / "g.npz")
    assert g.skeleton is not None and g.config.msv and len(g.config.sensor_names) == 6
    assert "16_32" not in g.clip_names and (tmp / "g.json").is_file()


@pytest.mark.parametrize("extra", [[], ["--lag", "1.0"]])
def test_synthesize_a_held_out_take(built, extra, capsys):
    tmp, truth = built
    out = tmp / f"out{len(extra)}.bvh"
    assert synthesize_main(["--graph", str(tmp / "g.npz"), "--input", str(tmp / "take.npz"), "-o", str(out)]
                           + extra) == 0
    m = read_bvh(out)
    n = m.n_frames
    assert abs(n - truth.n_frames * 30 / 120) <= 2
    # the synthesised root follows the measured track (resampled 120 -> 30 Hz)
    track = truth.root_positions_m[::4, [0, 2]][:n]
    assert np.mean(np.linalg.norm(m.root_positions_m[: len(track), [0, 2]] - track, axis=1)) < 0.3


def test_synthesize_reports_bad_input_by_name(built, capsys, tmp_path):
    tmp, _ = built
    bad = tmp_path / "broken.npz"
    np.savez(bad, acc_g=np.zeros((10, 6)))
    assert synthesize_main(["--graph", str(tmp / "g.npz"), "--input", str(bad), "-o", str(tmp_path / "x.bvh")]) == 2
    assert "broken.npz" in capsys.readouterr().err


def test_gateway_export_is_accepted(tmp_path):
    t = np.arange(0, 4, 0.01)
    arrays = {}
    for k, sensor in enumerate((3, 7)):
        arrays[f"base/{sensor}/t_host_s"] = t + 0.002 * k
        arrays[f"base/{sensor}/acc_g"] = np.stack([np.sin(t), np.cos(t), np.full_like(t, k)], axis=1)
    np.savez(tmp_path / "export.npz", **arrays)
    obs = load_take(tmp_path / "export.npz", ["left_forearm", "right_forearm", "chest"], 30.0,
                    {"base/3": "chest", "base/7": "left_forearm"})
    assert obs.sensor_indices == (0, 2)  # columns in graph order, as the console feeds them live
    assert obs.acc_g.shape[1:] == (2, 3) and abs(obs.n_samples - 120) <= 1
    assert np.allclose(obs.acc_g[10:-10, 0, 2], 1.0, atol=1e-3) and np.allclose(obs.acc_g[10:-10, 1, 2], 0.0)


def test_heading_heuristic():
    fps = 30.0
    t = np.arange(90) / fps
    running = np.stack([3.0 * t, np.full_like(t, -5.0)], axis=1)  # 3 m/s along +x on the near side
    standing = np.tile([[0.0, 4.0]], (90, 1))  # still, far side
    assert np.allclose(heading_heuristic(running, fps)[10:-10], np.pi / 2)
    assert np.allclose(heading_heuristic(standing, fps), np.pi)


def test_evaluate_prints_the_table(capsys):
    assert evaluate_main(["--sample", "--variants", "plain", "--test-clips", "2"]) == 0
    lines = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("plain")]
    assert len(lines) == 7
    stats = [re.findall(r"(\d+\.\d) \(\s*(\d+\.\d)\)", ln) for ln in lines]
    assert all(len(s) == 3 for s in stats)  # joint, position, heading: mean (sd)
    assert all(0 < float(s[0][0]) < 30 for s in stats)


def test_synthesize_honours_a_human_constraint(built, capsys):
    """Require poses from the run clip 16_35 around 1 s into a walking take: the search complies (eq. 8), and
    an unknown label is a usage error."""
    import json

    tmp, _ = built
    args = ["--graph", str(tmp / "g.npz"), "--input", str(tmp / "take.npz"), "-o", str(tmp / "c.bvh")]
    g = MotionGraph.load(tmp / "g.npz")
    assert "16_35" in g.label_names
    assert synthesize_main(args + ["--require", "16_35@1.0", "--require-tolerance", "3"]) == 0
    out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert out["broken_constraints"] == 0
    assert synthesize_main(args + ["--require", "no-such-label@1.0"]) == 2


def test_gateway_export_camera_track(tmp_path):
    """Camera messages recorded by the gateway become the position/heading inputs, on the samples' clock."""
    import json

    t = np.arange(0, 4, 0.01)
    cams = [{"kind": "camera", "t_host_s": float(tc), "position_m": [1.0 + 0.5 * tc, -3.0], "heading_rad": 0.25}
            for tc in np.arange(0.5, 3.5, 1 / 25)]
    cams.insert(3, {"kind": "camera", "t_host_s": 0.6, "position_m": None, "tracking": False})
    np.savez(tmp_path / "export.npz", **{"base/1/t_host_s": t, "base/1/acc_g": np.zeros((len(t), 3)),
                                          "messages": np.array(json.dumps(cams + [{"kind": "event"}]))})
    take = read_take(tmp_path / "export.npz", ["chest"], 30.0, use_camera_heading=True)
    obs, ts = take.obs, take.t_s
    assert np.array_equal(ts, take.frame / 30.0)
    # each frame gets the fix of its own time; none next to the lost fix at 0.6 s or outside the track
    lost = (ts > cams[2]["t_host_s"]) & (ts < cams[4]["t_host_s"])
    inside = (ts >= 0.5) & (ts <= cams[-1]["t_host_s"]) & ~lost
    assert np.allclose(obs.position_m[inside, 0], 1.0 + 0.5 * ts[inside])
    assert np.allclose(obs.heading_rad[inside], 0.25)
    assert np.all(np.isnan(obs.position_m[~inside])) and lost.sum() == 1  # the 0.6 s frame
    assert read_take(tmp_path / "export.npz", ["chest"], 30.0).obs.heading_rad is None  # the tracker's rule: off

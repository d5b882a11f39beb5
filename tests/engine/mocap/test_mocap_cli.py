"""`python -m engine.mocap`: info/convert on a shipped clip, clear error on a bad file (real subprocess)."""
import subprocess
import sys

import numpy as np

import engine.mocap as M


def _run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "engine.mocap", *args], capture_output=True, text=True, timeout=120)


def test_convert_writes_a_bvh_that_reads_back_and_info_summarises_it(tmp_path):
    out = tmp_path / "run.bvh"
    done = _run("convert", str(M.sample_clips()["16_36"]), str(out), "--fps", "30")
    assert done.returncode == 0, done.stderr
    back = M.read_bvh(out)
    original = M.load_clip(M.sample_clips()["16_36"], fps=30)
    np.testing.assert_allclose(M.forward_kinematics(back)[0], M.forward_kinematics(original)[0], atol=1e-7)
    info = _run("info", str(out))
    assert info.returncode == 0 and f"{original.n_frames} frames at 30 Hz" in info.stdout
    assert "foot contact duty" in info.stdout


def test_bad_file_exits_2_naming_file_and_line(tmp_path):
    bad = tmp_path / "bad.bvh"
    bad.write_text("HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0\n}\nMOTION\nFrames: 1\nFrame Time: 0.01\n0\n")
    done = _run("info", str(bad))
    assert done.returncode == 2
    assert f"{bad}, line 4" in done.stderr and "OFFSET" in done.stderr

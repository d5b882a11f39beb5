"""Recorder: exact round trip, truncation anywhere, a real SIGKILL mid-recording, npz/CSV export."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from gateway.recorder import (RECORDING_FILE, Recorder, RecordingError, export_csv, export_npz, load_take,
                              read_recording)


def _batch(start: int, n: int) -> dict[str, np.ndarray]:
    counter = np.arange(start, start + n, dtype=np.uint32)
    return {"counter": counter, "t_host_s": counter * 0.01,
            "acc_g": (counter[:, None] * np.array([1, -2, 3]) % 97 / 10).astype(np.float32)}


def _record(tmp_path: Path, batches: int = 40, flush_interval_s: float = 0.01) -> Path:
    rec = Recorder(tmp_path, flush_interval_s=flush_interval_s)
    rec.start("t1", meta={"stations": ["a", "b"]})
    for i in range(batches):
        rec.put_samples("a", 0, _batch(i * 10, 10))
        rec.put_samples("b", 5, _batch(i * 7, 7), header={"nominal_hz": 100})
        if i % 10 == 0:
            rec.put("event", {"level": "info", "message": f"tick {i}"})
            time.sleep(0.02)  # let several flushes happen -> many chunks
    state = rec.stop()
    assert state["samples_written"] == batches * 17
    return Path(state["files"][0])


def test_round_trip_is_exact(tmp_path):
    path = _record(tmp_path)
    take = load_take(path)
    assert take.problem is None and take.meta["take"] == "t1" and take.meta["stations"] == ["a", "b"]
    np.testing.assert_array_equal(take.samples[("a", 0)]["counter"], np.arange(400))
    np.testing.assert_array_equal(take.samples[("b", 5)]["acc_g"], _batch(0, 280)["acc_g"])
    assert [m["message"] for m in take.others if m.kind == "event"] == [f"tick {i}" for i in (0, 10, 20, 30)]


def test_duplicate_or_bad_take_name_refused(tmp_path):
    _record(tmp_path)
    rec = Recorder(tmp_path)
    with pytest.raises(ValueError, match="already exists"):
        rec.start("t1")
    for bad in ("../evil", "..", ".", "take\n", "a/b", "x" * 101):  # issue 12: names escaped the directory
        with pytest.raises(ValueError, match="take name"):
            rec.start(bad)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t1"] and not (tmp_path.parent / "take.csrec").exists()


def test_truncated_anywhere_returns_intact_prefix(tmp_path):
    path = _record(tmp_path)
    full = read_recording(path)
    data = path.read_bytes()
    assert len(full.messages) > 8
    rng = np.random.default_rng(3)
    cut_dir = tmp_path / "cuts"
    cut_dir.mkdir()
    cuts = sorted(set(rng.integers(200, len(data), 60).tolist()) | {len(data) - 1})
    previous = -1
    for cut in cuts:
        cut_path = cut_dir / f"{cut}.csrec"
        cut_path.write_bytes(data[:cut])
        part = read_recording(cut_path)
        assert part.truncated or part.intact_bytes == cut
        assert part.intact_bytes <= cut
        assert len(part.messages) >= previous  # monotone in the cut length
        previous = len(part.messages)
        for got, want in zip(part.messages, full.messages):
            assert got.kind == want.kind and got.header == want.header
            for name in want.arrays:
                np.testing.assert_array_equal(got.arrays[name], want.arrays[name])
    # a cut after the very last byte but one loses exactly the last chunk: the end record, so the cut take reads
    # as crashed while the whole one reads as cleanly stopped
    last_but_one = read_recording(cut_dir / f"{len(data) - 1}.csrec")
    assert len(last_but_one.messages) == len(full.messages)
    assert full.ended_cleanly and full.end["samples_written"] == 680 and full.problem is None
    assert last_but_one.end is None and not last_but_one.ended_cleanly


def test_not_a_recording_names_file(tmp_path):
    bad = tmp_path / "x.csrec"
    bad.write_bytes(b"hello world, not a recording")
    with pytest.raises(RecordingError, match="x.csrec.*file magic"):
        read_recording(bad)


def test_export_npz_and_csv(tmp_path):
    path = _record(tmp_path, batches=5)
    npz = np.load(export_npz(path, tmp_path / "out.npz"))
    np.testing.assert_array_equal(npz["a/0/counter"], np.arange(50))
    files = export_csv(path, tmp_path / "csv")
    a_csv = tmp_path / "csv" / "a_0.csv"
    assert a_csv in files
    table = np.loadtxt(a_csv, delimiter=",", skiprows=1)
    header = a_csv.read_text().splitlines()[0].split(",")
    # no clock points recorded here, so the offline re-fit keeps the online times
    assert header == ["counter", "t_host_s", "acc_g_x", "acc_g_y", "acc_g_z", "t_realigned_s"]
    np.testing.assert_array_equal(table[:, 5], table[:, 1])
    np.testing.assert_array_equal(table[:, 0], np.arange(50))
    np.testing.assert_allclose(table[:, 2:5], _batch(0, 50)["acc_g"], rtol=0, atol=1e-7)


CHILD = textwrap.dedent(
    """
    import sys, time, numpy as np
    from gateway.recorder import Recorder
    rec = Recorder(sys.argv[1], flush_interval_s=0.05)
    rec.start("crash")
    i = 0
    while True:
        counter = np.arange(i * 25, i * 25 + 25, dtype=np.uint32)
        rec.put_samples("st", 1, {"counter": counter, "acc_g": np.repeat(counter[:, None], 3, 1).astype(np.float32)})
        i += 1
        print(rec.state()["samples_written"], flush=True)
        time.sleep(0.002)
    """
)


def test_sigkill_mid_recording_keeps_everything_fsynced(tmp_path):
    proc = subprocess.Popen([sys.executable, "-c", CHILD, str(tmp_path)], stdout=subprocess.PIPE, text=True)
    acknowledged = 0
    try:
        deadline = time.monotonic() + 30
        while acknowledged < 3000:
            line = proc.stdout.readline()
            assert line, "recorder child died"
            acknowledged = int(line)
            assert time.monotonic() < deadline
    finally:
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
        proc.stdout.close()
    take = load_take(tmp_path / "crash" / RECORDING_FILE)
    counters = take.samples[("st", 1)]["counter"]
    assert len(counters) >= acknowledged  # everything reported written survived
    np.testing.assert_array_equal(counters, np.arange(len(counters)))  # no holes, no duplicates
    np.testing.assert_array_equal(take.samples[("st", 1)]["acc_g"][:, 2], counters.astype(np.float32))


def test_a_sensor_whose_channels_change_mid_take_reads_nan_where_it_had_none(tmp_path):
    """An IMU whose orientation filter is switched on mid-take: batches without and with `quat_wxyz` in one
    flush and across flushes are written as separate chunks (never mixed into one), and the take reads them as
    one stream with NaN quaternions before the switch."""
    def with_quat(start: int, n: int) -> dict[str, np.ndarray]:
        return {**_batch(start, n), "quat_wxyz": np.tile(np.float32([1, 0, 0, 0]), (n, 1))}

    rec = Recorder(tmp_path, flush_interval_s=3600)  # one flush at stop: both kinds of batch in it
    rec.start("t1")
    rec.put_samples("a", 0, _batch(0, 10))
    rec.put_samples("a", 0, with_quat(10, 5))
    rec.put_samples("a", 0, _batch(15, 5))
    path = Path(rec.stop()["files"][0])
    cols = load_take(path).samples[("a", 0)]
    np.testing.assert_array_equal(cols["counter"], np.arange(20))
    assert cols["quat_wxyz"].shape == (20, 4)
    assert np.isnan(cols["quat_wxyz"][:10]).all() and np.isnan(cols["quat_wxyz"][15:]).all()
    np.testing.assert_array_equal(cols["quat_wxyz"][10:15], np.tile([1, 0, 0, 0], (5, 1)))
    assert len([m for m in read_recording(path).messages if m.kind == "samples"]) == 3

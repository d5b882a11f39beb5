"""Recording faults: a disk that fills (and frees), a slow disk, flipped bytes anywhere, damaged headers,
CRC-valid chunks from a foreign writer, and crashed vs cleanly stopped takes."""
from __future__ import annotations

import struct
import subprocess
import sys
import textwrap
import threading
import time
import zlib
from pathlib import Path

import numpy as np
import pytest

from gateway import codec
from gateway.client import GatewayClient, GatewayRequestError
from gateway.daemon import Gateway
from firmware_protocol.emulator.faultfs import SimulatedDisk
from gateway.recorder import (CHUNK_MAGIC, FILE_MAGIC, RECORDING_FILE, Recorder, RecordingError, load_take,
                              read_recording)

from .test_station_reader import wait_for


def _batch(start: int, n: int) -> dict[str, np.ndarray]:
    counter = np.arange(start, start + n, dtype=np.uint32)
    return {"counter": counter, "t_host_s": counter * 0.01, "acc_g": np.repeat(counter[:, None], 3, 1).astype(np.float32)}


def _recording(tmp_path: Path, chunks: int = 30) -> Path:
    """A stopped take with `chunks` sample chunks of 25 samples each (one flush per chunk)."""
    rec = Recorder(tmp_path, flush_interval_s=3600)
    rec.start("t")
    for i in range(chunks):
        rec.put_samples("st1", 0, _batch(i * 25, 25))
        rec._flush()  # one chunk per batch, deterministically
    rec.stop()
    return tmp_path / "t" / RECORDING_FILE


def _chunk_offsets(data: bytes, first: int) -> list[int]:
    offsets, pos = [], first
    while pos < len(data):
        offsets.append(pos)
        pos += 12 + struct.unpack_from(">I", data, pos + 4)[0]
    return offsets


def _header_end(data: bytes) -> int:
    return len(FILE_MAGIC) + 4 + struct.unpack_from(">I", data, len(FILE_MAGIC))[0] + 4


# ------------------------------------------------------------------------------------------- damaged files
def test_flipped_byte_costs_only_the_chunk_it_hit(tmp_path):
    path = _recording(tmp_path)
    data = path.read_bytes()
    offsets = _chunk_offsets(data, _header_end(data))
    assert len(offsets) == 32  # take_meta + 30 sample chunks + take_end
    rng = np.random.default_rng(5)
    for trial, k in enumerate(rng.choice(np.arange(1, 31), 12, replace=False)):
        hit = int(rng.integers(offsets[k], offsets[k + 1]))  # anywhere in chunk k: magic, length, CRC or body
        damaged = bytearray(data)
        damaged[hit] ^= 0x5A
        bad = tmp_path / f"bad{trial}.csrec"
        bad.write_bytes(bytes(damaged))
        contents = read_recording(bad)
        take = load_take(bad)
        counters = take.samples[("st1", 0)]["counter"]
        want = np.setdiff1d(np.arange(750), np.arange((k - 1) * 25, k * 25))
        np.testing.assert_array_equal(counters, want)  # every later chunk kept, only chunk k lost
        assert contents.skipped and contents.skipped[0][0] == offsets[k]
        assert "skipped 1 damaged region" in contents.problem
        assert contents.ended_cleanly  # the end record after the damage is found too


def test_flipped_header_byte_is_recovered_from_the_copy(tmp_path):
    path = _recording(tmp_path)
    data = path.read_bytes()
    for hit in (0, 5, len(FILE_MAGIC) + 1, len(FILE_MAGIC) + 10, _header_end(data) - 2):
        damaged = bytearray(data)
        damaged[hit] ^= 0x01
        bad = tmp_path / f"h{hit}.csrec"
        bad.write_bytes(bytes(damaged))
        contents = read_recording(bad)
        assert contents.header_recovered and contents.meta["take"] == "t", hit
        assert "recovered from its copy" in contents.problem
        assert len(load_take(bad).samples[("st1", 0)]["counter"]) == 750


def _old_style_file(path: Path, meta_bytes: bytes, bodies: list[bytes]) -> Path:
    """A file the way a foreign writer (or the pre-copy recorder) makes it: header + chunks, no take_meta."""
    out = FILE_MAGIC + struct.pack(">I", len(meta_bytes)) + meta_bytes + struct.pack(">I", zlib.crc32(meta_bytes))
    for body in bodies:
        out += struct.pack(">4sII", CHUNK_MAGIC, len(body), zlib.crc32(body)) + body
    path.write_bytes(out)
    return path


def test_header_with_valid_crc_but_invalid_json_is_a_clear_error(tmp_path):
    bad = _old_style_file(tmp_path / "j.csrec", b'{"take": "x",', [codec.encode("event", {"m": 1})])
    with pytest.raises(RecordingError, match=r"j\.csrec.*not UTF-8 JSON.*no intact copy"):
        read_recording(bad)


def test_chunk_with_valid_crc_but_missing_keys_is_a_clear_error(tmp_path):
    body = codec.encode("samples", {"sensor": 1}, _batch(0, 5))  # no 'station'
    bad = _old_style_file(tmp_path / "k.csrec", b'{"take": "x"}', [body])
    with pytest.raises(RecordingError, match=r"k\.csrec.*samples chunk without a string 'station'"):
        load_take(bad)
    ragged = codec.encode("samples", {"station": "a", "sensor": 1},
                          {"counter": np.arange(5, dtype=np.uint32), "acc_g": np.zeros((4, 3), np.float32)})
    bad = _old_style_file(tmp_path / "r.csrec", b'{"take": "x"}', [ragged])
    with pytest.raises(RecordingError, match="different lengths"):
        load_take(bad)
    points = codec.encode("clock_points", {"station": "a", "sensor": -1}, {"ticks": np.arange(3)})
    bad = _old_style_file(tmp_path / "p.csrec", b'{"take": "x"}', [points])
    with pytest.raises(RecordingError, match=r"missing arrays \['raw_ticks'"):
        load_take(bad)


# ------------------------------------------------------------------------------------------- disk faults
def _feed(rec: Recorder, stop: threading.Event, fed: list[int]) -> None:
    i = 0
    while not stop.is_set():
        rec.put_samples("st1", 0, _batch(i * 25, 25))
        fed[0] = (i + 1) * 25
        i += 1
        time.sleep(0.001)


def test_disk_full_closes_the_take_cleanly_and_recording_restarts_when_space_is_free(tmp_path):
    disk = SimulatedDisk(free_bytes=60_000)
    events: list[tuple[str, str]] = []
    rec = Recorder(tmp_path, flush_interval_s=0.01, opener=disk.open, on_event=lambda *e: events.append(e))
    rec.start("full")
    stop, fed = threading.Event(), [0]
    feeder = threading.Thread(target=_feed, args=(rec, stop, fed))
    feeder.start()
    try:
        assert wait_for(lambda: not rec.active, timeout_s=10)
        state = rec.state()
        assert "ENOSPC" in state["fault"] and state["samples_written"] > 0
        # the alarm follows once the take is closed (it reports what was kept)
        assert wait_for(lambda: any(level == "alarm" and "ENOSPC" in message for level, message in events))
        n_at_fault = fed[0]
        time.sleep(0.1)  # samples keep arriving: they are not queued any more (bounded memory)
        assert fed[0] > n_at_fault and rec._backlog_bytes == 0 and not rec._pending.rows
        with pytest.raises(ValueError, match="not recording.*disk fault.*ENOSPC"):
            rec.stop()
        # everything acknowledged as written is in the file, contiguous, and the file ends on a chunk boundary
        contents = read_recording(tmp_path / "full")
        take = load_take(tmp_path / "full")
        counters = take.samples[("st1", 0)]["counter"]
        np.testing.assert_array_equal(counters, np.arange(state["samples_written"]))
        assert contents.intact_bytes == contents.total_bytes
        # no space: a new take is refused with the reason, and leaves nothing behind
        disk.set_free(0)
        with pytest.raises(ValueError, match="cannot start take 'again'.*ENOSPC"):
            rec.start("again")
        assert not (tmp_path / "again").exists()  # not even an empty take directory (issue 22)
        # space freed: recording starts again and keeps everything
        disk.set_free(10 << 20)
        rec.start("again")
        time.sleep(0.1)
    finally:
        stop.set()
        feeder.join()
    final = rec.stop()
    again = load_take(tmp_path / "again")
    assert len(again.samples[("st1", 0)]["counter"]) == final["samples_written"] > 0
    assert again.end["reason"] == "stopped"


def _take_ended_by_a_full_disk(record_dir) -> Recorder:
    """Take "t" in ``record_dir``, recorded (flushed by hand) until a 40 kB disk is full."""
    disk = SimulatedDisk(free_bytes=40_000)
    rec = Recorder(record_dir, flush_interval_s=3600, opener=disk.open)
    rec.start("t")
    i = 0
    while rec.active:
        rec.put_samples("st1", 0, _batch(i * 100, 100))
        rec._flush()
        i += 1
    return rec


def test_disk_full_end_record_names_the_fault(tmp_path):
    rec = _take_ended_by_a_full_disk(tmp_path)
    state = rec.state()  # the backlog was freed with the take: its figures say 0, not their last value
    assert state["fault"] and state["samples_lost"] > 0 and state["backlog_bytes"] == state["samples_backlog"] == 0
    contents = read_recording(tmp_path / "t")
    # the failed chunk was cut back, which freed enough room for the small end record
    assert contents.end["reason"] == "fault" and "ENOSPC" in contents.end["fault"]
    assert contents.end["samples_written"] == len(load_take(tmp_path / "t").samples[("st1", 0)]["counter"])
    assert not contents.ended_cleanly and contents.problem is None


class _StalledDisk:
    """File layer whose writes block until released: a disk that cannot keep up."""

    def __init__(self):
        self.release = threading.Event()

    def open(self, path):
        outer = self

        class Stalled:
            def __init__(self):
                self._fh = open(path, "xb", buffering=0)
                self.header_done = False

            def write(self, data):
                if self.header_done:
                    outer.release.wait()
                return self._fh.write(data)

            def __getattr__(self, name):
                return getattr(self._fh, name)

        return Stalled()


def test_backlog_is_bounded_while_the_disk_stalls_and_the_gap_is_announced(tmp_path):
    disk = _StalledDisk()
    events: list[tuple[str, str]] = []
    rec = Recorder(tmp_path, flush_interval_s=0.01, opener=disk.open, max_backlog_bytes=20_000,
                   on_event=lambda *e: events.append(e))
    rec.start("slow")
    rec._file._fh.header_done = True
    per_batch = sum(a.nbytes for a in _batch(0, 25).values())
    for i in range(200):  # 200 x 400 bytes = 80 kB offered against a 20 kB bound
        rec.put_samples("st1", 0, _batch(i * 25, 25))
        assert rec._backlog_bytes <= 20_000
    state = rec.state()
    assert state["samples_dropped"] >= 25 * (200 - 20_000 // per_batch)
    assert [level for level, _ in events] == ["alarm"] and "disk too slow" in events[0][1]
    disk.release.set()
    assert wait_for(lambda: rec.state()["samples_backlog"] == 0)
    rec.put_samples("st1", 0, _batch(99_000, 25))  # admitted again, with a warning that names the gap
    assert events[-1][0] == "warning" and "resumed" in events[-1][1]
    final = rec.stop()
    assert final["samples_written"] + final["samples_dropped"] == 200 * 25 + 25


FSIZE_CHILD = textwrap.dedent(
    """
    import resource, signal, sys, time, numpy as np
    from gateway.recorder import Recorder
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)           # write() then fails with EFBIG, like a full quota
    resource.setrlimit(resource.RLIMIT_FSIZE, (120_000, 120_000))
    events = []
    rec = Recorder(sys.argv[1], flush_interval_s=0.01, on_event=lambda *e: events.append(e))
    rec.start("limited")
    i = 0
    while rec.active and i < 100_000:
        counter = np.arange(i * 50, i * 50 + 50, dtype=np.uint32)
        rec.put_samples("st", 1, {"counter": counter, "acc_g": np.zeros((50, 3), np.float32)})
        i += 1
        time.sleep(0.0005)
    rec._thread.join(5)  # the alarm is delivered right after the take closes
    print(rec.state()["fault"], rec.state()["samples_written"], len(events), flush=True)
    """
)


def test_kernel_file_size_limit_in_a_subprocess(tmp_path):
    done = subprocess.run([sys.executable, "-c", FSIZE_CHILD, str(tmp_path)], capture_output=True, text=True,
                          timeout=60)
    assert done.returncode == 0, done.stderr
    fault, written, n_events = done.stdout.split(") ")[0] + ")", *done.stdout.split(") ")[1].split()
    assert "EFBIG" in fault and int(n_events) == 1
    take = load_take(tmp_path / "limited")
    np.testing.assert_array_equal(take.samples[("st", 1)]["counter"], np.arange(int(written)))
    assert (tmp_path / "limited" / RECORDING_FILE).stat().st_size <= 120_000


def test_gateway_alarms_clients_keeps_streaming_and_records_again(tmp_path):
    disk = SimulatedDisk(free_bytes=150_000)
    url = "emu://diskfull?sensors=3&rate=200&seed=4"
    with Gateway([url], listen=("127.0.0.1", 0), record_dir=tmp_path, status_interval_s=0.2) as gw:
        gw.recorder.opener = disk.open
        gw.recorder.flush_interval_s = 0.02
        client = GatewayClient(*gw.address).connect()
        try:
            assert wait_for(lambda: client.list_stations()[0]["link"] == "streaming", timeout_s=10)
            client.start_recording("r1")
            assert wait_for(lambda: not gw.recorder.active, timeout_s=15)
            alarms = []
            deadline = time.monotonic() + 5
            while time.monotonic() < deadline and not alarms:
                msg = client.get(1, kinds=["event"])
                if msg is not None and msg["level"] == "alarm" and msg["source"] == "recorder":
                    alarms.append(msg)
            assert alarms and "ENOSPC" in alarms[0]["message"]
            got_after = []
            client.add_listener("samples", got_after.append)
            assert wait_for(lambda: len(got_after) > 20)  # streaming continues
            with pytest.raises(GatewayRequestError, match="not recording.*ENOSPC"):
                client.stop_recording()
            disk.set_free(50 << 20)
            client.start_recording("r2")
            time.sleep(0.5)
            final = client.stop_recording()
        finally:
            client.close()
    assert final["samples_written"] > 0
    assert load_take(tmp_path / "r2").end["reason"] == "stopped"
    r1 = read_recording(tmp_path / "r1")  # readable to its last chunk; never mistaken for a clean stop
    assert not r1.ended_cleanly and r1.intact_bytes == r1.total_bytes
    assert r1.end is None or r1.end["reason"] == "fault"  # the end record only if it still fitted


def _limit_file_size() -> None:
    import resource
    import signal

    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # write() fails with EFBIG instead of killing the process
    resource.setrlimit(resource.RLIMIT_FSIZE, (150_000, 150_000))


def test_gateway_process_with_a_full_disk_keeps_running_and_stops_on_sigterm(tmp_path):
    """The issue's run: the recorder thread died on ENOSPC, state stayed active, SIGTERM exited 1 and left the
    emulators running. Here the kernel refuses writes past 150 kB (EFBIG, like a full quota) in a real
    `courtside gateway --emulate 1` process, which is then stopped with SIGTERM."""
    import signal

    proc = subprocess.Popen(
        [sys.executable, "-m", "gateway.cli", "gateway", "--emulate", "1", "--emulate-motion", "none",
         "--record-dir", str(tmp_path), "--record", "full", "--listen", "127.0.0.1:0", "--quiet"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=_limit_file_size)
    try:
        assert "gateway listening" in proc.stdout.readline()
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and not (tmp_path / "full" / RECORDING_FILE).exists():
            time.sleep(0.1)
        while time.monotonic() < deadline and (tmp_path / "full" / RECORDING_FILE).stat().st_size < 140_000:
            time.sleep(0.1)
        time.sleep(1.0)  # the disk is full now; the gateway goes on streaming
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 0, err
    assert "gateway stopped" in out
    assert "File too large (EFBIG)" in err and "recording take full stopped" in err
    assert "Traceback" not in err
    contents = read_recording(tmp_path / "full")
    assert contents.intact_bytes == contents.total_bytes and not contents.ended_cleanly
    assert load_take(tmp_path / "full").samples


def test_export_says_when_a_take_was_never_closed(tmp_path, caplog):
    from gateway.recorder import export_npz

    path = _recording(tmp_path)
    data = path.read_bytes()
    offsets = _chunk_offsets(data, _header_end(data))
    crashed = tmp_path / "crashed.csrec"
    crashed.write_bytes(data[:offsets[-1]])  # everything but the end record: what a crash leaves
    with caplog.at_level("WARNING"):
        export_npz(path, tmp_path / "clean.npz")
        assert not caplog.records
        export_npz(crashed, tmp_path / "crashed.npz")
    assert "never closed" in caplog.text and "crashed.csrec" in caplog.text
    assert np.load(tmp_path / "crashed.npz")["st1/0/counter"].tolist() == list(range(750))


def test_export_of_a_faulted_take_warns_once(tmp_path, caplog):
    """`courtside gateway export --npz --csv-dir` of a take ended by a full disk: one warning (it was two)."""
    from gateway.daemon import main

    _take_ended_by_a_full_disk(tmp_path)
    caplog.clear()
    with caplog.at_level("WARNING"):
        assert main(["export", str(tmp_path / "t"), "--npz", str(tmp_path / "o.npz"), "--csv-dir",
                     str(tmp_path / "csv")]) == 0
    warnings = [r.getMessage() for r in caplog.records if r.levelname == "WARNING"]
    assert len(warnings) == 1 and "ended by a disk fault" in warnings[0] and "ENOSPC" in warnings[0], warnings
    assert (tmp_path / "o.npz").is_file() and (tmp_path / "csv" / "st1_0.csv").is_file()

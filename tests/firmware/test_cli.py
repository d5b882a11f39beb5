"""`courtside emulate` as a user runs it: a separate process, ptys opened with pyserial, Ctrl-C to stop."""
from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import serial

from firmware_protocol import Ack, Command, Hello, Opcode, SampleBatch, StreamDecoder, encode
from firmware_protocol.emulator.cli import main


def _start(*args: str) -> tuple[subprocess.Popen, list[list[str]]]:
    proc = subprocess.Popen([sys.executable, "-m", "firmware_protocol.emulator.cli", *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    lines = []
    while (line := proc.stdout.readline().strip()):
        lines.append(line.split())
    return proc, lines


def _read_until(port: serial.Serial, decoder: StreamDecoder, done, timeout_s: float = 10.0) -> list:
    """Read until `done(frames)` holds (generous timeout: the machine may be busy)."""
    frames = []
    end = time.monotonic() + timeout_s
    while not done(frames):
        assert time.monotonic() < end, "emulator did not deliver in time"
        frames += decoder.feed(port.read(port.in_waiting or 1))
    return frames


def test_emulate_two_stations_on_ptys_and_stop_with_ctrl_c(tmp_path):
    trace = tmp_path / "trace.npy"
    np.save(trace, np.random.default_rng(0).normal(0, 2, (300, 3, 3)))
    proc, lines = _start("--stations", "2", "--sensors", "3", "--rate", "200", "--autostart", "--speed", "4",
                         "--trace", str(trace), "--trace-fps", "100", "--link-dir", str(tmp_path / "dev"))
    try:
        assert [line[:2] for line in lines] == [["station", "1"], ["station", "2"]]
        for sid, path, symlink in ((int(a[1]), a[2], a[3]) for a in lines):
            assert (tmp_path / "dev" / f"station-{sid}").resolve() == Path(path).resolve()
            with serial.Serial(symlink, timeout=0.02) as port:
                decoder = StreamDecoder()
                frames = _read_until(port, decoder,
                                     lambda fs: sum(isinstance(f.message, SampleBatch) for f in fs) >= 30)
                port.write(encode(Command(7, Opcode.REQUEST_HELLO), sid, 0))
                frames += _read_until(port, decoder, lambda fs: any(isinstance(f.message, Hello) for f in fs))
            assert {f.station_id for f in frames} == {sid}
            assert any(isinstance(f.message, Ack) and f.message.command_id == 7 for f in frames)
            hello = next(f.message for f in frames if isinstance(f.message, Hello))
            assert [s.rate_hz for s in hello.sensors] == [200] * 3
            batches = [f.message for f in frames if isinstance(f.message, SampleBatch)]
            assert {b.sensor_id for b in batches} == {0, 1, 2}
            assert np.std(np.concatenate([b.acc_g() for b in batches])) > 0.5      # the trace, not gravity
            assert decoder.stats.corrupt_frames <= 1     # at most the frame cut when we attached mid-stream
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=10) == 0
        assert "stopped" in proc.stderr.read()
        assert not (tmp_path / "dev" / "station-1").exists()
    finally:
        if proc.poll() is None:
            proc.kill()


def test_emulate_rejects_bad_options(capsys):
    assert main(["--loss", "3"]) == 2
    assert "radio_loss 3.0 not a probability" in capsys.readouterr().err
    assert main(["--trace", "/nonexistent/x.npy"]) == 2
    assert "/nonexistent/x.npy: cannot read trace" in capsys.readouterr().err
    assert main(["--mocap", "no_such_clip"]) == 2
    assert "no_such_clip: no such file, and not a shipped clip" in capsys.readouterr().err


def test_emulate_runs_for_a_duration_with_mocap(capsys):
    assert main(["--mocap", "16_01", "--duration", "0.3", "--autostart"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("station 1 /dev/pts/")


def test_emulate_orientation_with_mocap_and_its_refusal_for_a_trace(tmp_path, capsys):
    """`courtside emulate --orientation --mocap`: a station sending protocol-v2 MOTION_BATCHes; an
    acceleration trace has no orientation to send, which is one clear line."""
    proc, _ = _start("--orientation", "--mocap", "16_01", "--autostart", "--link-dir", str(tmp_path / "dev"))
    try:
        with serial.Serial(str(tmp_path / "dev" / "station-1"), timeout=0.2) as port:
            frames = _read_until(port, StreamDecoder(),
                                 lambda fs: sum(isinstance(f.message, SampleBatch) for f in fs) >= 20, 20.0)
        batches = [f.message for f in frames if isinstance(f.message, SampleBatch)]
        assert all(b.quat_q14 is not None and b.gyro_counts is not None for b in batches)
    finally:
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=10)
    np.save(tmp_path / "t.npy", np.zeros((10, 6, 3)))
    assert main(["--orientation", "--trace", str(tmp_path / "t.npy")]) == 2
    assert "t.npy: an acceleration trace has no orientation" in capsys.readouterr().err

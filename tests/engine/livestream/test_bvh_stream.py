"""Live BVH stream (Axis Neuron convention) to real TCP clients on 127.0.0.1."""
from __future__ import annotations

import socket
import threading
import time

import numpy as np

from engine.livestream import BvhBroadcastServer
from engine.mocap import load_clip, sample_clips
from engine.mocap.bvh import bvh_frame_values


def _read_lines(sock: socket.socket, n: int) -> list[str]:
    buf = b""
    sock.settimeout(10.0)
    while buf.count(b"\n") < n:
        chunk = sock.recv(65536)
        if not chunk:
            break
        buf += chunk
    return buf.decode().splitlines()


def _collect(port: int, received: list[str]) -> None:
    """A client that keeps trying to connect (the server starts later), then reads until the server closes."""
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        try:
            sock = socket.create_connection(("127.0.0.1", port), timeout=1.0)
        except OSError:
            time.sleep(0.05)
            continue
        sock.settimeout(30.0)
        data = b""
        while chunk := sock.recv(65536):
            data += chunk
        received.extend(data.decode().splitlines())
        sock.close()
        return


def test_two_clients_receive_every_frame_in_axis_format():
    motion = load_clip(sample_clips()["16_01"]).slice(0, 40)
    frames = bvh_frame_values(motion)
    with BvhBroadcastServer("127.0.0.1", 0) as server:
        clients = [socket.create_connection(server.address) for _ in range(2)]
        assert server.wait_for_clients(2, 5.0)
        server.stream(frames)
        for client in clients:
            lines = _read_lines(client, len(frames))
            assert len(lines) == len(frames)
            for line, row in zip(lines, frames):
                tokens = line.split()
                assert tokens[:2] == ["0", "Avatar00"] and tokens[-1] == "||"
                np.testing.assert_allclose(np.array(tokens[2:-1], float), row, atol=1e-6)
            client.close()


def test_a_client_that_leaves_is_dropped_and_the_others_keep_receiving():
    with BvhBroadcastServer("127.0.0.1", 0) as server:
        stay, leave = socket.create_connection(server.address), socket.create_connection(server.address)
        assert server.wait_for_clients(2, 5.0)
        leave.close()
        for _ in range(50):
            server.send_frame(np.zeros(3))
        assert server.n_clients == 1
        assert len(_read_lines(stay, 50)) == 50
        stay.close()


def test_synthesize_streams_what_it_writes(tmp_path):
    """`courtside synthesize --stream-bvh PORT`: a real client receives exactly the frames of the written BVH."""
    from engine.graph.cli import build_graph_main, synthesize_main
    from engine.mocap import SEED000_SENSORS, resample, standard_placements, virtual_accelerometers

    assert build_graph_main(["--sample", "-o", str(tmp_path / "g.npz")]) == 0
    motion = resample(load_clip(sample_clips()["16_11"]), 30.0)
    acc = virtual_accelerometers(motion, standard_placements(motion.skeleton, SEED000_SENSORS))
    np.savez(tmp_path / "take.npz", acc_g=acc, fps=30.0)
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    received: list[str] = []
    thread = threading.Thread(target=_collect, args=(port, received))
    thread.start()
    out = tmp_path / "out.bvh"
    assert synthesize_main(["--graph", str(tmp_path / "g.npz"), "--input", str(tmp_path / "take.npz"), "-o", str(out),
                            "--stream-bvh", str(port), "--stream-wait", "30"]) == 0
    thread.join(60)
    text = out.read_text().splitlines()
    motion_rows = text[text.index("MOTION") + 3:]
    assert len(received) == len(motion_rows) == motion.n_frames
    for line, row in zip(received[::25], motion_rows[::25]):
        np.testing.assert_allclose(np.array(line.split()[2:-1], float), np.array(row.split(), float), atol=1e-5)


def test_fixed_lag_synthesis_streams_each_pose_as_decided(tmp_path):
    """With --lag every emitted pose goes out at once (raw node pose placed on the path): one line per sample,
    within a few cm of the written (blended, foot-fixed) file."""
    from engine.graph.cli import build_graph_main, synthesize_main
    from engine.mocap import SEED000_SENSORS, resample, standard_placements, virtual_accelerometers

    assert build_graph_main(["--sample", "-o", str(tmp_path / "g.npz")]) == 0
    motion = resample(load_clip(sample_clips()["16_16"]), 30.0)
    acc = virtual_accelerometers(motion, standard_placements(motion.skeleton, SEED000_SENSORS))
    np.savez(tmp_path / "take.npz", acc_g=acc, fps=30.0)
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    received: list[str] = []
    thread = threading.Thread(target=_collect, args=(port, received))
    thread.start()
    out = tmp_path / "lag.bvh"
    assert synthesize_main(["--graph", str(tmp_path / "g.npz"), "--input", str(tmp_path / "take.npz"), "-o", str(out),
                            "--lag", "0.5", "--stream-bvh", f"127.0.0.1:{port}", "--stream-wait", "30"]) == 0
    thread.join(60)
    text = out.read_text().splitlines()
    rows = np.array([r.split() for r in text[text.index("MOTION") + 3:]], float)
    streamed = np.array([line.split()[2:-1] for line in received], float)
    assert streamed.shape == rows.shape == (motion.n_frames, rows.shape[1])
    assert np.median(np.linalg.norm(streamed[:, :3] - rows[:, :3], axis=1)) < 5.0  # root, cm


def test_console_setup_streams_what_its_synthesizer_emits(tmp_path):
    """The console's --stream-bvh swaps only the synthesizer factory: poses pushed through it reach a client."""
    from dataclasses import dataclass
    from typing import Any, Callable

    from engine.graph.graph import MotionGraph
    from engine.graph.cli import build_graph_main
    from engine.graph.online import FixedLagSynthesizer
    from engine.livestream.console import streaming_setup
    from engine.mocap import SEED000_SENSORS, resample, standard_placements, virtual_accelerometers

    @dataclass
    class Setup:  # the fields of gui.synthesis.SynthesisSetup that matter here
        make_synthesizer: Callable[[float], Any]
        lag_s: float = 0.5

    assert build_graph_main(["--sample", "-o", str(tmp_path / "g.npz")]) == 0
    graph = MotionGraph.load(tmp_path / "g.npz")
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    setup = streaming_setup(Setup(lambda lag: FixedLagSynthesizer(graph, lag)), graph, graph.skeleton, str(port))
    client = socket.create_connection(("127.0.0.1", port))
    synth = setup.make_synthesizer(0.5)
    motion = resample(load_clip(sample_clips()["16_11"]), 30.0)
    acc = virtual_accelerometers(motion, standard_placements(motion.skeleton, SEED000_SENSORS))
    deadline = time.monotonic() + 10
    while synth._streamer.server.n_clients < 1 and time.monotonic() < deadline:
        time.sleep(0.01)
    emitted = sum(len(synth.push(a)) for a in acc[:60]) + len(synth.flush())
    lines = _read_lines(client, emitted)
    assert emitted == 60 and len(lines) == 60
    assert all(line.startswith("0 Avatar00 ") and line.endswith(" ||") for line in lines)
    client.close()
    synth._streamer.server.close()

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

    def client():
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

    thread = threading.Thread(target=client)
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

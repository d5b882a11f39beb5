"""Live BVH stream (Axis Neuron convention) to real TCP clients on 127.0.0.1."""
from __future__ import annotations

import socket
import threading
import time

import numpy as np
import pytest

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
        for row in frames:
            server.send_frame(row)
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


def _synthesize_streaming(tmp_path, clip: str, *options: str):
    """`courtside synthesize` on a clip's virtual accelerometers with a BVH client listening on a free loopback
    port; ``options`` may use ``{port}``. Returns (the clip, the lines the client received, the written BVH's lines)."""
    from engine.graph.cli import build_graph_main, synthesize_main
    from engine.mocap import SEED000_SENSORS, resample, standard_placements, virtual_accelerometers

    assert build_graph_main(["--sample", "-o", str(tmp_path / "g.npz")]) == 0
    motion = resample(load_clip(sample_clips()[clip]), 30.0)
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
                            *(o.format(port=port) for o in options), "--stream-wait", "30"]) == 0
    thread.join(60)
    return motion, received, out.read_text().splitlines()


def test_synthesize_streams_what_it_writes(tmp_path):
    """`courtside synthesize --stream-bvh PORT`: a real client receives exactly the frames of the written BVH."""
    motion, received, text = _synthesize_streaming(tmp_path, "16_11", "--stream-bvh", "{port}")
    motion_rows = text[text.index("MOTION") + 3:]
    assert len(received) == len(motion_rows) == motion.n_frames
    for line, row in zip(received[::25], motion_rows[::25]):
        np.testing.assert_allclose(np.array(line.split()[2:-1], float), np.array(row.split(), float), atol=1e-5)


def test_fixed_lag_synthesis_streams_each_pose_as_decided(tmp_path):
    """With --lag every emitted pose goes out at once (raw node pose placed on the path): one line per sample,
    within a few cm of the written (blended, foot-fixed) file."""
    motion, received, text = _synthesize_streaming(tmp_path, "16_16", "--lag", "0.5",
                                                   "--stream-bvh", "127.0.0.1:{port}")
    rows = np.array([r.split() for r in text[text.index("MOTION") + 3:]], float)
    streamed = np.array([line.split()[2:-1] for line in received], float)
    assert streamed.shape == rows.shape == (motion.n_frames, rows.shape[1])
    assert np.median(np.linalg.norm(streamed[:, :3] - rows[:, :3], axis=1)) < 5.0  # root, cm


def test_console_setup_streams_what_its_synthesizer_emits(tmp_path):
    """The console's --stream-bvh / --stream-vmc swap only the engine factory: every pose pushed through it reaches
    a BVH client and a VMC receiver, one line / one bundle each."""
    from pythonosc.dispatcher import Dispatcher
    from pythonosc.osc_server import ThreadingOSCUDPServer

    from engine.graph.graph import MotionGraph
    from engine.graph.cli import build_graph_main
    from engine.livestream.console import streaming_engine
    from engine.mocap import SEED000_SENSORS, resample, standard_placements, virtual_accelerometers
    from engine.graph.online_engine import motion_graph_spec

    assert build_graph_main(["--sample", "-o", str(tmp_path / "g.npz")]) == 0
    graph = MotionGraph.load(tmp_path / "g.npz")
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    vmc_t: list[float] = []
    dispatcher = Dispatcher()
    dispatcher.map("/VMC/Ext/T", lambda address, t: vmc_t.append(t))
    receiver = ThreadingOSCUDPServer(("127.0.0.1", 0), dispatcher)
    threading.Thread(target=receiver.serve_forever, daemon=True).start()
    try:
        spec = streaming_engine(motion_graph_spec(graph, "g.npz"), bvh=str(port),
                                vmc=f"127.0.0.1:{receiver.server_address[1]}")
        client = socket.create_connection(("127.0.0.1", port))
        synth = spec.make(0.5)
        motion = resample(load_clip(sample_clips()["16_11"]), 30.0)
        acc = virtual_accelerometers(motion, standard_placements(motion.skeleton, SEED000_SENSORS))
        deadline = time.monotonic() + 10
        while synth._streamer.server.n_clients < 1 and time.monotonic() < deadline:
            time.sleep(0.01)
        emitted = sum(len(synth.push(a)) for a in acc[:60]) + len(synth.flush())
        lines = _read_lines(client, emitted)
        deadline = time.monotonic() + 5
        while len(vmc_t) < emitted and time.monotonic() < deadline:
            time.sleep(0.01)
    finally:
        receiver.shutdown()
    assert emitted == 60 and len(lines) == 60 and len(vmc_t) == 60
    assert all(line.startswith("0 Avatar00 ") and line.endswith(" ||") for line in lines)
    client.close()
    synth._streamer.server.close()


def test_console_stream_flags_refuse_an_engine_without_a_skeleton():
    from engine.errors import CourtsideError
    from engine.livestream.console import streaming_engine
    from engine.stream.engines import EngineSpec

    spec = EngineSpec(name="olng", database="kb.npz", sensor_names=("left_wrist",), rate_hz=30.0,
                      parents=np.array([-1]), make=lambda lag_s: None)
    with pytest.raises(CourtsideError, match="--stream-vmc streams an engine.s decided rotations; the olng engine names no skeleton"):
        streaming_engine(spec, vmc="39539")


def test_vmc_bundles_rebuild_the_skeleton_on_a_real_udp_receiver():
    """VMC over OSC/UDP to a python-osc server on 127.0.0.1: composing the received bones (converted back from
    Unity's left-handed frame) along the humanoid hierarchy gives exactly the clip's mapped joint positions."""
    import threading as th

    from pythonosc.dispatcher import Dispatcher
    from pythonosc.osc_server import ThreadingOSCUDPServer

    from engine.livestream.vmc import VmcSender
    from engine.mocap import forward_kinematics, quaternions as quat

    motion = load_clip(sample_clips()["16_05"]).slice(100, 103)
    received: list[tuple] = []
    dispatcher = Dispatcher()
    dispatcher.map("/VMC/Ext/*", lambda address, *args: received.append((address, *args)))
    server = ThreadingOSCUDPServer(("127.0.0.1", 0), dispatcher)
    thread = th.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        sender = VmcSender(motion.skeleton, "127.0.0.1", server.server_address[1])
        sender.send_motion(motion)
        deadline = time.monotonic() + 5
        while sum(1 for m in received if m[0] == "/VMC/Ext/OK") < 3 and time.monotonic() < deadline:
            time.sleep(0.01)
    finally:
        server.shutdown()
    frames, current = [], {}
    for address, *args in received:
        if address == "/VMC/Ext/Bone/Pos":
            current[args[0]] = (np.array(args[1:4]) * [-1, 1, 1], np.array([args[7], args[4], -args[5], -args[6]]))
        elif address == "/VMC/Ext/OK":
            frames.append(current)
            current = {}
    assert len(frames) == 3 and len(frames[0]) == 21
    pos, _ = forward_kinematics(motion)
    vmap = sender.map
    for f, bones in enumerate(frames):
        world: dict[str, tuple] = {}
        for bone in vmap.parent_of:  # parents come before children in the table
            p, q = bones[bone]
            parent = vmap.parent_of[bone]
            if parent is None:
                world[bone] = (p, quat.to_matrix(q))
            else:
                pp, pr = world[parent]
                world[bone] = (pp + pr @ p, pr @ quat.to_matrix(q))
            np.testing.assert_allclose(world[bone][0], pos[f, vmap.joint_of[bone]], atol=1e-4)
    assert [m for m in received if m[0] == "/VMC/Ext/Root/Pos"][0][1] == "root"


def test_synthesize_sends_vmc_frames(tmp_path):
    """`courtside synthesize --lag 0.5 --stream-vmc PORT`: one VMC bundle per sample reaches a UDP receiver."""
    import threading as th

    from pythonosc.dispatcher import Dispatcher
    from pythonosc.osc_server import ThreadingOSCUDPServer

    from engine.graph.cli import build_graph_main, synthesize_main
    from engine.mocap import SEED000_SENSORS, resample, standard_placements, virtual_accelerometers

    assert build_graph_main(["--sample", "-o", str(tmp_path / "g.npz")]) == 0
    motion = resample(load_clip(sample_clips()["16_11"]), 30.0).slice(0, 60)
    acc = virtual_accelerometers(motion, standard_placements(motion.skeleton, SEED000_SENSORS))
    np.savez(tmp_path / "take.npz", acc_g=acc, fps=30.0)
    oks: list[float] = []
    dispatcher = Dispatcher()
    dispatcher.map("/VMC/Ext/T", lambda address, t: oks.append(t))
    server = ThreadingOSCUDPServer(("127.0.0.1", 0), dispatcher)
    th.Thread(target=server.serve_forever, daemon=True).start()
    try:
        assert synthesize_main(["--graph", str(tmp_path / "g.npz"), "--input", str(tmp_path / "take.npz"),
                                "-o", str(tmp_path / "o.bvh"), "--lag", "0.5",
                                "--stream-vmc", f"127.0.0.1:{server.server_address[1]}"]) == 0
        deadline = time.monotonic() + 5
        while len(oks) < 60 and time.monotonic() < deadline:
            time.sleep(0.01)
    finally:
        server.shutdown()
    assert len(oks) == 60 and oks == sorted(oks)

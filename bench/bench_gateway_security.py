"""What authentication and TLS cost on the gateway's client link (issue 13 "two machines").

Prints two tables, each against the plain (unauthenticated loopback) baseline measured in the same process:

1. connect: TCP connect + hello (+ HMAC challenge-response) (+ TLS handshake), median / p90 of N connects;
2. stream: M ``samples`` messages of 5 samples (one radio batch, the real message built by `SampleBlock`)
   published by the server and received by one client: messages/s and samples/s end to end.

Run: ``.venv/bin/python bench/bench_gateway_security.py [--connects 60] [--messages 20000] [--rounds 3]`` (needs the
``openssl`` command for the TLS rows). Real sockets on 127.0.0.6 only.
"""
from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from gateway import auth  # noqa: E402
from gateway.client import GatewayClient  # noqa: E402
from gateway.server import StreamServer  # noqa: E402
from gateway.station import SampleBlock  # noqa: E402

HOST = "127.0.0.6"


def _certificate(directory: Path) -> tuple[Path, Path] | None:
    if shutil.which("openssl") is None:
        return None
    cert, key = directory / "cert.pem", directory / "key.pem"
    subprocess.run(["openssl", "req", "-x509", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes",
                    "-days", "1", "-subj", "/CN=bench", "-keyout", str(key), "-out", str(cert)],
                   check=True, capture_output=True)
    return cert, key


def _block(i: int) -> SampleBlock:
    n = 5
    return SampleBlock("st1", i % 6, 100.0, True, 0, np.arange(i * n, i * n + n, dtype=np.uint32),
                       np.arange(n, dtype=np.uint32), np.arange(n, dtype=np.float64), np.zeros(n), np.zeros(n),
                       np.ones((n, 3), np.float32))


def _modes(secret: bytes, cert_key: tuple[Path, Path] | None):
    yield "plain (loopback, no auth)", {}, {}
    yield "HMAC challenge-response", {"secrets": auth.Secrets(secret)}, {"secret": secret}
    if cert_key is not None:
        cert, key = cert_key
        yield ("HMAC + TLS", {"secrets": auth.Secrets(secret), "tls": auth.server_tls_context(cert, key)},
               {"secret": secret, "tls": auth.client_tls_context(cert)})


def bench_connect(n: int, server_kw: dict, client_kw: dict) -> np.ndarray:
    server = StreamServer(lambda a, b, r: None, host=HOST, port=0, **server_kw).start()
    try:
        times = []
        for _ in range(n):
            t0 = time.perf_counter()
            client = GatewayClient(*server.address, **client_kw).connect()
            times.append(time.perf_counter() - t0)
            client.close()
        return np.array(times)
    finally:
        server.close()


def bench_stream(m: int, server_kw: dict, client_kw: dict) -> float:
    server = StreamServer(lambda a, b, r: None, host=HOST, port=0, display_queue_frames=m + 10, **server_kw).start()
    client = GatewayClient(*server.address, inbox_size=16, **client_kw).connect()
    done = threading.Event()
    got = [0]

    def count(_msg) -> None:
        got[0] += 1
        if got[0] == m:
            done.set()

    client.add_listener("samples", count)
    client.subscribe(["samples"])
    blocks = [_block(i) for i in range(m)]
    t0 = time.perf_counter()
    for block in blocks:
        server.publish("samples", block.header(), block.arrays())
    done.wait(120)
    elapsed = time.perf_counter() - t0
    client.close()
    server.close()
    if got[0] != m:
        raise RuntimeError(f"received {got[0]} of {m}")
    return elapsed


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--connects", type=int, default=60)
    parser.add_argument("--messages", type=int, default=20_000)
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    with tempfile.TemporaryDirectory() as tmp:
        secret = auth.new_secret().encode()
        cert_key = _certificate(Path(tmp))
        modes = list(_modes(secret, cert_key))
        print(f"\nconnect + hello (+ auth) (+ TLS), {args.connects} connects")
        print("| link | median ms | p90 ms | median vs plain |\n|---|---|---|---|")
        base = None
        for name, server_kw, client_kw in modes:
            t = bench_connect(args.connects, server_kw, client_kw) * 1e3
            base = base or float(np.median(t))
            print(f"| {name} | {np.median(t):.2f} | {np.percentile(t, 90):.2f} | {np.median(t) / base:.1f}x |")
        print(f"\nstream {args.messages} samples messages (5 samples each) to one client, best of {args.rounds} "
              "interleaved rounds")
        print("| link | messages/s | samples/s | time vs plain |\n|---|---|---|---|")
        best = {name: min(bench_stream(args.messages, server_kw, client_kw) for _ in range(1))
                for name, server_kw, client_kw in modes}
        for _ in range(args.rounds - 1):
            for name, server_kw, client_kw in modes:
                best[name] = min(best[name], bench_stream(args.messages, server_kw, client_kw))
        base = best[modes[0][0]]
        for name, elapsed in best.items():
            rate = args.messages / elapsed
            print(f"| {name} | {rate:,.0f} | {5 * rate:,.0f} | {elapsed / base:.2f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

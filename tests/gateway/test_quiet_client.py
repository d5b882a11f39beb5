"""Found by bench/bench_soak.py: an authenticated client that only listens must not be dropped as "too slow"
once the handshake timeout has passed (the frame deadline used to start before the frame did)."""
from __future__ import annotations

import time

from gateway.client import GatewayClient
from gateway.daemon import Gateway


def test_a_listening_client_outlives_the_handshake_timeout(tmp_path):
    with Gateway([], listen=("127.0.0.1", 0), record_dir=tmp_path, handshake_timeout_s=0.3) as gw:
        client = GatewayClient(*gw.address).connect()
        try:
            client.subscribe(["event"])
            time.sleep(1.2)  # four handshake timeouts without a byte from the client
            assert client.connected
            assert "t_host_s" in client.request("ping")
        finally:
            client.close()

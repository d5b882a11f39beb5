"""An authenticated (or loopback) client that sends nothing stays connected: the handshake/frame timeout bounds
a frame once started, not the quiet time between requests. (Merged daemon code cut every idle console off after
``handshake_timeout_s``; the console then reconnected and lost the samples in between.)"""
from __future__ import annotations

import time

from gateway.client import GatewayClient
from gateway.server import StreamServer


def test_an_idle_client_is_not_disconnected_by_the_frame_timeout():
    srv = StreamServer(lambda action, args, role: {"pong": True}, port=0, handshake_timeout_s=0.3).start()
    try:
        with GatewayClient(*srv.address).connect() as client:
            time.sleep(1.2)  # four timeouts' worth of silence
            assert client.connected
            assert client.request("ping") == {"pong": True}
    finally:
        srv.close()

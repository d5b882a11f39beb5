"""HID base stations: the fake hidapi bus (same API as `hid`) behind the production HidLink, discovery by
VID:PID, samples through the gateway, unplug -> lost -> replug -> streaming again."""
from __future__ import annotations

import time

from firmware_protocol.emulator import BaseStation, StationConfig
from firmware_protocol.emulator.hid_transport import FakeHidBus
from firmware_protocol.emulator.link import EmulatorLink
from gateway.daemon import Gateway
from gateway.links import HidLink, LinkError, discover_hid

import pytest


def wait_for(predicate, timeout_s=5.0):
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.02)
    return False


def test_hid_station_discovered_streams_and_survives_replug(tmp_path):
    bus = FakeHidBus()
    link = EmulatorLink(BaseStation(StationConfig(station_id=9, n_sensors=3)), realtime=True)
    bus.attach(link, serial_number="ABC123")
    found = discover_hid(enumerate_fn=bus.enumerate)
    assert [(p.transport, p.serial_number) for p in found] == [("hid", "ABC123")]
    with Gateway([], listen=("127.0.0.1", 0), record_dir=tmp_path, status_interval_s=0.1,
                 open_link=lambda source: HidLink(source, hid_module=bus),
                 discover=[lambda: discover_hid(enumerate_fn=bus.enumerate)]) as gw:
        assert wait_for(lambda: gw.readers and gw.readers[0].status()["link"] == "streaming")
        reader = gw.readers[0]
        assert reader.transport == "hid" and reader.name == "st9"
        assert wait_for(lambda: gw.samples_in > 300)
        link.unplug()
        assert wait_for(lambda: reader.status()["link"] == "lost")
        before = gw.samples_in
        link.replug()
        t0 = time.monotonic()
        assert wait_for(lambda: reader.status()["link"] == "streaming" and gw.samples_in > before + 50)
        assert time.monotonic() - t0 < 2.0
        status = reader.status()
        assert status["reconnects"] == 1 and status["clock"]["resets"] == 1
        assert len(gw.readers) == 1  # rediscovery did not add the same device twice


def test_hid_open_failure_is_a_link_error():
    with pytest.raises(LinkError, match="hid:1209:c0de"):
        HidLink("hid:1209:c0de", hid_module=FakeHidBus())
    with pytest.raises(LinkError, match="HID sources look like"):
        HidLink("/dev/ttyACM0", hid_module=FakeHidBus())


def test_real_hid_path_does_not_import_the_emulator():
    """The HID report framing is defined once in firmware_protocol.hid; opening a real HID link must not load
    the emulator package (issue 13 "Shape")."""
    import subprocess
    import sys

    code = (
        "import sys\n"
        "from gateway.links import HidLink, LinkError\n"
        "class Device:\n"
        "    def open(self, *a): raise OSError('no such device')\n"
        "class Hid:\n"
        "    device = Device\n"
        "try:\n"
        "    HidLink('hid:1209:c0de', hid_module=Hid())\n"
        "except LinkError as exc:\n"
        "    print('refused:', exc)\n"
        "print(sorted(m for m in sys.modules if m.startswith('firmware_protocol.emulator')))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=True).stdout
    assert "refused: hid:1209:c0de: cannot open (no such device)" in out
    assert out.strip().endswith("[]"), out

"""Soak: the gateway under hostile clients, a disk that fills and frees, and device faults, for 10 minutes of
emulated time (faster than real time), then the books are balanced.

    nice -n 10 .venv/bin/python bench/bench_soak.py [--minutes 10] [--speed 4]

What runs (all on this machine; sockets on 127.0.0.1 only):
* 2 emulated base stations (6 sensors x 100 Hz) over real ptys at `--speed` x real time, 1 % radio loss, bursts,
  wire corruption, every cable pulled every 150 emulated seconds; they run in a `courtside emulate` child process,
  so the RSS measured here is the gateway's (plus this script's hostile clients and sample bookkeeping);
* a faulty station (a `Link` that writes crafted frames): a HELLO with tick_rate_hz 0, batches with period 0 or
  a NaN scale, device ticks stepping back by 1 s, payloads over 4096 bytes, garbage bytes;
* hostile clients in bounded loops: random bytes, oversized and never-finished length prefixes, JSON nested
  200 000 deep, an array of shape [2**32, 2**32], connections that never finish the handshake, churn, more
  connections than allowed, a flood of invalid requests, a subscriber that never reads, and `--silent-askers`
  clients that send ``status`` requests as fast as they can without ever reading a reply (issue 22's probe: four
  of them grew the gateway by 139 MB in 13 s when queues were bounded in frames; now in bytes, with a budget);
* the recorder writes through `firmware_protocol.emulator.faultfs.SimulatedDisk`: the disk fills twice; each time the operator (this
  script) waits for the alarm, frees space 30 emulated seconds later and starts the next take.

Reported: samples delivered by the readers = samples recorded (per take, except the samples the full disk
cost, which the recorder counts), RSS over the run, the peak of the bytes queued for clients against the
server's budget, threads that died (threading.excepthook), refused device messages and clock epochs. Exit 1 if a
check fails.
"""
from __future__ import annotations

import argparse
import array
import json
import os
import socket
import struct
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import firmware_protocol as fp  # noqa: E402
from firmware_protocol.framing import CRC, HEADER, crc32  # noqa: E402
from gateway import codec  # noqa: E402
from gateway.client import GatewayClient  # noqa: E402
from gateway.daemon import Gateway  # noqa: E402
from firmware_protocol.emulator.faultfs import SimulatedDisk  # noqa: E402
from gateway.recorder import load_take  # noqa: E402
from gateway.station import SampleBlock  # noqa: E402

BYTES_PER_EMULATED_S = 70_000  # what 2 x 6 x 100 Hz + the faulty station + events cost on disk, roughly


UNPLUG_EVERY_EMULATED_S = 150.0


def rss_mb() -> float:
    return _rss_of("self")


def _rss_of(pid: int | str) -> float:
    with open(f"/proc/{pid}/status") as fh:
        for line in fh:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    return float("nan")


# ------------------------------------------------------------------------------------------- faulty station
class FaultyStationLink:
    """A station link that speaks the protocol with deliberate field faults (one instance per connect)."""

    transport = "serial"
    STATION_ID = 9

    def __init__(self, source: str, script: "FaultScript"):
        self.source = source
        self.script = script
        self.seq = 0
        self.out = bytearray()
        self.t0 = time.monotonic()
        self.next_batch_s = 0.0
        self.counter = 0
        self.tick_offset = 0
        hello_bad = fp.Hello((9, 9, 9), 9, 0x9999, 0, (100,), (8,), (fp.SensorInfo(0, 1, 100, 8),))
        self._send(hello_bad)
        script.count("hello tick_rate_hz 0")
        self._send(fp.Hello((9, 9, 9), 9, 0x9999, 1_000_000, (100,), (8,), (fp.SensorInfo(0, 1, 100, 8),)))

    def _send(self, message) -> None:
        self.out += fp.encode(message, self.STATION_ID, self.seq)
        self.seq += 1

    def _ticks(self, t_s: float) -> int:
        return (int(t_s * 1_000_000) + self.tick_offset) % (1 << 32)

    def read(self, max_bytes: int) -> bytes:
        now = time.monotonic() - self.t0
        while self.next_batch_s <= now:
            t = self.next_batch_s
            self.next_batch_s += 0.05
            k = int(round(t / 0.05))
            samples = np.tile(np.array([[0, 0, 4096]], np.int16), (5, 1))
            if k % 200 == 150:  # every 10 s: a batch with an impossible field
                bad = [fp.SampleBatch(0, 0, self.counter, self._ticks(t), 0, fp.scale_for_range(8), samples),
                       fp.SampleBatch(0, 0, self.counter, self._ticks(t), 2_560_000, float("nan"), samples)][k // 200 % 2]
                self._send(bad)
                self.script.count("batch field")
                continue
            if k % 400 == 300:  # every 20 s: the device clock steps back by 1 s
                self.tick_offset -= 1_000_000
                self.script.count("ticks back 1 s")
            if k % 300 == 100:  # every 15 s: a payload over 4096 bytes and garbage
                body = HEADER.pack(1, 0x7F, self.STATION_ID, self.seq, 4100) + bytes(4100)
                from cobs.cobs import encode as cobs_encode
                self.out += cobs_encode(body + CRC.pack(crc32(body))) + b"\x00" + os.urandom(300) + b"\x00"
                self.seq += 1
                self.script.count("oversized payload + garbage")
            self._send(fp.SampleBatch(0, 0, self.counter, self._ticks(t), 2_560_000, fp.scale_for_range(8), samples))
            self.counter += 5
            if k % 10 == 0:
                self._send(fp.ClockSync(self._ticks(t), k // 10))
        data, self.out = bytes(self.out[:max_bytes]), self.out[max_bytes:]
        if not data:
            time.sleep(0.01)
        return data

    def write(self, data: bytes) -> None:
        pass  # commands are ignored (no ACKs: the reader never waits for them at connect)

    def close(self) -> None:
        pass


class FaultScript:
    def __init__(self):
        self.counts: dict[str, int] = {}
        self.lock = threading.Lock()

    def count(self, what: str) -> None:
        with self.lock:
            self.counts[what] = self.counts.get(what, 0) + 1


# ------------------------------------------------------------------------------------------- hostile clients
def _frame(body: bytes) -> bytes:
    return struct.pack(">I", len(body)) + body


def hostile_clients(address: tuple[str, int], stop: threading.Event, tally: dict[str, int]) -> None:
    """Bounded loops of misbehaving clients, cycling until `stop`."""
    deep_json = b"[" * 200_000 + b"]" * 200_000
    deep = _frame(struct.pack(">I", len(deep_json)) + deep_json)
    shape_json = json.dumps({"kind": "request", "id": 1, "action": "ping", "args": {},
                             "arrays": [{"name": "a", "dtype": "<f8", "shape": [2**32, 2**32]}]}).encode()
    huge_shape = _frame(struct.pack(">I", len(shape_json)) + shape_json)
    bad_requests = [codec.encode("request", {"id": i, "action": a, "args": args}) for i, (a, args) in enumerate([
        ("explode", {}), ("start_recording", {"take": "../escape"}), ("start_recording", {"take": "a\nb"}),
        ("station_command", {"station": "st1", "command": "set_rate", "args": {"rate_hz": 2 ** 40}}),
        ("station_command", {"station": "nope", "command": "identify"}), ("calibration", {"action": "x"}),
        ("station_command", {"station": "st1", "command": "identify", "args": {"sensor": "all"}}),
    ])]

    def one(kind: str, payload: bytes | None, linger_s: float = 0.2) -> None:
        try:
            with socket.create_connection(address, timeout=2.0) as s:
                if payload:
                    s.sendall(payload)
                end = time.monotonic() + linger_s  # read what the server says, for at most linger_s in total
                try:
                    while (left := end - time.monotonic()) > 0:
                        s.settimeout(left)
                        if not s.recv(65536):
                            break
                except OSError:
                    pass
            tally[kind] = tally.get(kind, 0) + 1
        except OSError as exc:  # the accept queue full (timeout) or the connection refused
            why = "timed out" if isinstance(exc, TimeoutError) else "refused"
            tally[f"{kind} ({why})"] = tally.get(f"{kind} ({why})", 0) + 1

    cycle = 0
    while not stop.is_set() and cycle < 10_000:
        cycle += 1
        one("random bytes", os.urandom(4096))
        one("length 2**32-1", b"\xff\xff\xff\xff")
        one("64 MiB announced, never sent", struct.pack(">I", (64 << 20) - 1) + b"x" * 100)
        one("JSON nested 200k deep", deep)
        one("array shape [2**32, 2**32]", huge_shape)
        one("request flood", b"".join(_frame(b) for b in bad_requests * 20), linger_s=0.5)
        for _ in range(20):
            one("churn", None, linger_s=0.0)
        if cycle % 5 == 1:  # more connections than allowed, and handshakes never finished
            socks = []
            for _ in range(40):
                try:
                    socks.append(socket.create_connection(address, timeout=2.0))
                    tally["crowd"] = tally.get("crowd", 0) + 1
                except OSError as exc:
                    why = "timed out" if isinstance(exc, TimeoutError) else "refused"
                    tally[f"crowd ({why})"] = tally.get(f"crowd ({why})", 0) + 1
            stop.wait(1.0)
            for s in socks:
                s.close()
        stop.wait(0.5)


def never_reading_subscriber(address: tuple[str, int], stop: threading.Event) -> None:
    """Subscribes to everything and then stops reading: only its display frames may be dropped."""
    with socket.create_connection(address) as s:
        s.sendall(_frame(codec.encode("subscribe", {"id": 1, "topics": ["samples", "camera", "status"]})))
        stop.wait()


def silent_asker(address: tuple[str, int], stop: threading.Event, tally: dict[str, int], lock: threading.Lock) -> None:
    """Asks for ``status`` as fast as the socket takes it and never reads; reconnects when cut off."""
    request = _frame(codec.encode("request", {"id": 1, "action": "status", "args": {}}))
    while not stop.is_set():
        try:
            sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)  # before connecting: a small window
            sock.settimeout(2.0)
            sock.connect(address)
        except OSError:
            stop.wait(0.5)
            continue
        with sock:
            try:
                while not stop.is_set():
                    try:
                        sock.sendall(request)
                    except socket.timeout:  # the gateway is slow to read our requests: keep the connection
                        continue
            except OSError:  # cut off by the gateway (not reading): start again
                with lock:
                    tally["silent asker cut off"] = tally.get("silent asker cut off", 0) + 1
        stop.wait(0.2)


# ------------------------------------------------------------------------------------------- the run
class Books:
    """Every sample block the readers delivered: (time, stream, epoch, first counter, n), compactly."""

    def __init__(self):
        self.t, self.stream, self.epoch, self.first, self.n = (array.array("d"), array.array("q"), array.array("q"),
                                                               array.array("q"), array.array("q"))
        self.streams: dict[tuple[str, int], int] = {}
        self.lock = threading.Lock()

    def add(self, block: SampleBlock) -> None:
        with self.lock:
            sid = self.streams.setdefault((block.station, block.sensor), len(self.streams))
            self.t.append(time.monotonic())
            self.stream.append(sid)
            self.epoch.append(block.epoch)
            self.first.append(int(block.counter[0]))
            self.n.append(len(block.counter))

    def delivered(self, t0: float, t1: float) -> set[tuple[str, int, int, int]]:
        names = {v: k for k, v in self.streams.items()}
        out = set()
        with self.lock:
            for t, s, e, f, n in zip(self.t, self.stream, self.epoch, self.first, self.n):
                if t0 <= t <= t1:
                    station, sensor = names[s]
                    out.update((station, sensor, e, (f + i) % (1 << 32)) for i in range(n))
        return out


def recorded(path: Path) -> set[tuple[str, int, int, int]]:
    take = load_take(path)
    out = set()
    for (station, sensor), cols in take.samples.items():
        out.update(zip([station] * len(cols["counter"]), [sensor] * len(cols["counter"]),
                       cols["epoch"].tolist(), cols["counter"].tolist()))
    return out


def run(minutes: float, speed: float, silent_askers: int = 8) -> bool:
    span_s = minutes * 60.0
    tmp = Path(tempfile.mkdtemp(prefix="courtside-soak-"))
    died: list[str] = []
    threading.excepthook = lambda args: died.append(f"{args.thread.name if args.thread else '?'}: "
                                                    f"{args.exc_type.__name__}: {args.exc_value}")
    emulator = subprocess.Popen(
        [sys.executable, "-m", "firmware_protocol.emulator.cli", "--stations", "2", "--sensors", "6", "--rate", "100",
         "--loss", "0.01", "--burst", "0.01", "--corruption", "2e-5", "--drift", "40", "--speed", str(speed),
         "--link-dir", str(tmp), "--unplug-every", str(UNPLUG_EVERY_EMULATED_S / speed), "--unplug-for", "0.5"],
        stdout=subprocess.PIPE, text=True, cwd=Path(__file__).resolve().parent.parent)
    paths = []
    while (line := emulator.stdout.readline().strip()):
        paths.append(line.split()[-1])
    t_origin = time.monotonic()  # emulated time 0 (to within the emulator's start-up)
    threading.Thread(target=lambda: [None for _ in emulator.stdout], daemon=True).start()  # drain "replugged" lines
    disk = SimulatedDisk(free_bytes=int(BYTES_PER_EMULATED_S * span_s / 5))  # fills about 2 emulated min in
    books, script = Books(), FaultScript()
    gw = Gateway(paths, listen=("127.0.0.1", 0), record_dir=tmp / "rec", status_interval_s=0.5,
                 reconnect_interval_s=0.05)
    gw.recorder.opener = disk.open
    original_on_samples = gw.on_samples

    def on_samples(block: SampleBlock) -> None:
        books.add(block)
        original_on_samples(block)

    gw.on_samples = on_samples  # readers call sink.on_samples: the instance attribute wins
    gw.add_station("faulty://9", open_link=lambda source: FaultyStationLink(source, script))
    stop = threading.Event()
    tally: dict[str, int] = {}
    rss: list[tuple[float, float]] = []
    takes: list[dict] = []
    events: list[tuple[str, str, str]] = []  # (level, source, message) as a client saw them

    def emulated_now() -> float:
        return (time.monotonic() - t_origin) * speed

    queued_peak = [0]

    def sleep_until(t_emulated_s: float) -> None:
        while (left := (t_emulated_s - emulated_now()) / speed) > 0:
            stop.wait(min(left, 0.5))
            rss.append((emulated_now(), rss_mb()))
            queued_peak[0] = max(queued_peak[0], gw.server.queued_bytes)

    wall0 = time.monotonic()
    gw.start()
    monitor_drops = [0]

    def connect_monitor() -> GatewayClient:
        client = GatewayClient(*gw.address).connect()
        client.local_address = "%s:%d" % client._sock.getsockname()[:2]
        client.subscribe(["event"])
        client.add_listener("event", lambda m: events.append((m["level"], m["source"], m["message"])))
        return client

    monitor = connect_monitor()
    threads = [threading.Thread(target=hostile_clients, args=(gw.address, stop, tally), name="soak-hostile"),
               threading.Thread(target=never_reading_subscriber, args=(gw.address, stop), name="soak-silent")]
    tally_lock = threading.Lock()
    threads += [threading.Thread(target=silent_asker, args=(gw.address, stop, tally, tally_lock),
                                 name=f"soak-asker-{i}") for i in range(silent_askers)]
    for t in threads:
        t.start()
    threads_before = {t.name for t in threading.enumerate()}

    def start_take(name: str) -> None:
        state = gw.handle_request("start_recording", {"take": name})  # the operator, in-process
        takes.append({"take": name, "start": time.monotonic(), "path": state["path"], "end": None, "fault": None})

    try:
        sleep_until(5.0)
        start_take("soak-1")
        n_fills = 0
        while emulated_now() < span_s - 5.0:
            sleep_until(min(emulated_now() + 1.0, span_s - 5.0))
            if not monitor.connected:  # the server drops a client that falls too far behind; count and rejoin
                monitor_drops[0] += 1
                print(f"monitoring client {monitor.local_address} "
                      f"dropped at {emulated_now():.0f} s emulated", flush=True)
                monitor = connect_monitor()
            if takes[-1]["end"] is None and not gw.recorder.active:  # the disk filled
                takes[-1]["end"] = time.monotonic()
                takes[-1]["fault"] = gw.recorder.state().get("fault")
                takes[-1]["lost"] = gw.recorder.state().get("samples_lost")
                n_fills += 1
                sleep_until(emulated_now() + 30.0)  # the operator frees space half a minute later
                disk.set_free(int(BYTES_PER_EMULATED_S * span_s / 4) if n_fills < 2 else 1 << 40)
                start_take(f"soak-{len(takes) + 1}")
        final = gw.handle_request("stop_recording", {})
        takes[-1]["end"] = time.monotonic()
        with script.lock:
            injected = dict(script.counts)
        status = gw.status()
    finally:
        stop.set()
        for t in threads:
            t.join(30)
        monitor.close()
        try:  # after the hostile clients: can a normal client still connect and be served?
            with GatewayClient(*gw.address) as probe:
                reachable = "t_host_s" in probe.request("ping")
        except (OSError, ConnectionError):
            reachable = False
        threads_alive = {t.name for t in threading.enumerate()}
        gw.stop()
        emulator_rss_mb = _rss_of(emulator.pid)
        emulator.terminate()
        emulator.wait(10)
    wall_s = time.monotonic() - wall0
    alarms = [m for level, source, m in events if level == "alarm" and source == "recorder"]
    stepped_back = {st: sum("went back" in m for _, source, m in events if source == st) for st in ("st1", "st2")}

    print(f"soak: {span_s / 60:g} min emulated at {speed:g}x in {wall_s:.0f} s wall, load average "
          f"{os.getloadavg()[0]:.1f}, records in {tmp}")
    ok = True
    margin_s = 1.0  # two flush intervals: a block read at the edge of a window may or may not be in the take
    print(f"\n{'take':8} {'ended by':24} {'delivered in window':>20} {'recorded':>9} {'missing':>8} {'extra':>6} "
          f"{'lost to full disk':>18}")
    for take in takes:
        got = recorded(Path(take["path"]))
        window = books.delivered(take["start"] + margin_s, take["end"] - margin_s - (2.0 if take["fault"] else 0))
        everything = books.delivered(take["start"] - margin_s, take["end"] + margin_s)
        missing, extra = len(window - got), len(got - everything)
        ok &= missing == 0 and extra == 0
        print(f"{take['take']:8} {str(take['fault'] or 'stop'):24} {len(window):>20,} {len(got):>9,} {missing:>8} "
              f"{extra:>6} {take.get('lost') if take['fault'] else '-':>18}")
    warm_s = min(60.0, span_s / 4)
    steady = [m for t, m in rss if t >= warm_s]
    growth = max(steady) - steady[0] if steady else float("nan")
    print(f"\nRSS (gateway process): {rss[0][1]:.0f} MB at start, {steady[0]:.0f} MB at {warm_s:.0f} s emulated, max {max(steady):.0f} MB, "
          f"{steady[-1]:.0f} MB at the end (growth after warm-up {growth:.0f} MB); the emulator child: "
          f"{emulator_rss_mb:.0f} MB")
    ok &= growth < 50
    budget = gw.server.queue_budget_bytes
    print(f"{silent_askers} clients asking for status without reading: cut off {tally.get('silent asker cut off', 0)} "
          f"times; bytes queued for all clients peaked at {queued_peak[0] / 1e6:.1f} MB (budget {budget / 1e6:.1f} MB)")
    ok &= queued_peak[0] <= budget
    dead_gateway_threads = sorted(n for n in threads_before - threads_alive if n.startswith("gw-station")
                                  or n.startswith("gw-status") or n == "gw-accept")
    print(f"threads that died with an exception: {len(died)}" + "".join(f"\n  {d}" for d in died[:10]))
    print(f"gateway threads gone before stop: {dead_gateway_threads or 'none'}")
    ok &= not died and not dead_gateway_threads
    faulty = next(s for s in status["stations"] if s["source"] == "faulty://9")
    print(f"faulty station: injected {injected}; gateway refused {faulty['invalid_fields']} messages, "
          f"clock epoch {faulty['clock'].get('epoch')}, internal errors {faulty['internal_errors']}, "
          f"length errors counted as framing errors {faulty['framing_errors']}")
    wanted = injected.get("batch field", 0) + injected.get("hello tick_rate_hz 0", 0)
    ok &= faulty["internal_errors"] == 0 and wanted - 1 <= faulty["invalid_fields"] <= wanted  # one may be in flight
    print(f"a new client after the hostile ones: {'served' if reachable else 'NOT SERVED'}")
    ok &= reachable
    for s in status["stations"]:
        if s["source"] != "faulty://9":
            print(f"{s['station']}: link {s['link']}, reconnects {s['reconnects']}, crc errors {s['crc_errors']}, "
                  f"internal errors {s['internal_errors']}, epoch {s['clock'].get('epoch')}")
            ok &= s["internal_errors"] == 0
    print(f"recorder alarms seen by a client: {len(alarms)} (disk fills: {sum(1 for t in takes if t['fault'])}; "
          f"the monitoring client was dropped as too slow {monitor_drops[0]} time(s))")
    ok &= len(alarms) >= sum(1 for t in takes if t["fault"]) >= 1
    print("hostile connections: " + ", ".join(f"{k} {v}" for k, v in sorted(tally.items()))
          + f"; the server refused {gw.server.refused_connections} over its {gw.server.max_clients}-client cap")
    extra_epochs = {st["station"]: st["clock"].get("epoch", 0) - st["reconnects"] for st in status["stations"]
                    if st["source"] != "faulty://9"}
    print(f"clock epochs beyond one per replug: {extra_epochs} (at {speed:g}x a device clock runs {speed:g}x the host "
          f"clock, so a reader starved for > {2.0 / (speed - 1) if speed > 1 else float('inf'):.2f} s sees a "
          f"far jump and starts an epoch); 'device ticks went back' events on them: {stepped_back}")
    ok &= not any(stepped_back.values())
    print(f"final take: {final['samples_written']:,} samples written")
    print("PASS" if ok else "FAIL")
    return ok


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--minutes", type=float, default=10.0, help="emulated minutes")
    parser.add_argument("--speed", type=float, default=4.0, help="emulated seconds per wall second")
    parser.add_argument("--silent-askers", type=int, default=8,
                        help="clients that request status without ever reading (issue 22)")
    args = parser.parse_args()
    return 0 if run(args.minutes, args.speed, args.silent_askers) else 1


if __name__ == "__main__":
    sys.exit(main())

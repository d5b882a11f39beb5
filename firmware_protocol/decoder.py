"""Streaming frame decoder: arbitrary byte chunks in, decoded messages with their header out.

It never raises on bad bytes. Every chunk between two 0x00 delimiters is decoded independently, so damage is
confined to the frame(s) whose bytes (or delimiter) were hit, and the next intact frame is always recovered.
Why `bytes.split` + C COBS: splitting a chunk at every delimiter is one C call, the `cobs` package decodes each
frame in C, and samples become a numpy view, so Python-level work is a few dozen operations per frame,
not per byte.
"""
from __future__ import annotations

import struct
from zlib import crc32
from dataclasses import dataclass, field
from typing import NamedTuple

from cobs.cobs import DecodeError as CobsDecodeError
from cobs.cobs import decode as cobs_decode

from .codec import MAX_PAYLOAD_BYTES, UNPACKERS, UNPACKERS_V2, PayloadError
from .framing import CRC, HEADER, MAX_ENCODED_FRAME_BYTES, MIN_BODY_BYTES, SEQ_MODULUS
from .messages import Message, MessageType

_HALF_SEQ = SEQ_MODULUS // 2
_SEQ_MASK = SEQ_MODULUS - 1
# header version -> the layouts it defines (a version-1 frame of type MOTION_BATCH is an unknown type)
_UNPACKERS = {1: {int(k): v for k, v in UNPACKERS.items()}, 2: {int(k): v for k, v in UNPACKERS_V2.items()}}
_HELLO = int(MessageType.HELLO)
HEADER_BYTES = HEADER.size


class DecodedFrame(NamedTuple):
    """One good frame: header fields plus the decoded message (a NamedTuple: cheapest object to build)."""
    station_id: int
    seq: int
    message: Message


@dataclass(slots=True)
class DecoderStats:
    """Counters since the decoder was created. `corrupt_frames` = cobs + length + crc errors."""
    bytes_received: int = 0
    bytes_discarded: int = 0           # bytes of every rejected frame (delimiters not counted)
    frames_ok: int = 0                 # decoded and returned
    cobs_errors: int = 0
    length_errors: int = 0             # too short, header length != actual or > 4096, or longer than any legal frame
    crc_errors: int = 0
    unsupported_version: int = 0       # CRC fine, version byte not 1 or 2: not returned, not seq-tracked
    unknown_types: int = 0             # CRC fine, message type unknown: skipped (seq still tracked)
    malformed_payloads: int = 0        # CRC fine, payload does not fit its layout (a sender bug)
    seq_gaps: int = 0                  # frames missing according to the link sequence numbers, all stations
    seq_resets: int = 0                # sequence went backwards / restarted (station reboot)
    gaps_by_station: dict[int, int] = field(default_factory=dict)

    @property
    def corrupt_frames(self) -> int:
        return self.cobs_errors + self.length_errors + self.crc_errors


class StreamDecoder:
    """Feed it bytes from one link (serial port, HID stream, file) in chunks split anywhere.

    Sequence tracking is per station id. A HELLO with seq 0 marks a (re)boot and re-anchors without counting a gap;
    a sequence that goes backwards otherwise is counted in `seq_resets` and re-anchors too.
    """

    def __init__(self) -> None:
        self.stats = DecoderStats()
        self._pending = b""
        self._skipping = False          # inside an over-long run of bytes: drop until the next delimiter
        self._expected_seq: dict[int, int] = {}

    def feed(self, chunk: bytes | bytearray | memoryview) -> list[DecodedFrame]:
        stats = self.stats
        stats.bytes_received += len(chunk)
        data = self._pending + bytes(chunk) if self._pending else bytes(chunk)
        parts = data.split(b"\x00")
        self._pending = parts.pop()
        if self._skipping and parts:
            stats.bytes_discarded += len(parts[0])
            parts[0] = b""
            self._skipping = False
        if len(self._pending) > MAX_ENCODED_FRAME_BYTES:
            if not self._skipping:
                stats.length_errors += 1
            stats.bytes_discarded += len(self._pending)
            self._pending = b""
            self._skipping = True
        out: list[DecodedFrame] = []
        # Hot loop: names bound to locals, one early exit per failure kind.
        unpack_header, crc_unpack, by_version = HEADER.unpack_from, CRC.unpack_from, _UNPACKERS
        expected, track = self._expected_seq, self._track_seq
        for part in parts:
            if not part:
                continue
            if len(part) > MAX_ENCODED_FRAME_BYTES:
                stats.length_errors += 1
                stats.bytes_discarded += len(part)
                continue
            try:
                body = cobs_decode(part)
            except CobsDecodeError:
                stats.cobs_errors += 1
                stats.bytes_discarded += len(part)
                continue
            n = len(body)
            if n < MIN_BODY_BYTES:
                stats.length_errors += 1
                stats.bytes_discarded += len(part)
                continue
            if crc32(body[:-4]) != crc_unpack(body, n - 4)[0]:
                stats.crc_errors += 1
                stats.bytes_discarded += len(part)
                continue
            version, msg_type, station_id, seq, length = unpack_header(body, 0)
            if length != n - MIN_BODY_BYTES or length > MAX_PAYLOAD_BYTES:  # zero-rich bodies encode compactly
                stats.length_errors += 1
                stats.bytes_discarded += len(part)
                continue
            unpackers = by_version.get(version)
            if unpackers is None:
                stats.unsupported_version += 1
                stats.bytes_discarded += len(part)
                continue
            if expected.get(station_id) == seq:              # the common case, inline
                expected[station_id] = (seq + 1) & _SEQ_MASK
            else:
                track(station_id, seq, msg_type)
            unpack = unpackers.get(msg_type)
            if unpack is None:
                stats.unknown_types += 1
                stats.bytes_discarded += len(part)
                continue
            try:
                message = unpack(body[HEADER_BYTES:-4])
            except (PayloadError, struct.error, IndexError, ValueError):
                stats.malformed_payloads += 1
                stats.bytes_discarded += len(part)
                continue
            out.append(DecodedFrame(station_id, seq, message))
        stats.frames_ok += len(out)
        return out

    def _track_seq(self, station_id: int, seq: int, msg_type: int) -> None:
        expected = self._expected_seq.get(station_id)
        self._expected_seq[station_id] = (seq + 1) % SEQ_MODULUS
        if expected is None or (seq == 0 and msg_type == _HELLO):
            return
        missing = (seq - expected) % SEQ_MODULUS
        if missing == 0:
            return
        stats = self.stats
        if missing < _HALF_SEQ:
            stats.seq_gaps += missing
            stats.gaps_by_station[station_id] = stats.gaps_by_station.get(station_id, 0) + missing
        else:
            stats.seq_resets += 1

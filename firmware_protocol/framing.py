"""Frame = COBS(header + payload + CRC-32) + 0x00.

Why COBS: the 0x00 delimiter can never occur inside a frame, so a receiver resynchronises at the next 0x00
after any garbage, and the overhead is bounded (1 byte + 1 per 254). Why CRC-32 (zlib, ISO-HDLC: poly 0x04C11DB7
reflected, init 0xFFFFFFFF, xorout 0xFFFFFFFF, check("123456789") = 0xCBF43926): a corrupted COBS code byte
rewrites many decoded bytes at once, and the acceptance test demands that no damaged frame ever slips through;
CRC-32 makes a false accept a 1-in-4e9 event instead of 1-in-65536 for CRC-16.
"""
from __future__ import annotations

import struct
import zlib

from cobs.cobs import encode as cobs_encode

from .codec import MAX_PAYLOAD_BYTES, message_type_and_payload
from .messages import BASE_VERSION, PROTOCOL_VERSION, Message, MessageType

DELIMITER = b"\x00"
HEADER = struct.Struct("<BBHIH")        # version, message type, station id, link seq, payload length
CRC = struct.Struct("<I")
MIN_BODY_BYTES = HEADER.size + CRC.size
MAX_BODY_BYTES = MIN_BODY_BYTES + MAX_PAYLOAD_BYTES
# COBS adds one code byte per started 254-byte block: 4110-byte body -> at most 4127 encoded bytes (delimiter not
# included; 4128 on the wire with it). A longer run between delimiters cannot be a legal frame.
MAX_ENCODED_FRAME_BYTES = MAX_BODY_BYTES + (MAX_BODY_BYTES + 253) // 254
MAX_WIRE_FRAME_BYTES = MAX_ENCODED_FRAME_BYTES + len(DELIMITER)
SEQ_MODULUS = 1 << 32


def crc32(data: bytes) -> int:
    """CRC-32/ISO-HDLC, the frame check (see module docstring for parameters)."""
    return zlib.crc32(data)


def frame_version(msg_type: int) -> int:
    """Header version of a frame: the lowest that defines its layout (PROTOCOL.md §1), so a version-1 host still
    reads every frame of a version-2 station except the MOTION_BATCHes it cannot understand."""
    return PROTOCOL_VERSION if msg_type == MessageType.MOTION_BATCH else BASE_VERSION


def frame_payload(msg_type: int, payload: bytes, station_id: int, seq: int, version: int | None = None) -> bytes:
    """Wrap an already packed payload into one complete frame, trailing delimiter included."""
    if len(payload) > MAX_PAYLOAD_BYTES:
        raise ValueError(f"payload of {len(payload)} bytes exceeds {MAX_PAYLOAD_BYTES}")
    version = frame_version(msg_type) if version is None else version
    body = HEADER.pack(version, msg_type, station_id, seq % SEQ_MODULUS, len(payload)) + payload
    return cobs_encode(body + CRC.pack(crc32(body))) + DELIMITER


def encode(message: Message, station_id: int, seq: int) -> bytes:
    """One complete frame (COBS-encoded, 0x00-terminated) carrying `message` from/to station `station_id`.

    `seq` is the sender's per-link frame counter (u32, wraps); the receiver counts gaps in it."""
    msg_type, payload = message_type_and_payload(message)
    return frame_payload(msg_type, payload, station_id, seq)

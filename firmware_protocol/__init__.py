"""The bytes between a base station and the PC (see PROTOCOL.md), plus an emulated base station.

Public API (what the gateway calls):
    encode(message, station_id, seq) -> bytes      one complete frame, 0x00 delimiter included
    StreamDecoder().feed(chunk) -> list[DecodedFrame]; .stats is a DecoderStats
    message dataclasses: Hello, SampleBatch, ClockSync, Status, Command, Ack, Nack, Error (+ SensorInfo, SensorLink)
    constants/enums: MessageType, Opcode, NackReason, ErrorCode, StationFlags, BatchFlags, BROADCAST_SENSOR
The emulator lives in `firmware_protocol.emulator` (imported lazily: the gateway does not pay for it).

Importing this package also registers the `emu://` pyserial URL scheme (a list append, nothing else), so any
code that calls `serial.serial_for_url("emu://...")` after `import firmware_protocol` gets an emulated station.
"""
from __future__ import annotations

import serial as _serial

from .decoder import DecodedFrame, DecoderStats, StreamDecoder
from .framing import MAX_ENCODED_FRAME_BYTES, SEQ_MODULUS, encode
from .messages import (
    BROADCAST_SENSOR,
    PERIODIC_BEACON,
    PROTOCOL_VERSION,
    Ack,
    BatchFlags,
    ClockSync,
    Command,
    Error,
    ErrorCode,
    Hello,
    Message,
    MessageType,
    Nack,
    NackReason,
    Opcode,
    SampleBatch,
    SensorInfo,
    SensorKind,
    SensorLink,
    StationFlags,
    Status,
    scale_for_range,
)

URL_HANDLER_PACKAGE = "firmware_protocol.emulator"
if URL_HANDLER_PACKAGE not in _serial.protocol_handler_packages:
    _serial.protocol_handler_packages.append(URL_HANDLER_PACKAGE)

__all__ = [
    "BROADCAST_SENSOR", "PERIODIC_BEACON", "PROTOCOL_VERSION", "MAX_ENCODED_FRAME_BYTES", "SEQ_MODULUS",
    "Ack", "BatchFlags", "ClockSync", "Command", "DecodedFrame", "DecoderStats", "Error", "ErrorCode", "Hello",
    "Message", "MessageType", "Nack", "NackReason", "Opcode", "SampleBatch", "SensorInfo", "SensorKind",
    "SensorLink", "StationFlags", "Status", "StreamDecoder", "encode", "scale_for_range",
]

"""Structural check of a C3D file before ezc3d parses it.

Why: ezc3d trusts the file. Damaged parameter records make it crash the interpreter (a segmentation fault, not an
exception), and a file cut short is read without complaint as fewer frames. This module walks the 512-byte
header, the parameter section's linked records and the data size in pure Python and raises MalformedFileError
naming the problem, so only files that are whole and self-consistent reach the C++ reader.

Layout used (C3D.org user guide, "The C3D file format"): block 1 is the header (byte 0 = first parameter block,
byte 1 = 0x50; 16-bit words: points, analog values per frame, first and last frame, scale factor (float, < 0 means
float data), data start block). The parameter section starts with 4 bytes (byte 2 = its length in 512-byte
blocks, byte 3 = processor type 84 Intel / 85 DEC / 86 MIPS, which fixes the byte order) followed by records:
``i8 name length (negative = locked; 0 ends the list), i8 id (< 0 group, > 0 parameter), name,
i16 offset to the next record counted from this field`` and, for parameters, ``i8 type (-1 char, 1 byte,
2 int16, 4 float), u8 dimensions, u8 x dims, data``, then ``u8 description length, description``.
"""
from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

from engine.errors import MalformedFileError

BLOCK = 512
_PROCESSORS = {84: "<", 85: "<", 86: ">"}  # Intel, DEC (little-endian words), MIPS
_TYPES = {-1: 1, 1: 1, 2: 2, 4: 4}


def check_c3d(path: Path) -> None:
    """Raise MalformedFileError if the file is not a structurally sound C3D file. Reads only the header and the
    parameter section (the data size comes from the file size)."""
    try:
        with open(path, "rb") as fh:
            size = fh.seek(0, 2)
            fh.seek(0)
            data = fh.read(BLOCK + 4)
            if len(data) == BLOCK + 4 and data[1] == 0x50 and data[0] >= 2:
                fh.seek(0)
                data = fh.read((data[0] - 1 + 255) * BLOCK)  # header + the longest possible parameter section
    except OSError as exc:
        raise MalformedFileError(path, None, f"cannot read file: {exc.strerror}") from None
    if len(data) < BLOCK + 4:
        raise MalformedFileError(path, None, f"not a C3D file ({size} bytes, shorter than its header)")
    first_param_block, magic = data[0], data[1]
    if magic != 0x50 or first_param_block < 2:
        raise MalformedFileError(path, None, "not a C3D file (bad header key)")
    start = (first_param_block - 1) * BLOCK
    if start + 4 > len(data):
        raise MalformedFileError(path, None, f"parameter section (block {first_param_block}) is past the end of the file")
    n_blocks, processor = data[start + 2], data[start + 3]
    if processor not in _PROCESSORS:
        raise MalformedFileError(path, None, f"unknown processor type {processor} in the parameter section")
    order = _PROCESSORS[processor]
    end = min(start + max(n_blocks, 1) * BLOCK, len(data))
    _walk_parameters(path, data, start + 4, end, order)
    _check_data_size(path, data, size, order, processor)


def _walk_parameters(path: Path, data: bytes, pos: int, end: int, order: str) -> None:
    i16 = struct.Struct(order + "h")
    for _ in range(100_000):  # far more records than any real file; a loop in the links ends here
        if pos + 2 > end:
            return
        n_char = abs(struct.unpack_from("b", data, pos)[0])
        if n_char == 0:
            return
        record_id = struct.unpack_from("b", data, pos + 1)[0]
        name = data[pos + 2:pos + 2 + n_char]
        offset_at = pos + 2 + n_char
        if offset_at + 2 > end or not all(32 <= c < 127 for c in name):
            raise MalformedFileError(path, None, f"parameter section damaged at byte {pos} (bad record name)")
        (next_offset,) = i16.unpack_from(data, offset_at)
        body = offset_at + 2
        if record_id > 0:  # a parameter: type, dimensions, values
            if body + 2 > end:
                raise MalformedFileError(path, None, f"parameter {name.decode()!r} is cut off")
            kind, n_dims = struct.unpack_from("bB", data, body)
            if kind not in _TYPES or n_dims > 7 or body + 2 + n_dims > end:
                raise MalformedFileError(path, None, f"parameter {name.decode()!r} has an invalid type or dimensions")
            dims = data[body + 2:body + 2 + n_dims]
            body += 2 + n_dims + _TYPES[kind] * int(np.prod(list(dims), dtype=np.int64))
        if body + 1 > end or body + 1 + data[body] > end:
            raise MalformedFileError(path, None, f"record {name.decode()!r} runs past the parameter section")
        if next_offset == 0:
            return
        nxt = offset_at + next_offset
        if nxt <= pos or nxt > end:
            raise MalformedFileError(path, None, f"parameter section damaged at byte {pos} (record "
                                                 f"{name.decode()!r} links to byte {nxt})")
        pos = nxt
    raise MalformedFileError(path, None, "parameter section has no end")


def _check_data_size(path: Path, data: bytes, size: int, order: str, processor: int) -> None:
    u16 = struct.Struct(order + "H")
    points, analog, first, last = (u16.unpack_from(data, 2 + 2 * k)[0] for k in range(4))
    (data_block,) = u16.unpack_from(data, 16)
    sign_byte = {84: 15, 85: 13, 86: 12}[processor]  # where the scale factor's sign bit lives
    value_bytes = 4 if data[sign_byte] & 0x80 else 2
    if data_block < 2:
        raise MalformedFileError(path, None, f"data start block {data_block} is inside the header")
    if last < first:  # large files keep the frame count in POINT:FRAMES; ezc3d checks those itself
        return
    frames = last - first + 1
    per_frame = (4 * points + analog) * value_bytes
    available = size - (data_block - 1) * BLOCK
    if per_frame and available < frames * per_frame:
        whole = max(available, 0) // per_frame
        raise MalformedFileError(path, None, f"file is cut short: holds {whole} of the {frames} frames its header "
                                             "declares")

"""A minimal XDF writer (Extensible Data Format, the Lab Streaming Layer recording format) for
`courtside gateway export --xdf`.

Layout (XDF 1.0 specification): the magic ``XDF:``, then chunks ``[NumLengthBytes][Length][Tag][Content]``
where Length (1, 4 or 8 byte little-endian, announced by NumLengthBytes) counts Tag + Content. Tags: 1
FileHeader (XML), 2 StreamHeader (stream id + XML), 3 Samples (stream id, sample count, then per sample a time
stamp flag + float64 stamp + the values), 6 StreamFooter (stream id + XML). Written by hand because pyxdf only
reads (it is used to check the files: tests/gateway/test_lsl_xdf.py). Streams have the layout of the gateway's
LSL outlets (gateway.lsl): per station, irregular rate, float32 ``sensor, acc_x_g, acc_y_g, acc_z_g``, plus a
``<station> orientation`` stream (`gateway.lsl.ORIENTATION_CHANNELS`) when any of its sensors recorded
orientation or angular rate; time stamps are the recording's offline-refitted gateway clock."""
from __future__ import annotations

import struct
from pathlib import Path
from xml.sax.saxutils import escape

import numpy as np

from gateway.lsl import LAYOUTS, channel_meta, orientation_rows


def _varlen(n: int) -> bytes:
    if n < 256:
        return struct.pack("<BB", 1, n)
    if n < 2**32:
        return struct.pack("<BI", 4, n)
    return struct.pack("<BQ", 8, n)


def _chunk(tag: int, content: bytes) -> bytes:
    return _varlen(len(content) + 2) + struct.pack("<H", tag) + content


def stream_header_xml(name: str, source_id: str, n_samples: int, kind: str = "acc") -> str:
    _, stream_type, labels = LAYOUTS[kind]
    channels = "".join(f"<channel><label>{c}</label><unit>{channel_meta(c)[0]}</unit></channel>" for c in labels)
    return (f'<?xml version="1.0"?><info><name>{escape(name)}</name><type>{stream_type}</type>'
            f"<channel_count>{len(labels)}</channel_count><nominal_srate>0</nominal_srate>"
            f"<channel_format>float32</channel_format><source_id>{escape(source_id)}</source_id>"
            f"<created_at>0</created_at><desc><channels>{channels}</channels></desc></info>")


def write_xdf(path: str | Path, streams: list[tuple[str, str, np.ndarray, np.ndarray]],
              samples_per_chunk: int = 4096) -> Path:
    """``streams``: (name, source_id, time stamps (N,) s, values (N, C)) each, C = 4 (accelerations) or 8
    (orientation, `gateway.lsl.ORIENTATION_CHANNELS`); returns ``path``."""
    path = Path(path)
    with open(path, "wb") as fh:
        fh.write(b"XDF:")
        fh.write(_chunk(1, b'<?xml version="1.0"?><info><version>1.0</version></info>'))
        for sid, (name, source_id, stamps, values) in enumerate(streams, start=1):
            kind = "acc" if values.shape[1] == len(LAYOUTS["acc"][2]) else "orientation"
            fh.write(_chunk(2, struct.pack("<I", sid) + stream_header_xml(name, source_id, len(stamps), kind).encode()))
        for sid, (_, _, stamps, values) in enumerate(streams, start=1):
            order = np.argsort(stamps, kind="stable")
            stamps = np.asarray(stamps, "<f8")[order]
            values = np.asarray(values, "<f4")[order]
            record = np.dtype([("flag", "u1"), ("t", "<f8"), ("v", "<f4", (values.shape[1],))])
            for start in range(0, len(stamps), samples_per_chunk):
                block = np.zeros(min(samples_per_chunk, len(stamps) - start), record)
                block["flag"] = 8
                block["t"] = stamps[start:start + len(block)]
                block["v"] = values[start:start + len(block)]
                fh.write(_chunk(3, struct.pack("<I", sid) + _varlen(len(block)) + block.tobytes()))
        for sid, (_, _, stamps, _) in enumerate(streams, start=1):
            t0, t1 = (float(np.min(stamps)), float(np.max(stamps))) if len(stamps) else (0.0, 0.0)
            footer = (f'<?xml version="1.0"?><info><first_timestamp>{t0!r}</first_timestamp><last_timestamp>'
                      f"{t1!r}</last_timestamp><sample_count>{len(stamps)}</sample_count></info>")
            fh.write(_chunk(6, struct.pack("<I", sid) + footer.encode()))
    return path


def export_xdf(recording: str | Path, out: str | Path, gateway_name: str = "courtside-gateway") -> Path:
    """A gateway recording as XDF: one stream per station, offline clock re-fit as time stamps."""
    from gateway.recorder import load_take, realign_take

    take = load_take(recording)
    realigned = realign_take(take)
    per_stream: dict[tuple[str, str], list[tuple[np.ndarray, np.ndarray]]] = {}
    for (station, sensor), cols in take.samples.items():
        acc = np.asarray(cols["acc_g"], float).reshape(-1, 3)
        rows = np.column_stack([np.full(len(acc), float(sensor)), acc])
        per_stream.setdefault((station, "acc"), []).append((realigned[(station, sensor)], rows))
        if "quat_wxyz" in cols or "gyro_rps" in cols:
            rows = orientation_rows(sensor, len(acc), cols.get("quat_wxyz"), cols.get("gyro_rps"))
            per_stream.setdefault((station, "orientation"), []).append((realigned[(station, sensor)], rows))
    streams = [(f"{gateway_name} {station}{LAYOUTS[kind][0]}",
                f"courtside/{gateway_name}/{station}{LAYOUTS[kind][0].replace(' ', '/')}",
                np.concatenate([t for t, _ in parts]), np.concatenate([r for _, r in parts]))
               for (station, kind), parts in sorted(per_stream.items())]
    return write_xdf(out, streams)

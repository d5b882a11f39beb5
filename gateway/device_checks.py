"""Plausibility checks on what a base station tells us (HELLO, SAMPLE_BATCH) and on the values we send it.

Why here and not in the decoder: a frame with a valid CRC is well formed, but its fields can still be impossible
(a tick rate of 0 Hz, a sample period of 0 ticks, a NaN scale). Such a station is faulty or foreign; the reader
must refuse the message with a counted error and one event, keep the link (the next HELLO may be fine), and
never let the value reach a division. The limits are wide on purpose: they reject what cannot be a working
station, not what is merely unusual.
"""
from __future__ import annotations

import math

import firmware_protocol as fp

MIN_TICK_RATE_HZ = 1_000  # a clock slower than 1 kHz cannot time samples at the rates we support
MAX_TICK_RATE_HZ = 1_000_000_000
MIN_SAMPLE_RATE_HZ = 0.1
MAX_SAMPLE_RATE_HZ = 100_000.0
I32_MIN, I32_MAX = -(1 << 31), (1 << 31) - 1


def hello_problem(hello: fp.Hello) -> str | None:
    """Why this HELLO cannot be used, or None."""
    if not MIN_TICK_RATE_HZ <= hello.tick_rate_hz <= MAX_TICK_RATE_HZ:
        return f"HELLO tick_rate_hz {hello.tick_rate_hz} outside {MIN_TICK_RATE_HZ}..{MAX_TICK_RATE_HZ}"
    ids = [s.sensor_id for s in hello.sensors]
    if len(set(ids)) != len(ids):
        return f"HELLO lists sensor ids {ids} with duplicates"
    for s in hello.sensors:
        if not MIN_SAMPLE_RATE_HZ <= s.rate_hz <= MAX_SAMPLE_RATE_HZ:
            return f"HELLO sensor {s.sensor_id} rate_hz {s.rate_hz} outside {MIN_SAMPLE_RATE_HZ}..{MAX_SAMPLE_RATE_HZ:g}"
        if s.range_g <= 0:
            return f"HELLO sensor {s.sensor_id} range_g {s.range_g} is not positive"
    return None


def batch_problem(batch: fp.SampleBatch, tick_rate_hz: int) -> str | None:
    """Why this SAMPLE_BATCH cannot be used (with the station's HELLO tick rate), or None."""
    if batch.period_ticks_q8 <= 0:
        return f"SAMPLE_BATCH sensor {batch.sensor_id} period_ticks_q8 is 0"
    rate_hz = tick_rate_hz * 256.0 / batch.period_ticks_q8
    if not MIN_SAMPLE_RATE_HZ <= rate_hz <= MAX_SAMPLE_RATE_HZ:
        return f"SAMPLE_BATCH sensor {batch.sensor_id} period gives {rate_hz:.4g} Hz, outside " \
               f"{MIN_SAMPLE_RATE_HZ}..{MAX_SAMPLE_RATE_HZ:g}"
    scale = batch.scale_g_per_lsb
    if not (math.isfinite(scale) and scale > 0):
        return f"SAMPLE_BATCH sensor {batch.sensor_id} scale_g_per_lsb {scale!r} is not a positive number"
    gyro_scale = batch.gyro_scale_rps_per_lsb
    if batch.gyro_counts is not None and not (math.isfinite(gyro_scale) and gyro_scale > 0):
        return f"MOTION_BATCH sensor {batch.sensor_id} gyro_scale_rps_per_lsb {gyro_scale!r} is not a positive number"
    return None


def command_int(name: str, value: object, low: int, high: int) -> int:
    """An integer command argument in ``low..high`` (the field's wire range); ValueError names the field."""
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        raise ValueError(f"'{name}' must be an integer, got {value!r}")
    try:
        number = int(value)
    except (ValueError, OverflowError):
        raise ValueError(f"'{name}' must be an integer, got {value!r}") from None
    if isinstance(value, float) and number != value:
        raise ValueError(f"'{name}' must be an integer, got {value!r}")
    if not low <= number <= high:
        raise ValueError(f"'{name}' = {number} is outside {low}..{high}")
    return number

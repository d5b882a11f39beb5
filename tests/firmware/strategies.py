"""Hypothesis strategies for every protocol message (shared by the firmware tests)."""
from __future__ import annotations

import numpy as np
from hypothesis import strategies as st

from firmware_protocol import (
    Ack, ClockSync, Command, Error, Hello, Nack, SampleBatch, SensorInfo, SensorLink, Status, scale_for_range,
)
from firmware_protocol.codec import MAX_ERROR_TEXT_BYTES

u8 = st.integers(0, 0xFF)
u16 = st.integers(0, 0xFFFF)
u32 = st.integers(0, 0xFFFF_FFFF)
i8 = st.integers(-128, 127)
i32 = st.integers(-(2**31), 2**31 - 1)


@st.composite
def sample_batches(draw, max_samples: int = 40) -> SampleBatch:
    """Version-1 batches (accelerations only) and version-2 ones with orientation and/or angular rate."""
    n = draw(st.integers(1, max_samples))
    rng = np.random.default_rng(draw(u32))
    samples = rng.integers(-32768, 32768, size=(n, 3), dtype=np.int16)
    quat = rng.integers(-32768, 32768, size=(n, 4), dtype=np.int16) if draw(st.booleans()) else None
    gyro = rng.integers(-32768, 32768, size=(n, 3), dtype=np.int16) if draw(st.booleans()) else None
    gyro_scale = float(np.float32(draw(st.floats(1e-6, 1.0)))) if gyro is not None else 0.0
    return SampleBatch(draw(u8), draw(u8), draw(u32), draw(u32), draw(u32),
                       scale_for_range(draw(st.integers(1, 64))), samples, quat, gyro, gyro_scale)


hellos = st.builds(
    Hello,
    st.tuples(u8, u8, u16), u32, u32, u32,
    st.lists(u16, max_size=8).map(tuple), st.lists(u8, max_size=8).map(tuple),
    st.lists(st.builds(SensorInfo, u8, u8, u16, u8), max_size=12).map(tuple),
)
statuses = st.builds(Status, u8, u8, u16, u32, u32, u32, u32,
                     st.lists(st.builds(SensorLink, u8, i8, u8), max_size=12).map(tuple))
error_texts = st.text(max_size=60).filter(lambda s: len(s.encode()) <= MAX_ERROR_TEXT_BYTES)

messages = st.one_of(
    hellos,
    sample_batches(),
    st.builds(ClockSync, u32, u32, u16),
    statuses,
    st.builds(Command, u16, u8, u8, i32),
    st.builds(Ack, u16, u8),
    st.builds(Nack, u16, u8, u8),
    st.builds(Error, u16, error_texts),
)

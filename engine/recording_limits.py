"""What a recording of body-worn IMUs can be: the limits every reader of one (`courtside import-imu`, the take
check shared by `courtside calibrate` and `courtside synthesize`) refuses beyond, in one place.

Why limits at all (issue 30): one typo'd timestamp (1e10 ms) or ``--rate 1e12`` made the importer allocate a
7 GiB grid, a wrong ``--time-unit`` produced a 100 kHz take, an hour-long gap was interpolated into 360 000
invented samples, and 1e300 accelerations went through. The limits are far outside anything a worn sensor
records and far inside what breaks the machine:

* sample rate 1 Hz .. 4 kHz (body-worn IMUs stream 50 Hz .. 2 kHz; a rate off by 1000 is a unit mistake);
* a take at most 6 hours long (a whole training session), so memory is bounded by rate x 6 h and by the input;
* a gap of at most 0.5 s in a sensor's accelerations is bridged by interpolation, a longer one is refused (the
  take must be split there: what happened in between is unknown);
* accelerations within +-1000 g (high-g accelerometers stop at 400 g; beyond is a wrong column or unit);
* an orientation is a unit quaternion to 1 % (6-digit and even 4-decimal exports are far inside; anything else is
  a wrong column or Euler angles).
"""
from __future__ import annotations

import math

MIN_RATE_HZ = 1.0
MAX_RATE_HZ = 4000.0
MAX_TAKE_S = 6 * 3600.0
MAX_GAP_S = 0.5
MAX_ACC_G = 1000.0
QUAT_NORM_TOLERANCE = 0.01


def rate_problem(rate_hz: float) -> str | None:
    """Why ``rate_hz`` cannot be a recording's sample rate, or None (NaN, inf, negative and zero included)."""
    if not isinstance(rate_hz, (int, float)):
        return f"{rate_hz!r} is not a number of Hz"
    if not (math.isfinite(rate_hz) and MIN_RATE_HZ <= rate_hz <= MAX_RATE_HZ):
        return f"{rate_hz:g} Hz is outside {MIN_RATE_HZ:g}..{MAX_RATE_HZ:g} Hz"
    return None

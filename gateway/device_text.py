"""Text a device sends (a station's ERROR message) made safe for events and logs, and throttled.

Why (issue 22): a station's ERROR text went into events and log lines unchanged and unthrottled, so a newline
in it forged a log line, U+202E (right-to-left override) reordered what an operator reads, and 500 ERROR frames
made 500 events. `escape` shows every control, format and separator character as a visible escape (and
backslashes doubled, so an escape cannot be forged either) and caps the length; `EventThrottle` lets a burst
through, then one event per interval, and counts every message it holds back.
"""
from __future__ import annotations

import unicodedata

MAX_DEVICE_TEXT_CHARS = 200
_NAMED = {"\n": "\\n", "\r": "\\r", "\t": "\\t", "\\": "\\\\"}
# Cc control, Cf format (bidi overrides, zero-width), Zl/Zp line/paragraph separators, Cs/Co/Cn unassigned & co
_ESCAPED_CATEGORIES = frozenset({"Cc", "Cf", "Zl", "Zp", "Cs", "Co", "Cn"})


def escape(text: str, max_chars: int = MAX_DEVICE_TEXT_CHARS) -> str:
    """``text`` on one line with only visible characters: controls as ``\\n`` / ``\\x1b`` / ``\\u202e``; longer
    than ``max_chars`` (escaped) it is cut and says how many characters were left out."""
    out: list[str] = []
    length = 0
    for i, ch in enumerate(text):
        if ch in _NAMED:
            piece = _NAMED[ch]
        elif unicodedata.category(ch) in _ESCAPED_CATEGORIES:
            code = ord(ch)
            piece = f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}" if code < 0x10000 else f"\\U{code:08x}"
        else:
            piece = ch
        if length + len(piece) > max_chars:
            out.append(f"... ({len(text) - i} more characters)")
            break
        out.append(piece)
        length += len(piece)
    return "".join(out)


class EventThrottle:
    """At most ``burst`` events at once, then one per ``interval_s``; `allow` counts what it holds back.

    Not thread-safe: each station reader owns its own (its thread alone calls it)."""

    def __init__(self, burst: int = 3, interval_s: float = 10.0):
        self.burst = burst
        self.interval_s = interval_s
        self.suppressed = 0  # held back since the last event let through
        self.suppressed_total = 0
        self._tokens = float(burst)
        self._last_s: float | None = None

    def allow(self, now_s: float) -> bool:
        """True when an event may be sent now (then report ``take_suppressed()`` with it)."""
        if self._last_s is not None:
            self._tokens = min(float(self.burst), self._tokens + (now_s - self._last_s) / self.interval_s)
        self._last_s = now_s
        if self._tokens >= 1.0:
            self._tokens -= 1.0
            return True
        self.suppressed += 1
        self.suppressed_total += 1
        return False

    def take_suppressed(self) -> int:
        """How many were held back since the last event let through (and reset that count)."""
        n, self.suppressed = self.suppressed, 0
        return n

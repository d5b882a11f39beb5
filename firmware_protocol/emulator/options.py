"""One table of user-facing station options, shared by the `emu://` URL query and the `courtside emulate` CLI."""
from __future__ import annotations

from dataclasses import replace
from urllib.parse import parse_qs

from .station import StationConfig


def parse_flag(text: str) -> bool:
    if text.lower() in {"1", "true", "yes", "on"}:
        return True
    if text.lower() in {"0", "false", "no", "off"}:
        return False
    raise ValueError(f"expected a boolean, got {text!r}")


# option name -> (StationConfig field, parser, help)
STATION_OPTIONS: dict[str, tuple[str, type | object, str]] = {
    "sensors": ("n_sensors", int, "number of sensors"),
    "rate": ("rate_hz", int, "sample rate, Hz"),
    "range": ("range_g", int, "full-scale range, +-g"),
    "station-id": ("station_id", int, "station id in every frame header"),
    "serial": ("serial", int, "station serial number"),
    "tick-rate": ("tick_rate_hz", int, "station clock, Hz"),
    "tick-offset": ("tick_offset", int, "u32 tick register at boot (set near 2**32 to see a wrap soon)"),
    "drift": ("drift_ppm", float, "crystal drift, ppm (+ = fast)"),
    "batch": ("batch_samples", int, "samples per radio batch"),
    "noise": ("noise_g", float, "sensor white noise, g RMS"),
    "loss": ("radio_loss", float, "probability a radio batch is lost"),
    "latency": ("latency_s", float, "radio latency floor, s"),
    "jitter": ("jitter_s", float, "mean extra radio latency, s"),
    "burst": ("burst_probability", float, "probability a batch hits a radio outage"),
    "burst-duration": ("burst_duration_s", float, "radio outage length, s"),
    "corruption": ("byte_corruption", float, "per-byte corruption probability on the USB wire"),
    "beacon": ("beacon_interval_s", float, "CLOCK_SYNC period, s"),
    "status": ("status_interval_s", float, "STATUS period, s"),
    "autostart": ("autostart", parse_flag, "stream from boot without a START command"),
    "orientation": ("orientation", parse_flag, "also stream orientation quaternions + angular rate (protocol v2)"),
    "seed": ("seed", int, "random seed"),
}


def apply_options(config: StationConfig, options: dict[str, str]) -> StationConfig:
    """Apply textual options (names from STATION_OPTIONS; '_' and '-' interchangeable) to a config."""
    changes = {}
    for name, text in options.items():
        key = name.replace("_", "-")
        if key not in STATION_OPTIONS:
            raise ValueError(f"unknown station option {name!r} (known: {', '.join(sorted(STATION_OPTIONS))})")
        field, parse, _ = STATION_OPTIONS[key]
        try:
            changes[field] = parse(text)  # type: ignore[operator]
        except ValueError as exc:
            raise ValueError(f"station option {name}={text!r}: {exc}") from None
    return replace(config, **changes)


def parse_query(query: str) -> dict[str, str]:
    """URL query -> {name: last value}."""
    return {k: v[-1] for k, v in parse_qs(query, keep_blank_values=True, strict_parsing=False).items()}

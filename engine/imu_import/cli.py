"""`courtside import-imu FILE --format csv|xsens|ximu3 ... -o take.npz`: a recorded IMU file -> a take that
`courtside calibrate`, `courtside synthesize` and `courtside reconstruct` read (docs/imu-import.md)."""
from __future__ import annotations

import argparse
import json
import sys

from engine.atomic_write import refuse_overwriting_inputs
from engine.errors import ArgumentParser, CourtsideError, check_output_dir
from engine.progress import add_quiet_argument
from engine.imu_import.csv_generic import GYRO_UNITS_RPS, TIME_UNITS_S, read_generic_csv
from engine.imu_import.detect import QUAT_ORDERS, UNITS_TO_G
from engine.imu_import.take import assemble
from engine.imu_import.xsens import read_xsens
from engine.imu_import.ximu3 import read_ximu3


def _pairs(items: list[str] | None, flag: str) -> dict[str, str]:
    out = {}
    for item in items or []:
        key, sep, value = item.partition("=")
        if not sep or not key or not value:
            raise CourtsideError(f"{flag} {item!r}: expected KEY=VALUE")
        out[key.strip()] = value.strip()
    return out


def _columns(items: list[str] | None, flag: str) -> dict[str, list[str]]:
    return {k: [c.strip() for c in v.split(",")] for k, v in _pairs(items, flag).items()}


def build_parser() -> argparse.ArgumentParser:
    p = ArgumentParser(prog="courtside import-imu", description=__doc__)
    p.add_argument("file", help="csv/tsv file; xsens: .mvnx, an MT Manager/DOT .txt/.csv export or a folder of "
                                "them; ximu3: the data-logger recording folder (or a device folder)")
    p.add_argument("--format", required=True, choices=["csv", "xsens", "ximu3"],
                   help="csv: any delimited text (columns named by --sensor/--quat/--gyro); xsens: MVN .mvnx or MT "
                        "Manager / DOT exports; ximu3: an x-IMU3 data-logger recording")
    p.add_argument("-o", "--output", required=True, help="take .npz (synthesis-input format)")
    p.add_argument("--sensor", action="append", metavar="PLACEMENT=AX,AY,AZ",
                   help="csv: acceleration columns of one sensor (names or 0-based indexes), repeat per sensor")
    p.add_argument("--quat", action="append", metavar="PLACEMENT=Q1,Q2,Q3,Q4",
                   help="csv: quaternion columns in file order (w-first or w-last is detected)")
    p.add_argument("--gyro", action="append", metavar="PLACEMENT=GX,GY,GZ", help="csv: gyro columns")
    p.add_argument("--time", help="csv: time column")
    p.add_argument("--time-unit", default="s", choices=list(TIME_UNITS_S), help="csv: unit of the --time column")
    p.add_argument("--rate", type=float, help="csv: constant sample rate (Hz) instead of a time column; "
                                              "xsens text: rate when SampleTimeFine is absent")
    p.add_argument("--gyro-unit", default="rad/s", choices=list(GYRO_UNITS_RPS), help="csv: unit of the --gyro columns")
    p.add_argument("--delimiter", help="csv: field delimiter (default: sniffed from the header: tab , ;)")
    p.add_argument("--sensor-map", action="append", metavar="LABEL=PLACEMENT",
                   help="xsens/ximu3: device id / MVN sensor label / x-IMU3 device -> standard placement")
    p.add_argument("--units", default="auto", choices=["auto", *UNITS_TO_G],
                   help="acceleration unit (default: detected from |a| at rest; a contradicted value is refused)")
    p.add_argument("--quat-order", default="auto", choices=["auto", *QUAT_ORDERS],
                   help="csv quaternion column order (default: detected from gravity consistency)")
    add_quiet_argument(p)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(sys.argv[1:] if argv is None else argv)
    check_output_dir(args.output)  # refused before a long read, not after it
    refuse_overwriting_inputs([args.output], [args.file])
    sensor_map = _pairs(args.sensor_map, "--sensor-map") or None
    ignored: list[str] = []
    if args.format == "csv":
        if not args.sensor:
            raise CourtsideError("csv needs at least one --sensor PLACEMENT=AX,AY,AZ")
        streams = read_generic_csv(args.file, _columns(args.sensor, "--sensor"), _columns(args.quat, "--quat"),
                                   _columns(args.gyro, "--gyro"), args.time, args.time_unit, args.rate,
                                   args.gyro_unit, args.delimiter)
    elif args.format == "xsens":
        streams, ignored = read_xsens(args.file, sensor_map, args.rate)
    else:
        streams, ignored = read_ximu3(args.file, sensor_map)
    take = assemble(streams, args.format, args.units, args.quat_order, {"source": str(args.file), "ignored": ignored})
    take.save(args.output)
    if ignored:
        print(f"import-imu: not mapped to a placement, left out: {', '.join(ignored)}", file=sys.stderr)
    if take.report.get("no_orientation"):
        print(f"import-imu: no orientation from {', '.join(take.report['no_orientation'])} (NaN in quat_wxyz; the "
              "other sensors keep theirs)", file=sys.stderr)
    print(json.dumps({"output": args.output, "fps": take.fps, "samples": int(len(take.t_s)),
                      "sensors": dict(zip(take.source_labels, take.sensor_names)),
                      "units": {k: v["units"] for k, v in take.report["sensors"].items()}}))
    return 0

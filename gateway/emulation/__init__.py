"""Emulation harnesses that pair `firmware_protocol.emulator` with the gateway, kept out of the daemon's core
(issue 13 "Shape"): `stations` serves emulated base stations on real ptys (`courtside gateway --emulate`, the
demo, tests) and replays mocap as worn accelerometers; `virtual_time` runs a station through a `StationReader`
in virtual time, scored against ground truth (tests, bench). Nothing in the daemon's data path imports these;
`gateway.assembly` imports `stations` only when a config asks for emulated stations."""

"""The bytes between a base station and the PC (see PROTOCOL.md), plus an emulated base station."""

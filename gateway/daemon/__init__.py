"""The gateway daemon: `Gateway` (`core`: readers, clock, recorder, server in one process) and its command line
(`cli`: `courtside gateway`, the `gateway.daemon:main` entry point)."""
from .cli import main
from .core import Gateway, format_status_lines

__all__ = ["Gateway", "format_status_lines", "main"]

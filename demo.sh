#!/usr/bin/env bash
# Set everything up, then run the live demo: emulated base stations replaying real mocap as virtual
# accelerometers + a synthetic overhead camera -> gateway -> operator console. Without a display it runs
# under Xvfb. Extra arguments go to `courtside demo` (see `courtside demo --help`).
set -euo pipefail
cd "$(dirname "$0")"
scripts/setup.sh
if [ -z "${DISPLAY:-}" ] && [ -z "${WAYLAND_DISPLAY:-}" ] && command -v xvfb-run >/dev/null 2>&1; then
  echo "demo: no display found, running under Xvfb (use --duration/--screenshots to capture what it shows)"
  exec xvfb-run -a -s "-screen 0 1600x1000x24" .venv/bin/courtside demo "$@"
fi
exec .venv/bin/courtside demo "$@"

#!/usr/bin/env bash
# One idempotent set-up used by both README commands and by CI:
#   system libraries (Qt offscreen / Xvfb / Mesa EGL) via apt when missing, a .venv, and an editable install
#   of courtside with the console and test extras. Re-running is cheap: pip runs only when pyproject.toml changed.
set -euo pipefail
cd "$(dirname "$0")/.."

APT_PACKAGES=(xvfb xauth libegl1 libgl1-mesa-dri libgl1 libxkbcommon0 libxkbcommon-x11-0 libfontconfig1 libdbus-1-3
              libglib2.0-0 libxcb-cursor0 libxcb-icccm4 libxcb-keysyms1 libxcb-shape0 libxcb-xinerama0
              libxcb-randr0 libxcb-render-util0 libxcb-image0
              strace)  # strace: the LSL test proves liblsl sends nothing beyond 127.0.0.1

missing=()
if command -v dpkg >/dev/null 2>&1; then
  for p in "${APT_PACKAGES[@]}"; do dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p"); done
fi
if ((${#missing[@]})); then
  echo "setup: installing system packages: ${missing[*]}"
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  if ! { $SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"; } >/tmp/courtside-apt.log 2>&1; then
    echo "setup: WARNING could not install ${missing[*]} (see /tmp/courtside-apt.log); GUI tests may be skipped or fail" >&2
  fi
fi

PYTHON=${PYTHON:-python3}
"$PYTHON" -c 'import sys; sys.exit(0 if sys.version_info >= (3, 11) else 1)' \
  || { echo "setup: Python >= 3.11 required (found $("$PYTHON" --version))" >&2; exit 1; }
[ -x .venv/bin/python ] || "$PYTHON" -m venv .venv
stamp=.venv/.courtside-installed
want=$(sha256sum pyproject.toml | cut -d' ' -f1)
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ]; then
  echo "setup: installing courtside[console,test] into .venv"
  .venv/bin/python -m pip install -q --upgrade pip >/dev/null 2>&1 || true
  .venv/bin/python -m pip install -q -e '.[console,test]' >.venv/pip-install.log 2>&1 \
    || { tail -30 .venv/pip-install.log >&2; echo "setup: pip install failed (full log: .venv/pip-install.log)" >&2; exit 1; }
  .venv/bin/python -c 'import numpy, scipy, serial, hid, PySide6, pyqtgraph, moderngl, cv2, ezc3d, pytest, xdist, hypothesis' \
    || { echo "setup: dependency import failed" >&2; exit 1; }
  echo "$want" > "$stamp"
fi

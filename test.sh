#!/usr/bin/env bash
# Set everything up, then run the whole test suite (real ptys, sockets, Qt offscreen, OpenGL via EGL/llvmpipe):
# spread over the cores (pytest-xdist, at most 4 workers), then the tests marked `alone` -- they measure keeping
# up in real time, so they run after the rest on an idle machine. With arguments: just that pytest run.
# pytest exits non-zero when no tests are collected, so CI can never go green on an empty suite.
set -euo pipefail
cd "$(dirname "$0")"
scripts/setup.sh
export QT_QPA_PLATFORM=${QT_QPA_PLATFORM:-offscreen}
pytest=(.venv/bin/python -m pytest -q -p no:cacheprovider)
if (($#)); then
  exec "${pytest[@]}" "$@"
fi
workers=$(nproc 2>/dev/null || echo 2)
((workers > 4)) && workers=4
status=0
"${pytest[@]}" -n "$workers" -m "not alone" --durations=25 || status=$?
"${pytest[@]}" -m alone --durations=5 || status=$?
exit "$status"

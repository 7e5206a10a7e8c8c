#!/usr/bin/env bash
# livedic set-up on a fresh Debian machine: system packages, a virtual environment,
# the livedic package and its dependencies; then the main job or the tests.
#
#   ./setup.sh          set up, then run the main job
#   ./setup.sh test     set up, then run the test suite (what CI runs)
#   ./setup.sh install  set up only
#
# Safe to run again: each step is skipped when already done.
set -euo pipefail
cd "$(dirname "$0")"
mode=${1:-run}
venv=.venv

say() { printf '[setup] %s\n' "$*" >&2; }

as_root() { if [ "$(id -u)" -eq 0 ]; then "$@"; else sudo "$@"; fi; }

python=${PYTHON:-python3}
if ! command -v "$python" >/dev/null 2>&1 || ! "$python" -c 'import venv, ensurepip' >/dev/null 2>&1; then
  say "installing python3 and python3-venv (Debian)"
  as_root apt-get update -qq
  as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq python3 python3-venv >/dev/null
  python=python3
fi
"$python" - <<'PY' || { say "livedic needs Python >= 3.10"; exit 1; }
import sys; sys.exit(sys.version_info < (3, 10))
PY

if [ ! -x "$venv/bin/python" ]; then
  say "creating $venv"
  "$python" -m venv "$venv"
fi
if [ ! -x "$venv/bin/uv" ]; then
  "$venv/bin/python" -m pip install -q --disable-pip-version-check uv
fi
if [ -f scripts/install_system.sh ]; then
  bash scripts/install_system.sh "$venv"
fi
say "installing livedic and its dependencies into $venv"
"$venv/bin/uv" pip install -q --python "$venv/bin/python" -e ".[test]"
# numba's on-disk caches (__pycache__/*.nbi, *.nbc) are keyed by source file, not by module name: after
# an update that renamed modules, a cached kernel would try to import its old module. Rebuild them
# (about a minute, once) whenever the code changed since the last set-up.
stamp="$venv/.livedic-code"
code=$(git rev-parse HEAD 2>/dev/null || echo unknown)
if [ "$(cat "$stamp" 2>/dev/null)" != "$code" ]; then
  find acquire dic stream bench -name '*.nb[ic]' -delete 2>/dev/null || true
  echo "$code" > "$stamp"
fi

case "$mode" in
  install) say "done: activate with 'source $venv/bin/activate' or call $venv/bin/livedic" ;;
  test) exec "$venv/bin/python" -m pytest -q ;;
  run) exec "$venv/bin/livedic" run --gauge-length 400 --load synthetic ;;
  *) say "unknown mode '$mode': use run, test or install"; exit 2 ;;
esac

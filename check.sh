#!/usr/bin/env bash
# Every check modscope has, from a fresh clone: installs what the tests need (a virtual
# environment with the dev extras, and the peer programs tshark, socat and mbpoll from
# Debian's packages), then runs ruff, mypy (strict) and the whole test suite.
#
#   ./check.sh            everything, slow tests included
#   ./check.sh --quick    skip the tests marked slow
set -euo pipefail
cd "$(dirname "$0")"

VENV=${MODSCOPE_VENV:-.venv}
PYTHON=${PYTHON:-python3}

if [ ! -x "$VENV/bin/python" ]; then
  echo "== creating $VENV"
  "$PYTHON" -m venv "$VENV"
fi
echo "== installing modscope with its dev extras"
"$VENV/bin/python" -m pip install --quiet --upgrade pip >/dev/null 2>&1 || true
"$VENV/bin/python" -m pip install --quiet -e '.[dev,imports]'

missing=()
for tool in tshark socat mbpoll mosquitto mosquitto_sub; do
  command -v "$tool" >/dev/null 2>&1 || missing+=("$tool")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "== installing peer programs for the tests: ${missing[*]}"
  SUDO=""
  [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq tshark socat mbpoll mosquitto mosquitto-clients >/dev/null
fi

echo "== ruff"
"$VENV/bin/ruff" check .
"$VENV/bin/ruff" format --check .
echo "== mypy (strict)"
"$VENV/bin/mypy"
echo "== pytest"
if [ "${1:-}" = "--quick" ]; then
  "$VENV/bin/pytest" -m "not slow"
else
  "$VENV/bin/pytest"
fi

#!/usr/bin/env bash
# Every check modscope has, from a fresh clone: a virtual environment with the dev
# extras, the peer programs the tests talk to (from Debian's packages, where apt-get and
# root or sudo are available), then ruff, mypy (strict), lint-imports, the test suite, and
# the tests that drive the TUI again at the lowest Textual pyproject.toml allows. Each step
# says what it does and how long it took. Without apt, or without root, the programs
# that are missing are named and the tests that need them are skipped with that reason;
# everything else still runs.
#
#   ./check.sh            everything, slow tests included
#   ./check.sh --quick    skip the tests marked slow
set -euo pipefail
cd "$(dirname "$0")"

VENV=${MODSCOPE_VENV:-.venv}
PYTHON=${PYTHON:-python3}
# program -> Debian package; tests that need a missing program skip, naming it
PEERS="tshark:tshark socat:socat mbpoll:mbpoll mosquitto:mosquitto \
mosquitto_pub:mosquitto-clients tcpdump:tcpdump tmux:tmux chromium:chromium ip:iproute2 \
prometheus:prometheus"

T0=$SECONDS
STEP_START=$SECONDS
step() {  # step "what is done now"
  STEP_START=$SECONDS
  echo "== $1"
}
done_step() {
  echo "   done in $((SECONDS - STEP_START)) s"
}
# ticking CMD ...: run CMD, saying every 20 s that it still runs, so that a step that takes
# long (a first mypy run, apt-get, pip building the compiled core) is never silent for long;
# returns CMD's exit status
ticking() {
  "$@" &
  local pid=$! waited=0
  while kill -0 "$pid" 2>/dev/null; do
    sleep 1
    waited=$((waited + 1))
    if [ $((waited % 20)) -eq 0 ]; then
      echo "   ... still running after ${waited} s: $1 ${2-}"
    fi
  done
  wait "$pid"
}

# -- what is missing, and whether we can install it: said before anything is done -------
have() {  # a program on PATH, or in /usr/sbin (mosquitto) that a user's PATH may lack
  command -v "$1" >/dev/null 2>&1 || [ -x "/usr/sbin/$1" ]
}
missing_pkgs=()
missing_progs=()
for pair in $PEERS; do
  prog=${pair%%:*}
  pkg=${pair#*:}
  if ! have "$prog"; then
    missing_progs+=("$prog")
    [[ " ${missing_pkgs[*]-} " == *" $pkg "* ]] || missing_pkgs+=("$pkg")
  fi
done
# the compiled core (sniffer/_core.c, built by pip install) needs a C compiler and the
# headers of the Python that builds it (Debian's python3-dev for Debian's python3)
if ! have cc; then
  missing_progs+=(cc)
  missing_pkgs+=(gcc)
fi
if ! "$PYTHON" -c 'import os, sysconfig, sys; sys.exit(not os.path.exists(os.path.join(sysconfig.get_paths()["include"], "Python.h")))' 2>/dev/null; then
  missing_progs+=(Python.h)
  missing_pkgs+=(python3-dev)
fi
SUDO=""
can_apt=no
if [ ${#missing_pkgs[@]} -gt 0 ]; then
  if ! command -v apt-get >/dev/null 2>&1; then
    echo "== note: ${missing_progs[*]} not installed and there is no apt-get here;"
    echo "   the tests that need them will be skipped (they say which program)"
  elif [ "$(id -u)" -eq 0 ]; then
    can_apt=yes
  elif command -v sudo >/dev/null 2>&1; then
    echo "== note: installing ${missing_pkgs[*]} with apt-get needs root: sudo may ask for"
    echo "   your password now (Ctrl-C and install them yourself to avoid it)"
    SUDO="sudo"
    can_apt=yes
  else
    echo "== note: ${missing_pkgs[*]} not installed; apt-get needs root and there is no sudo:"
    echo "   as root run: apt-get install ${missing_pkgs[*]}"
    echo "   until then the tests that need them are skipped (they say which program)"
  fi
fi

# -- peer programs, and a C compiler before pip builds the compiled core ----------------
if [ "$can_apt" = yes ]; then
  step "installing peer programs for the tests: ${missing_pkgs[*]} (apt-get, quietly)"
  if ticking $SUDO env DEBIAN_FRONTEND=noninteractive apt-get update -qq >/dev/null \
    && echo "   package lists updated; installing (a line per package set up)" \
    && ticking $SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends \
      "${missing_pkgs[@]}" | { grep --line-buffered '^Setting up' || true; } | sed -u 's/^/   /'; then
    done_step
  else
    echo "   apt-get failed; the tests that need ${missing_progs[*]} will be skipped"
  fi
fi

# -- the virtual environment -------------------------------------------------------------
if [ ! -x "$VENV/bin/python" ]; then
  step "creating the virtual environment $VENV"
  "$PYTHON" -m venv "$VENV"
  done_step
fi
step "installing modscope and its dev extras into $VENV (a minute or two the first time)"
ticking "$VENV/bin/python" -m pip install --quiet --disable-pip-version-check -e '.[dev,imports]'
done_step
# The tests start modscope several hundred times. pip compiles what it installs, but not
# an editable project, and where PYTHONDONTWRITEBYTECODE is set (some CI images and
# containers set it) no run keeps what it compiled: every start would parse all of
# sniffer/ again, about 0.5 s of CPU. Compiled once here instead; a source changed later
# only makes its own file's bytecode stale, which Python then ignores.
step "compiling modscope's modules to bytecode"
"$VENV/bin/python" -m compileall -q -j 0 sniffer dissectors >/dev/null
done_step

# the compiled core's tests fail, not skip, where it was not built
export MODSCOPE_REQUIRE_COMPILED=1
# pytest rewrites each test module's asserts and keeps the result as bytecode, unless
# PYTHONDONTWRITEBYTECODE forbids it: then every worker rewrote every module each run
# (15 s of CPU a worker, 7 s with the cache). Unset for the checks below.
unset PYTHONDONTWRITEBYTECODE

# -- the checks --------------------------------------------------------------------------------
step "ruff (lint and format), and no merge conflict markers left in any file"
if git grep -n -I -E '^(<<<<<<<|>>>>>>>)( |$)' -- . ':!*.svg' 2>/dev/null; then
  echo "   merge conflict markers above: resolve them"
  exit 1
fi
"$VENV/bin/ruff" check .
"$VENV/bin/ruff" format --check .
done_step
# pytest rewrites every test module's asserts the first time it imports it, 15 s of CPU
# that each worker below would spend again on a clean clone; done once here instead, on
# the CPU mypy leaves idle, so the workers find the rewritten modules (errors are left
# for the real run to report)
"$VENV/bin/pytest" -q -p no:cacheprovider --collect-only >/dev/null 2>&1 &
warm_pid=$!
step "mypy (strict)"
ticking "$VENV/bin/mypy"
done_step
step "lint-imports (the stages' layers and the other import contracts in pyproject.toml)"
"$VENV/bin/lint-imports"
done_step
# pytest-xdist runs the tests in parallel, two workers a CPU: many tests wait on something
# (a broker restarting, the clock a liveness test reads, a modscope they started), and with
# one worker a CPU a third of the machine sat idle (on 2 CPUs: 586 s, and 495 s with 4
# workers). tests/support/progress.py names each test file as it starts and what still runs
# when the screen has been quiet for 20 s.
JOBS=${MODSCOPE_TEST_JOBS:-$("$VENV/bin/python" -c 'import os; print(2 * (os.cpu_count() or 1))')}
wait "$warm_pid" || true
if [ "${1:-}" = "--quick" ]; then
  step "pytest, without the slow tests ($JOBS workers)"
  "$VENV/bin/pytest" -q -n "$JOBS" --durations=10 -m "not slow"
else
  step "pytest, the whole suite, slow tests included ($JOBS workers; a few minutes)"
  "$VENV/bin/pytest" -q -n "$JOBS" --durations=10
fi
done_step
# -- the TUI at the lowest Textual pyproject.toml allows ------------------------------------
# The suite above ran with the Textual pip chose for the venv (the newest, on a clean clone);
# the floor in pyproject.toml is a claim too. Textual at the floor, with the dependencies
# pip picks for it, goes into a folder inside the venv that PYTHONPATH puts first; the TUI
# tests run against it. The folder is kept, so later runs only run the tests.
FLOOR=$("$VENV/bin/python" - <<'PY'
import re, tomllib
with open("pyproject.toml", "rb") as f:
    deps = tomllib.load(f)["project"]["dependencies"]
floors = [m[1] for d in deps if (m := re.fullmatch(r"textual>=([0-9.]+)(,.*)?", d.replace(" ", "")))]
print(floors[0] if len(floors) == 1 else "")
PY
)
if [ -z "$FLOOR" ]; then
  echo "== pyproject.toml has no 'textual>=X' dependency to test the floor of"
  exit 1
fi
VERSION='from importlib.metadata import version; print(version("textual"))'
NEWEST=$("$VENV/bin/python" -c "$VERSION")
FLOOR_DIR="$VENV/textual-floor-$FLOOR"
step "the TUI tests at Textual $FLOOR, the floor pyproject.toml declares (above: $NEWEST)"
if [ ! -d "$FLOOR_DIR" ]; then
  ticking "$VENV/bin/python" -m pip install --quiet --disable-pip-version-check \
    --target "$FLOOR_DIR.part" "textual==$FLOOR"
  mv "$FLOOR_DIR.part" "$FLOOR_DIR"
fi
got=$(PYTHONPATH="$FLOOR_DIR" "$VENV/bin/python" -c "$VERSION")
if [ "$got" != "$FLOOR" ]; then
  echo "   Textual $got loaded instead of $FLOOR: the floor check would prove nothing"
  exit 1
fi
# The files that tell Textual releases apart: every screen's snapshot at 80x24 (where
# older releases drew differently, docs/install.md), each key binding, both themes and
# the panes' navigation. Not again here: what the run above already drove through the
# same widgets (the filter bar, exports and recordings of test_tui_app, the details and
# layout), what does not depend on Textual's version (row and query logic, the contrast
# arithmetic, textual-serve) and the snapshots at larger sizes. The whole of tests/tui
# again took 170 s, a quarter of this script; the list below, about 25 s on 2 CPUs. The
# served app's driver (test_tui_webdriver) leans on a private attribute of Textual's.
FLOOR_TESTS="test_tui_snapshots test_tui_keys test_tui_navigate test_tui_units
test_tui_ladder test_tui_regtable test_tui_theme test_tui_commands test_tui_status
test_tui_webdriver"
floor_files=()
for name in $FLOOR_TESTS; do floor_files+=("tests/tui/$name.py"); done
PYTHONPATH="$FLOOR_DIR" "$VENV/bin/pytest" -q -n "$JOBS" -p no:cacheprovider -m "not slow" \
  -k "not 120x36 and not 160x48 and not 200x50" "${floor_files[@]}"
done_step
echo "== all checks passed in $((SECONDS - T0)) s"

#!/usr/bin/env bash
# What the test suite needs beyond scripts/setup.sh: ParaView's pvpython, which tests/test_paraview.py runs
# to check that ParaView reads results.xdmf (Debian packages paraview and python3-paraview, about 540 MB,
# 1-2 minutes the first time). Quick when pvpython is already there; run by scripts/test.sh.
# A failing step prints one line "[setup-tests] failed: STEP: REASON; WHAT TO DO" and exits non-zero.
set -uo pipefail
command -v pvpython >/dev/null 2>&1 && exit 0

say() { echo "[setup-tests] $*" >&2; }
fail() { echo "[setup-tests] failed: $*" >&2; exit 1; }
command -v apt-get >/dev/null 2>&1 \
  || fail "pvpython (ParaView) is missing and there is no apt-get; install ParaView with its pvpython on PATH"
sudo=""
if [ "$(id -u)" -ne 0 ]; then
  command -v sudo >/dev/null 2>&1 || fail "apt-get needs root and sudo is missing; install paraview and python3-paraview as root"
  sudo="sudo"
fi
log=$(mktemp) || fail "mktemp: cannot create a temporary file; check that /tmp is writable"
trap 'rm -f "$log"' EXIT
say "installing ParaView (paraview, python3-paraview: about 540 MB) for tests/test_paraview.py"
export DEBIAN_FRONTEND=noninteractive
$sudo apt-get update -qq >"$log" 2>&1 \
  || fail "apt-get update: $(tail -n 1 "$log" | cut -c1-200); check the network or apt sources"
$sudo apt-get install -y -qq --no-install-recommends paraview python3-paraview >"$log" 2>&1 \
  || fail "apt-get install paraview python3-paraview: $(tail -n 1 "$log" | cut -c1-200)"
command -v pvpython >/dev/null 2>&1 || fail "pvpython is not on PATH after installing paraview"
say "ready: $(command -v pvpython)"

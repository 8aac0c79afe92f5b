#!/usr/bin/env bash
# What the test suite needs beyond scripts/setup.sh: ParaView's pvpython, which tests/test_paraview.py runs
# to check that ParaView reads results.xdmf (Debian packages paraview and python3-paraview, about 540 MB,
# 1-2 minutes the first time), and mount(8), with which tests/test_faults.py fills a small tmpfs (Debian
# package mount: on every installed system, missing only from minimal roots such as mmdebstrap's). Quick
# when both are already there; run by scripts/test.sh.
# A failing step prints one line "[setup-tests] failed: STEP: REASON; WHAT TO DO" and exits non-zero.
set -uo pipefail
packages=()
command -v pvpython >/dev/null 2>&1 || packages+=(paraview python3-paraview)
command -v mount >/dev/null 2>&1 || packages+=(mount)
[ ${#packages[@]} -eq 0 ] && exit 0

say() { echo "[setup-tests] $*" >&2; }
fail() { echo "[setup-tests] failed: $*" >&2; exit 1; }
command -v apt-get >/dev/null 2>&1 \
  || fail "${packages[*]} missing and there is no apt-get; install ParaView (pvpython on PATH) and mount"
sudo=""
if [ "$(id -u)" -ne 0 ]; then
  command -v sudo >/dev/null 2>&1 || fail "apt-get needs root and sudo is missing; install ${packages[*]} as root"
  sudo="sudo"
fi
log=$(mktemp) || fail "mktemp: cannot create a temporary file; check that /tmp is writable"
trap 'rm -f "$log"' EXIT
say "installing ${packages[*]} for the tests (ParaView: about 540 MB)"
export DEBIAN_FRONTEND=noninteractive
$sudo apt-get update -qq >"$log" 2>&1 \
  || fail "apt-get update: $(tail -n 1 "$log" | cut -c1-200); check the network or apt sources"
$sudo apt-get install -y -qq --no-install-recommends "${packages[@]}" >"$log" 2>&1 \
  || fail "apt-get install ${packages[*]}: $(tail -n 1 "$log" | cut -c1-200)"
command -v pvpython >/dev/null 2>&1 || fail "pvpython is not on PATH after installing paraview"
command -v mount >/dev/null 2>&1 || fail "mount is not on PATH after installing mount"
say "ready: $(command -v pvpython), $(command -v mount)"

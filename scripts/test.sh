#!/usr/bin/env bash
# The test suite, serially and under `mpirun -n 2` (rank 1's report goes to a log shown when it fails), after
# installing what only the tests need (scripts/setup-tests.sh: ParaView's pvpython).
# Extra arguments are passed to pytest (e.g. `scripts/test.sh -k hertz`).
# `scripts/test.sh --fast` (make check) is the fast tier: the tests not marked slow, serially, with every
# Python it starts noting which modules of petroll ran code (tests/modules_run/sitecustomize.py; the run
# fails if one did not, unless pytest arguments follow, which choose fewer tests), then the rank-count
# comparisons among them (marker parallel) under `mpirun -n 2`.
set -uo pipefail
cd "$(dirname "$0")/.."
py=.venv/bin/python
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_rmaps_base_oversubscribe=1
export OMPI_MCA_btl_vader_single_copy_mechanism=none OMPI_MCA_mpi_yield_when_idle=1
# compiled files kept (__pycache__, ignored by git): else each of the suite's hundreds of Python processes
# compiles petroll again, and each pytest (the docs run some) rewrites the asserts of every test module
unset PYTHONDONTWRITEBYTECODE

scripts/setup-tests.sh || exit 1  # ParaView's pvpython for tests/test_paraview.py (first time: apt-get)

log=$(mktemp)
if [ "${1:-}" = "--fast" ]; then
  shift
  notes=$(mktemp -d)
  trap 'rm -rf "$notes"' EXIT
  echo "== fast tier, serial: pytest -m 'not slow' =="
  if [ $# -eq 0 ]; then
    PETROLL_MODULES_RUN="$notes" PYTHONPATH="$PWD/tests/modules_run${PYTHONPATH:+:$PYTHONPATH}" \
      "$py" -m pytest -q -m "not slow" tests
  else
    "$py" -m pytest -q -m "not slow" "$@" tests
  fi
  serial=$?
  echo "== fast tier, rank-count comparisons: mpirun -n 2 pytest -m 'parallel and not slow' =="
  timeout 600 mpirun -n 1 "$py" -m pytest -q --color=no -p no:cacheprovider -m "parallel and not slow" "$@" tests \
    : -n 1 sh -c "\"$py\" -m pytest -q --color=no -p no:cacheprovider -m 'parallel and not slow' $* tests > \"$log\" 2>&1"
  parallel=$?
  [ $parallel -eq 5 ] && [ $# -gt 0 ] && parallel=0  # pytest's 5: the arguments chose none of them
  if [ $parallel -ne 0 ]; then echo "== rank 1 report =="; cat "$log"; fi
  rm -f "$log"
  echo "serial exit $serial, parallel exit $parallel"
  [ $serial -eq 0 ] && [ $parallel -eq 0 ]
  exit
fi

echo "== serial: pytest =="
"$py" -m pytest -q "$@" tests
serial=$?

echo "== parallel: mpirun -n 2 pytest =="
timeout 1800 mpirun -n 1 "$py" -m pytest -q --color=no -p no:cacheprovider "$@" tests \
  : -n 1 sh -c "\"$py\" -m pytest -q --color=no -p no:cacheprovider $* tests > \"$log\" 2>&1"
parallel=$?
if [ $parallel -ne 0 ]; then echo "== rank 1 report =="; cat "$log"; fi
rm -f "$log"

echo "== parallel: mpirun -n 4 pytest -m ranks4 (oversubscribed; a small selection) =="
timeout 900 mpirun -n 1 "$py" -m pytest -q --color=no -p no:cacheprovider -m ranks4 "$@" tests \
  : -n 3 sh -c "\"$py\" -m pytest -q --color=no -p no:cacheprovider -m ranks4 $* tests > \"$log.\$OMPI_COMM_WORLD_RANK\" 2>&1"
four=$?
if [ $four -ne 0 ]; then for f in "$log".*; do echo "== $f =="; cat "$f"; done; fi
rm -f "$log".*

echo "serial exit $serial, parallel exit $parallel, four ranks exit $four"
[ $serial -eq 0 ] && [ $parallel -eq 0 ] && [ $four -eq 0 ]

#!/usr/bin/env bash
# Set up petroll's project-local environment in .venv (idempotent; quick when already done).
#
# Route, in this order:
#   1. a Python that already imports petsc4py and mpi4py ($PETROLL_PYTHON, else python3 on PATH):
#      a cluster module, conda or a source build is used as it is;
#   2. Debian/Ubuntu packages (apt-get, as root or with sudo): PETSc/petsc4py, mpi4py, h5py-mpi, Open MPI;
#   3. otherwise PETSc and petsc4py are built from PyPI inside the venv (about 20 minutes; needs a C
#      compiler, MPI headers and BLAS/LAPACK: docs/getting-started.md).
# Then .venv is created with --system-site-packages and petroll is installed into it in editable mode.
#
# Every failing step prints one line "[setup] failed: STEP: REASON; WHAT TO DO" and exits non-zero.
# PETROLL_SETUP_NO_APT=1 skips the apt route (to exercise the PyPI route on a machine that has apt);
# PETROLL_SETUP_PYTHONS lists the Pythons probed for petsc4py after $PETROLL_PYTHON (default
# "python3 /usr/bin/python3": the first on PATH, then the one Debian's packages are built for).
set -uo pipefail
cd "$(dirname "$0")/.." || { echo "[setup] failed: cannot enter the project folder" >&2; exit 1; }
root=$(pwd)
venv="$root/.venv"
stamp="$venv/.petroll-setup"
want="$(cat pyproject.toml scripts/setup.sh | sha256sum | cut -c1-16)"

if [ -x "$venv/bin/python" ] && [ "$(cat "$stamp" 2>/dev/null)" = "$want" ] \
   && "$venv/bin/python" -c "import petsc4py, mpi4py, h5py, meshio, scipy, tomli_w, petroll" 2>/dev/null; then
  exit 0
fi

say() { echo "[setup] $*" >&2; }
fail() { echo "[setup] failed: $*" >&2; exit 1; }
has_petsc() { "$1" -c "import petsc4py; petsc4py.init([]); import mpi4py, h5py" >/dev/null 2>&1; }
last_line() { tail -n 1 "$1" 2>/dev/null | tr -d '\r' | cut -c1-200; }
log=$(mktemp) || fail "mktemp: cannot create a temporary file; check that /tmp is writable"
trap 'rm -f "$log"' EXIT

debian_petsc_path() {
  # Debian's petsc4py.pth points at /usr/lib/petsc, which exists only with the -dev package installed.
  # Prints nothing (and succeeds) when there is no such folder.
  local found
  found=$(ls -d /usr/lib/petscdir/petsc*/*-real/lib/python3/dist-packages 2>/dev/null | sort -V | tail -n 1)
  echo "${found:-}"
  return 0
}

usable() {
  # $1 imports petsc4py, mpi4py and h5py, as it is or with Debian's petsc4py folder on its path.
  local extra
  has_petsc "$1" && return 0
  extra=$(debian_petsc_path)
  [ -n "$extra" ] && PYTHONPATH="$extra" has_petsc "$1"
}

find_python() {
  local candidate
  for candidate in "${PETROLL_PYTHON:-}" ${PETROLL_SETUP_PYTHONS:-python3 /usr/bin/python3}; do
    [ -n "$candidate" ] && command -v "$candidate" >/dev/null 2>&1 || continue
    if usable "$candidate"; then command -v "$candidate"; return 0; fi
  done
  return 0
}

if [ -n "${PETROLL_PYTHON:-}" ] && ! usable "$PETROLL_PYTHON"; then
  fail "PETROLL_PYTHON=$PETROLL_PYTHON does not import petsc4py, mpi4py and h5py; point it at a Python that does, or unset it"
fi
python=$(find_python)

if [ -z "$python" ] && [ "${PETROLL_SETUP_NO_APT:-0}" != 1 ] && command -v apt-get >/dev/null 2>&1; then
  sudo=""
  if [ "$(id -u)" -ne 0 ]; then
    command -v sudo >/dev/null 2>&1 \
      || fail "apt-get needs root and sudo is missing; run 'make' as root, or set PETROLL_PYTHON to a Python that imports petsc4py"
    sudo="sudo"
  fi
  say "installing PETSc, petsc4py, mpi4py, h5py (MPI), scipy and Open MPI from Debian packages (about 1 min)"
  export DEBIAN_FRONTEND=noninteractive
  $sudo apt-get update -qq >"$log" 2>&1 \
    || fail "apt-get update: $(last_line "$log"); check the network or apt sources, or set PETROLL_PYTHON to a Python that imports petsc4py"
  $sudo apt-get install -y -qq --no-install-recommends \
    python3-petsc4py python3-mpi4py python3-h5py-mpi python3-numpy python3-venv python3-pip \
    python3-meshio python3-pytest python3-hypothesis python3-matplotlib python3-scipy python3-tomli-w \
    openmpi-bin libopenmpi-dev >"$log" 2>&1 \
    || fail "apt-get could not install python3-petsc4py and its companions: $(last_line "$log"); set PETROLL_PYTHON to a Python that imports petsc4py, or install them by hand"
  python=/usr/bin/python3
  has_petsc "$python" || [ -n "$(debian_petsc_path)" ] \
    || fail "Debian's petsc4py does not import after apt-get; set PETROLL_PYTHON to a Python that imports petsc4py"
fi

if [ -z "$python" ]; then
  python=$(command -v python3 || true)
  [ -n "$python" ] || fail "no python3 on PATH; install Python 3.10 or newer"
  say "no petsc4py found and no apt route: PETSc and petsc4py will be built from PyPI (about 20 minutes)"
fi

say "creating $venv from $python"
"$python" -m venv --system-site-packages "$venv" >"$log" 2>&1 \
  || fail "$python -m venv: $(last_line "$log"); install the venv module (Debian: python3-venv)"
site=$("$venv/bin/python" -c "import sysconfig; print(sysconfig.get_paths()['purelib'])") \
  || fail "the new .venv's python does not start; remove .venv and try again"
extra=$(debian_petsc_path)
if [ -n "$extra" ] && ! has_petsc "$venv/bin/python"; then
  echo "$extra" > "$site/petroll-debian-petsc.pth" 2>"$log" \
    || fail "cannot write $site/petroll-debian-petsc.pth: $(last_line "$log"); remove .venv and try again"
fi
if ! has_petsc "$venv/bin/python"; then
  say "building PETSc and petsc4py from PyPI: this takes about 20 minutes"
  # An optimised build; without a Fortran compiler PETSc's configure must be told so.
  default_options="--with-debugging=0"
  command -v gfortran >/dev/null 2>&1 || default_options="$default_options --with-fc=0"
  export PETSC_CONFIGURE_OPTIONS="${PETSC_CONFIGURE_OPTIONS:-$default_options}"
  "$venv/bin/python" -m pip install -q "petsc" "petsc4py" "mpi4py" "h5py" >"$log" 2>&1 \
    || fail "pip could not build petsc/petsc4py/mpi4py/h5py: $(last_line "$log"); install a C compiler, MPI (headers and mpicc) and BLAS/LAPACK, or set PETROLL_PYTHON to a Python that imports petsc4py"
fi
# petroll itself without dependency resolution, then only the modules that do not import: pip must not
# shadow the system's builds (Debian's MPI h5py, numpy 1.x that petsc4py was compiled against).
"$venv/bin/python" -m pip install -q --no-deps --no-build-isolation -e . >"$log" 2>&1 \
  || "$venv/bin/python" -m pip install -q --no-deps -e . >"$log" 2>&1 \
  || fail "pip install -e . (petroll itself): $(last_line "$log"); check that setuptools is installed in $python"
modules="numpy h5py meshio pytest hypothesis scipy matplotlib tomli_w"  # tomli_w: pip finds tomli-w
# x3pio reads .x3p topographies and needs Python >= 3.11 (older: .x3p files are refused in one line)
"$venv/bin/python" -c "import sys; sys.exit(sys.version_info < (3, 11))" 2>/dev/null && modules="$modules x3pio"
missing=()
for module in $modules; do
  "$venv/bin/python" -c "import $module" 2>/dev/null || missing+=("$module")
done
if [ ${#missing[@]} -gt 0 ]; then
  say "installing from PyPI: ${missing[*]}"
  "$venv/bin/python" -m pip install -q "${missing[@]}" >"$log" 2>&1 \
    || fail "pip install ${missing[*]}: $(last_line "$log"); check that PyPI is reachable"
fi
"$venv/bin/python" -c "import petsc4py, mpi4py, h5py, meshio, scipy, tomli_w, petroll" >"$log" 2>&1 \
  || fail "the new .venv does not import petroll's dependencies: $(last_line "$log"); remove .venv and try again"
echo "$want" > "$stamp"
say "ready: $venv"

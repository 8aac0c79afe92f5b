#!/usr/bin/env bash
# Set up petroll's project-local environment in .venv (idempotent; quick when already done).
#
# Route, in this order:
#   1. a Python that already imports petsc4py and mpi4py ($PETROLL_PYTHON, else python3 on PATH):
#      a cluster module, conda or a source build is used as it is;
#   2. Debian/Ubuntu packages (apt-get, as root or with sudo): PETSc/petsc4py, mpi4py, h5py-mpi, Open MPI;
#   3. otherwise PETSc and petsc4py are built from PyPI inside the venv (about 20 minutes).
# Then .venv is created with --system-site-packages and petroll is installed into it in editable mode.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)
venv="$root/.venv"
stamp="$venv/.petroll-setup"
want="$(cat pyproject.toml scripts/setup.sh | sha256sum | cut -c1-16)"

if [ -x "$venv/bin/python" ] && [ "$(cat "$stamp" 2>/dev/null)" = "$want" ] \
   && "$venv/bin/python" -c "import petsc4py, mpi4py, h5py, meshio, petroll" 2>/dev/null; then
  exit 0
fi

say() { echo "[setup] $*" >&2; }
has_petsc() { "$1" -c "import petsc4py; petsc4py.init([]); import mpi4py, h5py" >/dev/null 2>&1; }

debian_petsc_path() {
  # Debian's petsc4py.pth points at /usr/lib/petsc, which exists only with the -dev package installed.
  ls -d /usr/lib/petscdir/petsc*/*-real/lib/python3/dist-packages 2>/dev/null | sort -V | tail -n 1
}

python=""
for candidate in "${PETROLL_PYTHON:-}" python3 /usr/bin/python3; do
  [ -n "$candidate" ] && command -v "$candidate" >/dev/null 2>&1 || continue
  if has_petsc "$candidate"; then python=$(command -v "$candidate"); break; fi
  extra=$(debian_petsc_path)
  if [ -n "$extra" ] && PYTHONPATH="$extra" has_petsc "$candidate"; then python=$(command -v "$candidate"); break; fi
done

if [ -z "$python" ] && command -v apt-get >/dev/null 2>&1; then
  sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  say "installing PETSc, petsc4py, mpi4py, h5py (MPI) and Open MPI from Debian packages (about 30 s)"
  export DEBIAN_FRONTEND=noninteractive
  $sudo apt-get update -qq
  $sudo apt-get install -y -qq --no-install-recommends \
    python3-petsc4py python3-mpi4py python3-h5py-mpi python3-numpy python3-venv python3-pip \
    python3-meshio python3-pytest python3-hypothesis python3-matplotlib python3-scipy \
    openmpi-bin libopenmpi-dev >/dev/null
  python=/usr/bin/python3
fi

if [ -z "$python" ]; then
  python=$(command -v python3)
  say "no petsc4py found and no apt-get: PETSc and petsc4py will be built from PyPI (about 20 minutes)"
fi

say "creating $venv from $python"
"$python" -m venv --system-site-packages "$venv"
site=$("$venv/bin/python" -c "import sysconfig; print(sysconfig.get_paths()['purelib'])")
extra=$(debian_petsc_path)
if [ -n "$extra" ] && ! has_petsc "$venv/bin/python"; then
  echo "$extra" > "$site/petroll-debian-petsc.pth"
fi
if ! has_petsc "$venv/bin/python"; then
  say "building PETSc and petsc4py from PyPI: this takes about 20 minutes"
  "$venv/bin/python" -m pip install -q "petsc" "petsc4py" "mpi4py" "h5py"
fi
# petroll itself without dependency resolution, then only the modules that do not import: pip must not
# shadow the system's builds (Debian's MPI h5py, numpy 1.x that petsc4py was compiled against).
"$venv/bin/python" -m pip install -q --no-deps --no-build-isolation -e . 2>/dev/null \
  || "$venv/bin/python" -m pip install -q --no-deps -e .
missing=()
for module in numpy h5py meshio pytest hypothesis scipy matplotlib; do
  "$venv/bin/python" -c "import $module" 2>/dev/null || missing+=("$module")
done
if [ ${#missing[@]} -gt 0 ]; then
  say "installing from PyPI: ${missing[*]}"
  "$venv/bin/python" -m pip install -q "${missing[@]}"
fi
"$venv/bin/python" -c "import petsc4py, mpi4py, h5py, meshio, petroll"
echo "$want" > "$stamp"
say "ready: $venv"

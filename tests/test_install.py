"""petroll from a non-editable install: ``pip install .`` (no dependencies: PETSc and the rest come from the
system site, as in .venv) into a fresh virtual environment, then ``petroll bench warm --quick`` run from
outside the source tree. The benchmark finds runs/sphere.toml as the package data ``petroll.scenes``;
``petroll bench peers``, whose scripts only a checkout has, is refused in one line."""

import csv
import pathlib
import shutil
import subprocess
import sys

import h5py
import mpi4py
import petsc4py
import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
pytestmark = pytest.mark.serial


@pytest.mark.slow
def test_an_installed_petroll_runs_its_quick_benchmark_outside_the_source_tree(tmp_path, cli):
    source = tmp_path / "source"  # a copy, so that the build leaves nothing in the working tree
    skip = ("results", "build", "__pycache__")
    shutil.copytree(ROOT, source, ignore=lambda folder, names: [
        n for n in names if n.startswith(".") or n in skip or n.endswith(".egg-info")])
    venv = tmp_path / "venv"
    # from the base Python of this one (.venv's), with the system's site packages, as scripts/setup.sh does
    base = pathlib.Path(sys.base_prefix) / "bin" / f"python{sys.version_info.major}.{sys.version_info.minor}"
    subprocess.run([str(base), "-m", "venv", "--system-site-packages", str(venv)], check=True)
    site = subprocess.run([str(venv / "bin" / "python"), "-c", "import sysconfig; print(sysconfig.get_paths()"
                           "['purelib'])"], check=True, capture_output=True, text=True).stdout.strip()
    # PETSc, MPI and HDF5 where this Python finds them (setup.sh may have added Debian's petsc4py folder)
    folders = {str(pathlib.Path(m.__file__).parents[1]) for m in (petsc4py, mpi4py, h5py)}
    (pathlib.Path(site) / "system-petsc.pth").write_text("\n".join(sorted(folders)) + "\n")
    pip = subprocess.run([str(venv / "bin" / "python"), "-m", "pip", "install", "-q", "--no-deps",
                          "--no-build-isolation", str(source)], capture_output=True, text=True, timeout=300)
    assert pip.returncode == 0, pip.stderr
    work = tmp_path / "elsewhere"
    work.mkdir()
    env = {k: v for k, v in cli.env.items() if k != "PYTHONPATH"}  # nothing but the install

    def installed(program, *args):
        return subprocess.run([str(venv / "bin" / program), *args], cwd=work, env=env, capture_output=True,
                              text=True, timeout=300)

    where = installed("python", "-c", "import petroll, petroll.model.scene as s; print(petroll.__file__); "
                      "print(s.shipped_scene('sphere.toml'))")
    assert where.returncode == 0, where.stderr
    assert all(pathlib.Path(p).is_relative_to(venv) for p in where.stdout.split()), where.stdout
    done = installed("petroll", "bench", "warm", "--quick", "--out", "bench")
    assert done.returncode == 0, done.stderr
    with open(work / "bench" / "warm.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["start"] for r in rows] == ["cold", "carried", "extrapolated"]
    assert len({r["force"] for r in rows}) == 1  # the first guess changes the cost, not the answer
    refused = installed("petroll", "bench", "peers", "--quick", "--out", "bench")  # its scripts: a checkout's
    assert refused.returncode == 2 and len(refused.stderr.strip().splitlines()) == 1, refused.stderr
    assert "scripts/peers" in refused.stderr and not (work / "bench" / "peers.csv").exists()
    for room in ("petroll/bench/verbs.py", "petroll/studies/stability/runs.py"):  # every package installed
        assert list(venv.rglob(room)), room

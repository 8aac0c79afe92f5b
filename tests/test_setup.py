"""scripts/setup.sh never ends silently: with its probes failing (no PETSc, no apt, or apt failing) in a
sandboxed PATH it stops with one line naming the failed step and what to do. Nothing is installed: the
sandbox holds fake python3/apt-get programs and a copy of the script in a temporary project."""

import os
import pathlib
import shutil
import subprocess

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
TOOLS = ("cat", "sha256sum", "cut", "ls", "sort", "tail", "tr", "mktemp", "rm", "dirname", "head", "mkdir", "cp")

FAKE_PYTHON = """#!/bin/bash
# A Python without petsc4py whose pip cannot reach PyPI; `-m venv DIR` makes DIR/bin/python a copy of it.
if [ "$1" = -c ]; then
  case "$2" in *sysconfig*) echo "${0%/bin/*}/lib/site-packages"; exit 0;; esac
  echo "ModuleNotFoundError: No module named 'petsc4py'" >&2; exit 1
fi
if [ "$1 $2" = "-m venv" ]; then dir="${@: -1}"; mkdir -p "$dir/bin" "$dir/lib/site-packages"; cp "$0" "$dir/bin/python"; exit 0; fi
if [ "$1 $2" = "-m pip" ]; then
  echo "ERROR: Could not find a version that satisfies the requirement petsc (from versions: none)" >&2; exit 1
fi
exit 1
"""

FAKE_APT = """#!/bin/bash
echo "E: The repository 'http://deb.debian.org/debian bookworm Release' is not signed." >&2
exit 100
"""


def sandbox(tmp_path: pathlib.Path, apt: bool) -> tuple[pathlib.Path, dict]:
    """A project copy with scripts/setup.sh and a PATH of fakes plus the few tools the script uses."""
    project = tmp_path / "project"
    (project / "scripts").mkdir(parents=True)
    shutil.copy(ROOT / "scripts" / "setup.sh", project / "scripts" / "setup.sh")
    shutil.copy(ROOT / "pyproject.toml", project / "pyproject.toml")
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    for tool in TOOLS:
        (bin_dir / tool).symlink_to(shutil.which(tool))
    fakes = {"python3": FAKE_PYTHON, "id": "#!/bin/bash\necho 0\n"}
    if apt:
        fakes["apt-get"] = FAKE_APT
    for name, text in fakes.items():
        (bin_dir / name).write_text(text)
        (bin_dir / name).chmod(0o755)
    env = {"PATH": str(bin_dir), "HOME": str(tmp_path), "PETROLL_SETUP_PYTHONS": "python3"}
    return project, env


def run_setup(project: pathlib.Path, env: dict) -> subprocess.CompletedProcess:
    return subprocess.run([shutil.which("bash"), "scripts/setup.sh"], cwd=project, env=env, capture_output=True,
                          text=True, timeout=60)


def failure_line(done: subprocess.CompletedProcess) -> str:
    """The one failure line: non-zero exit, the last line of stderr, and no other failure line."""
    assert done.returncode != 0, done.stderr
    lines = done.stderr.strip().splitlines()
    assert lines, "set-up failed silently"
    failed = [line for line in lines if line.startswith("[setup] failed:")]
    assert failed == [lines[-1]], done.stderr
    assert all(line.startswith("[setup] ") for line in lines), done.stderr  # nothing unexplained leaks out
    assert "Traceback" not in done.stderr
    return lines[-1]


@pytest.mark.serial
def test_no_petsc_and_no_apt_names_the_pypi_build_and_what_it_needs(tmp_path):
    project, env = sandbox(tmp_path, apt=False)
    line = failure_line(run_setup(project, env))
    assert "pip could not build petsc" in line
    assert "Could not find a version" in line  # pip's own reason, passed on
    assert "C compiler" in line and "MPI" in line and "PETROLL_PYTHON" in line


@pytest.mark.serial
def test_failing_apt_names_apt_and_the_alternative(tmp_path):
    project, env = sandbox(tmp_path, apt=True)
    line = failure_line(run_setup(project, env))
    assert line.startswith("[setup] failed: apt-get update:")
    assert "is not signed" in line and "PETROLL_PYTHON" in line
    assert not (project / ".venv").exists()


@pytest.mark.serial
def test_a_petroll_python_without_petsc4py_is_named(tmp_path):
    project, env = sandbox(tmp_path, apt=True)
    env["PETROLL_PYTHON"] = str(tmp_path / "bin" / "python3")
    line = failure_line(run_setup(project, env))
    assert f"PETROLL_PYTHON={env['PETROLL_PYTHON']} does not import petsc4py" in line
    assert not (project / ".venv").exists()


@pytest.mark.serial
def test_fresh_machine_script_without_root_says_so_in_one_line(tmp_path):
    """The fresh-root proof needs root; run as another user it says so and changes nothing."""
    if os.geteuid() != 0:
        done = subprocess.run(["bash", str(ROOT / "scripts" / "fresh-machine.sh")], capture_output=True, text=True)
    else:
        fake_id = tmp_path / "id"
        fake_id.write_text("#!/bin/bash\necho 1000\n")
        fake_id.chmod(0o755)
        done = subprocess.run([shutil.which("bash"), str(ROOT / "scripts" / "fresh-machine.sh")],
                              env={"PATH": f"{tmp_path}:/usr/bin:/bin"}, capture_output=True, text=True, timeout=30)
    assert done.returncode == 2
    assert done.stderr.strip().splitlines() == [
        "fresh-machine: needs root (chroot and mounts); run it as root, e.g. sudo scripts/fresh-machine.sh"]

"""Tests run serially and under `mpirun -n 2` (scripts/test.sh). Collective tests use ``comm``: under
mpirun every rank runs every test, and comparisons against COMM_SELF check rank-count independence.
Shared fixtures: ``comm``, ``shared_dir`` (one directory for all ranks), ``api_and_cli`` (a scene run from
Python and from its TOML), ``cli`` (the command line in a child process) and ``cli_main`` (in this process)."""

import os
import pathlib
import subprocess
import sys

import petsc4py

petsc4py.init([])

import pytest  # noqa: E402
from mpi4py import MPI  # noqa: E402


@pytest.fixture
def comm():
    return MPI.COMM_WORLD


@pytest.fixture
def shared_dir(comm, tmp_path) -> pathlib.Path:
    """Rank 0's tmp_path on every rank (the ranks share a file system): where collective tests write."""
    return pathlib.Path(comm.bcast(str(tmp_path) if comm.rank == 0 else None, root=0))


@pytest.fixture
def api_and_cli(comm, shared_dir, capsys):
    """Runs a raw scene (a dict) twice: ``petroll.run`` from Python (into shared_dir/api) and ``petroll run``
    on its TOML in this process (shared_dir/cli). Returns (api Results, cli Results, the command's stdout;
    "" on ranks other than 0)."""
    import petroll
    from petroll.cli import main
    from petroll.model.scene import dumps

    def run(raw: dict):
        api = petroll.run(petroll.parse_scene(raw), comm, out=shared_dir / "api")
        if comm.rank == 0:
            (shared_dir / "scene.toml").write_text(dumps(raw), encoding="utf-8")
        comm.Barrier()
        capsys.readouterr()
        assert main(["run", str(shared_dir / "scene.toml"), "--out", str(shared_dir / "cli"), "--quiet"]) == 0
        out = capsys.readouterr().out if comm.rank == 0 else ""
        return api, petroll.Results.open(shared_dir / "cli" / "results.h5"), out

    return run


class PetrollCommand:
    """The ``petroll`` command line run as a child process (``python -m petroll.cli``) of this Python, with
    an environment that lets Open MPI run as root and oversubscribe (``env``)."""

    argv = (sys.executable, "-m", "petroll.cli")
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1", OMPI_MCA_btl_vader_single_copy_mechanism="none",
               OMPI_MCA_mpi_yield_when_idle="1")

    def __call__(self, *args, cwd, ranks=0, timeout=300.0, **env) -> subprocess.CompletedProcess:
        """``petroll ARGS`` in ``cwd`` (under ``mpirun -n ranks`` if ranks > 0), output captured as text;
        keyword arguments are extra environment variables."""
        mpirun = ("mpirun", "-n", str(ranks)) if ranks else ()
        return subprocess.run([*mpirun, *self.argv, *map(str, args)], cwd=cwd, env=dict(self.env, **env),
                              capture_output=True, text=True, timeout=timeout)

    def start(self, *args, cwd, **popen) -> subprocess.Popen:
        """``petroll ARGS`` started in ``cwd`` without waiting (subprocess.Popen keywords pass through)."""
        return subprocess.Popen([*self.argv, *map(str, args)], cwd=cwd, env=self.env, **popen)


@pytest.fixture
def cli() -> PetrollCommand:
    return PetrollCommand()


@pytest.fixture
def cli_main(capsys):
    """``petroll ARGS`` in this process (``petroll.cli.main``, argparse's exits included), called with the
    list of arguments: (exit status, stdout, stderr)."""
    from petroll.cli import main

    def call(argv: list) -> tuple:
        try:
            code = main(argv)
        except SystemExit as exc:  # argparse
            code = exc.code
        captured = capsys.readouterr()
        return code, captured.out, captured.err

    return call


def pytest_collection_modifyitems(config, items):
    """Tests marked ``serial`` (they start their own processes) run in the serial pass only. Tests marked
    ``parallel`` compare rank counts: on one rank they would compare the code with itself, so there they
    are skipped, saying so."""
    if MPI.COMM_WORLD.size > 1:
        chosen = [item for item in items if item.get_closest_marker("serial")]
        for item in chosen:
            items.remove(item)
        config.hook.pytest_deselected(items=chosen)
        return
    skip = pytest.mark.skip(reason="compares rank counts: runs under mpirun -n 2 (scripts/test.sh)")
    for item in items:
        if item.get_closest_marker("parallel"):
            item.add_marker(skip)


def pytest_configure(config):
    config.addinivalue_line("markers", "serial: a test that starts its own processes; run in the serial pass")
    config.addinivalue_line("markers", "parallel: a test that compares rank counts; skipped on one rank, "
                            "run in the mpirun -n 2 pass")
    config.addinivalue_line("markers", "ranks4: a cheap collective test also run in the mpirun -n 4 pass "
                            "(scripts/test.sh: oversubscribed, -m ranks4)")
    config.addinivalue_line("markers", "slow: not in the fast tier (`make check` runs -m 'not slow'; "
                            "`make test` runs everything)")


# -- which modules ran (make check) ------------------------------------------------------------------------
PACKAGE = pathlib.Path(__file__).resolve().parents[1] / "petroll"
PEERS_VENV = "runs in .venv-peers, a virtual environment with {} from PyPI, which the tests do not make"
NOT_RUN_HERE = {
    "studies/peers/solve_tamaas.py": PEERS_VENV.format("Tamaas"),
    "studies/peers/solve_tamaas_periodic.py": PEERS_VENV.format("Tamaas"),
    "studies/peers/solve_contactmechanics.py": PEERS_VENV.format("ContactMechanics"),
}
"""Modules of petroll that the tests cannot run, and why (`make check` fails on any other module whose
code does not run)."""


def modules_not_run(notes: pathlib.Path) -> list[str]:
    """The modules of petroll (paths relative to the package) of which no function ran, by the notes of
    tests/modules_run/sitecustomize.py in the directory ``notes``; a module that defines no function counts
    when it ran (was imported). A note names a file by its path: the part after its last ``petroll/`` is
    the module (the docs' blocks run in a copy of the repository)."""
    ran: dict[str, set[str]] = {}
    for record in notes.iterdir():
        for line in record.read_text(encoding="utf-8", errors="replace").splitlines():
            kind, _, filename = line.partition(" ")
            _, found, module = filename.rpartition("/petroll/")
            if found:
                ran.setdefault(module, set()).add(kind)
    missing = []
    for path in sorted(PACKAGE.rglob("*.py")):
        module = path.relative_to(PACKAGE).as_posix()
        code = compile(path.read_text(encoding="utf-8"), str(path), "exec")
        has_functions = any(_functions(code))
        if module not in NOT_RUN_HERE and "F" not in ran.get(module, ()) and (
                has_functions or "M" not in ran.get(module, ())):
            missing.append(module)
    return missing


COMPREHENSIONS = ("<listcomp>", "<dictcomp>", "<setcomp>", "<genexpr>")


def _functions(code):
    """The functions defined in ``code`` (a module's), at any depth; comprehensions are their caller's."""
    for const in code.co_consts:
        if hasattr(const, "co_code"):
            if const.co_flags & 1 and const.co_name not in COMPREHENSIONS:
                yield const
            yield from _functions(const)


def pytest_runtest_setup(item):
    """With PETROLL_MODULES_RUN: the trace function of tests/modules_run/sitecustomize.py set again if a
    test before switched it off."""
    rearm = getattr(sys.modules.get("sitecustomize"), "petroll_rearm", None)
    if rearm is not None:
        rearm()


def pytest_sessionfinish(session, exitstatus):
    """With PETROLL_MODULES_RUN (scripts/test.sh --fast), the session fails if a module of petroll, not
    exempt, ran no code."""
    notes = os.environ.get("PETROLL_MODULES_RUN")
    if notes and MPI.COMM_WORLD.size == 1:
        missing = modules_not_run(pathlib.Path(notes))
        session.config.stash[MISSING] = missing
        if missing and session.exitstatus == 0:
            session.exitstatus = pytest.ExitCode.TESTS_FAILED


MISSING = pytest.StashKey[list]()


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    missing = config.stash.get(MISSING, None)
    if missing is None:
        return
    if missing:
        terminalreporter.write_line(f"modules of petroll whose code no test ran ({len(missing)}): "
                                    + ", ".join(missing), red=True)
    else:
        modules = sum(1 for _ in PACKAGE.rglob("*.py"))
        terminalreporter.write_line(f"every module of petroll ran code: {modules - len(NOT_RUN_HERE)} of "
                                    f"{modules}, exempt: {', '.join(sorted(NOT_RUN_HERE)) or 'none'}")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_call(item):
    """Keep ranks in step: a test that fails on one rank fails on all, so none waits in a collective."""
    outcome = yield
    comm = MPI.COMM_WORLD
    if comm.size == 1:
        return
    failed = comm.allreduce(outcome.excinfo is not None, op=MPI.LOR)
    if failed and outcome.excinfo is None:  # raised here: pluggy < 1.1 has no outcome.force_exception
        raise AssertionError("failed on another rank (see that rank's report)")

"""Tests run serially and under `mpirun -n 2` (scripts/test.sh). Collective tests use ``comm``: under
mpirun every rank runs every test, and comparisons against COMM_SELF check rank-count independence."""

import petsc4py

petsc4py.init([])

import pytest  # noqa: E402
from mpi4py import MPI  # noqa: E402


@pytest.fixture
def comm():
    return MPI.COMM_WORLD


def pytest_collection_modifyitems(config, items):
    """Tests marked ``serial`` (they start their own processes) run in the serial pass only, tests marked
    ``parallel`` (they compare rank counts) in the ``mpirun -n 2`` pass only."""
    other = "serial" if MPI.COMM_WORLD.size > 1 else "parallel"
    chosen = [item for item in items if item.get_closest_marker(other)]
    for item in chosen:
        items.remove(item)
    config.hook.pytest_deselected(items=chosen)


def pytest_configure(config):
    config.addinivalue_line("markers", "serial: a test that starts its own processes; run in the serial pass")
    config.addinivalue_line("markers", "parallel: a test that needs 2 ranks; run in the mpirun -n 2 pass")
    config.addinivalue_line("markers", "ranks4: a cheap collective test also run in the mpirun -n 4 pass "
                            "(scripts/test.sh: oversubscribed, -m ranks4)")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_call(item):
    """Keep ranks in step: a test that fails on one rank fails on all, so none waits in a collective."""
    outcome = yield
    comm = MPI.COMM_WORLD
    if comm.size == 1:
        return
    failed = comm.allreduce(outcome.excinfo is not None, op=MPI.LOR)
    if failed and outcome.excinfo is None:
        outcome.force_exception(AssertionError("failed on another rank (see that rank's report)"))

"""results.h5 grows by appending (docs/results.md): what is read back equals what was appended, earlier
fields stay where they were written (byte offsets of their chunks unchanged), the file is valid after real
SIGKILLs at random moments, and a resumed file continues from a given step.

Unmarked tests are collective (every rank under mpirun); tests that start processes are marked ``serial``.
"""

import pathlib
import signal
import subprocess
import sys
import time

import h5py
import numpy as np
import pytest

from petroll.io.results import ResultsFile, Results
from petroll.solver.partition import RowPartition
from petroll.records import INTEGER_SERIES, SERIES, StepRecord

NAMES = list(SERIES)
NX, NY = 37, 23


def record(step: int) -> StepRecord:
    return StepRecord(**{k: step if k in INTEGER_SERIES else step + 0.25 for k in NAMES})


def field(step: int, nx: int = NX, ny: int = NY) -> np.ndarray:
    """A whole field whose every value names its step and cell (a wrong row or step cannot match)."""
    return step * 1e4 + np.arange(nx)[:, None] * ny + np.arange(ny)[None, :] + 0.5


def grow(path, comm, steps: int, every: int, records=None, out=None) -> tuple[ResultsFile, list]:
    """Append steps (a field every ``every``) up to ``steps`` to ``out`` (default: a new file at path)."""
    x, y = np.linspace(-1, 1, NX), np.linspace(0, 2, NY)
    out = out or ResultsFile(path, "[grid]\n", x, y, comm)
    r0, r1 = RowPartition(NX, comm.size).range(comm.rank)
    records = records if records is not None else []
    for step in range(len(records), steps):
        records.append(record(step))
        saved = {"pressure": field(step)[r0:r1]} if step % every == 0 else None
        out.append(records, saved, describe=step % 4 == 0)
    return out, records


@pytest.mark.slow
@pytest.mark.ranks4
def test_appended_series_and_fields_read_back_and_earlier_chunks_are_never_rewritten(comm, shared_dir):
    path = shared_dir / "results.h5"
    out, records = grow(path, comm, 6, 2)
    offsets = None
    if comm.rank == 0:
        with h5py.File(path, "r") as f:
            d = f["fields/pressure"]
            offsets = [d.id.get_chunk_info(i).byte_offset for i in range(d.id.get_num_chunks())]
    grow(path, comm, 40, 2, records, out)
    r = Results.open(path)
    assert np.array_equal(r.series["step"], np.arange(40)) and np.array_equal(r.series["t"], np.arange(40) + 0.25)
    assert list(r.field_steps) == list(range(0, 40, 2)) and not r.complete
    assert all(np.array_equal(r.pressure[k], field(s)) for k, s in enumerate(r.field_steps))
    assert np.allclose(r.x, np.linspace(-1, 1, NX)) and r.pressure.shape == (20, NX, NY)
    if comm.rank == 0:
        with h5py.File(path, "r") as f:
            d = f["fields/pressure"]
            later = [d.id.get_chunk_info(i).byte_offset for i in range(len(offsets))]
            assert f.attrs["steps_written"] == 40 and f.attrs["fields_written"] == 20
            assert f["mesh/xy"].shape == ((NX + 1) * (NY + 1), 2)
            corners = f["mesh/xy"][()].reshape(NX + 1, NY + 1, 2)
        assert later == offsets  # appended after them, never moved or rewritten
        dx, dy = 2 / (NX - 1), 2 / (NY - 1)
        assert np.allclose(corners[:, 0, 0], -1 - dx / 2 + dx * np.arange(NX + 1), atol=1e-14)
        assert np.allclose(corners[0, :, 1], -dy / 2 + dy * np.arange(NY + 1), atol=1e-14)


def test_mesh_corners_written_in_blocks_are_every_cell_corner(comm, shared_dir, monkeypatch):
    """The mesh is written a block of corner rows at a time (5 rows here; ranks with fewer blocks than
    another still take part in each collective write): every corner is where the uniform grid puts it."""
    monkeypatch.setattr("petroll.io.hdf5.BLOCK_BYTES", 5 * (NY + 1) * 8)
    grow(shared_dir / "results.h5", comm, 1, 1)
    if comm.rank == 0:
        with h5py.File(shared_dir / "results.h5", "r") as f:
            corners = f["mesh/xy"][()].reshape(NX + 1, NY + 1, 2)
        dx, dy = 2 / (NX - 1), 2 / (NY - 1)
        i, j = np.meshgrid(np.arange(NX + 1), np.arange(NY + 1), indexing="ij")
        assert np.allclose(corners[..., 0], -1 - dx / 2 + dx * i, rtol=0, atol=1e-14)
        assert np.allclose(corners[..., 1], -dy / 2 + dy * j, rtol=0, atol=1e-14)


@pytest.mark.ranks4
def test_a_resumed_file_keeps_the_given_prefix_and_continues(comm, shared_dir):
    path = shared_dir / "results.h5"
    grow(path, comm, 15, 3)
    x, y = np.linspace(-1, 1, NX), np.linspace(0, 2, NY)
    elsewhere = ResultsFile(shared_dir / "copy" / "results.h5", "[grid]\n", x, y, comm)
    elsewhere.resume(path, 7, [0, 3, 6])
    r0, r1 = RowPartition(NX, comm.size).range(comm.rank)
    records = [record(s) for s in range(9)]
    elsewhere.append(records[:8], None)
    elsewhere.append(records, {"pressure": -field(8)[r0:r1]}, complete=True, describe=True)
    r = Results.open(shared_dir / "copy" / "results.h5")
    assert r.complete and np.array_equal(r.series["step"], np.arange(9))
    assert list(r.field_steps) == [0, 3, 6, 8]
    assert np.array_equal(r.pressure[3], -field(8)) and np.array_equal(r.pressure[2], field(6))
    assert len(Results.open(path).series["t"]) == 15  # the source is left as it was
    if comm.rank == 0:
        assert "step 8" in (shared_dir / "copy" / "results.xdmf").read_text()


CHILD = """
import sys
import numpy as np
from mpi4py import MPI
sys.path.insert(0, sys.argv[2])
from test_results import grow
grow(sys.argv[1], MPI.COMM_WORLD, 10**6, 1)
"""


@pytest.mark.slow
@pytest.mark.serial
def test_sigkill_at_random_moments_leaves_a_file_holding_exactly_the_steps_written(tmp_path):
    """A writer appending a field at every step is killed at random moments: the file opens, and holds
    exactly ``steps_written`` steps, each with its own values."""
    rng = np.random.default_rng(3)
    here = pathlib.Path(__file__).parent
    written = []
    for attempt in range(5):
        path = tmp_path / f"r{attempt}.h5"
        proc = subprocess.Popen([sys.executable, "-c", CHILD, str(path), str(here)])
        start = time.monotonic()
        while not path.exists():
            assert proc.poll() is None and time.monotonic() - start < 60
            time.sleep(0.005)
        time.sleep(rng.uniform(0.05, 0.6))
        proc.kill()
        assert proc.wait() == -signal.SIGKILL
        r = Results.open(path)
        n = len(r.series["step"])
        assert np.array_equal(r.series["step"], np.arange(n)) and np.array_equal(r.field_steps, np.arange(n))
        assert all(np.array_equal(r.pressure[k], field(k)) for k in range(n))
        written.append(n)
    print("steps in the file after each kill:", written)
    assert max(written) > 3

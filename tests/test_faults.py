"""Faults (issue 28): a write that fails anywhere leaves results.h5 as it was and every rank learns it; a
full disk stops a run with one line, and a restart then continues it bitwise; one run per output
directory; a restart checks that its checkpoint and results belong together; stale temporary files are
cleaned.

Failures on demand: ``petroll.io.journal.write_all`` (every disk write of a results or checkpoint file
goes through it, on rank 0) is replaced by one that fails the way a full disk does (:class:`Full`: a
write that needs new space fails with ENOSPC) or at one chosen call (``Broken``: EIO). The real thing, a
small tmpfs filled up, is in the serial tests. Unmarked tests are collective; ``serial`` ones start
processes.
"""

import errno
import hashlib
import os
import pathlib
import shutil
import signal
import subprocess
import sys

import h5py
import numpy as np
import pytest
from mpi4py import MPI

from petroll.cli import main
from petroll.driver import run
from petroll.io import journal
from petroll.io.checkpoint import list_checkpoints, read_checkpoint, restart_scene
from petroll.io.results import OutputError, Results, ResultsFile
from petroll.io.rundir import LOCK_NAME, RunLock
from petroll.solver.partition import RowPartition
from test_checkpoint import LENGTH, PRONY, SLS, assert_identical, make_scene, raw_scene, snapshot, write_toml
from test_results import NX, NY, field, record

real_write_all = journal.write_all


class Full:
    """write_all as on a full disk from the moment it is armed: a write that would make a file longer
    fails with ENOSPC (rewriting bytes a file already has still works)."""

    def __init__(self):
        self.armed = False

    def __call__(self, fd, data, at):
        if self.armed and at + len(memoryview(data).cast("B")) > os.fstat(fd).st_size:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        real_write_all(fd, data, at)


class Broken:
    """write_all failing with EIO at its ``fail``-th call (0-based) counted from now; ``calls`` counts."""

    def __init__(self, fail: int | None = None):
        self.fail, self.calls = fail, 0

    def __call__(self, fd, data, at):
        self.calls += 1
        if self.calls - 1 == self.fail:
            raise OSError(errno.EIO, os.strerror(errno.EIO))
        real_write_all(fd, data, at)


def digest(path: pathlib.Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def on_rank0(comm, value):
    return comm.bcast(value if comm.rank == 0 else None, root=0)


# -- results.h5 -------------------------------------------------------------------------------------------
@pytest.mark.ranks4
def test_a_write_failing_anywhere_in_an_append_leaves_results_h5_byte_for_byte_as_it_was(comm, shared_dir,
                                                                                          monkeypatch):
    """Every disk write of an append (new chunks, the journal, the rewritten pages) is failed in turn, then
    the disk is made full: each time every rank raises OutputError naming the file and the cause, and the
    file is the same bytes as before (read through petroll or plain h5py); then the append goes through."""
    path = shared_dir / "results.h5"
    x, y = np.linspace(-1, 1, NX), np.linspace(0, 2, NY)
    out = ResultsFile(path, "[grid]\n", x, y, comm)
    r0, r1 = RowPartition(NX, comm.size).range(comm.rank)
    records = []
    for step in range(6):
        records.append(record(step))
        out.append(records, {"pressure": field(step)[r0:r1]} if step % 2 == 0 else None)
    records.append(record(6))
    before = on_rank0(comm, digest(path) if comm.rank == 0 else None)

    def attempt(hook):
        if comm.rank == 0:
            monkeypatch.setattr(journal, "write_all", hook)
        try:
            out.append(records, {"pressure": field(6)[r0:r1]}, describe=True)
            return None
        except OutputError as exc:
            return str(exc)
        finally:
            monkeypatch.undo()

    counter = Broken()
    copy = shared_dir / "copy.h5"
    if comm.rank == 0:
        shutil.copy(path, copy)
    probe = ResultsFile(copy, "[grid]\n", x, y, comm)
    probe.steps, probe.field_steps, probe.started = 6, [0, 2, 4], True
    if comm.rank == 0:
        monkeypatch.setattr(journal, "write_all", counter)
    probe.append(records, {"pressure": field(6)[r0:r1]})
    monkeypatch.undo()
    calls = on_rank0(comm, counter.calls)
    assert calls >= 5  # new chunks, the journal, pages
    for hook in [Broken(k) for k in range(calls)] + [Full()]:
        if isinstance(hook, Full):
            hook.armed = True
        message = attempt(hook)
        assert message is not None and message.startswith(f"{path}: cannot write the results (")
        assert ("No space left on device" if isinstance(hook, Full) else "Input/output error") in message
        if comm.rank == 0:
            assert digest(path) == before, hook.fail
            assert not (shared_dir / ".results.h5.journal").stat().st_size
            with h5py.File(path, "r") as f:
                assert f.attrs["steps_written"] == 6 and f.attrs["fields_written"] == 3
        assert out.steps == 6 and out.field_steps == [0, 2, 4]  # nothing counted
    assert attempt(lambda fd, data, at: real_write_all(fd, data, at)) is None
    r = Results.open(path)
    assert np.array_equal(r.series["step"], np.arange(7)) and list(r.field_steps) == [0, 2, 4, 6]
    assert all(np.array_equal(r.pressure[k], field(s)) for k, s in enumerate(r.field_steps))


def test_a_commit_cut_short_is_read_as_before_and_rolled_back_by_the_next_writer(tmp_path, monkeypatch):
    """A process that dies while it writes an append's pages (after its journal is in place) leaves a file
    that petroll reads as it was before that append; the next append (or journal.recover) puts the old
    bytes back, and plain h5py reads the file again."""
    path = tmp_path / "results.h5"
    x, y = np.linspace(-1, 1, NX), np.linspace(0, 2, NY)
    out = ResultsFile(path, "[grid]\n", x, y, MPI.COMM_SELF)
    records = [record(0), record(1)]
    out.append(records[:1], {"pressure": field(0)})
    before = digest(path)

    class Died(BaseException):
        pass

    pages = Broken()

    def die_in_the_pages(fd, data, at):  # the journal is written by write_all too: count from the pages
        if pathlib.Path(os.readlink(f"/proc/self/fd/{fd}")).name == "results.h5" and at < os.fstat(fd).st_size:
            pages.calls += 1
            if pages.calls == 3:
                raise Died()
        real_write_all(fd, data, at)

    monkeypatch.setattr(journal, "write_all", die_in_the_pages)
    with pytest.raises(Died):
        out.append(records, {"pressure": field(1)})
    monkeypatch.undo()
    assert digest(path) != before and (tmp_path / ".results.h5.journal").stat().st_size  # torn
    r = Results.open(path)
    assert list(r.series["step"]) == [0] and np.array_equal(r.pressure[0], field(0))
    assert journal.recover(path) and digest(path) == before
    with h5py.File(path, "r") as f:
        assert f.attrs["steps_written"] == 1
    out.append(records, {"pressure": field(1)})
    assert list(Results.open(path).field_steps) == [0, 1]


# -- a full disk during a run -----------------------------------------------------------------------------
THREE = ["pressure", "displacement", "gap"]


def field_rows(path: pathlib.Path, name: str) -> np.ndarray:
    r = Results.open(path)
    return r.field(name)


def test_a_full_disk_stops_the_run_in_one_line_and_the_restart_continues_it_bitwise(comm, shared_dir,
                                                                                    monkeypatch, capsys):
    """The disk fills at step 6 (every step saves three fields; a checkpoint every 4 steps): exit status 2
    and one line naming results.h5, the cause, what it holds and how to continue; results.h5 counts only
    whole steps (steps 0-5, each equal to the uninterrupted run's); the checkpoint of step 4 is intact;
    once space is back, the restart ends bitwise as the uninterrupted run."""
    raw = raw_scene(PRONY, output={"every": 1, "checkpoint_every": 4, "keep": 2, "fields": THREE})
    reference = run(make_scene(raw), comm, shared_dir / "reference")
    if comm.rank == 0:
        write_toml(shared_dir / "s.toml", raw)
    comm.Barrier()
    full, appends = Full(), []
    real_append = ResultsFile.append

    def append(self, *args, **kwargs):
        appends.append(True)
        full.armed = len(appends) == 7  # step 6
        return real_append(self, *args, **kwargs)

    monkeypatch.setattr(ResultsFile, "append", append)
    if comm.rank == 0:
        monkeypatch.setattr(journal, "write_all", full)
    capsys.readouterr()
    out = shared_dir / "full"
    assert main(["run", str(shared_dir / "s.toml"), "--out", str(out), "--quiet"]) == 2
    monkeypatch.undo()
    if comm.rank == 0:
        assert capsys.readouterr().err.splitlines() == [
            f"petroll: error: {out}/results.h5: cannot write the results (No space left on device); it holds "
            f"steps 0 to 5 as before; free space (or fix the cause) and continue with: petroll restart "
            f"{out}/checkpoints/step-00000004.h5"]
    partial = Results.open(out / "results.h5")
    assert len(partial.series["t"]) == 6 and list(partial.field_steps) == list(range(6)) and not partial.complete
    for name in reference.series:
        if name != "solve_time":
            assert np.array_equal(partial.series[name], reference.series[name][:6], equal_nan=True), name
    for name in THREE:
        assert np.array_equal(partial.field(name), reference.field(name)[:6]), name
    assert [p.name for p in list_checkpoints(out / "checkpoints")] == ["step-00000004.h5"]
    assert main(["restart", str(out), "--quiet"]) == 0
    restarted = Results.open(out / "results.h5")
    assert_identical(restarted, reference)
    for name in THREE:
        assert np.array_equal(restarted.field(name), reference.field(name)), name


def mount_tmpfs(where: pathlib.Path, size: int) -> None:
    where.mkdir()
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(where)],
                          capture_output=True, text=True)
    if done.returncode:
        pytest.skip(f"cannot mount a tmpfs here (needs root): {done.stderr.strip()}")


@pytest.mark.serial
def test_a_really_full_file_system_serially_and_under_mpirun(tmp_path, cli):
    """A tmpfs too small for the run's files: the command exits 2 with one line from petroll (no hang:
    timeout), results.h5 holds whole steps equal to the uninterrupted run's and the newest checkpoint is
    readable; once space is freed, ``petroll restart`` ends the run bitwise as the uninterrupted one (on
    the same rank count: serially, then under mpirun -n 2)."""
    raw = raw_scene(SLS, output={"every": 1, "checkpoint_every": 3, "keep": 2, "fields": THREE})
    write_toml(tmp_path / "s.toml", raw)
    serial = run(make_scene(raw), MPI.COMM_SELF, tmp_path / "reference")
    used = sum(p.stat().st_size for p in (tmp_path / "reference").rglob("*") if p.is_file())
    disk = tmp_path / "disk"
    mount_tmpfs(disk, 2 * used)
    try:
        for ranks in (0, 2):
            reference = serial
            if ranks:
                done = cli("run", "s.toml", "--out", "reference2", "--quiet", cwd=tmp_path, ranks=ranks)
                assert done.returncode == 0, done.stderr
                reference = Results.open(tmp_path / "reference2" / "results.h5")
            (disk / "filler").write_bytes(bytes(2 * used - 3 * used // 4))  # fills after a checkpoint or two
            out = f"disk/run{ranks}"
            done = cli("run", "s.toml", "--out", out, "--quiet", cwd=tmp_path, ranks=ranks, timeout=180)
            lines = [line for line in done.stderr.splitlines() if line.startswith("petroll")]
            assert done.returncode == 2 and len(lines) == 1, done.stderr
            assert "No space left on device" in lines[0] and lines[0].startswith(f"petroll: error: {out}/")
            partial = Results.open(tmp_path / out / "results.h5")
            n = len(partial.series["t"])
            assert 0 < n < len(reference.series["t"]) and list(partial.field_steps) == list(range(n))
            assert np.array_equal(partial.series["force"], reference.series["force"][:n])
            for name in THREE:
                assert np.array_equal(partial.field(name), reference.field(name)[:n]), name
            found = list_checkpoints(tmp_path / out / "checkpoints")
            assert found and read_checkpoint(found[-1], MPI.COMM_SELF).step <= n - 1
            (disk / "filler").unlink()
            done = cli("restart", out, "--quiet", cwd=tmp_path, ranks=ranks, timeout=180)
            assert done.returncode == 0, done.stderr
            assert_identical(Results.open(tmp_path / out / "results.h5"), reference)
            print(f"{'mpirun -n 2' if ranks else 'serial'}: the disk filled after {n} steps; {lines[0]}")
            shutil.rmtree(tmp_path / out)
    finally:
        subprocess.run(["umount", "-l", str(disk)], capture_output=True)

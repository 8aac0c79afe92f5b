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
import time
import warnings

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
from petroll.model.limits import PetrollWarning
from petroll.solver.partition import RowPartition
from test_checkpoint import (LENGTH, PRONY, SLS, assert_identical, make_scene, raw_scene, snapshot, unseal,
                             write_toml)
from test_results import NX, NY, field, record

ROOT = pathlib.Path(__file__).resolve().parents[1]
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


def said(stderr: str) -> list[str]:
    """The lines of ``stderr`` but the resolution warnings (these tests' grids are coarse on purpose)."""
    return [line for line in stderr.splitlines() if not line.startswith("petroll: warning:")]


def on_rank0(comm, value):
    return comm.bcast(value if comm.rank == 0 else None, root=0)


# -- results.h5 -------------------------------------------------------------------------------------------
@pytest.mark.slow
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


@pytest.mark.slow
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
        assert said(capsys.readouterr().err) == [
            f"petroll: error: {out}/results.h5: cannot write the results (No space left on device); results.h5 "
            f"holds steps 0 to 5; free space (or fix the cause) and continue with: petroll restart "
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


@pytest.mark.slow
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
            lines = [line for line in said(done.stderr) if line.startswith("petroll")]
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


# -- one run per output directory -------------------------------------------------------------------------
def test_a_directory_in_use_is_refused_naming_its_holder_and_a_stale_lock_is_taken_over(comm, shared_dir,
                                                                                       capsys):
    raw = raw_scene()
    out = shared_dir / "run"
    lock = None
    if comm.rank == 0:
        out.mkdir()
        lock = RunLock(out, "petroll run other.toml")
        lock.acquire()
        write_toml(shared_dir / "s.toml", raw)
    comm.Barrier()
    before = snapshot(shared_dir)
    with pytest.raises(OutputError) as info:
        run(make_scene(raw), comm, out)
    pid, host = on_rank0(comm, (os.getpid(), os.uname().nodename))
    assert str(info.value).startswith(f"{out}: in use by PID {pid} on host {host}, since ")
    assert str(info.value).endswith("(petroll run other.toml); wait for it to finish, or choose another output "
                                    "directory")
    capsys.readouterr()
    assert main(["run", str(shared_dir / "s.toml"), "--out", str(out), "--quiet"]) == 2
    if comm.rank == 0:
        assert said(capsys.readouterr().err) == [f"petroll: error: {info.value}"]
    assert snapshot(shared_dir) == before
    if comm.rank == 0:  # the holder dies without removing its lock file: the next run takes it over
        os.close(lock.fd)
    comm.Barrier()
    assert (out / LOCK_NAME).exists()
    results = run(make_scene(raw), comm, out)
    comm.Barrier()  # rank 0 holds the lock and releases it on its way out of run
    assert results.complete and not (out / LOCK_NAME).exists()


@pytest.mark.slow
def test_on_every_rank_run_returns_or_refuses_only_once_the_directory_is_free(comm, shared_dir, monkeypatch):
    """Rank 0 releases the lock slowly: no rank returns from a run, or from its refusal of another scene's
    results, while petroll.lock is still there (a script's next step on that directory sees it free)."""
    release = RunLock.release

    def slow(self):
        time.sleep(0.5)
        release(self)

    monkeypatch.setattr(RunLock, "release", slow)
    out = shared_dir / "run"
    run(make_scene(raw_scene(SLS)), comm, out)
    free_after_run = not (out / LOCK_NAME).exists()
    with pytest.raises(OutputError, match="another scene"):
        run(make_scene(raw_scene(PRONY)), comm, out)
    assert free_after_run and not (out / LOCK_NAME).exists()


@pytest.mark.slow
@pytest.mark.serial
def test_a_second_run_or_restart_on_a_directory_in_use_is_refused_and_the_first_is_untouched(tmp_path, cli,
                                                                                              tmp_path_factory):
    from test_checkpoint import long_scene, wait_for

    reference = long_scene(tmp_path, tmp_path_factory)
    first = cli.start("run", "long.toml", "--out", "shared", "--quiet", cwd=tmp_path, stdout=subprocess.PIPE,
                      stderr=subprocess.PIPE, text=True)
    wait_for(tmp_path / "shared" / "checkpoints" / "step-00000005.h5", first, limit=600)
    first.send_signal(signal.SIGSTOP)  # held while the others try (a stopped process keeps its lock)
    try:
        second = cli("run", "long.toml", "--out", "shared", "--quiet", cwd=tmp_path)
        again = cli("restart", "shared", "--quiet", cwd=tmp_path)
    finally:
        first.send_signal(signal.SIGCONT)
    assert first.wait(timeout=120) == 0, first.communicate()
    for refused in (second, again):
        assert refused.returncode == 2 and len(said(refused.stderr)) == 1, refused.stderr
        assert said(refused.stderr)[0].startswith("petroll: error: ")  # the restart names the directory in full
        assert f"shared: in use by PID {first.pid} on host " in refused.stderr
    assert "(petroll run long.toml)" in second.stderr
    assert_identical(Results.open(tmp_path / "shared" / "results.h5"), reference)


@pytest.mark.slow
def test_the_results_of_another_scene_are_replaced_only_when_told(comm, shared_dir, capsys):
    """A second scene into a directory holding another scene's results: refused in one line, nothing
    changed; with --overwrite it runs and the earlier run's checkpoints go. The same scene again runs."""
    first, other = raw_scene(SLS), raw_scene(PRONY)
    if comm.rank == 0:
        write_toml(shared_dir / "first.toml", first)
        write_toml(shared_dir / "other.toml", other)
    comm.Barrier()
    out = shared_dir / "run"
    capsys.readouterr()
    assert main(["run", str(shared_dir / "first.toml"), "--out", str(out), "--quiet"]) == 0
    before = snapshot(out)
    assert main(["run", str(shared_dir / "other.toml"), "--out", str(out), "--quiet"]) == 2
    if comm.rank == 0:
        assert said(capsys.readouterr().err) == [
            f"petroll: error: {out}: holds the complete results of another scene ({out}/results.h5); give "
            "--overwrite (Python: overwrite=True) to replace them, or another output directory"]
    assert snapshot(out) == before
    assert main(["run", str(shared_dir / "first.toml"), "--out", str(out), "--quiet"]) == 0  # the same: runs
    assert main(["run", str(shared_dir / "other.toml"), "--out", str(out), "--quiet", "--overwrite"]) == 0
    reference = run(make_scene(other), comm, shared_dir / "reference")
    assert_identical(Results.open(out / "results.h5"), reference)
    mine = [p.name for p in list_checkpoints(shared_dir / "reference" / "checkpoints")]
    assert [p.name for p in list_checkpoints(out / "checkpoints")] == mine
    for path in list_checkpoints(out / "checkpoints"):
        assert read_checkpoint(path, comm).run_id == Results.open(out / "results.h5").run_id


@pytest.mark.slow
def test_the_same_scene_text_over_a_changed_height_map_is_another_scene(comm, shared_dir, capsys):
    """The scene names a height map file; the file is edited (the sphere's radius 10 -> 12 mm) and the same
    scene text run again into the same directory: refused in one line, the earlier results untouched
    (their attribute fingerprint is the one of the material and body they were computed with); with
    --overwrite it runs and gives what a fresh run on the edited map gives."""
    def sphere_map(radius: float) -> np.ndarray:
        x = np.arange(-60, 61) * 2e-5  # m: 2.4 mm square, beyond the body's reach over the run
        return (x[:, None] ** 2 + x[None, :] ** 2) / (2 * radius)

    raw = {**raw_scene(SLS), "body": {"shape": "heightmap", "file": "map.npy", "cell": 2e-5}}
    out = shared_dir / "run"
    if comm.rank == 0:
        np.save(shared_dir / "map.npy", sphere_map(0.010))
        write_toml(shared_dir / "s.toml", raw)
    comm.Barrier()
    capsys.readouterr()
    assert main(["run", str(shared_dir / "s.toml"), "--out", str(out), "--quiet"]) == 0
    first = Results.open(out / "results.h5")
    comm.Barrier()  # every rank has read it before rank 0 edits the map
    if comm.rank == 0:
        np.save(shared_dir / "map.npy", sphere_map(0.012))
    comm.Barrier()
    before = snapshot(out)
    assert main(["run", str(shared_dir / "s.toml"), "--out", str(out), "--quiet"]) == 2
    if comm.rank == 0:
        assert said(capsys.readouterr().err) == [
            f"petroll: error: {out}: holds the complete results of this scene with another material or body "
            f"({out}/results.h5): a file it names ([material] file or [body] file) has changed since; give "
            "--overwrite (Python: overwrite=True) to replace them, or another output directory"]
    assert snapshot(out) == before
    assert main(["run", str(shared_dir / "s.toml"), "--out", str(out), "--quiet", "--overwrite"]) == 0
    fresh = run(make_scene(raw, base_dir=shared_dir), comm, shared_dir / "fresh")
    assert_identical(Results.open(out / "results.h5"), fresh)
    # the edited map was used: the force at the same penetration grows like sqrt(R) (Hertz; measured 1.089)
    assert fresh.series["force"][-1] / first.series["force"][-1] == pytest.approx(1.2**0.5, rel=0.02)
    assert main(["run", str(shared_dir / "s.toml"), "--out", str(out), "--quiet"]) == 0  # the same: runs


# -- restart identity -------------------------------------------------------------------------------------
def forget_run_ids(path: pathlib.Path) -> None:
    """As written before run ids (the other checks must hold by themselves)."""
    with h5py.File(path, "r+") as f:
        del f.attrs["run_id"]
    unseal(path)


@pytest.mark.slow
@pytest.mark.parametrize("change, expected", [
    ({"grid": {"nx": 28}}, "[grid] nx = 25, the file's 28"),
    ({"material": {"E0": 12e6}}, "[material] E0 = 10000000.0, the file's 12000000.0"),
])
@pytest.mark.parametrize("run_ids", [True, False])
def test_a_restart_refuses_the_results_of_another_run_and_touches_nothing(change, expected, run_ids, comm,
                                                                         shared_dir, capsys):
    """results.h5 of a run on another grid (or of another material) in place of the checkpoint's run's:
    refused in one line naming both, nothing written; by run id, or, for files without run ids, by the
    scene and the steps."""
    raw = raw_scene(SLS)
    other = raw_scene(SLS)
    for section, values in change.items():
        other[section] = {**other[section], **values}
    run(make_scene(raw), comm, shared_dir / "mine")
    run(make_scene(other), comm, shared_dir / "theirs")
    if comm.rank == 0:
        shutil.copy(shared_dir / "theirs" / "results.h5", shared_dir / "mine" / "results.h5")
        if not run_ids:
            forget_run_ids(shared_dir / "mine" / "results.h5")
            for path in list_checkpoints(shared_dir / "mine" / "checkpoints"):
                strip_run_id(path)
    comm.Barrier()
    before = snapshot(shared_dir)
    capsys.readouterr()
    path = shared_dir / "mine" / "checkpoints" / "step-00000008.h5"
    assert main(["restart", str(path), "--quiet"]) == 2
    if comm.rank == 0:
        lines = said(capsys.readouterr().err)
        assert len(lines) == 1 and lines[0].startswith(f"petroll: error: {path}: belongs to another "), lines
        assert ("run than" if run_ids else expected) in lines[0], lines
    assert snapshot(shared_dir) == before


def strip_run_id(path: pathlib.Path) -> None:
    """A checkpoint as written before run ids: the attribute removed, the file's digest made again."""
    from petroll.io.checkpoint import _plain, root_digest

    with h5py.File(path, "r+") as f:
        del f.attrs["run_id"]
        attrs = {k: _plain(v) for k, v in f.attrs.items()}
        digests = {}
        f.visititems(lambda name, item: digests.__setitem__(name, _plain(item.attrs["sha256"]))
                     if isinstance(item, h5py.Dataset) else None)
        f.attrs["sha256"] = root_digest(attrs, digests)
    unseal(path)


@pytest.mark.slow
def test_a_foreign_checkpoint_among_a_runs_checkpoints_is_refused_and_the_run_restarts_from_its_own(
        comm, shared_dir, capsys):
    run(make_scene(raw_scene(SLS)), comm, shared_dir / "reference")
    stop_at = 8
    from test_checkpoint import interrupter
    from petroll.io.checkpoint import RunInterrupted

    stop, on_step = interrupter(stop_at, comm)
    with pytest.raises(RunInterrupted):
        run(make_scene(raw_scene(SLS)), comm, shared_dir / "mine", stop=stop, on_step=on_step)
    run(make_scene(raw_scene(SLS, distance=2 * LENGTH)), comm, shared_dir / "theirs")
    if comm.rank == 0:
        shutil.copy(shared_dir / "theirs" / "checkpoints" / "step-00000012.h5", shared_dir / "mine" / "checkpoints")
    comm.Barrier()
    before = snapshot(shared_dir / "mine")
    capsys.readouterr()
    assert main(["restart", str(shared_dir / "mine"), "--quiet"]) == 2
    foreign = shared_dir / "mine" / "checkpoints" / "step-00000012.h5"
    if comm.rank == 0:
        lines = said(capsys.readouterr().err)
        assert len(lines) == 1 and lines[0].startswith(f"petroll: error: {foreign}: belongs to another run "), lines
    assert snapshot(shared_dir / "mine") == before
    assert main(["restart", str(shared_dir / "mine" / "checkpoints" / "step-00000008.h5"), "--quiet"]) == 0
    assert_identical(Results.open(shared_dir / "mine" / "results.h5"),
                     Results.open(shared_dir / "reference" / "results.h5"))
    assert not foreign.exists()  # no longer of any use: its results.h5 is not here


@pytest.mark.slow
def test_a_restart_into_another_runs_directory_is_refused_unless_told(comm, shared_dir, capsys):
    """`petroll restart B/checkpoints/step-N.h5 --out A` with A holding another run's complete results:
    refused, A untouched; with --overwrite A holds B's run, continued to its end, and A's old checkpoints
    are gone."""
    run(make_scene(raw_scene(SLS)), comm, shared_dir / "A")
    b = run(make_scene(raw_scene(PRONY)), comm, shared_dir / "B")
    before = snapshot(shared_dir / "A")
    source = shared_dir / "B" / "checkpoints" / "step-00000004.h5"
    capsys.readouterr()
    assert main(["restart", str(source), "--out", str(shared_dir / "A"), "--quiet"]) == 2
    if comm.rank == 0:
        assert said(capsys.readouterr().err) == [
            f"petroll: error: {shared_dir / 'A'}: holds the complete results of another run ({shared_dir / 'A'}"
            f"/results.h5), not of checkpoint {source}'s; give --overwrite (Python: overwrite=True) to replace "
            "them, or another --out"]
    assert snapshot(shared_dir / "A") == before
    assert main(["restart", str(source), "--out", str(shared_dir / "A"), "--quiet", "--overwrite"]) == 0
    assert_identical(Results.open(shared_dir / "A" / "results.h5"), b)
    run_id = read_checkpoint(source, comm).run_id
    assert all(read_checkpoint(p, comm).run_id == run_id for p in list_checkpoints(shared_dir / "A" / "checkpoints"))


@pytest.mark.slow
def test_stale_temporary_files_are_removed_at_start_and_restart(comm, shared_dir):
    from test_checkpoint import interrupter
    from petroll.io.checkpoint import RunInterrupted

    dead = on_rank0(comm, _dead_pid() if comm.rank == 0 else None)
    live = on_rank0(comm, os.getppid())  # alive, and not this process (whose own temporary names these are)
    stop, on_step = interrupter(5, comm)
    out = shared_dir / "run"
    if comm.rank == 0:
        (out / "checkpoints").mkdir(parents=True)
        for name in (f".results.h5.tmp{dead}", f"checkpoints/.step-00000004.h5.tmp{dead}",
                     f".results.h5.tmp{live}", "notes.txt"):
            (out / name).write_bytes(b"left")
    comm.Barrier()
    with pytest.raises(RunInterrupted):
        run(make_scene(raw_scene()), comm, out, stop=stop, on_step=on_step)
    left = sorted(str(p.relative_to(out)) for p in out.rglob("*") if p.name.startswith((".", "notes")))
    comm.Barrier()  # every rank has looked before rank 0 leaves another temporary file
    assert left == sorted([".results.h5.journal", f".results.h5.tmp{live}", "notes.txt"])
    if comm.rank == 0:
        (out / "checkpoints" / f".step-00000009.h5.tmp{dead}").write_bytes(b"left")
    comm.Barrier()
    run(make_scene(raw_scene()), comm, out, restart=read_checkpoint(out / "checkpoints" / "step-00000005.h5", comm))
    assert not (out / "checkpoints" / f".step-00000009.h5.tmp{dead}").exists()


def _dead_pid() -> int:
    """The PID of a process that has ended (and been reaped)."""
    child = subprocess.Popen(["true"])
    child.wait()
    return child.pid


# -- exit codes under mpirun ------------------------------------------------------------------------------
@pytest.mark.slow
@pytest.mark.serial
def test_sigterm_and_sigint_to_petroll_launch_mpirun_end_the_run_with_a_checkpoint_and_143_or_130(tmp_path,
                                                                                                  cli,
                                                                                                  tmp_path_factory):
    """``petroll launch mpirun -n 2 petroll run ...`` signalled as a batch system or Ctrl-C would: the ranks
    get the signal itself, write a checkpoint, name the signal, and the exit status is 128 + its number;
    the restart (on 2 ranks) finishes the run as the uninterrupted one (to round-off across rank counts)."""
    from test_checkpoint import assert_close, long_scene, wait_for

    reference = long_scene(tmp_path, tmp_path_factory)
    mpirun = ["mpirun", "-n", "2", *cli.argv]
    for signum, code in ((signal.SIGTERM, 143), (signal.SIGINT, 130)):
        out = f"out-{signum.name}"
        proc = subprocess.Popen([*cli.argv, "launch", *mpirun, "run", "long.toml", "--out", out, "--quiet"],
                                cwd=tmp_path, env=cli.env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        wait_for(tmp_path / out / "checkpoints" / "step-00000005.h5", proc, limit=600)
        proc.send_signal(signum)
        _, err = proc.communicate(timeout=300)
        assert proc.returncode == code, err
        lines = [line for line in said(err) if line.startswith("petroll")]
        assert len(lines) == 1 and f": interrupted by {signum.name} after step " in lines[0], err
        assert not Results.open(tmp_path / out / "results.h5").complete
    done = cli("restart", out, "--quiet", cwd=tmp_path, ranks=2, timeout=600)
    assert done.returncode == 0, done.stderr
    assert_close(Results.open(tmp_path / out / "results.h5"), reference, rtol=1e-8)


@pytest.mark.serial
def test_launch_passes_a_signal_to_a_command_without_ranks_and_exits_with_its_status(tmp_path, cli, cli_main):
    """``petroll launch`` of a command that is no MPI launch line (no child carries a rank): SIGTERM and
    SIGINT reach the command itself, which they end, and launch exits with 128 + the signal's number; no
    command at all is refused in one line, exit 2. The command sets both signals' default action, as
    petroll's ranks set their handlers (a job started in the background inherits SIGINT ignored)."""
    command = ("import pathlib, signal, sys, time; signal.signal(signal.SIGINT, signal.SIG_DFL); "
               "signal.signal(signal.SIGTERM, signal.SIG_DFL); pathlib.Path(sys.argv[1]).touch(); time.sleep(60)")
    for signum in (signal.SIGTERM, signal.SIGINT):
        started = tmp_path / f"started-{signum.name}"
        proc = cli.start("launch", sys.executable, "-c", command, started, cwd=tmp_path,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        limit = time.monotonic() + 60
        while not started.exists():
            assert proc.poll() is None and time.monotonic() < limit, proc.communicate()
            time.sleep(0.01)
        time.sleep(1.0)  # launch sets its handlers just after starting the command
        proc.send_signal(signum)
        _, err = proc.communicate(timeout=60)
        assert proc.returncode == 128 + signum, err
    code, _, err = cli_main(["launch"])
    assert code == 2 and err.count("\n") == 1 and err.startswith("petroll: error: petroll launch needs a command")


# -- kills at every kill point and at random instants ------------------------------------------------------
@pytest.mark.slow
@pytest.mark.serial
def test_runs_killed_at_every_kill_point_and_at_random_instants_leave_results_and_checkpoints_whole(tmp_path):
    """Runs (every step saving three fields and writing a checkpoint) SIGKILLed just before the first call
    of each of their kill points (each disk write, fsync, rename, truncation and removal, by file and by
    where the run was: tests/kills.py), then 40 more at instants drawn uniformly over a run, their disk
    writes of results.h5 slowed (0.5 ms each) so that many kills land inside appends and their commits:
    every results.h5 opens and holds, value for value, the uninterrupted run's steps up to its last
    complete append (after a commit cut short, plain h5py too once recovered), every checkpoint is whole,
    and restarts from the newest ones end as the uninterrupted run. The random instants' seed is
    ``PETROLL_KILL_SEED`` if set, else a new one, printed (``pytest -s``) and named in a failure
    (scripts/kill-storm.py runs longer storms)."""
    import secrets
    import tempfile

    from kills import storm, summary

    seed = int(os.environ.get("PETROLL_KILL_SEED") or secrets.randbits(32))
    fast = pathlib.Path("/dev/shm")  # memory: no fsync cost; a SIGKILL sees the same files as on a disk
    where = pathlib.Path(tempfile.mkdtemp(dir=fast if os.access(fast, os.W_OK) else tmp_path))
    try:
        trials = storm(where, 40, seed=seed, slow=0.0005, restarts=4, every_point=True)
    finally:
        shutil.rmtree(where, ignore_errors=True)
    counts = summary(trials)
    print(f"seed {seed} (PETROLL_KILL_SEED={seed}):", counts)
    assert counts["trials with a loss"] == 0, (seed, [(t.index, t.point, t.phase, t.lost) for t in trials if t.lost])
    points = [t for t in trials if t.point]
    assert len(points) == counts["kill points"] == len(trials) - 40  # each once
    assert {"write results.h5 append", "write .results.h5.journal commit", "fsync .results.h5.journal commit",
            "write results.h5 commit", "truncate .results.h5.journal commit", "replace step-N.h5 outside",
            "unlink step-N.h5 outside", "replace results.xdmf append"} <= {t.point for t in points}
    # a kill once the journal is whole and before it is emptied leaves a commit cut short (rolled back and
    # read by plain h5py in _inspect); one before the journal is whole leaves none
    torn = {t.point: t.torn for t in points}
    assert torn["write results.h5 commit"] and torn["truncate .results.h5.journal commit"], torn
    assert not torn["write .results.h5.journal commit"] and not torn["write results.h5 append"], torn
    assert counts["results.h5 left"] >= 20 and counts["restarted"] == 4, (seed, counts)


# -- bad numbers ------------------------------------------------------------------------------------------
def bad_scene(tmp: pathlib.Path, name: str) -> dict:
    """The scenes of issue 28 item 7 (and their kin) on the small scene of tests/test_bad_input.py."""
    import copy

    from test_bad_input import BASE

    raw = copy.deepcopy(BASE)
    moving = {"velocity": [0.01, 0.0], "penetration": 2e-5}
    x = np.linspace(-1e-3, 1e-3, 41)[:, None]
    sphere = (x**2 + x.T**2) / 0.02
    changes = {
        "tau tiny": lambda: raw["material"].update(tau_relax=1e-300),
        "tau huge": lambda: raw["material"].update(tau_relax=1e300),
        "dt tiny, distance": lambda: (raw["motion"].update(moving), raw.update(time={"dt": 1e-300, "distance": 1e-3})),
        "dt small, distance": lambda: (raw["motion"].update(moving), raw.update(time={"dt": 1e-10, "distance": 1e-3})),
        "steps_per_cell huge": lambda: (raw["motion"].update(moving),
                                        raw.update(time={"steps_per_cell": 1e300, "distance": 1e-3})),
        "at rest, distance": lambda: raw.update(time={"dt": 0.01, "distance": 1e-3}),
        "x huge": lambda: raw["grid"].update(x=[-1e300, 1e300]),
        "x far out": lambda: raw["grid"].update(x=[1e6, 1e6 + 2e-3]),
        "complex heightmap": lambda: (np.save(tmp / "c.npy", sphere + 1j * sphere),
                                      raw.update(body={"shape": "heightmap", "file": "c.npy", "cell": 5e-5})),
        "heights tiny": lambda: (np.save(tmp / "tiny.npy", sphere * 1e-300),
                                 raw.update(body={"shape": "heightmap", "file": "tiny.npy", "cell": 5e-5})),
        "heights huge": lambda: (np.save(tmp / "huge.npy", sphere * 1e300),
                                 raw.update(body={"shape": "heightmap", "file": "huge.npy", "cell": 5e-5})),
        "text as npy": lambda: ((tmp / "t.npy").write_text("0 1\n1 2\n"),
                                raw.update(body={"shape": "heightmap", "file": "t.npy", "cell": 5e-5})),
    }
    changes[name]()
    return raw


BAD_NUMBERS = {
    "tau tiny": ("[material] tau_relax", "1e-300 s is outside what petroll computes with: non-zero magnitudes "
                                         "from 1e-30 to 1e+30; rescale the units"),
    "tau huge": ("[material] tau_relax", "1e+300 s is outside what petroll computes with"),
    "dt tiny, distance": ("[time] dt", "1e-300 s is outside what petroll computes with"),
    "dt small, distance": ("[time] dt", "too many steps: distance / (peak speed x dt) = 1e+09 steps at least, "
                                        "more than [time] max_steps = 100000"),
    "steps_per_cell huge": ("[time] steps_per_cell", "too many steps: distance / cell x steps_per_cell = "
                                                     "2e+301 steps at least"),
    "at rest, distance": ("[time] distance", "a body at rest never rolls it"),
    "x huge": ("[grid] x", "-1e+300 m is outside what petroll computes with"),
    "x far out": ("[grid] x", "a cell must be at least 1e-09 of the largest coordinate"),
    "complex heightmap": ("[body] file", "holds complex numbers (complex128)"),
    "heights tiny": ("[body] file", "relief (highest - lowest height) 1e-304 m is outside what petroll computes "
                                    "with"),  # was: numpy's overflow warning, then another refusal
    "heights huge": ("[body] file", "height 1e+296 m is outside what petroll computes with"),
    "text as npy": ("[body] file", "is not a .npy file (those begin with the bytes \\x93NUMPY"),
}


@pytest.mark.parametrize("name", BAD_NUMBERS)
def test_numbers_beyond_double_precision_or_the_step_limit_are_refused_up_front(name, tmp_path, cli_main, comm):
    from petroll.errors import SceneError
    from petroll.model.scene import dumps

    key, expected = BAD_NUMBERS[name]
    raw = bad_scene(tmp_path, name)
    with warnings.catch_warnings(), pytest.raises(SceneError) as info:
        warnings.simplefilter("error")  # nothing (numpy's warnings included) said on the way to the refusal
        parse_scene_here(raw, tmp_path)
    assert info.value.key == key and expected in str(info.value), str(info.value)
    (tmp_path / "bad.toml").write_text(dumps(raw))
    code, out, err = cli_main(["run", str(tmp_path / "bad.toml"), "--out", str(tmp_path / "out"), "--quiet"])
    said_here = [f"petroll: error: {info.value}".replace("test", str(tmp_path / "bad.toml"), 1)]
    assert code == 2 and said(err) == (said_here if comm.rank == 0 else []), err  # rank 0 speaks
    assert not (tmp_path / "out").exists()


def parse_scene_here(raw: dict, base: pathlib.Path):
    from petroll.model.scene import parse_scene

    return parse_scene(raw, source="test", base_dir=base)


@pytest.mark.parametrize("tau", [1e-30, 1e30])
def test_time_constants_at_the_ends_of_the_range_run_without_a_warning_to_their_limits(tau, comm, shared_dir):
    """tau_relax at 1e-30 and 1e30 s against steps of 0.01 s: no warning of any kind (numpy's included),
    and the force at the held penetration is the limit's: relaxed at once (Einf: step 0's instantaneous
    E0 force / 5, E0/Einf = 5, the force scaling with the modulus) or never (E0: step 0's), to 1e-6."""
    import copy

    from petroll.model.scene import parse_scene
    from test_bad_input import BASE

    raw = copy.deepcopy(BASE)
    raw["material"]["tau_relax"] = tau
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        force = run(parse_scene(raw), comm, shared_dir / "run").series["force"]
    limit = force[0] / 5 if tau < 1 else force[0]
    assert len(force) == 4 and np.all(np.abs(force[1:] - limit) <= 1e-6 * limit), (force, limit)


# -- messages ---------------------------------------------------------------------------------------------
def test_a_results_xdmf_that_cannot_be_written_is_named(comm, shared_dir):
    out = shared_dir / "run"
    if comm.rank == 0:
        (out / "results.xdmf").mkdir(parents=True)
    comm.Barrier()
    with pytest.raises(OutputError) as info:
        run(make_scene(raw_scene()), comm, out)
    assert str(info.value).startswith(f"{out}/results.xdmf: cannot write the results (Is a directory)")


# -- issue 35: petroll stress on a full disk ----------------------------------------------------------------
@pytest.mark.slow
def test_stress_on_a_full_disk_is_one_line_and_keeps_the_earlier_stress_file(comm, shared_dir, capsys,
                                                                             monkeypatch):
    """stress.h5 written through a journal Session: a disk write refused with ENOSPC (Full, from the first
    write of the new file) never reaches HDF5, which on a real full disk raised 'Disable slist on flush
    dest failure' and then crashed (SIGSEGV). One line, exit 2, on every rank; the earlier stress.h5 and
    results.h5 byte for byte; no temporary file."""
    run(make_scene(raw_scene()), comm, shared_dir / "run")
    assert main(["stress", str(shared_dir / "run"), "--depth", "0,1e-4"]) == 0
    kept = on_rank0(comm, {name: digest(shared_dir / "run" / name) for name in ("stress.h5", "results.h5")}
                    if comm.rank == 0 else None)
    full = Full()
    monkeypatch.setattr(journal, "write_all", full)
    full.armed = True
    capsys.readouterr()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert main(["stress", str(shared_dir / "run"), "--depth", "0,1e-4,2e-4"]) == 2
    if comm.rank == 0:
        path = shared_dir / "run" / "stress.h5"
        assert said(capsys.readouterr().err) == [f"petroll: error: {path}: cannot write the stresses (No space "
                                                 "left on device)"]
        assert {name: digest(shared_dir / "run" / name) for name in kept} == kept
        assert not list((shared_dir / "run").glob(".*.tmp*"))


@pytest.mark.slow
@pytest.mark.serial
def test_stress_on_a_really_full_file_system(tmp_path, cli):
    """The issue's trial (5 of 5 crashed: 'Disable slist on flush dest failure', then SIGSEGV): a tmpfs
    left with 4 kB to 700 kB free, the real command: one line, exit 2, results.h5 untouched, nothing left."""
    raw = raw_scene(SLS)
    write_toml(tmp_path / "s.toml", raw)
    done = cli("run", "s.toml", "--out", "reference", "--quiet", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    disk = tmp_path / "disk"
    mount_tmpfs(disk, 4 * 2**20)
    try:
        shutil.copytree(tmp_path / "reference", disk / "run")
        before = digest(disk / "run" / "results.h5")
        names = sorted(p.name for p in (disk / "run").iterdir())
        for free in (4_000, 40_000, 200_000, 400_000, 700_000):
            stat = os.statvfs(disk)
            (disk / "filler").write_bytes(bytes(max(0, stat.f_bavail * stat.f_frsize - free)))
            done = cli("stress", disk / "run", cwd=tmp_path, timeout=120)
            lines = said(done.stderr)
            assert done.returncode == 2 and lines == [f"petroll: error: {disk / 'run' / 'stress.h5'}: cannot write "
                                                      "the stresses (No space left on device)"], done.stderr
            assert digest(disk / "run" / "results.h5") == before
            assert sorted(p.name for p in (disk / "run").iterdir()) == names  # no stress.h5, no temporary
            (disk / "filler").unlink()
    finally:
        subprocess.run(["umount", "-l", str(disk)], capture_output=True)


@pytest.mark.slow
@pytest.mark.serial
def test_the_temporaries_of_killed_stress_plot_sweep_and_fit_writers_are_removed(tmp_path, cli_main, monkeypatch):
    """``.stress.h5.tmpPID``, ``.NAME.png.tmpPID`` and the like that a kill left were never removed (issue
    35): each command removes those of the files it writes whose process is gone; a live process's, and
    other programs' files, stay."""
    monkeypatch.chdir(tmp_path)
    dead, live = _dead_pid(), os.getppid()
    write_toml(tmp_path / "s.toml", raw_scene(SLS))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert cli_main(["run", "s.toml", "--out", "run", "--quiet"])[0] == 0
    left = {"run/.stress.h5.tmp{}": "stress", "run/.stress.png.tmp{}": "stress",
            "run/plots/.pressure.png.tmp{}": "plot", "fit/.rubber.toml.tmp{}": "fit", "fit/.rubber.png.tmp{}": "fit",
            "sweep/.sweep.csv.tmp{}": "sweep", "sweep/.sweep.h5.tmp{}": "sweep", "sweep/.sweep.png.tmp{}": "sweep"}
    for name in left:
        for pid in (dead, live):
            (tmp_path / name.format(pid)).parent.mkdir(parents=True, exist_ok=True)
            (tmp_path / name.format(pid)).write_bytes(b"cut short")
    (tmp_path / "fit" / f".notes.txt.tmp{dead}").write_bytes(b"another program's")
    write_toml(tmp_path / "static.toml", {"grid": {"nx": 16, "ny": 16, "x": [-0.8e-3, 0.8e-3], "y": [-0.8e-3, 0.8e-3],
                                                   "allow_coarse": True},
                                          "material": dict(SLS), "body": {"shape": "sphere", "radius": 0.01},
                                          "motion": {"penetration": 2e-5}})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PetrollWarning)
        for argv in (["stress", "run"], ["plot", "run"],
                     ["material", "fit", ROOT / "runs" / "rubber-dma.csv", "--shift", "wlf:8.86,101.6,293.15", "--out",
                      "fit/rubber.toml"],
                     ["sweep", "static.toml", "--vary", "motion.penetration=1e-5,2e-5", "--out", "sweep", "--quiet"]):
            assert cli_main([str(a) for a in argv])[0] == 0, argv
    for name in left:
        assert not (tmp_path / name.format(dead)).exists(), name
        assert (tmp_path / name.format(live)).read_bytes() == b"cut short", name
    assert (tmp_path / "fit" / f".notes.txt.tmp{dead}").exists()

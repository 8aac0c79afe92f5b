"""Checkpoints and restart (docs/checkpoints.md): interrupted-and-restarted runs equal uninterrupted ones
(bitwise on the same ranks, 1e-10 across 1 <-> 2 ranks), SIGTERM and SIGKILL of real processes, every
kind of bad checkpoint refused with one line, write failures, the results file and its XDMF companion.

Unmarked tests are collective (every rank under mpirun) and write only into rank 0's tmp_path; tests that
start processes are marked ``serial``.
"""

import errno
import hashlib
import pathlib
import shutil
import signal
import subprocess
import sys
import time
import xml.etree.ElementTree as ET

import h5py
import numpy as np
import pytest
from mpi4py import MPI

from petroll.io import checkpoint_writer as ckpt_writer
from petroll.io.checkpoint import (CheckpointError, RunInterrupted, StopRequest, latest_checkpoint,
                                list_checkpoints, read_checkpoint, restart_scene)
from petroll.cli import main
from petroll.model.tao import DEFAULT_TAO_TYPE
from petroll.errors import SceneError
from petroll.io.results import OutputError, Results
from petroll.model.scene import dumps, parse_scene
from petroll.driver import run

ROOT = pathlib.Path(__file__).resolve().parent.parent
HALF, LENGTH = 0.8e-3, 0.4e-3
SLS = {"model": "sls", "E0": 10e6, "Einf": 2e6, "nu": 0.5, "tau_relax": 0.01}
PRONY = {"model": "prony", "series": "maxwell", "Einf": 2e6, "nu": 0.5, "moduli": [5e6, 3e6],
         "times": [0.003, 0.03]}
CONSTANT = [0.05, 0.0]
SINUSOIDAL = {"kind": "sinusoidal", "mean": [0.05, 0.0], "amplitude": [0.03, 0.0], "period": 0.006}
PHYSICAL = ("t", "sx", "sy", "delta", "force", "force_x", "force_y", "mu_r", "area", "p_max", "cop_x",
            "cop_y", "lead", "trail", "dissipation", "distance")
"""Series compared across rank counts (iteration counts and residuals may differ in the last digits)."""


def raw_scene(material=None, velocity=CONSTANT, control=("penetration", 2e-5), n=20, distance=LENGTH,
              output=None) -> dict:
    """A sphere rolling ``distance`` (2 steps per cell: ~11 steps for LENGTH) on an n-cell-wide grid."""
    nx = int(round(n * (2 * HALF + distance) / (2 * HALF)))
    return {
        "grid": {"nx": nx, "ny": n, "x": [-HALF, distance + HALF], "y": [-HALF, HALF]},
        "material": dict(material or SLS),
        "body": {"shape": "sphere", "radius": 0.01},
        "motion": {"velocity": velocity, control[0]: control[1]},
        "time": {"steps_per_cell": 2, "distance": distance},
        "solver": {"tol": 1e-9},
        "output": {"every": 3, "checkpoint_every": 4, "keep": 10, **(output or {})},
    }


def make_scene(raw, base_dir="."):
    return parse_scene(raw, source="test_checkpoint", base_dir=base_dir)


def write_toml(path: pathlib.Path, raw: dict) -> None:
    path.write_text(dumps(raw), encoding="utf-8")


def on_root(comm, work):
    """Run ``work()`` on rank 0 only (the others wait); its result, or its failure, on every rank."""
    result, failure = None, None
    if comm.rank == 0:
        try:
            result = work()
        except Exception as exc:  # noqa: BLE001 - re-raised on every rank below
            failure = f"{type(exc).__name__}: {exc}"
    result, failure = comm.bcast((result, failure), root=0)
    if failure:
        raise AssertionError(f"on rank 0: {failure}")
    return result


def assert_identical(a: Results, b: Results) -> None:
    """Same series (all but the wall time), same saved fields and steps: bit for bit."""
    assert set(a.series) == set(b.series)
    for name in a.series:
        if name != "solve_time":
            assert np.array_equal(a.series[name], b.series[name], equal_nan=True), name
    assert np.array_equal(a.field_steps, b.field_steps)
    assert np.array_equal(a.pressure, b.pressure)
    assert a.pressure.dtype == b.pressure.dtype == np.float64


def assert_close(a: Results, b: Results, rtol=1e-10) -> None:
    """Same run to rtol relative to each quantity's scale (1 <-> 2 ranks): its largest value, or for what
    vanishes by symmetry (force_y, cop_y, sy) the normal force or the grid's extent."""
    assert len(a.series["t"]) == len(b.series["t"])
    worst = 0.0
    for name in PHYSICAL:
        x, y = a.series[name], b.series[name]
        scale = np.nanmax(np.abs(x))  # a force by the normal force, a position by the grid's extent
        if name in ("force_x", "force_y"):
            scale = max(scale, np.abs(a.series["force"]).max())
        if name in ("sx", "sy", "cop_x", "cop_y", "lead", "trail"):
            scale = max(scale, np.abs(a.x).max(), np.abs(a.y).max())
        assert np.array_equal(np.isnan(x), np.isnan(y)), name
        assert np.nanmax(np.abs(x - y)) <= rtol * scale, (name, np.nanmax(np.abs(x - y)), scale)
        worst = max(worst, np.nanmax(np.abs(x - y)) / scale)
    assert np.array_equal(a.field_steps, b.field_steps)
    assert np.abs(a.pressure - b.pressure).max() <= rtol * np.abs(a.pressure).max()
    print(f"largest relative difference: series {worst:.2e}, fields "
          f"{np.abs(a.pressure - b.pressure).max() / np.abs(a.pressure).max():.2e}")


def interrupter(step: int, comm):
    """A StopRequest set, on the last rank only, after ``step`` (as a signal reaching one rank)."""
    stop = StopRequest()

    def on_step(record):
        if record.step == step and comm.rank == comm.size - 1:
            stop.request(signal.SIGTERM)

    return stop, on_step


CASES = {
    "sls-constant-penetration": (SLS, CONSTANT, ("penetration", 2e-5)),
    "sls-sinusoidal-load": (SLS, SINUSOIDAL, ("load", 0.1)),
    "prony-constant-load": (PRONY, CONSTANT, ("load", 0.1)),
    "prony-sinusoidal-penetration": (PRONY, SINUSOIDAL, ("penetration", 2e-5)),
}


@pytest.mark.slow
@pytest.mark.parametrize("case", [pytest.param(c, marks=pytest.mark.ranks4) if c == "prony-constant-load" else c
                                  for c in CASES])
def test_interrupted_and_restarted_run_is_bitwise_the_uninterrupted_run(case, comm, shared_dir):
    material, velocity, control = CASES[case]
    scene = make_scene(raw_scene(material, velocity, control))
    reference = run(scene, comm, shared_dir / "reference")
    n = len(reference.series["t"])
    assert n >= 10 and list(reference.field_steps) == [0, 3, 6, 9, *([n - 1] if (n - 1) % 3 else [])]
    if velocity is SINUSOIDAL:
        assert np.ptp(np.diff(reference.series["t"])) > 0  # the time step follows the speed

    # A stop request after step 5 on one rank: every rank stops there, with a checkpoint and the results so
    # far.
    stop, on_step = interrupter(5, comm)
    with pytest.raises(RunInterrupted) as info:
        run(scene, comm, shared_dir / "stopped", stop=stop, on_step=on_step)
    assert info.value.step == 5 and info.value.exit_code == 143
    assert info.value.checkpoint == shared_dir / "stopped" / "checkpoints" / "step-00000005.h5"
    partial = Results.open(shared_dir / "stopped" / "results.h5")
    assert not partial.complete and reference.complete
    for name in PHYSICAL:
        assert np.array_equal(partial.series[name], reference.series[name][:6], equal_nan=True)
    assert list(partial.field_steps) == [0, 3]

    restarted = run(scene, comm, shared_dir / "stopped", restart=read_checkpoint(info.value.checkpoint, comm))
    assert_identical(restarted, reference)

    # Any periodic checkpoint of the uninterrupted run (steps 4, 8, and the last) continues identically.
    found = list_checkpoints(shared_dir / "reference" / "checkpoints")
    assert [int(p.stem[5:]) for p in found] == [4, 8, *([n - 1] if (n - 1) % 4 else [])]
    for path in found[:2]:
        check = read_checkpoint(path, comm)
        assert check.ranks == comm.size and check.step == int(path.stem[5:])
        again = run(restart_scene(check), comm, shared_dir / f"from-{path.stem}", restart=check)
        assert_identical(again, reference)


@pytest.mark.slow
def test_a_checkpoint_without_the_kept_first_guesses_restarts_to_the_same_answer(comm, shared_dir):
    """Checkpoints written before the warm start kept its last solutions lack state/recent: the restart
    then carries the checkpoint's pressure as the first guess and reaches the same answer within the
    tolerance (not bitwise: the first guesses differ)."""
    raw = raw_scene(SLS, CONSTANT, ("load", 0.1))
    raw["solver"]["tol"] = 1e-12
    scene = make_scene(raw)
    reference = run(scene, comm, shared_dir / "reference")
    check = read_checkpoint(shared_dir / "reference" / "checkpoints" / "step-00000004.h5", comm)
    assert len(check.state["recent"]) == 5  # steps 0-4: up to 6 are kept (3 per lag of 2); every rank its rows
    del check.state["recent"], check.state["recent_position"]
    assert_close(run(scene, comm, shared_dir / "older", restart=check), reference, rtol=1e-10)


@pytest.mark.slow
@pytest.mark.parallel
@pytest.mark.parametrize("material", ["sls", "prony"])
def test_restart_on_another_rank_count_agrees_to_1e_10(material, comm, shared_dir):
    """Written on 2 ranks, continued on 1 (rank 0, COMM_SELF); written on 1, continued on 2. The contact
    conditions are solved to 1e-12 so that the solver's own rank-count dependence (~ its tolerance) stays
    well below the 1e-10 checked."""
    raw = raw_scene(SLS if material == "sls" else PRONY, SINUSOIDAL, ("load", 0.1))
    raw["solver"]["tol"] = 1e-12
    scene = make_scene(raw)
    two = run(scene, comm, shared_dir / "two")
    middle = shared_dir / "two" / "checkpoints" / "step-00000004.h5"

    def continue_on_one():
        check = read_checkpoint(middle, MPI.COMM_SELF)
        assert check.ranks == comm.size
        assert_close(run(scene, MPI.COMM_SELF, shared_dir / "two-to-one", restart=check), two)
        return True

    assert on_root(comm, continue_on_one)

    one = on_root(comm, lambda: run(scene, MPI.COMM_SELF, shared_dir / "one").path)
    one = Results.open(one)
    check = read_checkpoint(shared_dir / "one" / "checkpoints" / "step-00000008.h5", comm)
    assert check.ranks == 1
    assert_close(run(scene, comm, shared_dir / "one-to-two", restart=check), one)
    assert_close(one, two)


@pytest.mark.slow
def test_tabulated_material_restarts_bitwise_and_a_changed_table_is_refused(comm, shared_dir):
    """The hereditary history (all increments and times) is in the checkpoint; its J table must not change."""
    if comm.rank == 0:
        t = np.array([0.0, 0.002, 0.005, 0.01, 0.02, 0.05, 1.0])
        J = 0.75 / (2e6 + 1e6 * np.exp(-t / 0.01))  # E0/Einf = 1.5: the paper scheme holds at these steps
        (shared_dir / "J.csv").write_text("".join(f"{a!r},{b!r}\n" for a, b in zip(t, J)))
    comm.Barrier()
    raw = raw_scene({"model": "tabulated", "file": "J.csv", "quantity": "J"}, CONSTANT, ("penetration", 2e-5))
    scene = make_scene(raw, base_dir=shared_dir)
    reference = run(scene, comm, shared_dir / "reference")
    check = read_checkpoint(shared_dir / "reference" / "checkpoints" / "step-00000004.h5", comm)
    assert check.attrs["history"] == "hereditary" and len(check.times) == 5
    assert_identical(run(restart_scene(check), comm, shared_dir / "again", restart=check), reference)
    if comm.rank == 0:
        (shared_dir / "J.csv").write_text("0.0,1e-7\n1.0,2e-7\n")
    comm.Barrier()
    with pytest.raises(CheckpointError, match="file named by \\[material\\] file or \\[body\\] file changed"):
        restart_scene(check)


@pytest.mark.slow
@pytest.mark.ranks4
def test_checkpoint_layout_and_sizes_do_not_grow_with_the_steps_for_prony(comm, shared_dir):
    """Prony: the state is p, W and one field per term whatever the step; only the series grow (the saved
    fields are in results.h5, not in the checkpoints). Every dataset is readable with plain h5py."""
    raw = raw_scene(PRONY, CONSTANT, ("penetration", 2e-5),
                    output={"every": 0, "checkpoint_every": 2, "keep": 2})
    results = run(make_scene(raw), comm, shared_dir)
    nx, ny = results.pressure.shape[1:]
    found = list_checkpoints(shared_dir / "checkpoints")
    assert [p.name for p in found] == ["step-00000008.h5", "step-00000010.h5"]  # 2, 4, 6 removed
    if comm.rank == 0:
        sizes = []
        for path in found:
            with h5py.File(path, "r") as f:
                step = int(f.attrs["step"])
                assert f["state/q"].shape == (2, nx, ny) and f["state/pressure"].shape == (nx, ny)
                assert f["series/force"].shape == (step + 1,)
                assert "pressure" not in f["fields"]  # the saved fields live in results.h5 only
                assert list(f["fields/step"]) == ([0] if step < 10 else [0, 10])
                assert f.attrs["format"] == "petroll-checkpoint" and f.attrs["format_version"] == 2
                assert "[material]" in f.attrs["scene"] and f.attrs["ranks"] == comm.size
            sizes.append(path.stat().st_size)
        print("checkpoint sizes (bytes):", dict(zip([p.name for p in found], sizes)),
              "results.h5:", (shared_dir / "results.h5").stat().st_size, "grid", nx, ny)
        # At most the raw bytes of p, W, the 2 s fields, the 6 recent solutions (the next first guess:
        # 3 per lag, and the body moves half a cell per step), the saved fields and the series, plus the
        # fixed cost of about 30 HDF5 objects (~1 kB each).
        for path, size in zip(found, sizes):
            with h5py.File(path, "r") as f:
                assert set(f["state"]) == {"pressure", "q", "displacement", "direction", "recent",
                                           "recent_position"}  # relaxation form
                assert f["state/recent"].shape == (6, nx, ny) and f["state/recent_position"].shape == (6, 2)
                raw_bytes = 8 * (10 * nx * ny + 21 * len(f["series/t"]))
            assert size < raw_bytes + 40_000, (path.name, size, raw_bytes)


@pytest.mark.slow
def test_keep_removes_older_checkpoints_and_those_of_the_run_replaced(comm, shared_dir):
    """Of the run's own checkpoints the newest ``keep`` stay; those an earlier run left in the directory (a
    later step) go once the new results.h5 is in place (they continued the results.h5 it replaced); one
    that cannot be read (damaged: not known to be another run's, issue 35) and other files stay. A restart
    keeps its run's later checkpoints."""
    raw = raw_scene(SLS, CONSTANT, ("penetration", 2e-5), output={"checkpoint_every": 2, "keep": 2})
    run(make_scene(raw_scene(SLS, CONSTANT, ("penetration", 2e-5), distance=2 * LENGTH,
                             output={"checkpoint_every": 20})), comm, shared_dir)
    if comm.rank == 0:
        (shared_dir / "checkpoints" / "step-00000099.h5").write_bytes(b"damaged")
        (shared_dir / "checkpoints" / "notes.txt").write_text("mine")
    comm.Barrier()
    earlier = sorted(p.name for p in (shared_dir / "checkpoints").iterdir())
    assert earlier == ["notes.txt", "step-00000020.h5", "step-00000099.h5"]  # 21 steps: the last one's
    results = run(make_scene(raw), comm, shared_dir, overwrite=True)
    last = len(results.series["t"]) - 1
    names = sorted(p.name for p in (shared_dir / "checkpoints").iterdir())
    mine = sorted([f"step-{last - last % 2 - (2 if last % 2 == 0 else 0):08d}.h5", f"step-{last:08d}.h5"])
    assert names == sorted([*mine, "notes.txt", "step-00000099.h5"])
    run(make_scene(raw), comm, shared_dir, restart=read_checkpoint(shared_dir / "checkpoints" / mine[0], comm))
    assert sorted(p.name for p in (shared_dir / "checkpoints").iterdir()) == names


@pytest.mark.slow
def test_results_xdmf_describes_the_saved_fields_over_the_hdf5_data(comm, shared_dir):
    results = run(make_scene(raw_scene()), comm, shared_dir)
    if comm.rank != 0:
        return
    nx, ny = results.pressure.shape[1:]
    root = ET.parse(shared_dir / "results.xdmf").getroot()
    grids = root.findall("./Domain/Grid/Grid")
    assert root.find("./Domain/Grid").get("CollectionType") == "Temporal"
    assert len(grids) == len(results.field_steps)
    with h5py.File(shared_dir / "results.h5", "r") as f:
        for k, (grid, step) in enumerate(zip(grids, results.field_steps)):
            assert float(grid.find("Time").get("Value")) == results.series["t"][step]
            topology = grid.find("Topology")
            assert topology.get("TopologyType") == "2DSMesh"
            assert topology.get("Dimensions") == f"{nx + 1} {ny + 1}"
            item = grid.find("Geometry/DataItem")
            h5name, dataset = item.text.split(":")
            assert h5name == "results.h5"
            xy = f[dataset][()].reshape(nx + 1, ny + 1, 2)
            assert tuple(int(d) for d in item.get("Dimensions").split()) == f[dataset].shape
            centres = 0.25 * (xy[:-1, :-1] + xy[1:, :-1] + xy[:-1, 1:] + xy[1:, 1:])
            assert np.allclose(centres[..., 0], results.x[:, None], rtol=0, atol=1e-15)
            assert np.allclose(centres[..., 1], results.y[None, :], rtol=0, atol=1e-15)
            item = grid.find("Attribute/DataItem")
            assert item.get("Format") == "HDF" and grid.find("Attribute").get("Center") == "Cell"
            h5name, dataset = item.text.split(":")
            assert h5name == "results.h5" and dataset == f"/xdmf/pressure/{k}"
            assert tuple(int(d) for d in item.get("Dimensions").split()) == f[dataset].shape == (nx, ny)
            view = f[dataset]  # a virtual dataset over this file's own fields/pressure[k]
            assert view.is_virtual and [(s.file_name, s.dset_name) for s in view.virtual_sources()] == [
                (".", "/fields/pressure")]
            assert np.array_equal(view[()], results.pressure[k])


# -- bad checkpoints --------------------------------------------------------------------------------------
def flip_byte_inside(path: pathlib.Path, dataset: str) -> None:
    """Overwrite bytes in the middle of the stored (compressed) data of ``dataset``."""
    with h5py.File(path, "r") as f:
        info = f[dataset].id.get_chunk_info(0)
    flip_byte_at(path, info.byte_offset + info.size // 2)


def flip_byte_at(path: pathlib.Path, offset: int) -> None:
    with open(path, "r+b") as fh:
        fh.seek(offset)
        byte = fh.read(1)
        fh.seek(offset)
        fh.write(bytes([byte[0] ^ 0xFF]))


def other_hdf5(path: pathlib.Path) -> None:
    with h5py.File(path, "w") as f:
        f.create_dataset("x", data=[1.0])


def set_attribute(path: pathlib.Path, name: str, value, reseal: bool = False) -> None:
    """An attribute edited (h5py): the file's seal broken, or made again (``reseal``: as its writer)."""
    from petroll.io.hdf5 import seal

    with h5py.File(path, "r+") as f:
        f.attrs[name] = value
    if reseal:
        seal(path)


def set_dataset_digest(path: pathlib.Path, name: str, value) -> None:
    """The checksum attribute of dataset ``name`` edited (h5py), and the file sealed again (as its writer)."""
    from petroll.io.hdf5 import seal

    with h5py.File(path, "r+") as f:
        f[name].attrs["sha256"] = value
    seal(path)


def unseal(path: pathlib.Path) -> None:
    """A checkpoint as written before seals (petroll.io.hdf5.seal): its user block's seal blanked."""
    from petroll.io.hdf5 import SEAL_BYTES, SEAL_MAGIC

    with open(path, "r+b") as fh:
        if fh.read(len(SEAL_MAGIC)) == SEAL_MAGIC:
            fh.seek(0)
            fh.write(bytes(SEAL_BYTES))


BAD = {
    "missing": (lambda good, p: None, "no such checkpoint file"),
    "empty": (lambda good, p: p.write_bytes(b""), "empty; not a petroll checkpoint"),
    "text": (lambda good, p: p.write_text("[grid]\nnx = 3\n"), "not an HDF5 file"),
    "truncated": (lambda good, p: p.write_bytes(good.read_bytes()[: good.stat().st_size // 2]), "truncated"),
    "results file": (lambda good, p: shutil.copy(good.parent.parent / "results.h5", p),
                     "not a petroll checkpoint (a petroll results file"),
    "other hdf5": (lambda good, p: other_hdf5(p), "not a petroll checkpoint (an HDF5 file"),
    "corrupted data": (lambda good, p: (shutil.copy(good, p), flip_byte_inside(p, "state/q")), "corrupted"),
    "damaged seal": (lambda good, p: (shutil.copy(good, p), flip_byte_at(p, 3)),
                     "corrupted (its seal, the file's first 512 bytes, is damaged)"),
    "edited scene": (lambda good, p: (shutil.copy(good, p), set_attribute(p, "scene", "[grid]\nnx = 1\n")),
                     "corrupted (its bytes do not match the checksum it was sealed with)"),
    "edited and sealed": (lambda good, p: (shutil.copy(good, p), set_attribute(p, "scene", "[grid]\nnx = 1\n",
                                                                                reseal=True)),
                          "corrupted (its attributes or list of datasets do not match the checksum)"),
    "digest not text": (lambda good, p: (shutil.copy(good, p), set_attribute(p, "sha256", np.zeros(3),
                                                                               reseal=True)),
                        "corrupted (its attributes or list of datasets do not match the checksum)"),
    "newer format": (lambda good, p: (shutil.copy(good, p), set_attribute(p, "format_version", 3, reseal=True)),
                     "written in checkpoint format 3"),
    "a dataset's digest not text": (lambda good, p: (shutil.copy(good, p), set_dataset_digest(p, "series/t",
                                                                                              np.zeros(3))),
                                    "corrupted (the data of series/t do not match their checksum)"),
}


def snapshot(directory: pathlib.Path) -> dict:
    return {str(p.relative_to(directory)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(directory.rglob("*")) if p.is_file()}


@pytest.mark.filterwarnings("error::FutureWarning")  # numpy's, of a comparison with a damaged value
def test_every_kind_of_bad_checkpoint_is_refused_with_one_line_and_nothing_written(comm, shared_dir, capsys):
    run(make_scene(raw_scene(PRONY)), comm, shared_dir / "run")
    good = shared_dir / "run" / "checkpoints" / "step-00000008.h5"
    if comm.rank == 0:
        (shared_dir / "bad").mkdir()
        for kind, (make, _) in BAD.items():
            make(good, shared_dir / "bad" / f"{kind.replace(' ', '-')}.h5")
    comm.Barrier()
    before = snapshot(shared_dir)
    for kind, (_, expected) in BAD.items():
        path = shared_dir / "bad" / f"{kind.replace(' ', '-')}.h5"
        with pytest.raises(CheckpointError) as info:
            read_checkpoint(path, comm)
        message = str(info.value)
        assert message.startswith(f"{path}: ") and expected in message, (kind, message)
        assert "\n" not in message
        # The command line: one line, exit status 2, on every rank; nothing created or changed.
        capsys.readouterr()
        assert main(["restart", str(path), "--out", str(shared_dir / "run"), "--quiet"]) == 2
        if comm.rank == 0:
            lines = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
            assert lines == [f"petroll: error: {message}"], (kind, lines)
    assert snapshot(shared_dir) == before
    assert read_checkpoint(good, comm).step == 8  # the good one is still good


@pytest.mark.slow
@pytest.mark.parametrize("change, key", [
    ({"grid": {"nx": 26}}, "[grid] nx"),
    ({"material": {"Einf": 3e6}}, "[material] Einf"),
    ({"body": {"radius": 0.011}}, "[body] radius"),
    ({"motion": {"load": 0.1}}, "[motion] load"),
    ({"solver": {"tol": 1e-8}}, "[solver] tol"),
    ({"time": {"steps_per_cell": 3}}, "[time] steps_per_cell"),
    ({"solver": {"integrator": "paper"}}, "[solver] integrator"),
    ({"output": {"fields": ["pressure", "displacement", "gap"]}}, "[output] fields"),
])
def test_restart_with_an_unsafe_scene_change_names_the_key(change, key, comm, shared_dir, capsys):
    raw = raw_scene()
    run(make_scene(raw), comm, shared_dir / "run")
    new = {s: dict(t) for s, t in raw.items()}
    for section, values in change.items():
        new[section].update(values)
        if "load" in values:
            new[section].pop("penetration")
    if comm.rank == 0:
        write_toml(shared_dir / "new.toml", new)
    comm.Barrier()
    check = read_checkpoint(shared_dir / "run" / "checkpoints" / "step-00000004.h5", comm)
    with pytest.raises(SceneError) as info:
        restart_scene(check, shared_dir / "new.toml")
    assert info.value.key == key
    message = str(info.value)
    assert message.startswith(f"{shared_dir / 'new.toml'}: {key} = ") and str(check.path) in message
    assert message.endswith("a restart may change only [time] end, distance, steady, max_steps and [output] dir, "
                            "every, checkpoint_every, keep") and "\n" not in message
    before = snapshot(shared_dir)
    capsys.readouterr()
    assert main(["restart", str(check.path), "--scene", str(shared_dir / "new.toml"), "--quiet"]) == 2
    if comm.rank == 0:
        assert capsys.readouterr().err.strip() == f"petroll: error: {message}"
    assert snapshot(shared_dir) == before


def test_restart_refuses_results_whose_datasets_reach_beyond_what_was_written(comm, shared_dir, capsys):
    """A results.h5 whose series or field was damaged to a huge extent (random bytes in its dataspace:
    series/trail 1095216660491 rows of 11): the restart, which cuts the datasets back to the checkpoint's
    step, refuses it in one line, exit 2, before writing (HDF5 walked every chunk of the cut: a hang that
    SIGTERM could not end). Likewise a saved field whose rows are not the grid's shape."""
    run(make_scene(raw_scene()), comm, shared_dir / "run")
    damages = {"series": ("series/trail", lambda d: d.resize((10**12,)),
                          "series/trail holds 1000000000000 rows, more than the"),
               "field rows": ("fields/pressure", lambda d: d.resize(10**9, axis=0),
                              "fields/pressure holds 1000000000 rows, more than the"),
               "field shape": ("fields/pressure", lambda d: d.resize(5, axis=2), "fields/pressure has shape (")}
    for kind, (name, damage, says) in damages.items():
        out = shared_dir / kind.replace(" ", "-")
        if comm.rank == 0:
            shutil.copytree(shared_dir / "run", out)
            with h5py.File(out / "results.h5", "r+") as f:
                damage(f[name])
        comm.Barrier()
        before = snapshot(out)
        capsys.readouterr()
        assert main(["restart", str(out / "checkpoints" / "step-00000004.h5"), "--quiet"]) == 2, kind
        if comm.rank == 0:
            lines = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
            assert len(lines) == 1 and lines[0].startswith(f"petroll: error: {out / 'results.h5'}: damaged (")
            assert says in lines[0], (kind, lines)
        assert snapshot(out) == before, kind


def test_restart_may_extend_the_run_and_change_outputs(comm, shared_dir, capsys):
    raw = raw_scene(distance=2 * LENGTH)
    raw["time"]["distance"] = LENGTH
    short = run(make_scene(raw), comm, shared_dir / "run")
    longer = {s: dict(t) for s, t in raw.items()}
    longer["time"]["distance"] = 2 * LENGTH
    longer["output"] = {"every": 5, "checkpoint_every": 0}
    longer["solver"]["tao_type"] = DEFAULT_TAO_TYPE  # the defaults, written out: no change
    longer["solver"]["integrator"] = make_scene(raw).solver.integrator
    if comm.rank == 0:
        write_toml(shared_dir / "longer.toml", longer)
    comm.Barrier()
    last = list_checkpoints(shared_dir / "run" / "checkpoints")[-1]
    assert main(["restart", str(shared_dir / "run"), "--scene", str(shared_dir / "longer.toml"), "--out",
                 str(shared_dir / "longer"), "--quiet"]) == 0
    extended = Results.open(shared_dir / "longer" / "results.h5")
    n = len(short.series["t"])
    assert int(last.stem[5:]) == n - 1 and len(extended.series["t"]) > n + 5
    assert np.array_equal(extended.series["force"][:n], short.series["force"])
    assert extended.series["distance"][-1] == pytest.approx(2 * LENGTH, rel=1e-6)
    assert list(extended.field_steps)[: len(short.field_steps)] == list(short.field_steps)
    assert not (shared_dir / "longer" / "checkpoints").exists()
    if comm.rank == 0:
        assert "Results: " + str(shared_dir / "longer" / "results.h5") in capsys.readouterr().out


# -- write failures ---------------------------------------------------------------------------------------
@pytest.mark.slow
def test_disk_full_during_a_checkpoint_is_a_clear_error_and_the_last_one_stays_usable(comm, shared_dir,
                                                                                      monkeypatch):
    scene = make_scene(raw_scene())
    reference = run(scene, comm, shared_dir / "reference")
    real, calls = ckpt_writer._write_dataset, []

    def full(f, name, data):
        calls.append(name)
        if len(calls) > 30:  # the second checkpoint, part-written
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(f, name, data)

    monkeypatch.setattr(ckpt_writer, "_write_dataset", full)
    with pytest.raises(CheckpointError) as info:
        run(scene, comm, shared_dir / "full")
    monkeypatch.undo()
    path = shared_dir / "full" / "checkpoints" / "step-00000008.h5"
    assert str(info.value) == (f"{path}: cannot write the checkpoint (No space left on device); the earlier "
                               f"checkpoints in {path.parent} are unchanged")
    assert sorted(p.name for p in path.parent.iterdir()) == ["step-00000004.h5"]  # no temporary file left
    partial = Results.open(shared_dir / "full" / "results.h5")  # brought up to step 8 before the checkpoint
    assert not partial.complete and len(partial.series["t"]) == 9
    check = read_checkpoint(path.parent / "step-00000004.h5", comm)
    assert_identical(run(scene, comm, shared_dir / "full", restart=check), reference)


def test_unwritable_output_directory_is_refused_before_any_step(comm, shared_dir, capsys):
    if comm.rank == 0:
        (shared_dir / "file").write_text("not a directory")
    comm.Barrier()
    with pytest.raises(OutputError, match=r"file/out: cannot write to the output directory \(Not a dir"):
        run(make_scene(raw_scene()), comm, shared_dir / "file" / "out")
    if comm.rank == 0:
        write_toml(shared_dir / "s.toml", raw_scene())
    comm.Barrier()
    capsys.readouterr()
    out = shared_dir / "file" / "out"
    assert main(["run", str(shared_dir / "s.toml"), "--out", str(out), "--quiet"]) == 2
    if comm.rank == 0:
        errors = [line for line in capsys.readouterr().err.splitlines() if not line.startswith("petroll: warning:")]
        assert len(errors) == 1  # (the coarse test scene's resolution warning aside)


# -- real processes ---------------------------------------------------------------------------------------
def wait_for(path: pathlib.Path, proc: subprocess.Popen, limit=60.0) -> None:
    start = time.monotonic()
    while not path.exists():
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() - start < limit
        time.sleep(0.005)


def long_raw() -> dict:
    """~80 steps (about a second): long enough to be interrupted after its first checkpoint."""
    raw = raw_scene(PRONY, SINUSOIDAL, ("load", 0.1), distance=2.4e-3)
    raw["output"] = {"every": 10, "checkpoint_every": 5, "keep": 2}
    return raw


_LONG_REFERENCE: list = []


def long_scene(tmp_path, tmp_path_factory):
    """long_raw() written to tmp_path/long.toml; returns its uninterrupted serial run, made once a session:
    what the interrupted runs of it (here and in tests/test_faults.py) end as."""
    write_toml(tmp_path / "long.toml", long_raw())
    if not _LONG_REFERENCE:
        _LONG_REFERENCE.append(run(make_scene(long_raw()), MPI.COMM_SELF, tmp_path_factory.mktemp("long") / "run"))
    return _LONG_REFERENCE[0]


@pytest.mark.slow
@pytest.mark.serial
def test_sigterm_during_a_cli_run_leaves_a_checkpoint_that_restart_finishes_identically(tmp_path, cli,
                                                                                       tmp_path_factory):
    reference = long_scene(tmp_path, tmp_path_factory)
    proc = cli.start("run", "long.toml", "--out", "stopped", "--quiet", cwd=tmp_path,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    wait_for(tmp_path / "stopped" / "checkpoints" / "step-00000005.h5", proc)
    proc.send_signal(signal.SIGTERM)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 143, err
    last = list_checkpoints(tmp_path / "stopped" / "checkpoints")[-1]
    step = int(last.stem[5:])
    assert 5 <= step < len(reference.series["t"]) - 1
    err = "\n".join(line for line in err.splitlines() if not line.startswith("petroll: warning:"))  # coarse
    assert err.strip() == (f"petroll: long.toml: interrupted by SIGTERM after step {step} (t = "
                           f"{reference.series['t'][step]:.6g} s); checkpoint stopped/checkpoints/"
                           f"{last.name}; continue with: petroll restart stopped/checkpoints/{last.name}")
    partial = Results.open(tmp_path / "stopped" / "results.h5")
    assert not partial.complete and len(partial.series["t"]) == step + 1
    done = cli("restart", f"stopped/checkpoints/{last.name}", "--quiet", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert_identical(Results.open(tmp_path / "stopped" / "results.h5"), reference)


KILLER = """
import os, signal, sys
from petroll.io import checkpoint_writer
from petroll.model.scene import load_scene
from petroll.driver import run

real, calls = checkpoint_writer._write_dataset, []

def write_then_die(f, name, data):
    calls.append(name)
    if len(calls) == int(sys.argv[2]):
        f.flush()  # part of the file is on disk, as when a writer dies in the middle
        os.kill(os.getpid(), signal.SIGKILL)
    return real(f, name, data)

checkpoint_writer._write_dataset = write_then_die
run(load_scene(sys.argv[1]), out="killed")
"""


@pytest.mark.slow
@pytest.mark.serial
def test_sigkill_during_a_checkpoint_write_leaves_the_previous_checkpoint_and_results_usable(tmp_path, cli):
    raw = long_raw()
    write_toml(tmp_path / "long.toml", raw)
    reference = run(make_scene(raw), MPI.COMM_SELF, tmp_path / "reference")
    # 25 whole datasets per checkpoint (p, W, direction, 21 series, fields/step): die in the third (step 15).
    proc = subprocess.run([sys.executable, "-c", KILLER, "long.toml", str(2 * 25 + 12)], cwd=tmp_path,
                          env=cli.env, capture_output=True, text=True, timeout=120)
    assert proc.returncode == -signal.SIGKILL, proc.stderr
    directory = tmp_path / "killed" / "checkpoints"
    leftovers = sorted(p.name for p in directory.iterdir())
    assert leftovers[0].startswith(".step-00000015.h5.tmp") and leftovers[1:] == ["step-00000005.h5",
                                                                                  "step-00000010.h5"]
    assert latest_checkpoint(tmp_path / "killed") == directory / "step-00000010.h5"
    partial = Results.open(tmp_path / "killed" / "results.h5")  # brought up to step 15 before the checkpoint
    assert not partial.complete and len(partial.series["t"]) == 16
    # A truncated copy at a checkpoint's name (a non-atomic copy killed midway) is refused, not used.
    bad = directory / "step-00000015.h5"
    bad.write_bytes((directory / "step-00000010.h5").read_bytes()[:20000])
    before = snapshot(tmp_path / "killed")
    refused = cli("restart", "killed", cwd=tmp_path)
    assert refused.returncode == 2 and refused.stderr.count("\n") == 1
    expected = f"petroll: error: {bad.relative_to(tmp_path)}: truncated"
    assert refused.stderr.startswith(expected), refused.stderr
    assert snapshot(tmp_path / "killed") == before
    bad.unlink()
    done = cli("restart", "killed", "--quiet", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert_identical(Results.open(tmp_path / "killed" / "results.h5"), reference)


# -- without parallel HDF5 --------------------------------------------------------------------------------
@pytest.mark.slow
def test_without_parallel_hdf5_rank_0_writes_the_same_files_and_restarts_bitwise(comm, shared_dir,
                                                                                   monkeypatch):
    """The path taken when h5py has no MPI (PyPI's h5py): rank 0 alone opens the files and moves the other
    ranks' rows in blocks (made 2 KiB here, so that every field takes several). Its results.h5 and
    checkpoints hold what the parallel path's hold, bit for bit, and a run stopped and restarted through
    it is the uninterrupted run. Under one rank both paths are rank 0's: the test bites under mpirun."""
    from petroll.io import hdf5

    scene = make_scene(raw_scene(PRONY, SINUSOIDAL, ("load", 0.1)))
    reference = run(scene, comm, shared_dir / "parallel")
    monkeypatch.setattr(hdf5, "parallel_hdf5", lambda comm: False)
    monkeypatch.setattr(hdf5, "BLOCK_BYTES", 2048)
    through_root = run(scene, comm, shared_dir / "rank0")
    assert_identical(through_root, reference)
    stop, on_step = interrupter(5, comm)
    with pytest.raises(RunInterrupted) as info:
        run(scene, comm, shared_dir / "stopped", stop=stop, on_step=on_step)
    restarted = run(scene, comm, shared_dir / "stopped", restart=read_checkpoint(info.value.checkpoint, comm))
    assert_identical(restarted, reference)

    def datasets(path: pathlib.Path) -> dict:
        found = {}
        with h5py.File(path, "r") as f:
            f.visititems(lambda name, item: found.__setitem__(name, item[()])
                         if isinstance(item, h5py.Dataset) and name != "series/solve_time" else None)
        return found

    def same_files(a: pathlib.Path, b: pathlib.Path) -> None:
        one, two = datasets(a), datasets(b)
        assert sorted(one) == sorted(two)
        for name in one:
            assert np.array_equal(one[name], two[name]), name

    def compare():
        same_files(shared_dir / "parallel" / "results.h5", shared_dir / "rank0" / "results.h5")
        for path in list_checkpoints(shared_dir / "parallel" / "checkpoints"):
            same_files(path, shared_dir / "rank0" / "checkpoints" / path.name)

    on_root(comm, compare)


@pytest.mark.slow
def test_remove_foreign_checkpoints_removes_only_those_it_read_as_another_runs(tmp_path, monkeypatch):
    """Issue 35: a checkpoint it fails to open (here a passing read error, OSError EIO), or finds damaged
    by its seal, is not known to be another run's and stays; one read as another run's goes; ours stay."""
    from petroll.io import checkpoint_writer as module
    from petroll.io.checkpoint_writer import remove_foreign_checkpoints

    run(make_scene(raw_scene(output={"checkpoint_every": 2, "keep": 10})), MPI.COMM_SELF, tmp_path / "run")
    found = list_checkpoints(tmp_path / "run" / "checkpoints")
    ours = read_checkpoint(found[0], MPI.COMM_SELF).run_id
    assert len(found) >= 4
    unreadable, damaged, foreign = found[1], found[2], found[3]
    set_attribute(foreign, "run_id", "another run", reseal=True)
    flip_byte_inside(damaged, "state/pressure")
    real_file = h5py.File

    def flaky(path, *args, **kwargs):
        if pathlib.Path(path) == unreadable:
            raise OSError(errno.EIO, "Input/output error")
        return real_file(path, *args, **kwargs)

    monkeypatch.setattr(module.h5py, "File", flaky)
    assert remove_foreign_checkpoints(found[0].parent, ours) == [foreign]
    assert [p for p in found if p.exists()] == [p for p in found if p != foreign]


@pytest.mark.slow
def test_a_restart_into_a_results_file_without_mu_lateral_adds_it(comm, shared_dir):
    """A periodic run's results.h5 written before rough/mu_lateral (the dataset removed) continued from its
    checkpoint: mu_lateral is added, NaN at the rows saved before, the lateral force's coefficient (a
    transient's mu_r) at those after; the group's other datasets as the uninterrupted run's."""
    raw = raw_scene()
    raw["grid"]["periodic"] = True
    scene = make_scene(raw)
    reference = run(scene, comm, shared_dir / "reference")
    stop, on_step = interrupter(5, comm)
    with pytest.raises(RunInterrupted) as info:
        run(scene, comm, shared_dir / "stopped", stop=stop, on_step=on_step)
    on_root(comm, lambda: _drop_mu_lateral(shared_dir / "stopped" / "results.h5"))
    restarted = run(scene, comm, shared_dir / "stopped", restart=read_checkpoint(info.value.checkpoint, comm))
    lateral, saved = restarted.rough["mu_lateral"], list(restarted.field_steps)
    assert saved == list(reference.field_steps) and saved[:2] == [0, 3] and len(saved) >= 4
    assert np.all(np.isnan(lateral[:2]))
    assert np.array_equal(lateral[2:], reference.rough["mu_lateral"][2:])
    assert np.allclose(lateral[2:], reference.series["mu_r"][saved[2:]], rtol=1e-12, atol=0)
    for name in ("area_fraction", "mean_gap", "spectrum", "q", "modes"):
        assert np.array_equal(restarted.rough[name], reference.rough[name], equal_nan=True)


def _drop_mu_lateral(path: pathlib.Path) -> None:
    """Remove rough/mu_lateral from a results.h5, as a file written before it holds none."""
    with h5py.File(path, "r+") as f:
        del f["rough/mu_lateral"]

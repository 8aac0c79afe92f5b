"""The verbs that read a run's files: ``petroll --version``, ``plot`` on every kind of output (run directory,
results.h5, sweep directory, stress.h5; png, pdf, svg), ``info`` and ``export --csv``, and the summary of
``restart``, checked against the files themselves read with h5py."""

import csv
import importlib.metadata
import pathlib

import h5py
import numpy as np
import pytest

import petroll

ROOT = pathlib.Path(__file__).resolve().parents[1]
MAGIC = {"png": b"\x89PNG", "pdf": b"%PDF", "svg": b"<?xml"}


@pytest.fixture
def run_dir(comm, shared_dir):
    """The default scene with a checkpoint every 10 steps, every field saved every 20 steps."""
    scene = petroll.load_scene(ROOT / "runs" / "sphere.toml").replace(
        {"output.checkpoint_every": 10, "output.fields": ["pressure", "displacement", "gap"]})
    petroll.run(scene, comm, out=shared_dir / "run")
    return shared_dir / "run"


def test_version_is_the_installed_distributions(cli_main, comm):
    code, out, _ = cli_main(["--version"])
    assert code == 0
    assert out == f"petroll {importlib.metadata.version('petroll')}\n"


def test_plot_takes_a_run_directory_its_results_file_a_sweep_and_a_stress_file(run_dir, cli_main, comm,
                                                                             shared_dir):
    """Every kind of input drawn as PNG, then one input (the results file) as PDF and as SVG: the format
    is matplotlib's choice at saving, the same for every figure."""
    from petroll.studies.sweep import sweep

    scene = petroll.load_scene(ROOT / "runs" / "master-curve.toml")
    sweep(scene, "motion.velocity=0.01,0.1", shared_dir / "sweep", comm, plot=False)
    petroll.stress(run_dir, depths=[0.0, 1e-4], comm=comm)
    cases = [([str(run_dir)], ["pressure", "patches", "series", "surface"], run_dir / "plots", "png"),
             ([str(run_dir / "results.h5"), "--out", str(shared_dir / "figs")], ["pressure"],
              shared_dir / "figs", "png"),
             ([str(shared_dir / "sweep")], ["sweep"], shared_dir / "sweep", "png"),
             ([str(run_dir / "stress.h5"), "--out", str(shared_dir / "s")], ["stress"], shared_dir / "s",
              "png"),
             *(([str(run_dir / "results.h5"), "--out", str(shared_dir / fmt)], ["pressure"], shared_dir / fmt,
                fmt) for fmt in ("pdf", "svg"))]
    for argv, names, where, fmt in cases:
        code, out, err = cli_main(["plot", *argv, "--format", fmt])
        assert code == 0, err
        if comm.rank == 0:
            for name in names:
                assert (where / f"{name}.{fmt}").read_bytes().startswith(MAGIC[fmt]), (argv, name)
            assert out.startswith("petroll: wrote ")


def test_plot_and_info_refuse_what_is_not_petroll_output_in_one_line(cli_main, comm, shared_dir):
    if comm.rank == 0:
        (shared_dir / "empty").mkdir()
        (shared_dir / "other.h5").write_bytes(b"not hdf5")
    comm.Barrier()
    for argv, says in ((["plot", str(shared_dir / "missing")], "no such file or directory"),
                       (["plot", str(shared_dir / "empty")], "holds no results.h5, sweep.h5 or stress.h5"),
                       (["info", str(shared_dir / "other.h5")], "not a petroll results.h5, sweep.h5 or "
                                                                 "stress.h5"),
                       (["export", str(shared_dir / "empty")], "holds no results.h5")):
        code, _, err = cli_main(argv)
        assert code == 2
        if comm.rank == 0:
            assert err.startswith("petroll: error: ") and says in err and err.count("\n") == 1, err


@pytest.mark.slow
def test_info_says_what_the_run_directory_holds(run_dir, cli_main, comm):
    code, out, _ = cli_main(["info", str(run_dir)])
    assert code == 0
    if comm.rank == 0:
        with h5py.File(run_dir / "results.h5") as f:
            n = int(f.attrs["steps_written"])
            steps = f["fields/step"][: int(f.attrs["fields_written"])].tolist()
            force, mu_r = f["series/force"][n - 1], f["series/mu_r"][n - 1]
        checkpoints = sorted(int(p.stem.split("-")[1]) for p in (run_dir / "checkpoints").glob("step-*.h5"))
        assert f"{n} written (0 ... {n - 1}), complete" in out
        assert f"force {force:.6g} N, mu_r {mu_r:.5g}" in out
        assert f"pressure, displacement, gap at {len(steps)} steps ({', '.join(map(str, steps))})" in out
        assert f"checkpoints: {len(checkpoints)} (steps {', '.join(map(str, checkpoints))})" in out
        assert f"scene: {ROOT / 'runs' / 'sphere.toml'}" in out and "petroll 0.1.0" in out
        with h5py.File(run_dir / "results.h5", "r+") as f:  # as a run stopped or killed leaves it
            f.attrs["complete"] = False
    comm.Barrier()
    code, out, _ = cli_main(["info", str(run_dir / "results.h5")])
    assert code == 0
    if comm.rank == 0:
        assert "partial" in out and f"petroll restart {run_dir} continues from the newest" in out


def _read_csv(path: pathlib.Path) -> tuple[list[str], np.ndarray]:
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    return rows[0], np.array(rows[1:], dtype=float)


@pytest.mark.slow
def test_export_writes_the_series_and_a_saved_field_as_csv(run_dir, cli_main, comm, shared_dir):
    code, out, _ = cli_main(["export", str(run_dir), "--csv"])
    assert code == 0
    code, _, _ = cli_main(["export", str(run_dir), "--field", "gap", "--step", "20", "--out",
                           str(shared_dir / "gap.csv")])
    assert code == 0
    bad, _, err = cli_main(["export", str(run_dir), "--field", "gap", "--step", "7"])
    assert bad == 2
    if comm.rank != 0:
        return
    assert "saved at steps 0, 20, 40, 51" in err
    header, table = _read_csv(run_dir / "series.csv")
    with h5py.File(run_dir / "results.h5") as f:
        n = int(f.attrs["steps_written"])
        for name, column in zip(header, table.T):
            key, unit = name.split(" (")
            assert unit[:-1] == f["series"][key].attrs["units"]
            assert np.array_equal(column, f["series"][key][:n]), key  # every digit round-trips
        assert len(header) == len(f["series"])
        k = list(f["fields/step"][()]).index(20)
        gap, x, y = f["fields/gap"][k], f["fields/x"][()], f["fields/y"][()]
    header, table = _read_csv(shared_dir / "gap.csv")
    assert header == ["x (m)", "y (m)", "gap (m)"]
    assert np.array_equal(table[:, 0], np.repeat(x, len(y)))
    assert np.array_equal(table[:, 1], np.tile(y, len(x)))
    assert np.array_equal(table[:, 2], gap.ravel())


@pytest.mark.slow
def test_restart_summary_names_the_step_it_resumed_from(run_dir, cli_main, comm):
    code, out, _ = cli_main(["restart", str(run_dir / "checkpoints" / "step-00000050.h5"), "--quiet"])
    assert code == 0
    if comm.rank == 0:
        assert "resumed after step 50 (t = 0.1875 s;" in out and "52 steps to t = 0.1913 s" in out


DAMAGES = {  # how a results.h5 is damaged (its HDF5 still readable): what the refusal names
    "a series renamed": (lambda f: f.move("series/delta", "series/deltx"), "(series delta: 0 values for the"),
    "a series cut short": (lambda f: (f.__delitem__("series/force"), f.create_dataset("series/force", data=[1.0])),
                           "(series force: 1 values for the"),
    "coordinates gone": (lambda f: f.__delitem__("fields/x"), "not a readable petroll results file ("),
    "steps_written a text": (lambda f: f.attrs.__setitem__("steps_written", "x"),
                             "not a readable petroll results file (invalid literal"),
    "scene gone": (lambda f: f.attrs.__delitem__("scene"), "not a readable petroll results file ("),
}


def test_damaged_results_sweep_and_stress_files_are_refused_in_one_line(cli_main, comm, shared_dir):
    """A run's results.h5 damaged behind HDF5's back (a dataset renamed, cut short or gone, an attribute of
    another type or gone; HDF5 reads each, h5py raises KeyError, ValueError, ...): ``info``, ``export``
    and ``plot`` refuse it in one line naming the file, exit 2 (were tracebacks: a fuzz of random bytes in
    results.h5 gave 57 in 200); likewise a sweep.h5 and a stress.h5 without their datasets. A run stopped
    during its first step (no step written) is described, not a traceback."""
    import shutil
    import warnings

    from petroll.model.limits import PetrollWarning

    scene = petroll.load_scene(ROOT / "runs" / "sphere.toml").replace(
        {"grid.nx": 16, "grid.ny": 16, "grid.allow_coarse": True, "time.distance": 1.2e-3})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PetrollWarning)  # a coarse grid, on purpose: a cheap run
        petroll.run(scene, comm, out=shared_dir / "run")
    for name, (damage, says) in DAMAGES.items():
        where = shared_dir / name.replace(" ", "-")
        if comm.rank == 0:
            shutil.copytree(shared_dir / "run", where)
            with h5py.File(where / "results.h5", "r+") as f:
                damage(f)
        comm.Barrier()
        for verb in (["info"], ["export"], ["plot"]):
            code, _, err = cli_main([*verb, str(where)])
            assert code == 2, (name, verb, err)
            if comm.rank == 0:
                assert err.startswith(f"petroll: error: {where / 'results.h5'}: ") and says in err, (name, err)
                assert err.count("\n") == 1, (name, verb, err)
    if comm.rank == 0:
        with h5py.File(shared_dir / "sweep.h5", "w") as f:
            f.attrs["format"] = "petroll-sweep"
        with h5py.File(shared_dir / "stress.h5", "w") as f:
            f.create_dataset("z", data=[0.0])
            f.create_dataset("von_mises", data=np.zeros((1, 2, 2)))
    comm.Barrier()
    for kind in ("sweep", "stress"):
        code, _, err = cli_main(["plot", str(shared_dir / f"{kind}.h5"), "--out", str(shared_dir / kind)])
        assert code == 2, (kind, err)
        if comm.rank == 0:
            assert err.startswith(f"petroll: error: {shared_dir / f'{kind}.h5'}: not a readable petroll {kind} "
                                  "file (") and err.count("\n") == 1, err
    if comm.rank == 0:
        with h5py.File(shared_dir / "run" / "results.h5", "r+") as f:  # as a run killed in its first step
            f.attrs["steps_written"], f.attrs["fields_written"], f.attrs["complete"] = 0, 0, False
    comm.Barrier()
    code, out, err = cli_main(["info", str(shared_dir / "run")])
    assert code == 0, err
    if comm.rank == 0:
        assert "  steps: none written, partial" in out and "pressure at 0 steps ()" in out, out

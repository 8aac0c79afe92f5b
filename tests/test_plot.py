"""``petroll plot``: PNG figures of a small viscoelastic rolling run, and the missing-results error.

The run is collective (every rank), the plotting happens on rank 0 only."""

import pathlib
import warnings

import pytest


from petroll.cli import main
from petroll.model.scene import parse_scene
from petroll.driver import run


from petroll.plot import plot_results, select_fields

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def rolling_scene():
    """A sphere (R = 10 mm) rolling 1.2 mm at 0.05 m/s on an SLS half-space: 16 steps, fields every 5."""
    return parse_scene({
        "grid": {"nx": 40, "ny": 20, "x": [-0.8e-3, 2.4e-3], "y": [-0.8e-3, 0.8e-3]},
        "material": {"model": "sls", "E0": 10e6, "Einf": 2e6, "nu": 0.5, "tau_relax": 0.01},
        "body": {"shape": "sphere", "radius": 0.01},
        "motion": {"velocity": [0.05, 0.0], "penetration": 2e-5},
        "time": {"steps_per_cell": 1, "distance": 1.2e-3},
        "output": {"every": 5},
    }, source="test_plot")


def png_width(path: pathlib.Path) -> int:
    return int.from_bytes(path.read_bytes()[16:20], "big")  # IHDR width


@pytest.mark.slow
def test_plot_writes_pressure_patches_and_series_pngs(comm, shared_dir):
    results = run(rolling_scene(), comm, shared_dir / "run")
    assert list(results.field_steps) == [0, 5, 10, 15]
    assert select_fields(results) == [0, 1, 2, 3]
    assert select_fields(results, [0.0, 0.0075, 1.0]) == [0, 1, 3]  # nearest saved fields (t = 0.008, 0.024 s)
    if comm.rank != 0:
        return
    paths = plot_results(shared_dir / "run")
    assert [p.name for p in paths] == ["pressure.png", "patches.png", "series.png"]
    for path in paths:
        assert path.parent == shared_dir / "run" / "plots"
        data = path.read_bytes()
        assert data[:8] == PNG_MAGIC, path
        assert len(data) > 10_000, (path, len(data))
    # Four pressure panels side by side by default; two for two requested times: half the width.
    two = plot_results(shared_dir / "run", shared_dir / "two", times=[0.0, 0.016])
    assert two[0] == shared_dir / "two" / "pressure.png"
    assert png_width(paths[0]) == 2 * png_width(two[0])


def test_cli_plot_without_results_exits_2_naming_the_file(comm, capsys, shared_dir):
    missing = shared_dir / "not-a-run"
    code = main(["plot", str(missing)])
    assert code == 2  # on every rank: rank 0's status is broadcast
    if comm.rank == 0:
        err = capsys.readouterr().err
        lines = [line for line in err.splitlines() if line.strip()]
        assert len(lines) == 1 and lines[0].startswith("petroll: error: "), err
        assert lines[0] == f"petroll: error: {missing}: no such file or directory"
        assert not missing.exists()  # no plots directory created


@pytest.mark.slow
def test_stress_sections_lie_on_the_contact_centre_line(comm, shared_dir):
    """The rolling sphere on 20 cells across (an even count: no row of cells on the centre line Y = 0): the
    section of stress.png is on the centre line, the mean of the two rows either side of it, which the
    symmetry of the contact makes equal (read here with h5py); an odd count (21 cells) has a row on it."""
    import h5py
    import numpy as np

    import petroll
    from petroll.io.stress import stress_planes
    from petroll.plot import plot_stress
    from petroll.plot.stress import centre_section

    for ny in (20, 21):
        out = shared_dir / f"ny{ny}"
        run(rolling_scene().replace("grid.ny", ny), comm, out)
        petroll.stress(out, depths=[0.0, 5e-5, 1e-4], comm=comm)
        if comm.rank != 0:
            continue
        for name in ("von_mises", "max_shear"):
            planes = stress_planes(out / "stress.h5", name)
            section, centre = centre_section(out / "stress.h5", name, planes)
            assert centre == 0.0
            with h5py.File(out / "stress.h5") as f:
                middle = [ny // 2 - 1, ny // 2] if ny % 2 == 0 else [ny // 2]
                rows = [f[name][:, :, j] for j in middle]
                assert np.allclose(f["y"][middle].sum(), 0.0, atol=1e-15)
            assert np.allclose(rows[0], rows[-1], rtol=1e-10, atol=1e-10 * rows[0].max())  # symmetric
            assert np.allclose(section, np.mean(rows, axis=0), rtol=1e-12, atol=0)
        assert plot_stress(out / "stress.h5").read_bytes()[:8] == PNG_MAGIC


@pytest.mark.slow
@pytest.mark.serial
@pytest.mark.parametrize("mode", ["full", "read-only"])
def test_on_a_full_or_read_only_disk_plot_says_so_in_one_line_and_keeps_the_earlier_figures(tmp_path, capsys,
                                                                                          monkeypatch, mode):
    """``petroll plot`` on a full (a few bytes free) or read-only file system: was an OSError traceback, and
    on a full disk pressure.png was left truncated (written in place: the good earlier figure lost). Now
    one line, exit 2, the earlier figures byte for byte, no temporary file. A real tmpfs where this process
    may mount one, else simulated (test_fuzz.Disk: a file-size limit, EROFS from the file layer)."""
    from mpi4py import MPI

    from test_fuzz import Disk

    disk = Disk(tmp_path / "disk", monkeypatch)
    try:
        run(rolling_scene(), MPI.COMM_SELF, disk.where / "run")
        assert main(["plot", str(disk.where / "run")]) == 0
        plots = disk.where / "run" / "plots"
        before = {p.name: p.read_bytes() for p in plots.iterdir()}
        capsys.readouterr()
        with disk.state(mode, 2048):
            with warnings.catch_warnings():
                warnings.simplefilter("error")
                code = main(["plot", str(disk.where / "run")])
        (disk.where / "filler").unlink(missing_ok=True)
        lines = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
        why = "Read-only file system" if mode == "read-only" else ("No space left on device" if disk.kind == "tmpfs"
                                                                   else "File too large")
        assert code == 2 and lines == [f"petroll: error: {plots / 'pressure.png'}: cannot write the figure ({why}); "
                                       "free space or give a writable directory"], (disk.kind, lines)
        assert {p.name: p.read_bytes() for p in plots.iterdir()} == before  # nothing lost, nothing left
        print(f"{mode} ({disk.kind}): {lines[0]}")
    finally:
        disk.close()

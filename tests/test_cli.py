"""PETSc options on the command line reach petroll's own TAO (prefix petroll_) and nothing else."""

import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]


def test_sides_and_steady_are_refused_where_a_benchmark_has_none(comm, capsys):
    from petroll.cli import main

    for args, message in [(["tao", "--steady"], "petroll bench tao: --steady applies to petroll bench memory and "
                                                "mpi only"),
                          (["mpi", "--sides", "512"], "petroll bench mpi: --sides applies with --steady only (the "
                                                      "rolling windows are fixed)")]:
        assert main(["bench", *args, "--quick"]) == 2
        if comm.rank == 0:
            assert capsys.readouterr().err == f"petroll: error: {message}\n"


@pytest.mark.slow
@pytest.mark.serial
def test_prefixed_tao_options_override_the_scene_and_failures_are_one_clear_line(tmp_path, cli):
    scene = str(ROOT / "runs" / "hertz.toml")
    done = cli("run", scene, "--out", "ok", "-petroll_tao_type", "blmvm", "-petroll_tao_view", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert "type: blmvm" in done.stdout  # the scene leaves the default (pk): the command line won
    failed = cli("run", scene, "--out", "bad", "-petroll_tao_type", "blmvm", "-petroll_tao_max_it", "2",
                     cwd=tmp_path)
    assert failed.returncode == 2
    lines = failed.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("petroll: error: TAO (blmvm) did not converge")
    assert "Traceback" not in failed.stderr
    assert not (tmp_path / "bad" / "results.h5").exists()


@pytest.mark.slow
@pytest.mark.serial
def test_unprefixed_tao_options_do_not_leak_into_petroll(tmp_path, cli):
    scene = str(ROOT / "runs" / "hertz.toml")
    done = cli("run", scene, "--out", "ok", "-tao_type", "blmvm", "-tao_max_it", "2", "-petroll_tao_view",
                   cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert "Python: petroll.solver.pk.PolonskyKeer" in done.stdout  # the default, untouched by -tao_type


@pytest.mark.slow
@pytest.mark.serial
def test_pk_on_the_command_line_and_its_view(tmp_path, cli):
    """-petroll_tao_type pk reaches TAO as pk's Python type; its view shows its own settings, the
    preconditioner on by default and off with -petroll_pc_circulant 0, and the monitor the true objective."""
    scene = str(ROOT / "runs" / "hertz.toml")
    done = cli("run", scene, "--out", "on", "-petroll_tao_type", "pk", "-petroll_tao_view",
                   "-petroll_tao_monitor", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert "Polonsky-Keer" in done.stdout and "type: preonly" in done.stdout
    assert "petroll.solver.petsc.CirculantInverse" in done.stdout and "gmres" not in done.stdout
    values = [float(line.split("Function value:")[1].split(",")[0]) for line in done.stdout.splitlines()
              if "Function value:" in line]
    assert values[0] == 0 and min(values) < 0  # the objective from p = 0 down: real values, not 0.
    off = cli("run", scene, "--out", "off", "-petroll_pc_circulant", "0", "-petroll_tao_view", cwd=tmp_path)
    assert off.returncode == 0, off.stderr
    assert "preconditioner: none" in off.stdout and "CirculantInverse" not in off.stdout


def test_ranks_are_refused_beside_benchmarks_other_than_mpi_memory_and_sliding(comm, capsys):
    from petroll.cli import main

    assert main(["bench", "tao", "--quick", "--ranks", "1,2"]) == 2
    if comm.rank == 0:
        err = capsys.readouterr().err
        assert err == ("petroll: error: petroll bench tao: --ranks applies to petroll bench mpi, memory and "
                       "sliding only\n")


@pytest.mark.slow
@pytest.mark.serial
def test_fft_workers_on_the_command_line(tmp_path, cli):
    """-petroll_fft_workers 2 runs (same answer as the default) and exits promptly (its kept TAO objects
    destroyed before PETSc finalises); 0 is one clear line."""
    import time

    import h5py

    scene = str(ROOT / "runs" / "hertz.toml")
    start = time.perf_counter()
    two = cli("run", scene, "--out", "two", "-petroll_fft_workers", "2", cwd=tmp_path)
    assert two.returncode == 0, two.stderr
    assert time.perf_counter() - start < 60
    one = cli("run", scene, "--out", "one", "-petroll_fft_workers", "1", cwd=tmp_path)
    with h5py.File(tmp_path / "one" / "results.h5") as a, h5py.File(tmp_path / "two" / "results.h5") as b:
        assert abs(a["series/force"][-1] / b["series/force"][-1] - 1) < 1e-12
    bad = cli("run", scene, "--out", "bad", "-petroll_fft_workers", "0", cwd=tmp_path)
    assert bad.returncode == 2 and "Traceback" not in bad.stderr
    assert bad.stderr.strip() == "petroll: error: -petroll_fft_workers 0: the FFT threads per rank must be >= 1"

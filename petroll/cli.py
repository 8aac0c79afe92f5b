"""The ``petroll`` command: a thin layer over the Python API.

    petroll run SCENE.toml [--out DIR] [--overwrite] [--estimate-error] [PETSc options, e.g. -petroll_tao_type gpcg]
    petroll restart CHECKPOINT.h5|DIR [--out DIR [--overwrite]] [--scene NEW.toml] [PETSc options]
    petroll launch mpirun -n N petroll run ...   the launch line run so that SIGTERM/SIGINT reach the ranks
                            and its exit status is theirs (143, 130; docs/cluster.md)
    petroll check SCENE.toml [--ranks N]   estimate the contact, its resolution, the steps and the memory
                            per rank without running (docs/accuracy.md)
    petroll keys            print the scene reference (docs/scene.md) generated from the schema
    petroll stability [--fast] [--out DIR]   the stability map (docs/stability.md): CSV and Markdown in DIR
    petroll plot PATH [--out DIR] [--times T1,T2,...] [--format png|pdf|svg]   figures (needs matplotlib) of a
                            run directory or its results.h5, a sweep directory, or a stress.h5
    petroll info DIR        what a run directory holds: scene, steps, last values, fields, checkpoints
    petroll export DIR --csv [--field NAME [--step N]] [--out FILE]   the series (or one saved field) as CSV
    petroll sweep SCENE.toml --vary KEY=SPEC [--vary KEY2=SPEC2] [--out DIR] [--estimate-error]   one
                            scene over values of a key; with KEY2 a curve per value of it (docs/sweep.md)
    petroll stress DIR [--step N] [--depth z1,z2,... | --depths auto] [--nu NU]   stresses below a saved
                            pressure field: DIR/stress.h5 and DIR/stress.png
    petroll bench tao|warm|skips|peers|precision|growth|mpi|memory|append|layer|steady|steady-growth|
                            estimate|accuracy|periodic|sliding [--out DIR] [--quick]   benchmarks
                            (docs/benchmarks.md); --quick: a seconds-long check that it runs; bench memory
                            --steady: steady solves; bench sliding --ranks/--sides: the rough solve's memory
                            per rank
    petroll material fit DMA.csv [--terms N | --per-decade K] [--nu NU] [--shift LAW|auto:T_REF]
                            [--tolerance K] [--einf E | --einf-from-data] [--columns C=NAME,...]
                            [--units C=UNIT,...] [--out FILE.toml]
                            a Prony series fitted to DMA data (petroll's CSV, or as pyvisco and
                            instruments export it): the [material] block (docs/materials.md)

Options that argparse does not know are handed to PETSc's options database. A user mistake (bad scene,
unreachable load, solver failure) prints one line ``petroll: error: ...`` and exits with status 2 (a bad
command line too); a scene that runs where the formulation loses accuracy prints ``petroll: warning: ...``.
Under MPI an error raised on every rank is printed once; one raised on some ranks only (the others wait in
a collective) is printed by the failing rank, which then aborts the whole job (MPI Abort) instead of
hanging. A run stopped by SIGTERM or SIGINT finishes its step, writes a checkpoint, prints how to continue
and exits with 128 + the signal number (143, 130); docs/checkpoints.md.
"""

from __future__ import annotations

import argparse
import math
import os
import signal
import sys
import time
import warnings

from petroll.cli_parser import parser


def _on_rank0(action, comm) -> int:
    """Verbs that only read and write files (plot, material): rank 0 runs ``action()``; every rank
    returns rank 0's exit status (2 and one line on a PetrollError)."""
    from petroll.errors import PetrollError

    code = 1
    try:
        if comm.rank == 0:
            try:
                action()
                code = 0
            except PetrollError as exc:
                print(f"petroll: error: {' '.join(str(exc).split())}", file=sys.stderr)
                code = 2
        else:
            code = 0
    finally:
        code = comm.bcast(code, root=0)
    return code


def _plot(args: argparse.Namespace) -> None:
    """``petroll plot``: the figures of a run, a sweep or a stress file, whichever ``args.path`` is."""
    import pathlib

    from petroll.io.export import file_kind
    from petroll.plot import plot_results, plot_stress, plot_sweep

    kind, file = file_kind(args.path)
    if kind == "run":
        paths = plot_results(file.parent, args.out, args.times, args.format)
    else:
        out = pathlib.Path(args.out) if args.out else file.parent
        out.mkdir(parents=True, exist_ok=True)
        if kind == "sweep":
            from petroll.studies.sweep import SweepTable

            paths = [plot_sweep(SweepTable.open(file), out / f"sweep.{args.format}")]
        else:
            paths = [plot_stress(file, out / f"stress.{args.format}")]
    print("petroll: wrote " + ", ".join(str(p) for p in paths))


def _info(args: argparse.Namespace) -> None:
    """``petroll info``: what a run directory holds, a few lines."""
    from petroll.io.export import run_contents

    found = run_contents(args.dir)
    r, s = found.results, found.results.series
    n, last = len(s["t"]), len(s["t"]) - 1
    state = "complete (the run finished)" if r.complete else "partial (still running, or stopped or killed)"
    per = "/m" if r.line else ""
    lines = [f"{found.directory}: a petroll run, written by petroll {r.version or '0.1.0'}",
             f"  scene: {r.scene_file or '(not recorded)'}; its text is in {r.path.name} (attribute scene)"]
    if n:
        lines += [f"  steps: {n} written (0 ... {last}), {state}" + (", the steady state solved directly"
                                                                     if r.solved_steady else ""),
                  f"  last step {last}: t = {s['t'][-1]:.6g} s, rolled {s['distance'][-1]:.6g} m, force "
                  f"{s['force'][-1]:.6g} N{per}, mu_r {s['mu_r'][-1]:.5g}, penetration {s['delta'][-1]:.6g} m"]
    else:  # a run stopped or killed during its first step
        lines.append(f"  steps: none written, {state}")
    lines.append(f"  saved fields: {', '.join(r.fields)} at {len(r.field_steps)} steps "
                 f"({', '.join(str(int(k)) for k in r.field_steps)}); results.xdmf for ParaView")
    if found.checkpoints:
        steps = ", ".join(str(step) for step, _ in found.checkpoints)
        where = found.checkpoints[-1][1].parent
        lines.append(f"  checkpoints: {len(found.checkpoints)} (steps {steps}) in {where}"
                     + ("" if r.complete else f"; petroll restart {found.directory} continues from the "
                                              "newest"))
    else:
        lines.append("  checkpoints: none")
    lines.append(f"  other files: {', '.join(found.others) or 'none'}")
    if r.error_estimate is not None:
        lines += ["  " + line for line in estimate_lines(r.error_estimate)]
    lines += [f"  warning: {line}" for line in r.warnings]
    print("\n".join(lines))


def _export(args: argparse.Namespace) -> None:
    """``petroll export``: the series, or one saved field, as CSV."""
    from petroll.io.export import open_results, write_field_csv, write_series_csv

    results = open_results(args.dir)
    if args.step is not None and args.field is None:
        args.field = "pressure"
    if args.field is None:
        path = write_series_csv(results, args.out or results.path.parent / "series.csv")
        what = f"{len(results.series['t'])} steps x {len(results.series)} series"
    else:
        step = int(results.field_steps[-1]) if args.step is None else args.step
        default = results.path.parent / f"{args.field}-step-{step}.csv"
        path = write_field_csv(results, args.field, step, args.out or default)
        what = f"{args.field} at step {step}, {len(results.x) * len(results.y)} cells"
    print(f"petroll: wrote {path} ({what})")


def _material_fit(args: argparse.Namespace) -> None:
    """``petroll material fit``: read, fit, write the block (or print it), draw the figure, report."""
    import pathlib

    from petroll.io.journal import atomic_write
    from petroll.io.rundir import clean_temporaries
    from petroll.model import dma
    from petroll.plot import plot_fit, plot_shifts  # matplotlib imported only when drawing

    shift = dma.parse_shift(args.shift) if args.shift else None
    columns = dma.parse_mapping("--columns", args.columns, "NAME") if args.columns else None
    units = dma.parse_mapping("--units", args.units, "UNIT") if args.units else None
    data = dma.read_dma(args.csv, shift, args.tolerance, columns, units)
    einf = "data" if args.einf_from_data else args.einf
    fit, warnings = dma.fit_dma(data, args.terms, args.per_decade, args.nu, einf)
    text = dma.material_toml(fit, data.shift, args.csv, data.T_ref, warnings, data.found)
    report = sys.stdout
    if args.out:
        out = pathlib.Path(args.out)
        try:
            out.parent.mkdir(parents=True, exist_ok=True)
            clean_temporaries(out.parent, [out.name])  # of a writer killed earlier
            atomic_write(out, lambda tmp: tmp.write_text(text, encoding="utf-8"))
        except OSError as exc:
            raise dma.DMAError(f"--out {out}: cannot write it ({exc.strerror})") from None
    else:
        print(text, end="", flush=True)
        report = sys.stderr  # the block alone on stdout, ready to redirect
    png = None  # the figure: --plot, else beside --out, else none
    if args.plot or args.out:
        png = pathlib.Path(args.plot or pathlib.Path(args.out).with_suffix(".png"))
    drawn = [] if png is None else [png] + (
        [png.with_name(png.stem + "-shift.png")] if data.found is not None else [])
    try:
        if drawn:
            plot_fit(data, fit, drawn[0])
        if len(drawn) > 1:
            plot_shifts(data, drawn[1])
    except ImportError:
        print("petroll: warning: matplotlib is not installed: no plot", file=sys.stderr)
        drawn = ["none"]
    print(dma.report(data, fit) + f" Block: {args.out or 'printed above'}; plot: "
          f"{', '.join(str(p) for p in drawn) or 'none (--plot PNG draws one)'}", file=report)
    for line in warnings:  # also in the block, as comments
        print(f"petroll: warning: {line}", file=sys.stderr)


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    args, petsc_args = parser().parse_known_args(argv)
    if args.verb == "launch":  # no MPI here: the launched command has it
        from petroll.launch import launch

        return launch(args.command + petsc_args)
    stray = [a for a in petsc_args if a.startswith("--")]
    if stray:
        parser().error(f"unknown option {stray[0]} (PETSc options start with a single dash)")

    import petsc4py

    from petroll.solver.pk import command_line

    petsc4py.init([sys.argv[0], *command_line(petsc_args)])
    signal.signal(signal.SIGPIPE, signal.SIG_IGN)  # Python's own setting, which PETSc's handler replaced
    try:
        code = _verbs(args)
        sys.stdout.flush()  # here, not at exit, where a closed pipe could not be answered
        return code
    except BrokenPipeError:  # stdout's reader stopped reading (``petroll check S | head -1``)
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no second error at exit
        return 128 + signal.SIGPIPE  # as a shell reports a command ended by SIGPIPE


def _verbs(args: argparse.Namespace) -> int:
    """Every verb but ``launch``, once PETSc is initialised (every rank)."""
    from mpi4py import MPI

    from petroll.errors import PetrollError
    from petroll.model.limits import PetrollWarning

    comm = MPI.COMM_WORLD
    if args.verb in ("plot", "info", "export"):
        return _on_rank0(lambda: {"plot": _plot, "info": _info, "export": _export}[args.verb](args), comm)
    if args.verb == "material":
        return _on_rank0(lambda: _material_fit(args), comm)
    errors = comm.Dup() if comm.size > 1 else None  # only for agreeing on an error (see _failed)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("always", PetrollWarning)
            warnings.showwarning = _warning_line(comm)
            return _main(args, comm)
    except PetrollError as exc:
        return _failed(comm, errors, "petroll: error: " + " ".join(str(exc).splitlines()), 2)
    except KeyboardInterrupt:  # SIGINT before a run handles it (or a second one during it)
        return _failed(comm, errors, "petroll: interrupted by SIGINT", 130)
    except MemoryError:
        return _failed(comm, errors, "petroll: error: out of memory: the scene needs more memory than this "
                       "machine has; use fewer cells ([grid] nx, ny) or more ranks (mpirun -n)", 2)
    except BrokenPipeError:
        raise  # not a failure of this rank's work: main ends quietly
    except Exception:
        if errors is None:
            raise  # a bug: its traceback, as always
        import traceback

        return _failed(comm, errors, traceback.format_exc().rstrip(), 1)
    finally:
        if errors is not None:
            errors.Free()


ERROR_AGREEMENT_S = 3.0
"""How long a rank that failed waits for the others to fail too before it aborts the job (s)."""


def _failed(comm, errors, message: str, code: int) -> int:
    """This rank raised: print the message once and return ``code`` if every rank raised (a collective
    error, e.g. a bad scene: they all reach the barrier of ``errors``, a communicator used for nothing else);
    otherwise the others wait in some collective: print it, then abort all ranks (MPI Abort)."""
    if errors is None:  # one rank
        print(message, file=sys.stderr, flush=True)
        return code
    request = errors.Ibarrier()
    deadline = time.monotonic() + ERROR_AGREEMENT_S
    while not request.Test():
        if time.monotonic() > deadline:
            lines = message.splitlines()
            lines[-1] += f" (on rank {comm.rank} of {comm.size} only; ending all ranks)"
            print("\n".join(lines), file=sys.stderr, flush=True)
            comm.Abort(code)
        time.sleep(0.005)
    if comm.rank == 0:
        print(message, file=sys.stderr, flush=True)
    return code


def _test_failure(comm) -> None:
    """Test hook: PETROLL_TEST_FAIL_RANK=R makes rank R alone raise a SolverError here (=R:crash, a
    RuntimeError), as a rank-local failure would; tests/test_bad_input.py checks that all ranks end."""
    hook = os.environ.get("PETROLL_TEST_FAIL_RANK")
    if not hook:
        return
    rank, _, kind = hook.partition(":")
    if rank.strip() == str(comm.rank):
        if kind == "crash":
            raise RuntimeError(f"test failure on rank {comm.rank} (PETROLL_TEST_FAIL_RANK)")
        from petroll.errors import SolverError

        raise SolverError(f"test failure on rank {comm.rank} (PETROLL_TEST_FAIL_RANK)")


def _warning_line(comm):
    """warnings.showwarning for the command line: PetrollWarnings as one line, on rank 0."""
    from petroll.model.limits import PetrollWarning

    original = warnings.showwarning

    def show(message, category, filename, lineno, file=None, line=None):
        if issubclass(category, PetrollWarning):
            if comm.rank == 0:
                print(f"petroll: warning: {message}", file=sys.stderr, flush=True)
        else:
            original(message, category, filename, lineno, file, line)

    return show


def _main(args: argparse.Namespace, comm) -> int:
    """The verbs other than plot (every rank)."""
    if args.verb == "keys":
        from petroll.model.reference import scene_reference

        if comm.rank == 0:
            print(scene_reference(), end="")
        return 0
    if args.verb == "check":
        from petroll.model.preflight import check
        from petroll.model.scene import load_scene

        found = check(load_scene(args.scene), ranks=args.ranks or comm.size)
        if comm.rank == 0:
            print("\n".join(f"petroll: {line}" if k == 0 else f"  {line}" for k, line in enumerate(found.lines())))
        return 0
    if args.verb == "bench":
        import pathlib

        from petroll.bench.verbs import run as bench

        bench(args.which, pathlib.Path(args.out), comm, args.quick, args.ranks, args.sides, args.steady)
        return 0
    if args.verb == "sweep":
        from petroll.studies.family import command

        return command(args.scene, args.vary, args.out, args.quiet, comm, args.transient, args.estimate_error)
    if args.verb == "stress":
        return _stress(args, comm)
    if args.verb == "stability":
        from petroll.studies.stability import command

        return command(args.out, args.fast, comm)
    from petroll.driver import RunFailed, run
    from petroll.io.checkpoint import RunInterrupted, StopRequest
    from petroll.io.results import Results
    from petroll.model.scene import load_scene
    from petroll.solver.allocation import LargeBlocksMapped
    from petroll.studies.target import asks_target, targeted

    start = time.perf_counter()
    if args.verb == "restart":
        scene, checkpoint, out = _restart_inputs(args, comm)
    else:
        with LargeBlocksMapped(True):  # a scene read allocates once, its grid unknown until read
            scene, checkpoint, out = load_scene(args.scene), None, args.out
        if asks_target(scene):  # its pilot before the note: the note says the grid chosen for the target
            scene = targeted(scene, comm)
        if scene.sizing is not None and comm.rank == 0:  # the grid petroll chose, before the run
            print(f"petroll: {scene.source}: {scene.sizing.note}", flush=True)
    _test_failure(comm)
    stop = StopRequest()
    try:
        with stop.handling():
            results = run(scene, comm, out, progress=not args.quiet and sys.stderr.isatty(),
                          restart=checkpoint, stop=stop, overwrite=args.overwrite,
                          estimate_error=getattr(args, "estimate_error", False))
    except RunInterrupted as exc:
        if comm.rank == 0:
            estimate = " --estimate-error" if getattr(args, "estimate_error", False) else ""
            how = (f"continue with: petroll restart {exc.checkpoint}{estimate}" if exc.checkpoint is not None
                   else f"run it again: petroll run {scene.source}{estimate}")
            print(f"petroll: {scene.source}: {exc}; {how}", file=sys.stderr)
        return exc.exit_code
    except RunFailed as exc:  # the summary of the steps kept, then the one-line error
        if comm.rank == 0:
            print(summary(scene, Results.open(exc.results), wall=time.perf_counter() - start))
        raise
    if comm.rank == 0:
        print(summary(scene, results, wall=time.perf_counter() - start, resumed=checkpoint))
        if results.error_estimate is not None:
            print("petroll: " + "\n".join(estimate_lines(results.error_estimate)))
    return 0


def estimate_lines(estimate: dict) -> list[str]:
    """results.h5's error_estimate group as lines (``petroll run --estimate-error`` prints them after the
    summary, ``petroll info`` indented): a heading naming the grids, the integrator and the order taken
    where none is observed; a line where no 4x grid checked the asymptotic range; then each quantity's value
    +- its discretisation error (with the order where it was observed; marked where its range was not
    checked; a steady sliding solve's mu_r: how much of its error is |mu_r - mu_lateral|), or why it has
    none. Files written before the integrator's order was stored read as order 2."""
    group = estimate[""]
    if group.get("failed"):
        return [f"no error estimate: {group['failed']}"]
    grids = ", ".join(f"{nx} x {ny}" for nx, ny in group["grids"])
    known = {name: float(estimate[name].get("known_order", 2.0))
             for name in ("force", "delta", "mu_r", "p_max") if name in estimate}
    common = known["mu_r"]
    others = ", ".join(f"{name} {order:g}" for name, order in known.items() if order != common)
    integrator = f'integrator "{group["integrator"]}": ' if group.get("integrator") else ""
    lines = [f"error estimate of the last step (grids {grids}; {integrator}order {common:g}"
             + (f" ({others})" if others else "") + ", 1 for what counts cells, unless observed):"]
    if group.get("range_unchecked"):
        lines.append(f"  the asymptotic range was not checked ({group['range_unchecked']}): the errors "
                     "assume the orders above (docs/accuracy.md)")
    for name in ("force", "delta", "mu_r", "p_max", "area", "lead", "trail"):
        if name in estimate:
            q = estimate[name]
            observed = (f", observed order {q['order']:.2f}" if q["observed_order"] and math.isfinite(q["order"])
                        else "")
            unchecked = "" if q.get("range_checked", True) else ", asymptotic range not checked"
            lateral = (f", {q['lateral_difference']:.1e} of it |mu_r - mu_lateral|"
                       if q.get("lateral_difference", 0.0) > 0 else "")
            lines.append(f"  {name} {q['value']:.4e} " + (
                "(the grids are not in the asymptotic range: no estimate)" if math.isnan(q["error"]) else
                f"+- {q['error']:.1e} (discretisation{observed}{unchecked}{lateral})"))
    return lines


def _stress(args: argparse.Namespace, comm) -> int:
    """``petroll stress``: every rank computes its rows; rank 0 draws stress.png and prints the maxima."""
    from petroll.driver import stress
    from petroll.errors import PetrollError

    found = stress(args.dir, args.step, args.depth if args.depth is not None else args.depths, args.nu, comm)
    if comm.rank == 0:
        from petroll.plot import plot_stress

        try:
            drawn = f" and {plot_stress(found.path)}"
        except PetrollError as exc:
            drawn = f" (no figure: {exc})"
        z = found.z
        print(f"petroll: stresses below step {found.step} (t = {found.t:.4g} s, nu = {found.nu:g}, peak "
              f"pressure {found.p_max:.6g} Pa) at {len(z)} depth{'s' * (len(z) != 1)} from {z[0]:.4g} to "
              f"{z[-1]:.4g} m: "
              f"max von Mises {found.von_mises_max:.6g} Pa at (x, y, z) = "
              f"({', '.join(f'{v:.4g}' for v in found.von_mises_at)}) m, max shear (Tresca) "
              f"{found.max_shear_max:.6g} Pa at ({', '.join(f'{v:.4g}' for v in found.max_shear_at)}) m. "
              f"Wrote {found.path}{drawn}")
    comm.Barrier()  # the others wait for the figure: a next collective call finds them in step
    return 0


def _restart_inputs(args: argparse.Namespace, comm):
    """``petroll restart``: (scene, checkpoint, output directory), all checked before anything is written."""
    from petroll.io.checkpoint import latest_checkpoint, read_checkpoint, restart_scene, run_directory

    path = latest_checkpoint(args.checkpoint)
    checkpoint = read_checkpoint(path, comm)
    scene = restart_scene(checkpoint, args.scene)
    return scene, checkpoint, args.out if args.out is not None else run_directory(path)


def summary(scene, results, wall: float, resumed=None) -> str:
    """One paragraph on a finished run: its extent, the last (steady) values, wall time and output path;
    ``resumed``: the checkpoint a restart continued from (its step is named)."""
    from petroll.model.clock import TimeMode

    s = results.series
    n = len(s["t"])
    if scene.time.mode is TimeMode.STEADY:
        how = "the steady state solved directly ([time] mode = \"steady\")"
    else:
        how = f"{n} step{'s' * (n != 1)} to t = {s['t'][-1]:.4g} s over {s['distance'][-1]:.4g} m of rolling"
    steady = scene.time.steady is not None and (
        (scene.time.end is not None and s["t"][-1] < scene.time.end * (1 - 1e-9))
        or (scene.time.distance is not None and s["distance"][-1] < scene.time.distance * (1 - 1e-9)))
    state = "steady state reached, " if steady and results.complete else ""
    if not results.complete:
        state = "partial: the run stopped before its end, results.h5 has complete = false; "
    line = scene.grid.line  # plane strain: per unit length, the penetration relative to the datum
    force, area = ("N/m", "contact width {:.4g} m") if line else ("N", "contact area {:.4g} m^2")
    if resumed is not None:
        how = f"resumed after step {resumed.step} (t = {resumed.t:.4g} s; {resumed.path}), {how}"
    g = scene.grid
    if g.topology.statistics:  # a periodic cell: sliding friction, area fraction, no single patch
        resisting = f"friction mu {s['mu_r'][-1]:.4e}"
        if results.solved_steady and "mu_lateral" in (results.rough or {}):  # mu_r: the dissipation's
            resisting += f" (from the dissipation; the lateral force's {results.rough['mu_lateral'][-1]:.4e})"
        patch = f"area fraction A/A0 {s['area'][-1] / ((g.x1 - g.x0) * (g.y1 - g.y0)):.4g}"
    else:
        resisting = f"mu_r {s['mu_r'][-1]:.4e}"
        patch = (f"patch from {s['trail'][-1]:.4g} to {s['lead'][-1]:.4g} m along the motion"
                 if s["area"][-1] > 0 else "no contact")
    return (f"petroll: {scene.source}: {how} ({state}wall time {wall:.1f} s). Last step: force "
            f"{s['force'][-1]:.6g} {force} at penetration {s['delta'][-1]:.6g} m"
            f"{' (to the datum)' if line else ''}, {resisting}, "
            f"{area.format(s['area'][-1])}, {patch}, max pressure "
            f"{s['p_max'][-1]:.6g} Pa; {int(s['applications'].sum())} operator applications in all. "
            f"Results: {results.path}")


if __name__ == "__main__":
    sys.exit(main())

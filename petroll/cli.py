"""The ``petroll`` command: a thin layer over the Python API.

    petroll run SCENE.toml [--out DIR] [PETSc options, e.g. -petroll_tao_type gpcg -petroll_tao_monitor]
    petroll keys            print the scene reference (docs/scene.md) generated from the schema
    petroll plot DIR [--out PLOTS] [--times T1,T2,...]   PNG figures of DIR/results.h5 (needs matplotlib)

Options that argparse does not know are handed to PETSc's options database. A user mistake (bad scene,
unreachable load, solver failure) prints one line ``petroll: error: ...`` and exits with status 2.
"""

from __future__ import annotations

import argparse
import sys
import time


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="petroll", description=__doc__.split("\n\n")[0],
                                     epilog="PETSc options (-petroll_tao_type, -log_view, ...) may follow.")
    verbs = parser.add_subparsers(dest="verb", required=True)
    run = verbs.add_parser("run", help="run a scene and write DIR/results.h5")
    run.add_argument("scene", help="scene file (TOML)")
    run.add_argument("--out", help="output directory (default: the scene's [output] dir)")
    run.add_argument("--quiet", action="store_true", help="no progress line (also off when not a terminal)")
    verbs.add_parser("keys", help="print the scene reference generated from the schema (Markdown)")
    bench = verbs.add_parser("bench", help="run a benchmark, print its table and write CSV (docs/benchmarks.md)")
    bench.add_argument("which", choices=["tao"], help="tao: every TAO type on the Hertz step")
    bench.add_argument("--out", default="results/bench", help="directory for the CSV files")
    plot = verbs.add_parser("plot", help="write PNG figures of a run (pressure maps, patch outlines, series)")
    plot.add_argument("dir", help="a run's output directory (holding results.h5)")
    plot.add_argument("--out", help="directory for the PNG files (default: DIR/plots)")
    plot.add_argument("--times", type=_seconds, help="comma-separated times in s: draw the saved pressure "
                      "fields nearest to them (default: up to 4 spread over the run)")
    return parser


def _seconds(text: str) -> list[float]:
    try:
        return [float(item) for item in text.split(",") if item.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated seconds, got {text!r}") from None


def _plot(args: argparse.Namespace, comm) -> int:
    """``petroll plot``: rank 0 draws; every rank returns rank 0's exit status."""
    from petroll.errors import PetrollError

    code = 1
    try:
        if comm.rank == 0:
            from petroll.plot import plot_results

            try:
                paths = plot_results(args.dir, args.out, args.times)
                print("petroll: wrote " + ", ".join(str(p) for p in paths))
                code = 0
            except PetrollError as exc:
                print(f"petroll: error: {exc}", file=sys.stderr)
                code = 2
        else:
            code = 0
    finally:
        code = comm.bcast(code, root=0)
    return code


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    args, petsc_args = _parser().parse_known_args(argv)
    stray = [a for a in petsc_args if a.startswith("--")]
    if stray:
        _parser().error(f"unknown option {stray[0]} (PETSc options start with a single dash)")

    import petsc4py

    petsc4py.init([sys.argv[0], *petsc_args])
    from mpi4py import MPI

    from petroll.errors import PetrollError

    comm = MPI.COMM_WORLD
    if args.verb == "plot":
        return _plot(args, comm)
    try:
        if args.verb == "keys":
            from petroll.docs import scene_reference

            if comm.rank == 0:
                print(scene_reference(), end="")
            return 0
        if args.verb == "bench":
            import pathlib

            from petroll.bench import tao_types

            tao_types(pathlib.Path(args.out), comm)
            return 0
        from petroll.scene import load_scene
        from petroll.simulation import run

        start = time.perf_counter()
        scene = load_scene(args.scene)
        results = run(scene, comm, args.out, progress=not args.quiet and sys.stderr.isatty())
        if comm.rank == 0:
            print(summary(scene, results, wall=time.perf_counter() - start))
        return 0
    except PetrollError as exc:
        if comm.rank == 0:
            print(f"petroll: error: {exc}", file=sys.stderr)
        return 2


def summary(scene, results, wall: float) -> str:
    """One paragraph on a finished run: its extent, the last (steady) values, wall time and output path."""
    s = results.series
    n = len(s["t"])
    steady = scene.time.steady is not None and (
        (scene.time.end is not None and s["t"][-1] < scene.time.end * (1 - 1e-9))
        or (scene.time.distance is not None and s["distance"][-1] < scene.time.distance * (1 - 1e-9)))
    state = "steady state reached, " if steady else ""
    return (f"petroll: {scene.source}: {n} step{'s' * (n != 1)} to t = {s['t'][-1]:.4g} s over {s['distance'][-1]:.4g} m "
            f"of rolling ({state}wall time {wall:.1f} s). Last step: force {s['force'][-1]:.6g} N at penetration "
            f"{s['delta'][-1]:.6g} m, mu_r {s['mu_r'][-1]:.4e}, contact area {s['area'][-1]:.4g} m^2, "
            f"patch from {s['trail'][-1]:.4g} to {s['lead'][-1]:.4g} m along the motion, max pressure "
            f"{s['p_max'][-1]:.6g} Pa; {int(s['applications'].sum())} operator applications in all. "
            f"Results: {results.path}")


if __name__ == "__main__":
    sys.exit(main())

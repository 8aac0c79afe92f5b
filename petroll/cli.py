"""The ``petroll`` command: a thin layer over the Python API.

    petroll run SCENE.toml [--out DIR] [PETSc options, e.g. -petroll_tao_type gpcg -petroll_tao_monitor]
    petroll keys            print the scene reference (docs/scene.md) generated from the schema

Options that argparse does not know are handed to PETSc's options database. A user mistake (bad scene,
unreachable load, solver failure) prints one line ``petroll: error: ...`` and exits with status 2.
"""

from __future__ import annotations

import argparse
import sys


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="petroll", description=__doc__.split("\n\n")[0],
                                     epilog="PETSc options (-petroll_tao_type, -log_view, ...) may follow.")
    verbs = parser.add_subparsers(dest="verb", required=True)
    run = verbs.add_parser("run", help="run a scene and write DIR/results.h5")
    run.add_argument("scene", help="scene file (TOML)")
    run.add_argument("--out", help="output directory (default: the scene's [output] dir)")
    run.add_argument("--quiet", action="store_true", help="no progress line (also off when not a terminal)")
    verbs.add_parser("keys", help="print the scene reference generated from the schema (Markdown)")
    return parser


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
    try:
        if args.verb == "keys":
            from petroll.docs import scene_reference

            if comm.rank == 0:
                print(scene_reference(), end="")
            return 0
        from petroll.scene import load_scene
        from petroll.simulation import run

        scene = load_scene(args.scene)
        results = run(scene, comm, args.out, progress=not args.quiet and sys.stderr.isatty())
        if comm.rank == 0:
            s = results.series
            print(f"petroll: {scene.source}: force {s['force'][-1]:.6g} N, penetration {s['delta'][-1]:.6g} m, "
                  f"contact area {s['area'][-1]:.6g} m^2, max pressure {s['p_max'][-1]:.6g} Pa "
                  f"({int(s['iterations'][-1])} TAO iterations); results in {results.path}")
        return 0
    except PetrollError as exc:
        if comm.rank == 0:
            print(f"petroll: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())

"""The ``petroll`` command's arguments: every verb's options, their help and their types (petroll.cli runs
them). A command-line mistake is one line, ``petroll: error: ...``, exit status 2."""

from __future__ import annotations

import argparse
import math

FIGURE_FORMATS = ("png", "pdf", "svg")


class _Parser(argparse.ArgumentParser):
    """Command-line mistakes as one line ``petroll: error: ...`` (exit status 2), without the usage text."""

    def error(self, message: str):
        verb = self.prog.partition(" ")[2]
        self.exit(2, f"petroll: error: {' '.join(message.split())} (petroll {verb + ' ' if verb else ''}"
                     "--help lists what is allowed)\n")


def parser() -> argparse.ArgumentParser:
    """The parser of every verb (``petroll --help``)."""
    from petroll import __version__

    parser = _Parser(prog="petroll", description="The ``petroll`` command: a thin layer over the Python API.",
                     epilog="PETSc options (-petroll_tao_type, -log_view, ...) may follow.")
    parser.add_argument("--version", action="version", version=f"petroll {__version__}")
    verbs = parser.add_subparsers(dest="verb", required=True)
    for add in (_run_verbs, _study_verbs, _material_verbs, _file_verbs):
        add(verbs)
    return parser


def _scene_run_options(verb, out: str, estimate: str) -> None:
    """What run and sweep share: the scene, --out, --quiet and --estimate-error (with their help texts)."""
    verb.add_argument("scene", help="scene file (TOML)")
    verb.add_argument("--out", help=out)
    verb.add_argument("--quiet", action="store_true", help="no progress line (also off when not a terminal)")
    verb.add_argument("--estimate-error", action="store_true", help=estimate)


def _run_verbs(verbs) -> None:
    """run, restart, keys."""
    run = verbs.add_parser("run", help="run a scene and write DIR/results.h5")
    _scene_run_options(run, "output directory (default: the scene's [output] dir)", "also solve on grids 2x "
                       "(and 4x) coarser and report the discretisation error of the last step's values "
                       "(docs/accuracy.md)")
    run.add_argument("--overwrite", action="store_true", help="replace the results of another scene in the "
                     "output directory (refused without it)")
    restart = verbs.add_parser("restart", help="continue a run from a checkpoint to its end "
                               "(docs/checkpoints.md)")
    restart.add_argument("checkpoint", help="a checkpoint file, or a run directory (its newest checkpoint)")
    restart.add_argument("--out", help="output directory (default: the run directory of the checkpoint)")
    restart.add_argument("--scene", help="scene file replacing the checkpoint's own; it may change only "
                         "[time] end, distance, steady, max_steps and [output] dir, every, checkpoint_every, "
                         "keep")
    restart.add_argument("--quiet", action="store_true", help="no progress line (also off when not a "
                         "terminal)")
    restart.add_argument("--overwrite", action="store_true", help="with --out: replace the results of another "
                         "run there (refused without it)")
    restart.add_argument("--estimate-error", action="store_true", help="as for run: at the end, the "
                         "discretisation error of the last step's values (docs/accuracy.md)")
    launch = verbs.add_parser("launch", help="run an MPI launch line (e.g. mpirun -n 4 petroll run ...) so "
                              "that SIGTERM/SIGINT reach the ranks and its exit status is theirs (143/130; "
                              "docs/cluster.md)")
    launch.add_argument("command", nargs=argparse.REMAINDER, help="the launch line")
    check = verbs.add_parser("check", help="estimate the contact, cells per contact half-width, steps and "
                             "memory per rank without running (docs/accuracy.md)")
    check.add_argument("scene", help="scene file (TOML)")
    check.add_argument("--ranks", type=_positive(int), help="ranks the memory is predicted for (default: "
                       "those of this command)")
    verbs.add_parser("keys", help="print the scene reference generated from the schema (Markdown)")


def _study_verbs(verbs) -> None:
    """stability, bench, sweep."""
    stability = verbs.add_parser("stability", help="sweep the stability map, write CSV and Markdown "
                                 "(docs/stability.md); exit status 1 if a run fails its checks")
    stability.add_argument("--fast", action="store_true", help="only the subset that the test suite runs")
    stability.add_argument("--out", default="results/stability", help="directory for stability.csv and .md")
    bench = verbs.add_parser("bench", help="run a benchmark, print its table and write CSV "
                             "(docs/benchmarks.md)")
    bench.add_argument("which", choices=["tao", "warm", "skips", "peers", "precision", "growth", "mpi",
                                         "memory", "append", "layer", "steady", "steady-growth", "estimate",
                                         "accuracy", "periodic", "sliding", "friction", "cutoff",
                                         "sized"],  # bench.verbs.VERBS
                       help="tao: every TAO type on the Hertz step; warm: operator applications per rolling "
                       "step for each first guess; skips: each saving on and off; peers: petroll against "
                       "Tamaas and ContactMechanics on the Hertz step and a wavy sphere, from the same start; "
                       "precision: error against run time of the "
                       "integrators and of grid refinement on the rolling sphere; growth: time per rolling "
                       "step against the contact window's cells, and along a long track; mpi: time per "
                       "rolling step against the rank count; memory: peak memory of every rank against the "
                       "grid's cells at 1, 2 and 4 ranks (--ranks); append: results.h5 writing time per "
                       "saved step over 1000 steps; layer: cost per step of layer scenes against the "
                       "half-space (docs/layer.md); steady: the direct steady solve against the transient "
                       "run to the same steady tolerance, V tau/a 1e-3 to 1e3; steady-growth: the direct "
                       "steady solve's time against the grid (512 x 256 to 2048 x 1024); estimate: the error "
                       "estimate's wall time against the run's; accuracy: the estimate against the true "
                       "error, and errors against cells per contact half-width (docs/accuracy.md); periodic: "
                       "the periodic operator's cost against the non-periodic one, and periodic rough contact "
                       "against Tamaas; sliding: steady sliding against its closed forms, a 1024^2 rough "
                       "surface, a 512^2 friction master curve (docs/rough.md); friction: Coulomb "
                       "friction's tangential solves (shift, transient and steady rolling) against the normal "
                       "solve, and a 30-point creep-force curve (docs/friction.md); cutoff: a rough "
                       "surface's friction and area against cells per short cut-off wavelength (docs/rough.md); "
                       "sized: grids petroll sizes against a hand-made fine grid on a fixed-load speed sweep "
                       "(docs/accuracy.md)")
    bench.add_argument("--out", default="results/bench", help="directory for the CSV (and PNG) files")
    bench.add_argument("--ranks", type=_ranks, help="mpi, memory and sliding only: rank counts to run side by "
                       "side as mpirun children, e.g. 1,2 (default: mpi: the current communicator only; memory: "
                       "1,2,4; sliding: 1,2, its memory and time per rank instead of its default tables)")
    bench.add_argument("--sides", type=_ranks, help="memory, sliding and mpi --steady only: grid sides (cells) "
                       "to measure, e.g. 1024,2048,4096 (memory's default; sliding: 2048,4096; mpi: 2048)")
    bench.add_argument("--steady", action="store_true", help="memory and mpi only: the steady state solved "
                       "directly ([time] mode = \"steady\") instead of rolled steps")
    bench.add_argument("--quick", action="store_true", help="the smallest sizes and one repeat, in seconds: "
                       "shows that the benchmark runs and writes its files (peers: petroll's solver only, "
                       "nothing installed); measures nothing")
    sweep = verbs.add_parser("sweep", help="run a scene over values of one key to steady state; table and "
                             "plot in DIR (docs/sweep.md); run again to resume")
    _scene_run_options(sweep, "output directory (default: the scene's [output] dir + -sweep)", "estimate each "
                       "point's discretisation error (grids 2x and 4x coarser): columns <quantity>_error "
                       "(docs/accuracy.md)")
    sweep.add_argument("--vary", action="append", required=True, metavar="KEY=SPEC",
                       help="KEY=V1,V2,... or KEY=START..STOP:log:N or KEY=START..STOP:lin:N, e.g. "
                       "motion.velocity=1e-4..1e-1:log:7 (a vector key varies its magnitude); given twice: "
                       "a family of curves, one sweep of the first key per value of the second")
    sweep.add_argument("--transient", action="store_true", help="run every point from rest to steady state, "
                       "even where its steady state can be solved directly (the default there)")


def _material_verbs(verbs) -> None:
    """material fit."""
    material = verbs.add_parser("material", help="materials from measurements (docs/materials.md)")
    material_verbs = material.add_subparsers(dest="material_verb", required=True, metavar="fit")
    fit = material_verbs.add_parser("fit", help="fit a Maxwell (relaxation) Prony series with non-negative "
                                    "moduli to DMA data; write the scene's [material] block and its figure")
    fit.add_argument("csv", help="DMA table: header frequency,storage,loss[,temperature][,set] (Hz, Pa, Pa, "
                     "K, a label; or the names pyvisco and instruments export), optionally a units row")
    density = fit.add_mutually_exclusive_group()
    density.add_argument("--terms", type=_positive(int), help="candidate relaxation times in all, evenly in "
                         "log (the fit keeps at most N terms)")
    density.add_argument("--per-decade", type=_positive(float), help="candidate relaxation times per decade "
                         "(default: chosen for the data, the coarsest whose error is within 5 %% of the best; "
                         "about 2 for measured data)")
    relaxed = fit.add_mutually_exclusive_group()
    relaxed.add_argument("--einf", type=_positive(float), help="the relaxed modulus Einf (Pa), instead of "
                         "fitting it")
    relaxed.add_argument("--einf-from-data", action="store_true", help="Einf = the mean E' within a quarter "
                         "decade of the lowest frequency")
    fit.add_argument("--nu", type=float, default=0.5, help="Poisson's ratio written into the block (default "
                     "0.5)")
    fit.add_argument("--shift", help="shift law for a temperature column, written into the block: "
                     "auto:T_ref (the factors found from the data, kept as a table law; WLF and Arrhenius "
                     "fitted to them are reported), wlf:C1,C2,T_ref or arrhenius:Ea,T_ref (C2, T_ref in K; Ea "
                     "in J/mol) or a TOML file whose [material] shift gives it")
    fit.add_argument("--columns", help="which header names hold petroll's columns, e.g. frequency=f,storage="
                     "E_stor,loss=E_loss,temperature=T,set=Set (default: petroll's names and those pyvisco and "
                     "instruments write, recognised; with --columns, other columns are ignored)")
    fit.add_argument("--units", help="the columns' units, e.g. frequency=Hz,storage=MPa,loss=MPa,temperature=C "
                     "(Hz or rad/s; Pa, kPa, MPa or GPa; K or C; default: a units row under the header, or Hz, "
                     "Pa, K)")
    fit.add_argument("--tolerance", type=float, default=0.5, help="temperatures (K) within which rows belong "
                     "to one measurement set, without a set column (default 0.5)")
    fit.add_argument("--out", help="write the [material] block here (atomically, its folder made if need "
                     "be; default: print it)")
    fit.add_argument("--plot", help="the figure of data and fit (default: beside --out, its name with .png; "
                     "without --out: none); with --shift auto, the shift factors' figure beside it, NAME-shift.png")


def _file_verbs(verbs) -> None:
    """plot, info, export, stress: verbs on a run's files."""
    plot = verbs.add_parser("plot", help="figures of a run (pressure maps, patch outlines, series), a sweep "
                            "or a stress file")
    plot.add_argument("path", help="a run directory or its results.h5 (figures in DIR/plots), a sweep "
                      "directory or its sweep.h5 (sweep figure beside it), or a stress.h5 (stress figure "
                      "beside it)")
    plot.add_argument("--out", help="directory for the figures (default: as above)")
    plot.add_argument("--times", type=_seconds, help="runs: comma-separated times in s: draw the saved "
                      "pressure fields nearest to them (default: up to 4 spread over the run)")
    plot.add_argument("--format", choices=FIGURE_FORMATS, default="png", help="file format of the figures "
                      "(default png)")
    info = verbs.add_parser("info", help="what a run directory holds: scene, steps written, complete or "
                            "partial, last values, saved fields, checkpoints, petroll version")
    info.add_argument("dir", help="a run's output directory (or its results.h5)")
    export = verbs.add_parser("export", help="a run's series (or one saved field) as CSV for a spreadsheet")
    export.add_argument("dir", help="a run's output directory (or its results.h5)")
    export.add_argument("--csv", action="store_true", help="CSV (the default and only format)")
    export.add_argument("--field", choices=("pressure", "displacement", "gap"), help="one saved field "
                        "instead of the series: columns x, y (m) and its value, one row per cell")
    export.add_argument("--step", type=int, help="with --field: the step of the saved field (default: the "
                        "last saved)")
    export.add_argument("--out", help="the CSV file (default: DIR/series.csv, DIR/FIELD-step-N.csv)")
    stress = verbs.add_parser("stress", help="the stresses below a saved pressure field: DIR/stress.h5 and "
                              "DIR/stress.png (docs/results.md)")
    stress.add_argument("dir", help="a run's output directory (holding results.h5)")
    stress.add_argument("--step", type=int, help="the step whose saved pressure field to use (default: the "
                        "last saved)")
    depth = stress.add_mutually_exclusive_group()
    depth.add_argument("--depth", type=_depths, help="comma-separated depths below the surface in m, e.g. "
                       "0,1e-4,2e-4")
    depth.add_argument("--depths", choices=["auto"], help="auto (the default): 41 depths from 0 to twice "
                       "the contact's smaller half-width")
    stress.add_argument("--nu", type=float, help="Poisson's ratio (default: the scene's [material] nu)")


def _depths(text: str) -> list[float]:
    try:
        values = [float(item) for item in text.split(",") if item.strip()]
    except ValueError:
        values = []
    if not values or not all(math.isfinite(v) and v >= 0 for v in values):
        raise argparse.ArgumentTypeError(f"expected comma-separated depths >= 0 in m, got {text!r}")
    return values


def _ranks(text: str) -> tuple[int, ...]:
    try:
        counts = tuple(int(item) for item in text.split(","))
    except ValueError:
        counts = ()
    if not counts or min(counts) < 1:
        raise argparse.ArgumentTypeError(f"expected comma-separated rank counts >= 1, got {text!r}")
    return counts


def _positive(kind: type):
    """An argparse type: a finite ``kind`` (int or float) > 0."""
    def parse(text: str):
        try:
            value = kind(text)
        except ValueError:
            value = 0
        if not 0 < value < float("inf"):
            raise argparse.ArgumentTypeError(f"expected {'an integer' if kind is int else 'a finite number'} "
                                             f"> 0, got {text!r}")
        return value

    return parse


def _seconds(text: str) -> list[float]:
    try:
        return [float(item) for item in text.split(",") if item.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated seconds, got {text!r}") from None

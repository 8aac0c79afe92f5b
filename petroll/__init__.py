"""petroll: 3-D time-dependent frictionless rolling contact of a rigid body on a viscoelastic half-space.

The Python API (the ``petroll`` command is a thin layer over it)::

    import petroll
    scene = petroll.load_scene("runs/sphere.toml").replace("motion.velocity", [0.02, 0.0])
    results = petroll.run(scene, out="results/faster")   # collective under mpirun
    results.series["mu_r"], results.pressure, results.x, results.y

:func:`check` estimates a scene's contact, its resolution, steps and memory without running it (``petroll
check``). Scenes can also be built from a dict of sections with :func:`parse_scene`; :class:`Results` reopens a
results file, and ``results.steady`` (:class:`SteadyState`) gives the final force and mu_r with their
convergence measure. Sweeps over a key: :func:`petroll.studies.sweep.sweep`. Reference: docs/api.md.

The package, by concern (each package's ``__init__`` states its rules; docs/design.md has the picture):

    model/     what a scene says: schema, material laws, bodies, motion programs, limits (no PETSc, no MPI)
    solver/    numerics on the grid: partition, influence operators, the TAO step, history integrators,
               warm start, wake, the time loop (writes no files)
    records.py what a run reports step by step (the solver makes, io stores)
    io/        results.h5, checkpoints, XDMF
    studies/   workflows: the error estimate, sweeps, master curves, the stability map
    bench/     the benchmarks (``petroll bench``; only the command line imports them)
    driver.py, cli.py, plot/, this file: the faces

``import petroll`` starts neither MPI nor PETSc: the names below are imported when first used.
"""

__version__ = "0.1.0"

_PUBLIC = {
    "Results": "petroll.io.results",
    "SteadyState": "petroll.io.results",
    "Scene": "petroll.model.scene",
    "load_scene": "petroll.model.scene",
    "parse_scene": "petroll.model.scene",
    "run": "petroll.driver",
    "check": "petroll.model.preflight",
    "stress": "petroll.driver",
}

__all__ = [*_PUBLIC, "__version__"]


def __getattr__(name: str):
    """Import a public name on first use (PEP 562), so that ``import petroll`` stays light."""
    if name not in _PUBLIC:
        raise AttributeError(f"module 'petroll' has no attribute {name!r}")
    import importlib

    value = getattr(importlib.import_module(_PUBLIC[name]), name)
    globals()[name] = value
    return value

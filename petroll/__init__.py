"""petroll: 3-D time-dependent frictionless rolling contact of a rigid body on a viscoelastic half-space.

The Python API (the ``petroll`` command is a thin layer over it)::

    import petroll
    scene = petroll.load_scene("runs/sphere.toml").replace("motion.velocity", [0.02, 0.0])
    results = petroll.run(scene, out="results/faster")   # collective under mpirun
    results.series["mu_r"], results.pressure, results.x, results.y

Scenes can also be built from a dict of sections with :func:`parse_scene`; :class:`Results` reopens a
results file, and ``results.steady`` (:class:`SteadyState`) gives the final force and mu_r with their
convergence measure. Sweeps over a key: :func:`petroll.sweep.sweep`. Reference: docs/api.md.
"""

__version__ = "0.1.0"

from petroll.results import Results, SteadyState  # noqa: E402
from petroll.scene import Scene, load_scene, parse_scene  # noqa: E402
from petroll.simulation import run  # noqa: E402

__all__ = ["Results", "Scene", "SteadyState", "load_scene", "parse_scene", "run", "__version__"]

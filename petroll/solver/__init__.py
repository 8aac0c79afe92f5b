"""Numerics on the grid: the partition of rows over MPI ranks, the influence operators (PETSc shell
matrices applied by zero-padded FFTs), the contact step (a bound-constrained QP solved by TAO, with
petroll's Polonsky-Keer type), the history integrators, the warm start, the wake and the time loop.

Rules: PETSc and MPI objects live here, PETSc's only in ``petsc.py`` (the adapter) and ``pk.py`` (a TAO
type); writes no files; imports ``petroll.model`` and ``petroll.errors``
only, never ``petroll.io``, ``petroll.studies`` or the faces.
"""

import os as _os

SINGLETON = {"OMPI_MCA_ess_singleton_isolated": "1", "OMPI_MCA_pml": "ob1"}
"""Open MPI's settings for a process that no launcher started (one rank): a singleton without the helper
daemon MPI_Init otherwise forks for it (petroll never spawns processes), with the ob1 messaging layer (a
lone process talks only to itself) rather than the default pick, which probes UCX's transports: MPI_Init
takes about 0.07 s with these settings, 0.27 s without (docs/benchmarks.md, peers)."""

MPI_SETTINGS: dict[str, str] = {}
"""Those of :data:`SINGLETON` this process started MPI with (none under a launcher, nor where the
environment already gave a value)."""

if not any(key in _os.environ for key in ("OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_RANK")):
    MPI_SETTINGS.update({key: value for key, value in SINGLETON.items() if key not in _os.environ})
    _os.environ.update(MPI_SETTINGS)
    try:
        from mpi4py import MPI as _MPI  # noqa: F401 (MPI starts here, with those settings)
    finally:  # MPI_Init has read them: the processes this one starts (mpirun's ranks) do not inherit them
        for _key in MPI_SETTINGS:
            _os.environ.pop(_key, None)

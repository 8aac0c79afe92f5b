"""Numerics on the grid: the partition of rows over MPI ranks, the influence operators (PETSc shell
matrices applied by zero-padded FFTs), the contact step (a bound-constrained QP solved by TAO, with
petroll's Polonsky-Keer type), the history integrators, the warm start, the wake and the time loop.

Rules: PETSc and MPI objects live here; writes no files; imports ``petroll.model`` and ``petroll.errors``
only, never ``petroll.io``, ``petroll.studies`` or the faces.
"""

import os as _os

if not any(key in _os.environ for key in ("OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_RANK")):
    # a process that no launcher started (one rank): Open MPI then starts it as a singleton without the
    # helper daemon MPI_Init otherwise forks for it (petroll never spawns processes), and with the ob1
    # messaging layer (a lone process talks only to itself), not the default pick's probe of UCX's
    # transports: MPI_Init in about 0.07 s instead of 0.27 s (docs/benchmarks.md, peers). Set before MPI
    # starts, i.e. before mpi4py or petsc4py is initialised; a value already in the environment is kept.
    _os.environ.setdefault("OMPI_MCA_ess_singleton_isolated", "1")
    _os.environ.setdefault("OMPI_MCA_pml", "ob1")

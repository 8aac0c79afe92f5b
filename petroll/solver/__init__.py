"""Numerics on the grid: the partition of rows over MPI ranks, the influence operators (PETSc shell
matrices applied by zero-padded FFTs), the contact step (a bound-constrained QP solved by TAO, with
petroll's Polonsky-Keer type), the history integrators, the warm start, the wake and the time loop.

Rules: PETSc and MPI objects live here; writes no files; imports ``petroll.model`` and ``petroll.errors``
only, never ``petroll.io``, ``petroll.studies`` or the faces.
"""

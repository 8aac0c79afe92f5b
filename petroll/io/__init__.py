"""Files: results.h5 (the layout of docs/results.md), restart checkpoints (docs/checkpoints.md), the
XDMF companion for ParaView.

Rules: moves arrays between ranks and files, does no numerics; writes atomically (temporary name, fsync,
rename); may import ``petroll.model``, ``petroll.records`` (the step records it stores) and, of the solver,
``petroll.solver.partition`` only (how a field's rows are split over the ranks, which every rank's writes
follow); never the solver's other modules (a checkpoint restores a Simulation through its attributes),
``petroll.studies``, ``petroll.bench`` or the faces.
"""

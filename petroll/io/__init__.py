"""Files: results.h5 (the layout of docs/results.md), restart checkpoints (docs/checkpoints.md), the
XDMF companion for ParaView.

Rules: moves arrays between ranks and files, does no numerics; writes atomically (temporary name, fsync,
rename); may import ``petroll.model`` and ``petroll.solver`` (to read and restore a run's state), never
``petroll.studies`` or the faces.
"""

"""The TAO types a scene's ``[solver] tao_type`` may name (a module of its own: the contact solver reads
them without importing the scene schema and its bodies)."""

TAO_TYPES = ("tron", "pk", "gpcg", "bntr", "bncg", "blmvm", "bqnls", "bnls", "bntl")
"""TAO's bound-constrained solvers that handle this QP (bqpip is left out: it needs finite upper bounds),
and ``pk``, petroll's Polonsky-Keer conjugate gradient as a TAO Python type (petroll/solver/pk.py)."""

DEFAULT_TAO_TYPE = "pk"
"""Chosen by measurement: see docs/benchmarks.md."""

"""Workflows built on the API: the error estimate of a run (three runs on coarser grids), sweeps over a
scene key, master curves, the stability map, the layer study, Persson's theory, synthetic DMA tables.

Rules: uses the public faces (``petroll.driver.run``, scenes, results) and the solver's objects; nothing
in ``petroll.model``, ``petroll.solver`` or ``petroll.io`` imports this package, and it imports nothing of
``petroll.bench`` or the command line. One face imports it: ``petroll.driver`` runs the error estimate
(:mod:`.estimate`), which is therefore built on ``Simulation`` and imports no face.
"""

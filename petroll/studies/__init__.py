"""Studies built on the API: sweeps over a scene key, the stability map, the benchmarks (``petroll
bench``) and the standalone peer scripts they start (``peers/``).

Rules: uses the public faces (``petroll.driver.run``, scenes, results) and the solver's objects; nothing
in ``petroll.model``, ``petroll.solver`` or ``petroll.io`` imports this package.
"""

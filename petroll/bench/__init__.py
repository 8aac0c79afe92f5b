"""The benchmarks (``petroll bench VERB``, docs/benchmarks.md): each verb's function and sizes
(:mod:`.verbs`), the solvers side by side (:mod:`.solvers`), rolling runs (:mod:`.rolling`), MPI scaling
(:mod:`.mpi`), memory and results.h5 appends (:mod:`.memory`), steady solves (:mod:`.steady`), rough
contact and sliding (:mod:`.rough`), the layer (:mod:`.layer`), the error estimate's accuracy and cost
(:mod:`.accuracy`), friction (:mod:`.friction`) and the peers, Tamaas and ContactMechanics
(:mod:`.peers`, whose scripts are in the checkout's scripts/peers/, not in an install).

Rules: measures; changes no numerics. May import everything below the command line (model, solver, io,
records, studies, driver, plot); only ``petroll.cli`` imports this package, so that a user's run never
loads it.
"""

"""What a scene says: the scene schema and its validation, material laws, bodies, motion programs, the
grid's geometry and the physical limits of the formulation.

Rules: imports no PETSc, no mpi4py and nothing of ``petroll.solver``, ``petroll.io``, ``petroll.studies``
or the faces; reads no files beyond the scene's own inputs (TOML, tables, height maps, meshes) and
material measurements (DMA tables, model/dma.py). A scene can be read and checked anywhere.
"""

"""The shipped scenes. Installed as the package data ``petroll.scenes`` (pyproject.toml), so that studies
and benchmarks find them from any install: ``petroll.model.scene.shipped_scene("sphere.toml")``."""

"""What the figures share: the figure itself (matplotlib's Agg canvas, constrained layout), units and cell
edges. Lengths are drawn in mm, pressures in MPa, kPa or Pa (whichever suits the peak)."""

from __future__ import annotations

import io
import pathlib

import numpy as np

from petroll.errors import PetrollError

MM = 1e3  # m -> mm


def write_figure(figure, path: str | pathlib.Path, dpi: int) -> pathlib.Path:
    """Write ``figure`` to ``path`` (the format by its suffix: pdf, svg, else png) whole or not at all: drawn
    in memory, written to a temporary name, renamed over ``path`` once complete (a figure already there
    stays until then; the temporaries of a writer killed earlier are removed first). PetrollError naming
    the file where it cannot be written (a read-only or full file system). Returns ``path``."""
    from petroll.io.journal import atomic_write
    from petroll.io.rundir import clean_temporaries

    path = pathlib.Path(path)
    fmt = path.suffix.lstrip(".").lower()
    drawn = io.BytesIO()  # not into the file: a backend failing midway (PDF: zlib) would leave it open
    figure.savefig(drawn, dpi=dpi, format=fmt if fmt in ("pdf", "svg") else "png")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        clean_temporaries(path.parent, [path.name])
        atomic_write(path, lambda tmp: tmp.write_bytes(drawn.getvalue()))
    except OSError as exc:
        why = exc.strerror or str(exc)
        raise PetrollError(f"{path}: cannot write the figure ({why}); free space or give a writable "
                           "directory") from None
    return path


def constrained_figure(width: float, height: float):
    """An empty figure (inches) on the Agg canvas, laid out by matplotlib's constrained layout."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(figure)
    return figure


def pressure_unit(p_max: float) -> tuple[str, float]:
    """(unit, Pa per unit) for pressures up to ``p_max`` (Pa): MPa, kPa or Pa."""
    for name, scale in (("MPa", 1e6), ("kPa", 1e3)):
        if p_max >= 0.1 * scale:
            return name, scale
    return "Pa", 1.0


def cell_edges(c: np.ndarray) -> np.ndarray:
    """Cell edges (m) of uniform cell centres ``c``."""
    h = c[1] - c[0] if len(c) > 1 else 1.0
    return np.concatenate([c - h / 2, [c[-1] + h / 2]])


def span_above(values: np.ndarray, level: float, pad: int = 2) -> slice:
    """Index slice spanning the entries of ``values`` above ``level``, widened by ``pad`` (all if none)."""
    inside = np.flatnonzero(values > level)
    if inside.size == 0:
        return slice(0, len(values))
    return slice(max(int(inside[0]) - pad, 0), min(int(inside[-1]) + pad + 1, len(values)))

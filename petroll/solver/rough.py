"""What a run on a grid periodic along every axis reports beyond the series of every run (results.h5's
group ``rough``, docs/results.md; one step's values: petroll.records.RoughOutputs): the real
contact area's fraction of the cell, the mean gap, and the radially averaged power spectrum of the
pressure.

The spectrum is Persson's C(q) (as petroll.model.roughness.radial_psd computes it for a whole field), of a
field whose rows are split over the ranks: each rank bins the modes of its Y-frequencies (the operator's
distributed transform, petroll.solver.influence.Convolution.forward), and the bins are summed over ranks.
"""

from __future__ import annotations

import math

import numpy as np
from mpi4py import MPI

BINS = 32
"""Logarithmic wavenumber bins of the pressure spectrum, from the cell's longest wavelength to its
shortest (2 pi / L to pi sqrt(1/dx^2 + 1/dy^2))."""

SPECTRUM_BLOCK = 1 << 20
"""Modes binned at once (a block of whole X-frequency rows): the binning makes no field-sized temporaries."""


def spectrum_edges(grid, bins: int = BINS) -> np.ndarray:
    """The bins' edges (rad/m) for ``grid``: geometric from 2 pi / (the cell's longer side) to just above the
    largest wavenumber of its lattice."""
    lowest = 2 * np.pi / max(grid.x1 - grid.x0, grid.y1 - grid.y0)
    highest = np.pi * math.hypot(1 / grid.dx, 1 / grid.dy) * (1 + 1e-9)
    return np.geomspace(lowest * (1 - 1e-9), highest, bins + 1)


def radial_spectrum(conv, local: np.ndarray, grid, edges: np.ndarray):
    """(q, C, modes) of the field whose rows on this rank are ``local`` (units of the field^2 m^2), over the
    wavenumber bins ``edges``, by the unpadded distributed transform ``conv`` of ``grid``: each mode of a
    real field counted once (half spectrum without its conjugate twins), the mean left out. Collective."""
    nx, ny = grid.nx, grid.ny
    half = conv.forward(local)  # (nx, this rank's Y-frequencies)
    f0, f1 = conv.freqs.range(conv.comm.rank)
    kx = 2 * np.pi * np.fft.fftfreq(nx, grid.dx)[:, None]
    my = np.arange(f0, f1)
    ky = 2 * np.pi * my / (ny * grid.dy)
    area = (grid.x1 - grid.x0) * (grid.y1 - grid.y0)
    twins = (my == 0) | ((ny % 2 == 0) & (my == ny // 2))  # ky = 0 or Nyquist: only kx > 0 is its own
    bins = len(edges) - 1
    sums = np.zeros(3 * bins)
    rows = max(1, SPECTRUM_BLOCK // max(1, half.shape[1]))
    for a in range(0, nx, rows):
        k = kx[a : a + rows]
        power = np.abs(half[a : a + rows] / (nx * ny)) ** 2 * area / (2 * np.pi) ** 2
        q = np.broadcast_to(np.hypot(k, ky[None, :]), power.shape)
        own = np.ones(power.shape, dtype=bool)
        own[:, twins] = (k > 0)[:, [0] * int(twins.sum())]
        which = np.digitize(q[own], edges) - 1
        inside = (which >= 0) & (which < bins)
        sums += np.concatenate([np.bincount(which[inside], minlength=bins).astype(float),
                                np.bincount(which[inside], q[own][inside], bins),
                                np.bincount(which[inside], power[own][inside], bins)])
    conv.comm.Allreduce(MPI.IN_PLACE, sums, op=MPI.SUM)
    count, total_q, total_c = sums[:bins], sums[bins : 2 * bins], sums[2 * bins :]
    with np.errstate(invalid="ignore"):
        return total_q / count, total_c / count, count.astype(np.int64)


def contact_islands(contact: np.ndarray, periodic: tuple[bool, bool] = (True, True)) -> tuple[np.ndarray, int]:
    """The connected islands of a whole grid's contact (booleans, cells sharing a side), joined across
    the edges of the periodic axes: (label of each cell, 0 outside the contact, 1 ... n; n)."""
    from scipy import ndimage

    labels, count = ndimage.label(contact)
    parent = np.arange(count + 1)

    def root(a: int) -> int:
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    edges = []
    if periodic[0]:
        edges.append((labels[0, :], labels[-1, :]))
    if periodic[1]:
        edges.append((labels[:, 0], labels[:, -1]))
    for first, last in edges:
        for a, b in zip(first[(first > 0) & (last > 0)], last[(first > 0) & (last > 0)]):
            ra, rb = root(int(a)), root(int(b))
            if ra != rb:
                parent[max(ra, rb)] = min(ra, rb)
    roots = np.array([root(a) for a in range(count + 1)])
    _, relabelled = np.unique(roots, return_inverse=True)  # roots in order: 0 stays 0
    return relabelled[labels], int(relabelled.max())

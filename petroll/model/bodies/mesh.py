"""Bodies from triangle meshes: the mesh's lowest surface rasterised to a :class:`HeightMap` (any format
meshio reads; lengths in m)."""

from __future__ import annotations

import math
import os

import numpy as np

from petroll.errors import SceneError
from petroll.model.bodies.base import PYTHON_SOURCE, cell_pair
from petroll.model.bodies.maps import HeightMap


def _read_triangles(path: str | os.PathLike, source: str) -> tuple[np.ndarray, np.ndarray]:
    import meshio  # imported lazily: only mesh bodies need it

    try:
        mesh = meshio.read(os.fspath(path))
    except Exception as exc:  # noqa: BLE001 - any read failure is the user's file
        reason = str(exc) or type(exc).__name__
        raise SceneError(source, "[body] file", str(path), f"cannot read a surface mesh: {reason}") from None
    blocks = [np.asarray(block.data, dtype=np.intp) for block in mesh.cells if block.type == "triangle"]
    blocks = [block for block in blocks if block.size]
    if not blocks:
        raise SceneError(
            source, "[body] file", str(path),
            "the mesh has no triangles (other cell types are ignored)",
        )
    points = np.asarray(mesh.points, dtype=float)
    if points.ndim != 2 or points.shape[1] != 3:
        raise SceneError(source, "[body] file", str(path), "the mesh must have 3-D points (x, y, z)")
    triangles = np.concatenate(blocks, axis=0)
    if not np.isfinite(points[np.unique(triangles)]).all():
        raise SceneError(
            source, "[body] file", str(path),
            "the mesh has points with NaN or infinite coordinates",
        )
    return points, triangles


_RASTER_CHUNK = 2_000_000  # candidate (triangle, grid point) pairs handled at once: bounds the memory
_TOL = 1e-9  # grid points within this fraction of a cell of a bounding box count as inside it


def mesh_height_map(
    path: str | os.PathLike, cell: tuple[float, float] | float, *, source: str = PYTHON_SOURCE
) -> HeightMap:
    """Rasterise the lowest surface of a triangle mesh (any format meshio reads; lengths in m) to a HeightMap.

    The body reference point is the x-y position of the mesh's lowest vertex (the first one if several
    share the lowest z), so a mesh of a sphere gives the same Z as :class:`Sphere`.  The grid has spacing
    ``cell`` = (hx, hy), contains that vertex as a grid point and covers the mesh's x-y bounding box.  A
    grid point takes the minimum over triangles whose x-y projection contains it of the barycentric z;
    points that no triangle covers get +inf (no surface).  Non-triangle cells and triangles with no x-y
    area (vertical walls) are ignored.
    """
    hx, hy = cell_pair(source, cell)
    points, triangles = _read_triangles(path, source)
    used = np.unique(triangles)
    lowest = used[np.argmin(points[used, 2])]
    vx, vy = points[lowest, 0], points[lowest, 1]

    p = points[triangles]  # (m, 3 vertices, xyz)
    x, y, z = p[..., 0] - vx, p[..., 1] - vy, p[..., 2]
    det = (x[:, 1] - x[:, 0]) * (y[:, 2] - y[:, 0]) - (x[:, 2] - x[:, 0]) * (y[:, 1] - y[:, 0])
    scale = (np.ptp(x, axis=1) + np.ptp(y, axis=1)) ** 2
    keep = np.abs(det) > 1e-12 * scale
    if not keep.any():
        raise SceneError(
            source, "[body] file", str(path),
            "the mesh has no triangle with a non-zero x-y area",
        )
    x, y, z, det = x[keep], y[keep], z[keep], det[keep]

    kx0, kx1, ky0, ky1 = _grid_range(x, y, hx, hy, source, cell)
    nx, ny = kx1 - kx0 + 1, ky1 - ky0 + 1
    grid = _lowest_z(x, y, z, det, (kx0, ky0), (nx, ny), (hx, hy))

    heights = grid.reshape(nx, ny)
    center = (0.5 * (kx0 + kx1) * hx, 0.5 * (ky0 + ky1) * hy)
    finite = np.isfinite(heights)
    if not (finite[:-1, :-1] & finite[1:, :-1] & finite[:-1, 1:] & finite[1:, 1:]).any():
        raise SceneError(
            source,
            "[body] cell",
            cell,
            "cell too large for the mesh: no grid cell lies fully on the mesh surface",
        )
    return HeightMap(heights, (hx, hy), center, source=source)


def _grid_range(x: np.ndarray, y: np.ndarray, hx: float, hy: float, source: str,
                cell) -> tuple[int, int, int, int]:
    """Grid points k * h (k integer, m) around the lowest vertex (the origin of ``x``, ``y``) covering the
    triangles' x-y bounding box: the index ranges kx0..kx1, ky0..ky1 (inclusive); SceneError naming
    ``cell`` where the grid would be smaller than 2 x 2 or larger than 5e7 points."""
    tol = _TOL
    kx0 = math.ceil(x.min() / hx - tol)
    kx1 = math.floor(x.max() / hx + tol)
    ky0 = math.ceil(y.min() / hy - tol)
    ky1 = math.floor(y.max() / hy + tol)
    nx, ny = kx1 - kx0 + 1, ky1 - ky0 + 1
    if nx < 2 or ny < 2:
        raise SceneError(
            source,
            "[body] cell",
            cell,
            f"cell too large for the mesh: the grid would have {nx} x {ny} points, needs 2 x 2",
        )
    if nx * ny > 50_000_000:
        raise SceneError(
            source, "[body] cell", cell,
            f"cell too small for the mesh: the grid would have {nx} x {ny} points",
        )
    return kx0, kx1, ky0, ky1


def _lowest_z(x: np.ndarray, y: np.ndarray, z: np.ndarray, det: np.ndarray, k0: tuple[int, int],
              shape: tuple[int, int], h: tuple[float, float]) -> np.ndarray:
    """The lowest barycentric z (m) of the triangles (vertex coordinates ``x``, ``y``, ``z``: (m, 3);
    ``det``: twice their signed x-y areas) at each grid point (k0 + index) * h, flattened (nx * ny,
    +inf where no triangle covers it). Scan-converted by chunks of about _RASTER_CHUNK candidate points:
    every grid point of each triangle's bounding box is tested by its barycentric coordinates."""
    (kx0, ky0), (nx, ny), (hx, hy) = k0, shape, h
    tol = _TOL
    # index ranges (relative to the grid) of the grid points in each triangle's bounding box
    i0 = np.clip(np.ceil(x.min(axis=1) / hx - tol).astype(np.int64) - kx0, 0, nx - 1)
    i1 = np.clip(np.floor(x.max(axis=1) / hx + tol).astype(np.int64) - kx0, 0, nx - 1)
    j0 = np.clip(np.ceil(y.min(axis=1) / hy - tol).astype(np.int64) - ky0, 0, ny - 1)
    j1 = np.clip(np.floor(y.max(axis=1) / hy + tol).astype(np.int64) - ky0, 0, ny - 1)
    ni = np.maximum(i1 - i0 + 1, 0)
    nj = np.maximum(j1 - j0 + 1, 0)
    count = ni * nj

    grid = np.full(nx * ny, np.inf)
    chunk = _RASTER_CHUNK
    ends = np.cumsum(count)
    start_tri = 0
    while start_tri < len(count):
        # take triangles until about `chunk` candidate points (at least one triangle)
        base = ends[start_tri - 1] if start_tri else 0
        stop_tri = max(int(np.searchsorted(ends, base + chunk, side="right")), start_tri + 1)
        sel = slice(start_tri, stop_tri)
        start_tri = stop_tri
        counts = count[sel]
        total = int(counts.sum())
        if total == 0:
            continue
        tri = np.repeat(np.arange(sel.start, sel.stop), counts)
        first = np.repeat(np.cumsum(counts) - counts, counts)
        local = np.arange(total) - first
        nj_t = nj[tri]
        gi = i0[tri] + local // nj_t
        gj = j0[tri] + local % nj_t
        px = (gi + kx0) * hx
        py = (gj + ky0) * hy
        x0, y0 = x[tri, 0], y[tri, 0]
        dx, dy = px - x0, py - y0
        d = det[tri]
        l1 = (dx * (y[tri, 2] - y0) - (x[tri, 2] - x0) * dy) / d
        l2 = ((x[tri, 1] - x0) * dy - dx * (y[tri, 1] - y0)) / d
        l0 = 1.0 - l1 - l2
        eps = 1e-9
        inside = (l0 >= -eps) & (l1 >= -eps) & (l2 >= -eps)
        if not inside.any():
            continue
        zz = (l0 * z[tri, 0] + l1 * z[tri, 1] + l2 * z[tri, 2])[inside]
        flat = (gi * ny + gj)[inside]
        order = np.lexsort((zz, flat))
        flat, zz = flat[order], zz[order]
        head = np.ones(flat.size, dtype=bool)
        head[1:] = flat[1:] != flat[:-1]
        flat, zz = flat[head], zz[head]
        grid[flat] = np.minimum(grid[flat], zz)

    return grid

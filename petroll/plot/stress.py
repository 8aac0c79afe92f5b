"""The figure of a stress.h5 (``petroll stress``): von Mises and Tresca stresses on a section along the
motion on the contact's centre line and on the plane of their maximum."""

from __future__ import annotations

import pathlib

import numpy as np

from petroll.errors import PetrollError
from petroll.plot.common import MM, cell_edges, constrained_figure, pressure_unit, span_above, write_figure


def plot_stress(stress_path: str | pathlib.Path, out: str | pathlib.Path | None = None) -> pathlib.Path:
    """Write stress.png (default: next to ``stress_path``) for a stress.h5 of ``petroll stress``: for the
    von Mises stress and the maximum shear stress, a section along the motion on the contact's centre line
    (depth downwards) and a map at the maximum's depth, zoomed on where the stress exceeds 10 % of its
    maximum (line contact: the plane-strain field and the profile at that depth)."""
    from petroll.io.stress import stress_planes

    stress_path = pathlib.Path(stress_path)
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        raise PetrollError("stress.png needs matplotlib: pip install matplotlib") from None
    figure = constrained_figure(11.0, 8.4)
    figure.get_layout_engine().set(h_pad=0.15)  # panel titles clear of the figure's and of each other
    axes = figure.subplots(2, 2, squeeze=False)
    for row, (name, title) in enumerate((("von_mises", "von Mises"), ("max_shear", "max shear (Tresca)"))):
        planes = stress_planes(stress_path, name)
        _stress_section(figure, axes[row, 0], stress_path, name, title, planes)
        (_stress_profile if planes["map"].ndim == 1 else _stress_map)(figure, axes[row, 1], title, planes)
    attrs = planes["attrs"]
    figure.suptitle(f"{stress_path.parent.resolve().name}: stresses below the surface, step "
                    f"{int(attrs['step'])} (t = {float(attrs['t']):.4g} s, nu = {float(attrs['nu']):g})")
    return write_figure(figure, pathlib.Path(out) if out is not None else stress_path.with_suffix(".png"), dpi=120)


def centre_section(stress_path: pathlib.Path, name: str, planes: dict) -> tuple[np.ndarray, float]:
    """The section along the motion on the contact's centre line: the stress-weighted mean position
    across the motion at the maximum's depth (the symmetry line of a symmetric contact), interpolated
    linearly between the two rows of cells either side of it. Returns (section (nz, n), its position, m)."""
    from petroll.io.stress import stress_section

    across_x = str(planes["attrs"]["motion_axis"]) != "x"
    coords = planes["x"] if across_x else planes["y"]
    weights = planes["map"].sum(axis=1 if across_x else 0)
    total = float(np.sum(weights))
    centre = float(np.sum(weights * coords)) / total if total > 0 else float(coords.mean())
    if abs(centre) < 1e-9 * (np.ptp(coords) or 1.0):
        centre = 0.0  # round-off of a symmetric contact's centre
    j = int(np.clip(np.searchsorted(coords, centre) - 1, 0, max(len(coords) - 2, 0)))
    if len(coords) == 1:
        return stress_section(stress_path, name, 0), float(coords[0])
    w = float(np.clip((centre - coords[j]) / (coords[j + 1] - coords[j]), 0.0, 1.0))
    section = (1 - w) * stress_section(stress_path, name, j) + w * stress_section(stress_path, name, j + 1)
    return section, centre


def _stress_section(figure, ax, stress_path: pathlib.Path, name: str, title: str, planes: dict) -> None:
    """Depth against the position along the motion: the centre-line section (line contact: the field)."""
    x, y, z, peak, (px, py, pz) = planes["x"], planes["y"], planes["z"], planes["peak"], planes["at"]
    axis = str(planes["attrs"]["motion_axis"])
    unit, scale = pressure_unit(max(peak, 1e-300))
    along, here = (x, px) if axis == "x" else (y, py)
    line = planes["map"].ndim == 1
    if line:
        section, label = planes["section"], "plane strain"
    else:
        section, centre = centre_section(stress_path, name, planes)
        label = f"on the centre line {'Y' if axis == 'x' else 'X'} = {centre * MM:.3g} mm"
    span = span_above(section.max(axis=0), 0.1 * peak)
    h = abs(along[1] - along[0]) if len(along) > 1 else 1e-3
    image = ax.pcolormesh(cell_edges(along)[span.start:span.stop + 1] * MM, _depth_edges(z, h) * MM,
                          section[:, span] / scale, cmap="viridis", shading="flat", vmin=0, vmax=peak / scale)
    ax.set_aspect("equal")
    ax.invert_yaxis()
    where = "" if line else f" at {'Y' if axis == 'x' else 'X'} = {(py if axis == 'x' else px) * MM:.3g} mm"
    ax.plot([here * MM], [pz * MM], marker="x", color="red", linestyle="none",
            label=f"maximum {peak / scale:.4g} {unit}{where}")
    ax.set_xlabel(f"{axis.upper()} (mm), along the motion")
    ax.set_ylabel("depth z (mm)")
    ax.set_title(f"{title}, {label}", fontsize=10)
    ax.legend(loc="lower right", fontsize=8)
    figure.colorbar(image, ax=ax, label=unit)


def _stress_map(figure, ax, title: str, planes: dict) -> None:
    """The stress over X, Y at the maximum's depth."""
    x, y, peak, (px, py, pz), plane = planes["x"], planes["y"], planes["peak"], planes["at"], planes["map"]
    unit, scale = pressure_unit(max(peak, 1e-300))
    bx, by = span_above(plane.max(axis=1), 0.1 * peak), span_above(plane.max(axis=0), 0.1 * peak)
    image = ax.pcolormesh(cell_edges(x)[bx.start:bx.stop + 1] * MM, cell_edges(y)[by.start:by.stop + 1] * MM,
                          plane[bx, by].T / scale, cmap="viridis", shading="flat", vmin=0, vmax=peak / scale)
    ax.plot([px * MM], [py * MM], marker="x", color="red", linestyle="none")
    ax.set_aspect("equal")
    ax.set_xlabel("X (mm)")
    ax.set_ylabel("Y (mm)")
    ax.set_title(f"{title} at the maximum's depth z = {pz * MM:.3g} mm", fontsize=10)
    figure.colorbar(image, ax=ax, label=unit)


def _stress_profile(figure, ax, title: str, planes: dict) -> None:
    """Line contact: the stress along X at the maximum's depth."""
    x, peak, (px, _, pz), plane = planes["x"], planes["peak"], planes["at"], planes["map"]
    unit, scale = pressure_unit(max(peak, 1e-300))
    span = span_above(plane, 0.1 * peak)
    ax.plot(x * MM, plane / scale, color="tab:blue")
    ax.plot([px * MM], [peak / scale], marker="x", color="red", linestyle="none")
    ax.set_xlim(cell_edges(x)[span.start] * MM, cell_edges(x)[span.stop] * MM)
    ax.set_xlabel("X (mm)")
    ax.set_ylabel(unit)
    ax.grid(alpha=0.3)
    ax.set_title(f"{title} at the maximum's depth z = {pz * MM:.3g} mm", fontsize=10)


def _depth_edges(z: np.ndarray, h: float) -> np.ndarray:
    """Edges (m) of depth bins centred at the sorted depths ``z`` (a single depth: a bin ``h`` high),
    clipped at 0."""
    if len(z) == 1:
        return np.array([max(z[0] - h / 2, 0.0), z[0] + h / 2])
    mid = (z[1:] + z[:-1]) / 2
    return np.concatenate([[max(z[0] - (mid[0] - z[0]), 0.0)], mid, [z[-1] + (z[-1] - mid[-1])]])

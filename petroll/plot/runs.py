"""Figures of a run's results.h5: pressure maps, patch outlines, series, the deformed surface (line contact:
pressure profiles along X instead of maps and outlines; forces per unit length), and on a periodic grid
the contact islands with the pressure's spectrum."""

from __future__ import annotations

import pathlib
from collections.abc import Sequence

import numpy as np

from petroll.errors import PetrollError
from petroll.io.results import Results
from petroll.plot.friction import traction_figure
from petroll.plot.common import MM, cell_edges, constrained_figure, pressure_unit, write_figure

MAX_PANELS = 4
MAX_TIMES = 16
"""The most pressure maps ``--times`` may pick (a figure of 4 x 4 panels)."""
"""Pressure maps drawn when no times are requested: the first, the last and evenly spaced ones between."""


def plot_results(results_dir: str | pathlib.Path, out_dir: str | pathlib.Path | None = None,
                 times: Sequence[float] | None = None, fmt: str = "png") -> list[pathlib.Path]:
    """Write pressure.png, patches.png and series.png for ``results_dir/results.h5``, surface.png
    when the run saved the surface displacement and gap ([output] fields), traction.png for a run with
    friction (its tractions and stick/slip map, petroll.plot.friction), and islands.png for a run on a
    periodic grid (the contact islands of the last saved field and the pressure's spectrum); ``fmt`` (png,
    pdf, svg) replaces the suffix.

    ``out_dir`` defaults to ``results_dir/plots``; ``times`` (s) picks the saved pressure fields nearest to
    those times for pressure.png (default: up to 4 spread over the run). Returns the written paths.
    """
    results_dir = pathlib.Path(results_dir)
    path = results_dir / "results.h5"
    if not path.is_file():
        raise PetrollError(f"{path}: no results file (is {results_dir} the output directory of a run?)")
    try:
        import matplotlib  # noqa: F401
        from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: F401
    except ImportError:
        raise PetrollError("petroll plot needs matplotlib: pip install matplotlib") from None
    results = Results.open(path)
    if len(results.field_steps) == 0:
        raise PetrollError(f"{path}: the file holds no saved pressure fields")
    out = pathlib.Path(out_dir) if out_dir is not None else results_dir / "plots"
    label = results_dir.resolve().name
    written = []
    pressure, patches = (_line_pressure_figure, _line_patches_figure) if results.line else (
        _pressure_figure, _patches_figure)
    figures = {"pressure": lambda: pressure(results, select_fields(results, times), label),
               "patches": lambda: patches(results, label), "series": lambda: _series_figure(results, label)}
    if "displacement" in results.fields:
        figures["surface"] = lambda: _surface_figure(results, label)
    if "traction_x" in results.fields:  # a run with friction
        figures["traction"] = lambda: traction_figure(results, label)
    if results.rough is not None:
        figures["islands"] = lambda: _islands_figure(results, label)
    for name, figure in figures.items():
        written.append(write_figure(figure(), out / f"{name}.{fmt}", dpi=120))
    return written


def select_fields(results: Results, times: Sequence[float] | None = None) -> list[int]:
    """Indices into ``results.pressure`` to draw: nearest to each of ``times`` (s), or up to 4 spread out."""
    n = len(results.field_steps)
    if times:
        t = field_times(results)
        picked = {int(np.argmin(np.abs(t - float(want)))) for want in times}
        if len(picked) > MAX_TIMES:
            raise PetrollError(f"--times: picks {len(picked)} saved fields; at most {MAX_TIMES} pressure maps are "
                               "drawn in one figure")
        return sorted(picked)
    return sorted({int(round(i)) for i in np.linspace(0, n - 1, min(MAX_PANELS, n))})


def field_times(results: Results) -> np.ndarray:
    """Time t (s) of each saved field."""
    return np.array([results.series["t"][_row(results, s)] for s in results.field_steps])


def _row(results: Results, step: int) -> int:
    """Index into the series of step number ``step``."""
    steps = results.series.get("step")
    if steps is None:
        return int(step)
    return int(np.flatnonzero(np.asarray(steps) == step)[0])


def _contact_box(p: np.ndarray, pad: int) -> tuple[slice, slice] | None:
    """Index slices of the cells with p > 0, widened by ``pad`` cells (None without contact)."""
    ix, iy = np.nonzero(p > 0)
    if ix.size == 0:
        return None
    nx, ny = p.shape
    return (slice(max(ix.min() - pad, 0), min(ix.max() + pad + 1, nx)),
            slice(max(iy.min() - pad, 0), min(iy.max() + pad + 1, ny)))


def _pressure_figure(results: Results, picks: list[int], label: str):
    x, y = results.x, results.y
    xe, ye = cell_edges(x), cell_edges(y)
    unit, scale = pressure_unit(float(results.pressure[picks].max(initial=0.0)))
    vmax = max(float(results.pressure[picks].max(initial=0.0)) / scale, 1e-300)
    cols = min(len(picks), MAX_PANELS)
    rows = -(-len(picks) // cols)
    figure = constrained_figure(max(4.2 * cols, 6.0), 3.9 * rows)
    axes = np.atleast_1d(figure.subplots(rows, cols, squeeze=False).ravel())
    image = None
    for ax, k in zip(axes, picks):
        p = results.pressure[k]
        row = _row(results, results.field_steps[k])
        t, sx, sy = (float(results.series[name][row]) for name in ("t", "sx", "sy"))
        size = _contact_box(p, 0)
        if size is None:
            box = (slice(0, len(x)), slice(0, len(y)))
        else:
            extent = max(size[0].stop - size[0].start, size[1].stop - size[1].start)
            box = _contact_box(p, max(3, extent // 4))
        image = ax.pcolormesh(xe[box[0].start:box[0].stop + 1] * MM, ye[box[1].start:box[1].stop + 1] * MM,
                              p[box].T / scale, cmap="inferno", vmin=0.0, vmax=vmax, shading="flat")
        ax.plot([sx * MM], [sy * MM], marker="+", color="cyan", markersize=14, markeredgewidth=2,
                linestyle="none", label="body centre")
        ax.set_aspect("equal")
        ax.set_xlabel("X (mm)")
        ax.set_ylabel("Y (mm)")
        ax.set_title(f"step {int(results.field_steps[k])}, t = {t:.4g} s\nbody at X = {sx * MM:.4g} mm, "
                     f"Y = {sy * MM:.4g} mm" + ("" if size is not None else "\n(no contact)"), fontsize=10)
    for ax in axes[len(picks):]:
        ax.set_visible(False)
    axes[0].legend(loc="upper left", fontsize=8, framealpha=0.7)
    figure.colorbar(image, ax=list(axes[:len(picks)]), label=f"contact pressure ({unit})", shrink=0.9)
    figure.suptitle(f"{label}: contact pressure (zoomed on the patch; material frame)")
    return figure


def _surface_figure(results: Results, label: str):
    """The deformed surface along the track's centre line at the last saved step: the surface -w and the
    body's surface Z - delta = gap - w (um, upwards; the undeformed surface at 0), and the pressure."""
    k = len(results.field_steps) - 1
    row = _row(results, results.field_steps[k])
    sx, sy = float(results.series["sx"][row]), float(results.series["sy"][row])
    j = int(np.argmin(np.abs(results.y - sy)))
    w, gap = results.field("displacement")[k, :, j], results.field("gap")[k, :, j]
    p = results.pressure[k, :, j]
    x = results.x * MM
    unit, scale = pressure_unit(float(p.max(initial=0.0)))
    figure = constrained_figure(7.5, 4.5)
    ax = figure.subplots()
    um = 1e6
    ax.plot(x, -w * um, color="C0", label="deformed surface, -w")
    ax.plot(x, (gap - w) * um, color="0.3", linestyle="--", label="body, Z - delta")
    ax.axhline(0.0, color="0.7", linewidth=0.8, label="undeformed surface")
    loaded = np.flatnonzero(p > 0)
    if loaded.size:
        pad = max(3, loaded[-1] - loaded[0])
        lo, hi = max(loaded[0] - pad, 0), min(loaded[-1] + pad, len(x) - 1)
        ax.set_xlim(x[lo], x[hi])
        shown = slice(lo, hi + 1)
        ax.set_ylim(1.5 * min((-w[shown]).min(), 0.0) * um, max(((gap - w)[shown]).max() * um, 1e-300))
    ax.set_xlabel("X (mm, material frame)")
    ax.set_ylabel("height (um)")
    ax.grid(alpha=0.3)
    twin = ax.twinx()
    twin.fill_between(x, p / scale, color="C3", alpha=0.25, linewidth=0, label="pressure")
    twin.set_ylabel(f"contact pressure ({unit})")
    twin.set_ylim(0, max(float(p.max(initial=0.0)) / scale, 1e-300) * 3)
    lines = ax.get_legend_handles_labels()[0] + twin.get_legend_handles_labels()[0]
    ax.legend(lines, [h.get_label() for h in lines], fontsize=8, loc="lower right")
    where = (" (line contact: w relative to the datum)" if results.line
             else f" at Y = {results.y[j] * MM:.3g} mm")
    ax.set_title(f"{label}: deformed surface{where}, step {int(results.field_steps[k])} "
                 f"(body centre X = {sx * MM:.3g} mm)", fontsize=10)
    return figure


def _line_pressure_figure(results: Results, picks: list[int], label: str):
    """Line contact: the pressure profiles p(X) of the picked fields, with the body's position."""
    unit, scale = pressure_unit(float(results.pressure[picks].max(initial=0.0)))
    figure = constrained_figure(7.5, 4.5)
    ax = figure.subplots()
    loaded = np.flatnonzero(results.pressure[picks].max(axis=(0, 2)) > 0)
    for k in picks:
        row = _row(results, results.field_steps[k])
        t, sx = float(results.series["t"][row]), float(results.series["sx"][row])
        line, = ax.plot(results.x * MM, results.pressure[k, :, 0] / scale,
                        label=f"step {int(results.field_steps[k])}, t = {t:.4g} s")
        ax.axvline(sx * MM, color=line.get_color(), linestyle=":", linewidth=0.8)
    if loaded.size:
        pad = max(3, (loaded[-1] - loaded[0]) // 8)
        lo, hi = max(loaded[0] - pad, 0), min(loaded[-1] + pad, len(results.x) - 1)
        ax.set_xlim(results.x[lo] * MM, results.x[hi] * MM)
    ax.set_xlabel("X (mm)")
    ax.set_ylabel(f"contact pressure ({unit})")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, title="dotted: body centre", title_fontsize=8)
    ax.set_title(f"{label}: contact pressure (line contact, material frame)", fontsize=10)
    return figure


def _line_patches_figure(results: Results, label: str):
    """Line contact: the pressure profile of every saved field in the body's frame, coloured by time."""
    import matplotlib

    t_fields = field_times(results)
    norm = matplotlib.colors.Normalize(vmin=t_fields.min(), vmax=max(t_fields.max(), t_fields.min() + 1e-300))
    cmap = matplotlib.colormaps["viridis"]
    unit, scale = pressure_unit(float(results.pressure.max(initial=0.0)))
    figure = constrained_figure(6.4, 4.5)
    ax = figure.subplots()
    for k, t in enumerate(t_fields):
        sx = float(results.series["sx"][_row(results, results.field_steps[k])])
        ax.plot((results.x - sx) * MM, results.pressure[k, :, 0] / scale, color=cmap(norm(t)), linewidth=1.0)
    loaded = np.flatnonzero(results.pressure.max(axis=(0, 2)) > 0)
    reach = float(np.nanmax(np.abs(np.concatenate([results.series["lead"], results.series["trail"]]))))
    if loaded.size and np.isfinite(reach):
        ax.set_xlim(-1.3 * reach * MM, 1.3 * reach * MM)
    ax.axvline(0.0, color="black", linewidth=0.6)
    ax.set_xlabel("X - sx (mm)")
    ax.set_ylabel(f"contact pressure ({unit})")
    ax.grid(alpha=0.3)
    ax.set_title(f"{label}: pressure profiles in the body frame,\n{len(t_fields)} saved fields coloured by "
                 "time", fontsize=10)
    figure.colorbar(matplotlib.cm.ScalarMappable(norm=norm, cmap=cmap), ax=ax, label="time t (s)")
    return figure


def _patches_figure(results: Results, label: str):
    import matplotlib

    x, y = results.x, results.y
    t_fields = field_times(results)
    norm = matplotlib.colors.Normalize(vmin=t_fields.min(), vmax=max(t_fields.max(), t_fields.min() + 1e-300))
    cmap = matplotlib.colormaps["viridis"]
    figure = constrained_figure(6.4, 5.2)
    ax = figure.subplots()
    lo, hi = np.array([np.inf, np.inf]), np.array([-np.inf, -np.inf])
    for k, t in enumerate(t_fields):
        p = results.pressure[k]
        box = _contact_box(p, 2)
        if box is None:
            continue
        row = _row(results, results.field_steps[k])
        sx, sy = float(results.series["sx"][row]), float(results.series["sy"][row])
        bx, by = (x[box[0]] - sx) * MM, (y[box[1]] - sy) * MM
        inside = (p[box] > 0).astype(float).T
        if inside.shape[0] < 2 or inside.shape[1] < 2:
            continue
        ax.contour(bx, by, inside, levels=[0.5], colors=[cmap(norm(t))], linewidths=1.3)
        ix, iy = np.nonzero(p > 0)
        lo = np.minimum(lo, [(x[ix.min()] - sx) * MM, (y[iy.min()] - sy) * MM])
        hi = np.maximum(hi, [(x[ix.max()] - sx) * MM, (y[iy.max()] - sy) * MM])
    ax.plot([0], [0], marker="+", color="black", markersize=14, markeredgewidth=2, linestyle="none",
            label="body centre")
    if np.all(np.isfinite(lo)):
        cell = max(abs(x[1] - x[0]) if len(x) > 1 else 0, abs(y[1] - y[0]) if len(y) > 1 else 0) * MM
        margin = max(0.15 * float((hi - lo).max()), 2 * cell)
        ax.set_xlim(min(lo[0], 0) - margin, max(hi[0], 0) + margin)
        ax.set_ylim(min(lo[1], 0) - margin, max(hi[1], 0) + margin)
    else:
        ax.text(0.5, 0.6, "no contact in any saved field", transform=ax.transAxes, ha="center")
    ax.set_aspect("equal")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left", fontsize=8)
    ax.set_xlabel("X - sx (mm)")
    ax.set_ylabel("Y - sy (mm)")
    direction = _motion_direction(results.series)
    if direction is not None:
        tail = np.array([0.83, 0.08]) - 0.07 * direction
        ax.annotate("motion", xy=tuple(tail + 0.14 * direction), xytext=tuple(tail), xycoords="axes fraction",
                    textcoords="axes fraction", ha="center", va="center", fontsize=9,
                    arrowprops={"arrowstyle": "->", "color": "black"}, bbox={"fc": "white", "ec": "none"})
    ax.set_title(f"{label}: contact-patch outlines (p > 0)\nin the body frame, "
                 f"{len(t_fields)} saved fields coloured by time", fontsize=10)
    mappable = matplotlib.cm.ScalarMappable(norm=norm, cmap=cmap)
    figure.colorbar(mappable, ax=ax, label="time t (s)")
    return figure


def _islands_figure(results: Results, label: str):
    """The contact islands of the last saved field (cells sharing a side, joined around the periodic cell;
    each island one colour) and the radially averaged spectrum of its pressure (results.h5 group rough)."""
    import matplotlib

    from petroll.solver.rough import contact_islands

    p = results.pressure[-1]
    islands, count = contact_islands(p > 0)
    x, y = results.x * MM, results.y * MM
    figure = constrained_figure(11, 5)
    left, right = figure.subplots(1, 2, gridspec_kw={"width_ratios": [1.15, 1]})
    colours = matplotlib.colormaps["tab20"](np.arange(20))
    shade = np.where(islands[..., None] > 0, colours[(islands - 1) % 20], [1.0, 1.0, 1.0, 1.0])
    left.imshow(np.transpose(shade, (1, 0, 2)), origin="lower", interpolation="nearest",
                extent=(*cell_edges(x)[[0, -1]], *cell_edges(y)[[0, -1]]))
    left.set(xlabel="X (mm)", ylabel="Y (mm)", aspect="equal")
    fraction = float(results.rough["area_fraction"][-1])
    left.set_title(f"{label}: {count} contact islands, {100 * fraction:.2f} % of the cell\n"
                   f"(step {int(results.field_steps[-1])}; each island a colour)", fontsize=10)
    q, spectrum = results.rough["q"][-1], results.rough["spectrum"][-1]
    shown = np.isfinite(q) & (spectrum > 0)
    right.loglog(q[shown], spectrum[shown], "o-", markersize=3)
    right.set(xlabel="wavenumber q (rad/m)", ylabel="C(q) of the pressure (Pa$^2$ m$^2$)")
    right.set_title("radially averaged power spectrum of the pressure", fontsize=10)
    right.grid(alpha=0.3, which="both")
    return figure


def _series_figure(results: Results, label: str):
    s = results.series
    rolling = float(np.nanmax(s["distance"], initial=0.0)) > 0
    abscissa, xlabel = (s["distance"] * MM, "rolling distance (mm)") if rolling else (s["t"], "time t (s)")
    style = {"marker": "o", "markersize": 3} if len(abscissa) <= 30 else {}
    figure = constrained_figure(7.5, 8.0)
    force_ax, mu_ax, edge_ax = figure.subplots(3, 1, sharex=True)

    force_ax.plot(abscissa, s["force"], color="tab:blue", **style)
    force_ax.set_ylabel("normal force (N/m)" if results.line else "normal force (N)", color="tab:blue")
    force_ax.tick_params(axis="y", labelcolor="tab:blue")
    delta_ax = force_ax.twinx()
    delta_ax.plot(abscissa, s["delta"] * 1e6, color="tab:orange", linestyle="--",
                  **({**style, "marker": "s", "fillstyle": "none"} if style else {}))
    _widen_flat(force_ax, s["force"], 0.0)
    _widen_flat(delta_ax, s["delta"] * 1e6, 0.0)
    delta_ax.set_ylabel("penetration (µm, to the datum)" if results.line else "penetration (µm)",
                        color="tab:orange")
    delta_ax.tick_params(axis="y", labelcolor="tab:orange")
    force_ax.set_title(f"{label}: normal force and penetration", fontsize=10)

    mu_ax.plot(abscissa, s["mu_r"], color="tab:green", **style)
    mu_ax.axhline(0.0, color="grey", linewidth=0.6)
    _widen_flat(mu_ax, s["mu_r"], 1e-4)
    for ax in (force_ax, mu_ax, edge_ax):
        ax.grid(alpha=0.3)
    if results.rough is not None:  # a periodic cell: sliding friction and the area fraction, no one patch
        mu_ax.set_ylabel(r"friction $\mu$ (-)")
        mu_ax.set_title(r"friction coefficient $\mu$ = friction force / normal force", fontsize=10)
        cell = len(results.x) * (results.x[1] - results.x[0]) * len(results.y) * (results.y[1] - results.y[0])
        edge_ax.plot(abscissa, s["area"] / cell, color="tab:purple", **style)
        edge_ax.set_ylabel(r"area fraction $A/A_0$ (-)")
        edge_ax.set_title("real contact area / the cell's area", fontsize=10)
        edge_ax.set_xlabel(xlabel)
        return figure
    mu_ax.set_ylabel(r"rolling resistance $\mu_r$ (-)")
    mu_ax.set_title(r"rolling-resistance coefficient $\mu_r$ = resisting force / normal force", fontsize=10)

    edge_ax.plot(abscissa, s["lead"] * MM, color="tab:red", label="leading edge", **style)
    edge_ax.plot(abscissa, s["trail"] * MM, color="tab:purple", label="trailing edge", **style)
    if "cop_x" in s and rolling:
        along = _along_motion(s)
        edge_ax.plot(abscissa, along * MM, color="grey", linestyle=":", label="centre of pressure", **style)
    edge_ax.axhline(0.0, color="black", linewidth=0.6)
    edge_ax.set_ylabel("along the motion,\nrelative to body (mm)")
    edge_ax.legend(loc="lower center", bbox_to_anchor=(0.5, 1.0), ncol=3, fontsize=9, frameon=False,
                   title="contact-patch edges", title_fontsize=10)
    edge_ax.set_xlabel(xlabel)
    return figure


def _along_motion(s: dict[str, np.ndarray]) -> np.ndarray:
    """Centre of pressure projected on the direction of motion of each step (m, relative to the body)."""
    dx, dy = np.gradient(s["sx"]), np.gradient(s["sy"])
    norm = np.hypot(dx, dy)
    with np.errstate(invalid="ignore", divide="ignore"):
        ux, uy = np.where(norm > 0, dx / norm, np.nan), np.where(norm > 0, dy / norm, np.nan)
    return s["cop_x"] * ux + s.get("cop_y", 0.0) * uy  # line contact: no cop_y


def _motion_direction(s: dict[str, np.ndarray]) -> np.ndarray | None:
    """Unit vector of the overall motion (first to last position), or None for a body that stays put."""
    d = np.array([s["sx"][-1] - s["sx"][0], s["sy"][-1] - s["sy"][0]], dtype=float)
    length = float(np.hypot(*d))
    return d / length if length > 0 else None


def _widen_flat(ax, values: np.ndarray, floor: float) -> None:
    """Plain tick labels, and y-limits spanning at least 10 % of the level (or +-``floor``) for a flat
    curve."""
    ax.ticklabel_format(axis="y", useOffset=False)
    finite = np.asarray(values, dtype=float)[np.isfinite(values)]
    if finite.size == 0:
        return
    lo, hi = float(finite.min()), float(finite.max())
    half = max(0.05 * max(abs(lo), abs(hi)), floor)
    if hi - lo < half:
        mid = 0.5 * (lo + hi)
        ax.set_ylim(mid - half, mid + half)

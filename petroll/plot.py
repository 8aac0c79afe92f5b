"""PNG figures of a run's results.h5 (``petroll plot DIR``): pressure maps, patch outlines, series.

Lengths are drawn in mm, pressures in MPa, kPa or Pa (whichever suits the peak), forces in N (line
contact: N/m, and pressure profiles along X instead of maps and outlines).
matplotlib is imported only here, with the Agg canvas, so the solver does not depend on it.
"""

from __future__ import annotations

import pathlib
from collections.abc import Sequence

import numpy as np

from petroll.errors import PetrollError
from petroll.io.results import Results, atomic_write

MAX_PANELS = 4
"""Pressure maps drawn when no times are requested: the first, the last and evenly spaced ones between."""

MM = 1e3  # m -> mm


def plot_results(results_dir: str | pathlib.Path, out_dir: str | pathlib.Path | None = None,
                 times: Sequence[float] | None = None) -> list[pathlib.Path]:
    """Write pressure.png, patches.png and series.png for ``results_dir/results.h5``, surface.png
    when the run saved the surface displacement and gap ([output] fields), and islands.png for a run on a
    periodic grid (the contact islands of the last saved field and the pressure's spectrum).

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
    try:
        results = Results.open(path)
    except (OSError, KeyError) as exc:
        raise PetrollError(f"{path}: not a readable petroll results file ({exc})") from None
    if len(results.field_steps) == 0:
        raise PetrollError(f"{path}: the file holds no saved pressure fields")
    out = pathlib.Path(out_dir) if out_dir is not None else results_dir / "plots"
    out.mkdir(parents=True, exist_ok=True)
    label = results_dir.resolve().name
    written = []
    pressure, patches = (_line_pressure_figure, _line_patches_figure) if results.line else (
        _pressure_figure, _patches_figure)
    for name, figure in (("pressure.png", pressure(results, select_fields(results, times), label)),
                         ("patches.png", patches(results, label)),
                         ("series.png", _series_figure(results, label))):
        target = out / name
        figure.savefig(target, dpi=120)
        written.append(target)
    if "displacement" in results.fields:
        target = out / "surface.png"
        _surface_figure(results, label).savefig(target, dpi=120)
        written.append(target)
    if results.rough is not None:
        target = out / "islands.png"
        _islands_figure(results, label).savefig(target, dpi=120)
        written.append(target)
    return written


def select_fields(results: Results, times: Sequence[float] | None = None) -> list[int]:
    """Indices into ``results.pressure`` to draw: nearest to each of ``times`` (s), or up to 4 spread out."""
    n = len(results.field_steps)
    if times:
        t = field_times(results)
        picked = {int(np.argmin(np.abs(t - float(want)))) for want in times}
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


def new_figure(width: float, height: float):
    """A matplotlib figure of width x height inches (constrained layout) on the Agg canvas."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(figure)
    return figure


def _pressure_unit(p_max: float) -> tuple[str, float]:
    for name, scale in (("MPa", 1e6), ("kPa", 1e3)):
        if p_max >= 0.1 * scale:
            return name, scale
    return "Pa", 1.0


def _cell_edges(c: np.ndarray) -> np.ndarray:
    """Cell edges (m) of uniform cell centres ``c``."""
    h = c[1] - c[0] if len(c) > 1 else 1.0
    return np.concatenate([c - h / 2, [c[-1] + h / 2]])


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
    xe, ye = _cell_edges(x), _cell_edges(y)
    unit, scale = _pressure_unit(float(results.pressure[picks].max(initial=0.0)))
    vmax = max(float(results.pressure[picks].max(initial=0.0)) / scale, 1e-300)
    cols = min(len(picks), MAX_PANELS)
    rows = -(-len(picks) // cols)
    figure = new_figure(max(4.2 * cols, 6.0), 3.9 * rows)
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
    unit, scale = _pressure_unit(float(p.max(initial=0.0)))
    figure = new_figure(7.5, 4.5)
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
    where = " (line contact: w relative to the datum)" if results.line else f" at Y = {results.y[j] * MM:.3g} mm"
    ax.set_title(f"{label}: deformed surface{where}, step {int(results.field_steps[k])} "
                 f"(body centre X = {sx * MM:.3g} mm)", fontsize=10)
    return figure


def _line_pressure_figure(results: Results, picks: list[int], label: str):
    """Line contact: the pressure profiles p(X) of the picked fields, with the body's position."""
    unit, scale = _pressure_unit(float(results.pressure[picks].max(initial=0.0)))
    figure = new_figure(7.5, 4.5)
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
    unit, scale = _pressure_unit(float(results.pressure.max(initial=0.0)))
    figure = new_figure(6.4, 4.5)
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
    figure = new_figure(6.4, 5.2)
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
    figure = new_figure(11, 5)
    left, right = figure.subplots(1, 2, gridspec_kw={"width_ratios": [1.15, 1]})
    colours = matplotlib.colormaps["tab20"](np.arange(20))
    shade = np.where(islands[..., None] > 0, colours[(islands - 1) % 20], [1.0, 1.0, 1.0, 1.0])
    left.imshow(np.transpose(shade, (1, 0, 2)), origin="lower", interpolation="nearest",
                extent=(*_cell_edges(x)[[0, -1]], *_cell_edges(y)[[0, -1]]))
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
    figure = new_figure(7.5, 8.0)
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
    for ax in (force_ax, mu_ax, edge_ax):
        ax.grid(alpha=0.3)
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
    """Plain tick labels, and y-limits spanning at least 10 % of the level (or +-``floor``) for a flat curve."""
    ax.ticklabel_format(axis="y", useOffset=False)
    finite = np.asarray(values, dtype=float)[np.isfinite(values)]
    if finite.size == 0:
        return
    lo, hi = float(finite.min()), float(finite.max())
    half = max(0.05 * max(abs(lo), abs(hi)), floor)
    if hi - lo < half:
        mid = 0.5 * (lo + hi)
        ax.set_ylim(mid - half, mid + half)


# -- sweeps (petroll sweep) ----------------------------------------------------------------------------
def plot_sweep(table, path: str | pathlib.Path) -> pathlib.Path:
    """One PNG of a sweep (a :class:`petroll.studies.sweep.SweepTable`): mu_r (linear and log), force or penetration,
    contact area, patch edges and the convergence measures against the varied value, with V tau/a on a
    second axis where it applies and the rolling limits (formulation §7) where they apply."""
    import tomllib

    c = {name: np.asarray(values, dtype=float) for name, values in table.columns.items()}
    order = np.argsort(c["value"])
    c = {name: values[order] for name, values in c.items()}
    x = c["value"]
    logx = bool(np.all(x > 0) and x.max() >= 10 * x.min())
    try:
        raw = tomllib.loads(table.scene_text)
    except tomllib.TOMLDecodeError:
        raw = {}
    load_control = table.key == "motion.load" or ("load" in raw.get("motion", {})
                                                  and table.key != "motion.penetration")
    tol = raw.get("time", {}).get("steady")
    if tol is None and "time" in raw:
        from petroll.model.scene import DEFAULT_STEADY

        tol = DEFAULT_STEADY
    limits = bool(np.all(np.isfinite(c["mu_r_slow"])))
    unit = "" if table.unit == "-" else f" ({table.unit})"
    vector = table.key in ("motion.velocity", "body.position")
    xlabel = f"{table.key}{unit}" + (" (magnitude)" if vector else "")
    dense = np.geomspace(x.min(), x.max(), 200) if logx else np.linspace(x.min(), x.max(), 200)
    secondary = _secondary_axis(x, c["v_tau_a"], logx)
    style = {"marker": "o", "markersize": 4}
    # titles at a fixed height (matplotlib's own placement measures every tick label: about 1 s here), the
    # top row's above the V tau/a axis
    title = {"fontsize": 10, "y": 1.0}
    top_title = dict(title, pad=40 if secondary is not None else 6)

    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(12.0, 11.5))  # fixed margins: constrained layout costs seconds with log ticks
    FigureCanvasAgg(figure)
    axes = figure.subplots(3, 2, sharex=True)
    figure.subplots_adjust(left=0.08, right=0.98, bottom=0.06, top=0.9, wspace=0.22, hspace=0.3)
    (mu_ax, log_ax), (force_ax, area_ax), (edge_ax, conv_ax) = axes

    mu_ax.plot(x, c["mu_r"], color="tab:green", label=r"petroll, steady $\mu_r$", **style)
    top = max(float(np.nanmax(c["mu_r"], initial=0.0)), 1e-300)
    bottom = min(float(np.nanmin(c["mu_r"], initial=0.0)), 0.0)
    if limits:
        slow = _proportional(x, c["mu_r_slow"], dense)
        mu_ax.plot(dense if slow is not None else x, slow if slow is not None else c["mu_r_slow"],
                   color="black", linestyle="--", label=r"slow-rolling limit $V\tau(1 - J_0/J_\infty)/R$")
        mu_ax.axhline(0.0, color="tab:blue", linestyle=":", linewidth=1.5,
                      label=r"fast-rolling limit $\mu_r \to 0$ (Hertz with $J_0$)")
    else:
        mu_ax.axhline(0.0, color="grey", linewidth=0.6)
    mu_ax.set_ylim(bottom - 0.05 * (top - bottom), top + 0.25 * (top - bottom))
    mu_ax.set_ylabel(r"rolling resistance $\mu_r$ (-)")
    mu_ax.set_title(r"$\mu_r$ = resisting force / normal force (steady)", **top_title)
    mu_ax.legend(fontsize=8, loc="upper left")

    positive = c["mu_r"] > 0
    if np.any(positive):
        log_ax.plot(x[positive], c["mu_r"][positive], color="tab:green", label=r"petroll, steady $\mu_r$",
                    **style)
        if limits:
            slow = _proportional(x, c["mu_r_slow"], dense)
            log_ax.plot(dense if slow is not None else x, slow if slow is not None else c["mu_r_slow"],
                        color="black", linestyle="--", label="slow-rolling limit")
        log_ax.set_yscale("log")
        lo, hi = float(c["mu_r"][positive].min()), float(c["mu_r"][positive].max())
        log_ax.set_ylim(lo / 3, hi * 3)
        log_ax.legend(fontsize=8, loc="lower center")
    else:
        log_ax.text(0.5, 0.5, r"no positive $\mu_r$", transform=log_ax.transAxes, ha="center")
    log_ax.set_ylabel(r"$\mu_r$ (-), log scale")
    log_ax.set_title(r"$\mu_r$ on a log scale" + (" (the slow limit is a slope-1 line)" if limits else ""),
                     **top_title)

    if load_control:
        force_ax.plot(x, c["delta"] * 1e6, color="tab:orange", label="petroll, steady", **style)
        pairs = (("delta_J0", "fast-rolling limit: Hertz with $J_0$"),
                 ("delta_Jinf", r"slow-rolling limit: Hertz with $J_\infty$"))
        scale, what = 1e6, "penetration (µm)"
    else:
        force_ax.plot(x, c["force"], color="tab:blue", label="petroll, steady", **style)
        pairs = (("force_J0", "fast-rolling limit: Hertz with $J_0$"),
                 ("force_Jinf", r"slow-rolling limit: Hertz with $J_\infty$"))
        scale, what = 1.0, "normal force (N)"
    if limits:
        for (name, text), color in zip(pairs, ("tab:blue", "black")):
            force_ax.plot(x, c[name] * scale, color=color, linestyle=":" if name.endswith("J0") else "--",
                          label=text)
    elif np.all(np.isfinite(c[pairs[0][0]])):  # an elastic sphere: Hertz itself
        force_ax.plot(x, c[pairs[0][0]] * scale, color="black", linestyle="--", label="Hertz")
    force_ax.legend(fontsize=8)
    force_ax.set_ylabel(what)
    force_ax.set_title(("penetration under the given load" if load_control else
                        "normal force at the given penetration") + " (steady)", **title)

    area_ax.plot(x, c["area"] * MM**2, color="tab:purple", label="contact area", **style)
    if np.all(np.isfinite(c["a"])):
        area_ax.plot(x, np.pi * c["a"] ** 2 * MM**2, color="grey", linestyle=":",
                     label=r"$\pi a^2$ ($a$: Hertz radius of the first step)")
    area_ax.set_ylabel("contact area (mm²)")
    area_ax.set_title("contact area (steady)", **title)
    area_ax.legend(fontsize=8)

    edge_ax.plot(x, c["lead"] * MM, color="tab:red", label="leading edge", **style)
    edge_ax.plot(x, c["trail"] * MM, color="tab:purple", label="trailing edge", **style)
    if np.all(np.isfinite(c["a"])):
        edge_ax.plot(x, c["a"] * MM, color="grey", linestyle=":", label=r"$\pm a$")
        edge_ax.plot(x, -c["a"] * MM, color="grey", linestyle=":")
    edge_ax.axhline(0.0, color="black", linewidth=0.6)
    edge_ax.set_ylabel("along the motion, relative\nto the body (mm)")
    edge_ax.set_title("contact-patch edges (steady)", **title)
    edge_ax.legend(fontsize=8)
    edge_ax.set_xlabel(xlabel)

    if np.all((c["steps"] == 1) & (c["force_change"] == 0)):  # every point solved directly
        conv_ax.text(0.5, 0.5, 'every point solved directly ([time] mode = "steady"):\nno transient to converge',
                     transform=conv_ax.transAxes, ha="center", va="center")
        conv_ax.set_yticks([])
    else:
        for name, color, text in (("force_change", "tab:blue", "force"), ("mu_r_change", "tab:green", r"$\mu_r$"),
                                  ("resisting_change", "tab:red", r"$\mu_r F$ / F")):
            values = np.where(c[name] > 0, c[name], np.nan)
            conv_ax.plot(x, values, label=text, color=color, **style)
        if tol is not None:
            conv_ax.axhline(tol, color="black", linestyle="--", linewidth=0.8, label=f"[time] steady = {tol:g}")
        unsteady = c["steady"] == 0
        if np.any(unsteady) and tol is not None:
            conv_ax.plot(x[unsteady], np.full(int(unsteady.sum()), tol), linestyle="none", marker="x",
                         color="red", markersize=9, label="not steady at its end")
        if np.any(np.isfinite(np.where(c["force_change"] > 0, c["force_change"], np.nan))):
            conv_ax.set_yscale("log")
        if not np.any(np.isfinite(c["force_change"])):
            conv_ax.text(0.5, 0.5, "no convergence measure:\nno run rolled one contact length",
                         transform=conv_ax.transAxes, ha="center", va="center")
        conv_ax.legend(fontsize=8)
    conv_ax.set_ylabel("relative change over the\nlast contact length (-)")
    conv_ax.set_title("convergence of the steady values", **title)
    conv_ax.set_xlabel(xlabel)

    from matplotlib.ticker import NullLocator

    for ax in axes.ravel():
        if logx:
            ax.set_xscale("log")
            ax.xaxis.set_minor_locator(NullLocator())  # decades only: each tick costs time
        ax.grid(alpha=0.3)
    if secondary is not None:
        for ax in axes[0]:
            top_axis = ax.secondary_xaxis("top", functions=secondary)
            top_axis.set_xlabel(r"$V\tau/a$ (-)")
            if logx:
                top_axis.xaxis.set_minor_locator(NullLocator())
    label = pathlib.Path(table.directory).resolve().name
    figure.suptitle(f"{label}: steady state against {table.key} ({len(x)} runs)")
    path = pathlib.Path(path)
    figure.savefig(path, dpi=110)
    return path


def _proportional(x: np.ndarray, y: np.ndarray, dense: np.ndarray) -> np.ndarray | None:
    """y on ``dense`` if y = k x for one k (to 1e-9), else None."""
    if np.any(x == 0):
        return None
    k = y / x
    if not np.all(np.isfinite(k)) or np.ptp(k) > 1e-9 * np.abs(k).max():
        return None
    return k[0] * dense


def _secondary_axis(x: np.ndarray, v: np.ndarray, logx: bool):
    """(forward, inverse) from the varied value to V tau/a, when V tau/a is finite, positive and strictly
    monotone in it (linear in logs on a log axis, extrapolated linearly); else None."""
    if len(x) < 2 or not np.all(np.isfinite(v) & (v > 0)):
        return None
    k = v / x
    if np.all(x > 0) and np.ptp(k) <= 1e-9 * k.max():  # V tau/a = k x (a speed sweep): exact and fast
        k0 = float(k[0])
        return (lambda q: np.asarray(q, dtype=float) * k0), (lambda q: np.asarray(q, dtype=float) / k0)
    if logx:
        u, w = np.log(x), np.log(v)
    elif np.ptp(np.log10(v)) > 1:
        return None  # decades of V tau/a over a linear axis (a temperature sweep): no readable top axis
    else:
        u, w = x, np.log(v)
    if not (np.all(np.diff(w) > 0) or np.all(np.diff(w) < 0)) or not np.all(np.diff(u) > 0):
        return None
    if w[0] > w[-1]:
        u_rev, w_rev = u[::-1], w[::-1]
    else:
        u_rev, w_rev = u, w

    def extrapolated(q, a, b):
        q = np.asarray(q, dtype=float)
        out = np.interp(q, a, b)
        low, high = q < a[0], q > a[-1]
        out = np.where(low, b[0] + (q - a[0]) * (b[1] - b[0]) / (a[1] - a[0]), out)
        return np.where(high, b[-1] + (q - a[-1]) * (b[-1] - b[-2]) / (a[-1] - a[-2]), out)

    def forward(q):
        with np.errstate(divide="ignore", invalid="ignore"):
            q = np.log(np.maximum(q, 1e-300)) if logx else q
        return np.exp(extrapolated(q, u, w))

    def inverse(q):
        with np.errstate(divide="ignore", invalid="ignore"):
            r = extrapolated(np.log(np.maximum(q, 1e-300)), w_rev, u_rev)
        return np.exp(r) if logx else r

    return forward, inverse


def plot_stress(stress_path: str | pathlib.Path, out: str | pathlib.Path | None = None) -> pathlib.Path:
    """Write stress.png (default: next to ``stress_path``) for a stress.h5 of ``petroll stress``: for the
    von Mises stress and the maximum shear stress, a section along the motion through the maximum (depth
    downwards) and a map at the maximum's depth, zoomed on where the stress exceeds 10 % of its maximum."""
    from petroll.io.stress import stress_planes

    stress_path = pathlib.Path(stress_path)
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        raise PetrollError("stress.png needs matplotlib: pip install matplotlib") from None
    figure = new_figure(11.0, 8.0)
    axes = figure.subplots(2, 2, squeeze=False)
    for row, (name, title) in enumerate((("von_mises", "von Mises"),
                                          ("max_shear", "max shear (Tresca)"))):
        planes = stress_planes(stress_path, name)
        x, y, z, peak, (px, py, pz) = planes["x"], planes["y"], planes["z"], planes["peak"], planes["at"]
        attrs = planes["attrs"]
        axis = str(attrs["motion_axis"])
        unit, scale = _pressure_unit(max(peak, 1e-300))
        along, here, across = (x, px, ("Y", py)) if axis == "x" else (y, py, ("X", px))
        section, plane = planes["section"], planes["map"]
        span = _above(section.max(axis=0), 0.1 * peak)
        ax = axes[row, 0]
        h = abs(along[1] - along[0]) if len(along) > 1 else 1e-3
        image = ax.pcolormesh(_cell_edges(along)[span.start:span.stop + 1] * MM, _depth_edges(z, h) * MM,
                              section[:, span] / scale, cmap="viridis", shading="flat", vmin=0,
                              vmax=peak / scale)
        ax.set_aspect("equal")
        ax.invert_yaxis()
        ax.plot([here * MM], [pz * MM], marker="x", color="red", linestyle="none",
                label=f"maximum {peak / scale:.4g} {unit}")
        ax.set_xlabel(f"{axis.upper()} (mm), along the motion")
        ax.set_ylabel("depth z (mm)")
        line = plane.ndim == 1  # line contact: the section is the whole (plane-strain) field
        ax.set_title(f"{title}: " + ("plane strain" if line else f"section at {across[0]} = "
                                     f"{across[1] * MM:.4g} mm"), fontsize=10)
        ax.legend(loc="lower right", fontsize=8)
        figure.colorbar(image, ax=ax, label=unit)
        if line:
            ax = axes[row, 1]
            ax.plot(x * MM, plane / scale, color="tab:blue")
            ax.plot([px * MM], [peak / scale], marker="x", color="red", linestyle="none")
            ax.set_xlim(_cell_edges(x)[span.start] * MM, _cell_edges(x)[span.stop] * MM)
            ax.set_xlabel("X (mm)")
            ax.set_ylabel(unit)
            ax.grid(alpha=0.3)
            ax.set_title(f"{title} at z = {pz * MM:.4g} mm (the maximum's depth)", fontsize=10)
            continue
        bx, by = _above(plane.max(axis=1), 0.1 * peak), _above(plane.max(axis=0), 0.1 * peak)
        ax = axes[row, 1]
        image = ax.pcolormesh(_cell_edges(x)[bx.start:bx.stop + 1] * MM,
                              _cell_edges(y)[by.start:by.stop + 1] * MM, plane[bx, by].T / scale,
                              cmap="viridis", shading="flat", vmin=0, vmax=peak / scale)
        ax.plot([px * MM], [py * MM], marker="x", color="red", linestyle="none")
        ax.set_aspect("equal")
        ax.set_xlabel("X (mm)")
        ax.set_ylabel("Y (mm)")
        ax.set_title(f"{title} at z = {pz * MM:.4g} mm (the maximum's depth)", fontsize=10)
        figure.colorbar(image, ax=ax, label=unit)
    figure.suptitle(f"{stress_path.parent.resolve().name}: stresses below the surface, step "
                    f"{int(attrs['step'])} (t = {float(attrs['t']):.4g} s, nu = {float(attrs['nu']):g})")
    target = pathlib.Path(out) if out is not None else stress_path.with_suffix(".png")
    figure.savefig(target, dpi=120)
    return target


def _above(values: np.ndarray, level: float, pad: int = 2) -> slice:
    """Index slice spanning the entries of ``values`` above ``level``, widened by ``pad`` (all if none)."""
    inside = np.flatnonzero(values > level)
    if inside.size == 0:
        return slice(0, len(values))
    return slice(max(int(inside[0]) - pad, 0), min(int(inside[-1]) + pad + 1, len(values)))


def _depth_edges(z: np.ndarray, h: float) -> np.ndarray:
    """Edges (m) of depth bins centred at the sorted depths ``z`` (a single depth: a bin ``h`` high),
    clipped at 0."""
    if len(z) == 1:
        return np.array([max(z[0] - h / 2, 0.0), z[0] + h / 2])
    mid = (z[1:] + z[:-1]) / 2
    return np.concatenate([[max(z[0] - (mid[0] - z[0]), 0.0)], mid, [z[-1] + (z[-1] - mid[-1])]])

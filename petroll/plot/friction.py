"""traction.png of a run with friction (``petroll plot``): the tangential tractions and the stick and slip
areas of the last saved field. 3-D: maps of |q| with arrows along q, and of stick / slip / no contact;
line contact: the profiles of mu p and q_x along X over the stick and slip zones."""

from __future__ import annotations

import tomllib

import numpy as np

from petroll.io.results import Results
from petroll.plot.common import MM, cell_edges, constrained_figure, pressure_unit, span_above

STICK, SLIP = 1, 2
"""The stick/slip map's values (0: no contact)."""


def stick_slip(p: np.ndarray, slip: np.ndarray) -> np.ndarray:
    """0 outside the contact (p = 0), STICK where the slip velocity is 0, SLIP elsewhere (NaN included: the
    slipping cells of a step of no duration)."""
    return np.where(p > 0, np.where(slip == 0, STICK, SLIP), 0)


def traction_figure(results: Results, label: str):
    """The last saved field's tractions and stick/slip map (module docstring)."""
    k = len(results.field_steps) - 1
    p, slip = results.pressure[k], results.field("slip")[k]
    mu = float(tomllib.loads(results.scene_text)["friction"]["coefficient"])
    title = f"{label}: tangential tractions on the body, step {int(results.field_steps[k])} (material frame)"
    if results.line:
        return _line_figure(results, k, p[:, 0], slip[:, 0], mu, title)
    q = np.stack([results.field("traction_x")[k], results.field("traction_y")[k]])
    magnitude = np.hypot(*q)
    unit, scale = pressure_unit(max(float(mu * p.max(initial=0.0)), 1e-300))
    rows, cols = span_above(p.max(axis=1), 0.0, 3), span_above(p.max(axis=0), 0.0, 3)
    xe, ye = cell_edges(results.x)[rows.start:rows.stop + 1] * MM, cell_edges(results.y)[cols.start:cols.stop + 1] * MM
    figure = constrained_figure(10.0, 4.4)
    left, right = figure.subplots(1, 2)
    image = left.pcolormesh(xe, ye, magnitude[rows, cols].T / scale, cmap="viridis", shading="flat")
    step = max(1, (rows.stop - rows.start) // 16)
    x, y = np.meshgrid(results.x[rows][::step] * MM, results.y[cols][::step] * MM, indexing="ij")
    on = p[rows, cols][::step, ::step] > 0  # arrows in the contact only
    left.quiver(x[on], y[on], q[0][rows, cols][::step, ::step][on], q[1][rows, cols][::step, ::step][on],
                color="white", angles="xy", width=0.004)
    figure.colorbar(image, ax=left, label=f"|q| ({unit})", shrink=0.9)
    left.set_title("|q| and its direction", fontsize=10)
    from matplotlib.colors import ListedColormap

    kinds = stick_slip(p, slip)[rows, cols]
    right.pcolormesh(xe, ye, kinds.T, cmap=ListedColormap(["white", "tab:blue", "tab:orange"]), vmin=-0.5,
                     vmax=2.5, shading="flat")
    right.set_title("stick (blue) and slip (orange)", fontsize=10)
    for ax in (left, right):
        ax.set_aspect("equal")
        ax.set_xlabel("X (mm)")
        ax.set_ylabel("Y (mm)")
    figure.suptitle(title, fontsize=10)
    return figure


def _line_figure(results: Results, k: int, p: np.ndarray, slip: np.ndarray, mu: float, title: str):
    """Line contact: mu p, -mu p and q_x along X, the slip zones shaded."""
    q = results.field("traction_x")[k][:, 0]
    unit, scale = pressure_unit(max(float(mu * p.max(initial=0.0)), 1e-300))
    figure = constrained_figure(7.5, 4.5)
    ax = figure.subplots()
    x = results.x * MM
    ax.plot(x, mu * p / scale, color="grey", linestyle="--", label="+- mu p")
    ax.plot(x, -mu * p / scale, color="grey", linestyle="--")
    ax.plot(x, q / scale, color="tab:blue", label="q_x")
    half = 0.5 * (x[1] - x[0]) if len(x) > 1 else 0.5
    for i in np.flatnonzero(stick_slip(p, slip) == SLIP):
        ax.axvspan(x[i] - half, x[i] + half, color="tab:orange", alpha=0.25, linewidth=0)
    loaded = span_above(p, 0.0, 3)
    ax.set_xlim(x[loaded.start] - half, x[loaded.stop - 1] + half)
    ax.set_xlabel("X (mm)")
    ax.set_ylabel(f"traction ({unit})")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, title="shaded: slip", title_fontsize=8)
    ax.set_title(title, fontsize=10)
    return figure

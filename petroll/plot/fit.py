"""The figure of a Prony fit to DMA data (``petroll material fit``, :mod:`petroll.model.dma`)."""

from __future__ import annotations

import pathlib

import numpy as np

from petroll.io.results import atomic_write
from petroll.plot.common import constrained_figure


def plot_fit(data, fit, path: str | pathlib.Path) -> pathlib.Path:
    """One PNG (written atomically) of a Prony fit to DMA data (:mod:`petroll.model.dma`): E', E'' and
    tan delta against the (reduced) frequency, the data as points (one colour per temperature), the fit
    as a line."""
    figure = constrained_figure(12, 4)
    axes = figure.subplots(1, 3)
    f = np.geomspace(*fit.frequency_range, 400)
    storage, loss = fit.dynamic(f)
    from matplotlib import colormaps

    temperatures = [None] if data.temperature is None else sorted(set(data.temperature.tolist()))
    for i, T in enumerate(temperatures):
        rows = np.ones(len(data.reduced), bool) if T is None else data.temperature == T
        colour = "tab:blue" if T is None else colormaps["viridis"](i / max(1, len(temperatures) - 1))
        label = "data" if T is None else f"data at {T:g} K"
        for ax, y in zip(axes, (data.storage, data.loss, data.loss / data.storage)):
            ax.plot(data.reduced[rows], y[rows], "o", markersize=3.5, color=colour, label=label, alpha=0.8)
    for ax, y, name in zip(axes, (storage, loss, loss / storage), ("E' (Pa)", "E'' (Pa)", "tan delta (-)")):
        ax.plot(f, y, "-", color="black", linewidth=1.2, label=f"fit: {len(fit.moduli)} Maxwell terms")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("reduced frequency (Hz)" if data.shift is not None else "frequency (Hz)")
        ax.set_ylabel(name)
        ax.grid(alpha=0.3, which="both")
    axes[0].legend(fontsize=8)
    at = f" at T_ref = {data.shift.T_ref:g} K" if data.shift is not None else ""
    figure.suptitle(f"{pathlib.Path(data.source).name}: Prony fit{at}; relative error rms "
                    f"{100 * fit.rms_error:.3g} %, max {100 * fit.max_error:.3g} %")
    path = pathlib.Path(path)
    atomic_write(path, lambda tmp: figure.savefig(tmp, dpi=110, format="png"))
    return path

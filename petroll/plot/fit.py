"""The figures of ``petroll material fit`` (:mod:`petroll.model.dma`): the master curve with the fit,
coloured by measurement set, and the shift factors found from the data."""

from __future__ import annotations

import pathlib

import numpy as np

from petroll.plot.common import constrained_figure, write_figure


def plot_fit(data, fit, path: str | pathlib.Path) -> pathlib.Path:
    """Write :func:`fit_figure` as one PNG (atomically)."""
    figure = fit_figure(data, fit)
    return write_figure(figure, path, dpi=110)


def fit_figure(data, fit):
    """The figure of a Prony fit to DMA data: E', E'' and tan delta against the (reduced) frequency, each
    measurement set's points in the colour of its temperature (a colour bar), the fit as a line."""
    from matplotlib import colormaps
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize

    figure = constrained_figure(13, 4)
    axes = figure.subplots(1, 3)
    f = np.geomspace(*fit.frequency_range, 400)
    storage, loss = fit.dynamic(f)
    temperatures = [s.temperature for s in data.sets if s.temperature is not None]
    colours = None
    if temperatures:
        lo, hi = min(temperatures), max(temperatures)
        colours = ScalarMappable(Normalize(lo, hi if hi > lo else lo + 1.0), colormaps["viridis"])
    for s in data.sets:
        colour = "tab:blue" if colours is None else colours.to_rgba(s.temperature)
        for ax, y in zip(axes, (data.storage, data.loss, data.loss / data.storage)):
            ax.plot(data.reduced[s.rows], y[s.rows], "o", markersize=3, color=colour, alpha=0.8,
                    label="data" if colours is None else None)
    for ax, y, name in zip(axes, (storage, loss, loss / storage), ("E' (Pa)", "E'' (Pa)", "tan delta (-)")):
        ax.plot(f, y, "-", color="black", linewidth=1.2, label=f"fit: {len(fit.moduli)} Maxwell terms")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("reduced frequency (Hz)" if data.shift is not None else "frequency (Hz)")
        ax.set_ylabel(name)
        ax.grid(alpha=0.3, which="both")
    axes[0].legend(fontsize=8)
    if colours is not None:
        figure.colorbar(colours, ax=axes, label=f"set temperature (K): {len(data.sets)} sets", pad=0.01)
    at = f" at T_ref = {data.T_ref:g} K" if data.shift is not None else ""
    figure.suptitle(f"{pathlib.Path(data.source).name}: Prony fit{at}; relative error rms "
                    f"{100 * fit.rms_error:.3g} %, max {100 * fit.max_error:.3g} %")
    return figure


def plot_shifts(data, path: str | pathlib.Path) -> pathlib.Path:
    """Write :func:`shift_figure` as one PNG (atomically)."""
    figure = shift_figure(data)
    return write_figure(figure, path, dpi=110)


def shift_figure(data):
    """The shift factors found from the data (``data.found``, petroll.model.tts): log10 a_T of each set
    against its temperature, with error bars of one standard error, the table law through them and the
    WLF and Arrhenius laws fitted to them (left), and each law's difference from the factors, the factors'
    standard errors as a band about 0 (right)."""
    found = data.found
    figure = constrained_figure(11, 4.2)
    left, right = figure.subplots(1, 2)
    T = np.linspace(found.temperatures[0], found.temperatures[-1], 300)
    left.errorbar(found.temperatures, found.log10_aT, yerr=found.sigma, fmt="o", color="black", markersize=4,
                  capsize=2, label=f"found: {len(found.temperatures)} sets, +- 1 standard error")
    left.plot(T, [found.law.log10(t) for t in T], "-", color="black", linewidth=1, label="table law (PCHIP)")
    for name, fit, style in (("WLF", found.wlf, "--"), ("Arrhenius", found.arrhenius, ":")):
        if fit.law is None:
            continue
        label = f"{name} fitted: rms {fit.rms:.2g}, max {fit.max:.2g} decade"
        left.plot(T, [fit.law.log10(t) for t in T], style, linewidth=1.5, label=label)
        right.plot(found.temperatures, [fit.law.log10(t) for t in found.temperatures] - found.log10_aT,
                   style + "o", markersize=3, label=name)
    left.axvline(found.T_ref, color="grey", linewidth=0.8)
    left.set_xlabel("temperature (K)")
    left.set_ylabel("log10 a_T")
    left.set_title(f"shift factors found from the data, T_ref = {found.T_ref:g} K", fontsize=10)
    right.axhline(0, color="black", linewidth=0.8)
    right.fill_between(found.temperatures, -found.sigma, found.sigma, color="grey", alpha=0.3,
                       label="+- the factors' standard error")
    right.set_xlabel("temperature (K)")
    right.set_ylabel("law - factors (decades)")
    right.set_title("residuals of the fitted laws", fontsize=10)
    for ax in (left, right):
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    figure.suptitle(f"{pathlib.Path(data.source).name}: time-temperature shift")
    return figure

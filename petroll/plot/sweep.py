"""The figure of a sweep (``petroll sweep``, :class:`petroll.studies.sweep.SweepTable`): the steady values
against the varied one, with the rolling limits (formulation §7) and V tau/a where they apply."""

from __future__ import annotations

import pathlib
from dataclasses import dataclass

import numpy as np

from petroll.plot.common import MM, write_figure

STYLE = {"marker": "o", "markersize": 4}
TITLE = {"fontsize": 10, "y": 1.0}
"""Titles at a fixed height: matplotlib's own placement measures every tick label (about 1 s here)."""


@dataclass(frozen=True)
class SweepData:
    """What every panel of a sweep's figure draws from: the columns sorted by the varied value ``x``."""

    c: dict[str, np.ndarray]
    x: np.ndarray
    logx: bool  # the values span a decade or more: log axes
    limits: bool  # the rolling limits apply (a sphere or cylinder on a Prony material)
    load_control: bool
    tol: float | None  # [time] steady of the swept scene
    xlabel: str
    dense: np.ndarray  # values between the points, for the limits' lines
    secondary: tuple | None  # (forward, inverse) to V tau/a for a top axis, or None
    cell: bool = False  # a periodic cell (rough sliding): friction mu, A/A0, no patch edges, no Hertz

    @classmethod
    def of(cls, table) -> "SweepData":
        import tomllib

        c = {name: np.asarray(values, dtype=float) for name, values in table.columns.items()}
        order = np.argsort(c["value"])
        c = {name: values[order] for name, values in c.items()}
        x = c["value"]
        logx = bool(np.all(x > 0) and x.max() >= 10 * x.min())
        try:
            raw = tomllib.loads(table.scene_text)
        except (ValueError, RecursionError):  # TOMLDecodeError is a ValueError
            raw = {}
        load_control = table.key == "motion.load" or ("load" in raw.get("motion", {})
                                                      and table.key != "motion.penetration")
        tol = raw.get("time", {}).get("steady")
        if tol is None and "time" in raw:
            from petroll.model.schema import DEFAULT_STEADY

            tol = DEFAULT_STEADY
        unit = "" if table.unit == "-" else f" ({table.unit})"
        vector = table.key in ("motion.velocity", "body.position", "motion.creepage", "motion.tangential_force")
        dense = np.geomspace(x.min(), x.max(), 200) if logx else np.linspace(x.min(), x.max(), 200)
        cell = "area_fraction" in c and bool(np.all(np.isfinite(c["area_fraction"])))
        xlabel = ("sliding speed V (m/s)" if cell and table.key == "motion.velocity" else
                  f"{table.key}{unit}" + (" (magnitude)" if vector else ""))
        return cls(c, x, logx, bool(np.all(np.isfinite(c["mu_r_slow"]))) and not cell, load_control, tol, xlabel,
                   dense, None if cell else _secondary_axis(x, c["v_tau_a"], logx), cell)

    @property
    def mu(self) -> str:
        """The coefficient's symbol: friction mu on a periodic cell, rolling resistance mu_r otherwise."""
        return r"$\mu$" if self.cell else r"$\mu_r$"

    def slow_limit(self) -> tuple[np.ndarray, np.ndarray]:
        """(x, mu_r) of the slow-rolling limit: a line on the dense values where it is proportional."""
        slow = _proportional(self.x, self.c["mu_r_slow"], self.dense)
        return (self.dense, slow) if slow is not None else (self.x, self.c["mu_r_slow"])


def plot_sweep(table, path: str | pathlib.Path) -> pathlib.Path:
    """One figure of a sweep (a :class:`petroll.studies.sweep.SweepTable`; format by ``path``'s suffix):
    mu_r (linear and log), force or penetration, contact area, patch edges and the convergence measures
    against the varied value, with V tau/a on a second axis where it applies and the rolling limits
    (formulation §7) where they apply."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    d = SweepData.of(table)
    figure = Figure(figsize=(12.0, 11.5))  # fixed margins: constrained layout costs seconds with log ticks
    FigureCanvasAgg(figure)
    axes = figure.subplots(3, 2, sharex=True)
    figure.subplots_adjust(left=0.08, right=0.98, bottom=0.06, top=0.9, wspace=0.22, hspace=0.3)
    top_title = dict(TITLE, pad=40 if d.secondary is not None else 6)  # above the V tau/a axis
    (mu_ax, log_ax), (force_ax, area_ax), (edge_ax, conv_ax) = axes
    mu_panel(mu_ax, d, top_title)
    if table.key not in CREEPAGES and np.any(np.isfinite(d.c.get("creep_coefficient", np.nan))):
        coefficient_panel(log_ax, d, top_title)  # friction at one creepage: the creep coefficient
    elif np.any(np.isfinite(d.c.get("traction_x", np.nan))):  # a sweep with friction: its creep-force curve
        creep_panel(log_ax, d, top_title, table.scene_text)
    else:
        log_mu_panel(log_ax, d, top_title)
    force_panel(force_ax, d)
    area_panel(area_ax, d)
    (pressure_panel if d.cell else edges_panel)(edge_ax, d)
    convergence_panel(conv_ax, d)
    _x_axes(axes, d)
    label = pathlib.Path(table.directory).resolve().name
    figure.suptitle(f"{label}: steady state against {table.key} ({len(d.x)} runs)")
    return write_figure(figure, path, dpi=110)


CREEPAGES = ("motion.creepage", "motion.tangential_force")
"""The keys whose sweep with friction is a traction (creep-force) curve."""
COEFFICIENT = r"creep coefficient $-F \cdot \xi / (G_\infty c^2 |\xi|^2)$"


def coefficient_panel(ax, d: SweepData, title: dict) -> None:
    """A sweep with [friction] at one creepage: the creep coefficient (petroll.studies.sweep's column,
    Kalker's normalisation with the relaxed modulus) against the varied value."""
    ax.plot(d.x, d.c["creep_coefficient"], color="tab:purple", label="petroll, steady", **STYLE)
    ax.set_ylabel(COEFFICIENT)
    ax.set_title(r"creep coefficient (relaxed $G_\infty$, $c$)", **title)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)


def traction_ratio(c: dict[str, np.ndarray], scene_text: str) -> np.ndarray:
    """|F_t| / (mu F) of a friction sweep's columns ``c`` (mu the scene's [friction] coefficient)."""
    import tomllib

    mu = float(tomllib.loads(scene_text)["friction"]["coefficient"])
    return np.hypot(c["traction_x"], np.nan_to_num(c.get("traction_y", 0.0 * c["traction_x"]))) / (mu * c["force"])


def plot_family(family, path: str | pathlib.Path) -> pathlib.Path:
    """One figure of a family of sweeps (a :class:`petroll.studies.sweep.Family`), one line per value of
    the family's key: each curve's traction ratio |F_t|/(mu F) and stick area's share against the
    creepage (a family of traction curves); or its creep coefficient and mu_r against V tau/a (friction at
    one creepage: the master curve, V tau/a including the temperature's shift); else mu_r and the force
    against the varied value."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(12.0, 5.0))
    FigureCanvasAgg(figure)
    left, right = figure.subplots(1, 2)
    figure.subplots_adjust(left=0.07, right=0.98, bottom=0.12, top=0.88, wspace=0.25)
    first = family.tables[0]
    traction = first.key in CREEPAGES and bool(np.any(np.isfinite(first.columns.get("traction_x", np.nan))))
    coefficient = not traction and bool(np.any(np.isfinite(first.columns.get("creep_coefficient", np.nan))))
    logs, xlabel = [], ""
    for value, table in zip(family.values, family.tables):
        d = SweepData.of(table)
        c = d.c
        master = not traction and bool(np.all(np.isfinite(c["v_tau_a"])) and np.all(c["v_tau_a"] > 0))
        x = c["v_tau_a"] if master else d.x
        xlabel = "V tau / a" if master else d.xlabel
        logs.append(bool(np.all(x > 0) and x.max() >= 10 * x.min()))
        label = f"{family.key} = {value:.4g}" + ("" if family.unit == "-" else f" {family.unit}")
        if traction and np.all(np.isfinite(c["v_tau_a"])):
            label += f" (V tau/a = {float(np.median(c['v_tau_a'])):.3g})"
        if traction:
            ys = (traction_ratio(c, table.scene_text), c["stick_area"] / c["area"])
        elif coefficient:
            ys = (c["creep_coefficient"], c["mu_r"])
        else:
            ys = (c["mu_r"], c["force"])
        for ax, y in zip((left, right), ys):
            ax.plot(x, y, label=label, **STYLE)
    names = ((r"$|F_t| / (\mu F)$", "stick area / contact area") if traction else
             (COEFFICIENT, r"$\mu_r$") if coefficient else (r"$\mu_r$", "force (N)"))
    for ax, name in zip((left, right), names):
        ax.set_xlabel(xlabel)
        ax.set_ylabel(name)
        if all(logs) and not traction:  # a traction curve on linear axes: its slope at the origin
            ax.set_xscale("log")
        ax.grid(alpha=0.3)
    left.legend(fontsize=8)
    what = "traction curves" if traction else "creep coefficient" if coefficient else "curves"
    label = pathlib.Path(family.directory).resolve().name
    figure.suptitle(f"{label}: {what}, {first.key} at {len(family.values)} values of {family.key}")
    return write_figure(figure, path, dpi=110)


def creep_panel(ax, d: SweepData, title: dict, scene_text: str) -> None:
    """A sweep with [friction]: the tangential force over mu x the normal force (the creep-force curve)
    and the stick area's fraction of the contact area, against the varied value."""
    c = d.c
    ax.plot(d.x, traction_ratio(c, scene_text), color="tab:blue", label=r"$|F_t| / (\mu F)$", **STYLE)
    ax.plot(d.x, c["stick_area"] / c["area"], color="tab:orange", label="stick area / contact area", **STYLE)
    ax.set_ylim(-0.02, 1.05)
    ax.set_title("creep-force curve", **title)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)


def mu_panel(ax, d: SweepData, title: dict) -> None:
    """mu_r against the varied value, with the slow- and fast-rolling limits (a periodic cell: the sliding
    friction mu)."""
    c, x = d.c, d.x
    ax.plot(x, c["mu_r"], color="tab:green", label=f"petroll, steady {d.mu}", **STYLE)
    top = max(float(np.nanmax(c["mu_r"], initial=0.0)), 1e-300)
    bottom = min(float(np.nanmin(c["mu_r"], initial=0.0)), 0.0)
    if d.limits:
        ax.plot(*d.slow_limit(), color="black", linestyle="--",
                label=r"slow-rolling limit $e/R$, $e = (V/J_\infty)\int_0^\infty (J_\infty - J)\,dt$")
        ax.axhline(0.0, color="tab:blue", linestyle=":", linewidth=1.5,
                   label=r"fast-rolling limit $\mu_r \to 0$ (Hertz with $J_0$)")
    else:
        ax.axhline(0.0, color="grey", linewidth=0.6)
    ax.set_ylim(bottom - 0.05 * (top - bottom), top + 0.25 * (top - bottom))
    if d.cell:
        ax.set_ylabel(r"friction $\mu$ (-)")
        ax.set_title(r"$\mu$ = friction force / normal force (steady sliding)", **title)
    else:
        ax.set_ylabel(r"rolling resistance $\mu_r$ (-)")
        ax.set_title(r"$\mu_r$ = resisting force / normal force (steady)", **title)
    ax.legend(fontsize=8, loc="upper left")


def log_mu_panel(ax, d: SweepData, title: dict) -> None:
    """mu_r on a log scale (the slow limit a slope-1 line)."""
    mu, x = d.c["mu_r"], d.x
    positive = mu > 0
    if np.any(positive):
        ax.plot(x[positive], mu[positive], color="tab:green", label=f"petroll, steady {d.mu}", **STYLE)
        if d.limits:
            ax.plot(*d.slow_limit(), color="black", linestyle="--", label="slow-rolling limit")
        ax.set_yscale("log")
        ax.set_ylim(float(mu[positive].min()) / 3, float(mu[positive].max()) * 3)
        ax.legend(fontsize=8, loc="lower center")
    else:
        ax.text(0.5, 0.5, f"no positive {d.mu}", transform=ax.transAxes, ha="center")
    ax.set_ylabel(f"{d.mu} (-), log scale")
    ax.set_title(f"{d.mu} on a log scale" + (" (the slow limit is a slope-1 line)" if d.limits else ""),
                 **title)


def force_panel(ax, d: SweepData) -> None:
    """The normal force (or, under load control, the penetration) with its Hertz limits."""
    c, x = d.c, d.x
    if d.load_control:
        ax.plot(x, c["delta"] * 1e6, color="tab:orange", label="petroll, steady", **STYLE)
        pairs = (("delta_J0", "fast-rolling limit: Hertz with $J_0$"),
                 ("delta_Jinf", r"slow-rolling limit: Hertz with $J_\infty$"))
        scale, what = 1e6, "penetration (µm)"
    else:
        ax.plot(x, c["force"], color="tab:blue", label="petroll, steady", **STYLE)
        pairs = (("force_J0", "fast-rolling limit: Hertz with $J_0$"),
                 ("force_Jinf", r"slow-rolling limit: Hertz with $J_\infty$"))
        scale, what = 1.0, "normal force (N)"
    if d.limits:
        for (name, text), color in zip(pairs, ("tab:blue", "black")):
            ax.plot(x, c[name] * scale, color=color, linestyle=":" if name.endswith("J0") else "--",
                    label=text)
    elif np.all(np.isfinite(c[pairs[0][0]])) and not d.cell:  # an elastic sphere: Hertz itself
        ax.plot(x, c[pairs[0][0]] * scale, color="black", linestyle="--", label="Hertz")
    ax.legend(fontsize=8)
    ax.set_ylabel(what)
    ax.set_title(("penetration under the given load" if d.load_control else
                  "normal force at the given penetration") + " (steady)", **TITLE)


def area_panel(ax, d: SweepData) -> None:
    """The contact area against pi a^2 (a periodic cell: the area fraction A/A0)."""
    c, x = d.c, d.x
    if d.cell:
        ax.plot(x, c["area_fraction"], color="tab:purple", label="area fraction", **STYLE)
        ax.set_ylabel(r"area fraction $A/A_0$ (-)")
        ax.set_title(r"real contact area / the cell's area, $A/A_0$ (steady)", **TITLE)
        ax.legend(fontsize=8)
        return
    ax.plot(x, c["area"] * MM**2, color="tab:purple", label="contact area", **STYLE)
    if np.all(np.isfinite(c["a"])):
        ax.plot(x, np.pi * c["a"] ** 2 * MM**2, color="grey", linestyle=":",
                label=r"$\pi a^2$ ($a$: Hertz radius of the first step)")
    ax.set_ylabel("contact area (mm²)")
    ax.set_title("contact area (steady)", **TITLE)
    ax.legend(fontsize=8)


def edges_panel(ax, d: SweepData) -> None:
    """The patch's leading and trailing edges relative to the body, against +-a."""
    c, x = d.c, d.x
    ax.plot(x, c["lead"] * MM, color="tab:red", label="leading edge", **STYLE)
    ax.plot(x, c["trail"] * MM, color="tab:purple", label="trailing edge", **STYLE)
    if np.all(np.isfinite(c["a"])):
        ax.plot(x, c["a"] * MM, color="grey", linestyle=":", label=r"$\pm a$")
        ax.plot(x, -c["a"] * MM, color="grey", linestyle=":")
    ax.axhline(0.0, color="black", linewidth=0.6)
    ax.set_ylabel("along the motion, relative\nto the body (mm)")
    ax.set_title("contact-patch edges (steady)", **TITLE)
    ax.legend(fontsize=8)
    ax.set_xlabel(d.xlabel)


def pressure_panel(ax, d: SweepData) -> None:
    """The peak pressure (a periodic cell's panel where a single patch's edges would be)."""
    ax.plot(d.x, d.c["p_max"] / 1e6, color="tab:red", label="peak pressure", **STYLE)
    ax.set_ylabel("peak pressure (MPa)")
    ax.set_title("peak pressure (steady)", **TITLE)
    ax.legend(fontsize=8)
    ax.set_xlabel(d.xlabel)


def convergence_panel(ax, d: SweepData) -> None:
    """How much each point's force and mu_r still changed over its last contact length (transient runs)."""
    c, x, tol = d.c, d.x, d.tol
    ax.set_ylabel("relative change over the\nlast contact length (-)")
    ax.set_title("convergence of the steady values", **TITLE)
    ax.set_xlabel(d.xlabel)
    if np.all((c["steps"] == 1) & (c["force_change"] == 0)):  # every point solved directly
        ax.text(0.5, 0.5, 'every point solved directly ([time] mode = "steady"):\nno transient to converge',
                transform=ax.transAxes, ha="center", va="center")
        ax.set_yticks([])
        return
    for name, color, text in (("force_change", "tab:blue", "force"), ("mu_r_change", "tab:green", r"$\mu_r$"),
                              ("resisting_change", "tab:red", r"$\mu_r F$ / F")):
        ax.plot(x, np.where(c[name] > 0, c[name], np.nan), label=text, color=color, **STYLE)
    if tol is not None:
        ax.axhline(tol, color="black", linestyle="--", linewidth=0.8, label=f"[time] steady = {tol:g}")
        unsteady = c["steady"] == 0
        if np.any(unsteady):
            ax.plot(x[unsteady], np.full(int(unsteady.sum()), tol), linestyle="none", marker="x", color="red",
                    markersize=9, label="not steady at its end")
    if np.any(np.isfinite(np.where(c["force_change"] > 0, c["force_change"], np.nan))):
        ax.set_yscale("log")
    if not np.any(np.isfinite(c["force_change"])):
        ax.text(0.5, 0.5, "no convergence measure:\nno run rolled one contact length", transform=ax.transAxes,
                ha="center", va="center")
    ax.legend(fontsize=8)


def _x_axes(axes, d: SweepData) -> None:
    """Log or linear x axes with a grid, and V tau/a on top of the first row where it applies."""
    from matplotlib.ticker import NullLocator

    for ax in axes.ravel():
        if d.logx:
            ax.set_xscale("log")
            ax.xaxis.set_minor_locator(NullLocator())  # decades only: each tick costs time
        ax.grid(alpha=0.3)
    if d.secondary is not None:
        for ax in axes[0]:
            top_axis = ax.secondary_xaxis("top", functions=d.secondary)
            top_axis.set_xlabel(r"$V\tau/a$ (-), $\tau = 1/\omega$ at the peak of the loss compliance "
                                r"$J''(\omega)$")
            if d.logx:
                top_axis.xaxis.set_minor_locator(NullLocator())


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

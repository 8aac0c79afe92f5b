"""What the benchmarks write: CSV tables printed as text, and PNG figures on matplotlib's Agg canvas
(matplotlib is optional: without it a figure is skipped with one line printed)."""

from __future__ import annotations

import csv
import pathlib

from petroll.plot.common import write_figure


def write_table(rows: list[dict], path: pathlib.Path, show: bool = True) -> None:
    """Write the rows (one dict per row, the first row's keys as columns) as CSV to ``path`` and
    (``show``) print them as a table."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    if show:
        print_table(rows)


def print_table(rows: list[dict]) -> None:
    """Print the rows as a text table, columns padded to their widest entry."""
    names = list(rows[0])
    widths = [max(len(n), *(len(str(r[n])) for r in rows)) for n in names]
    print(" | ".join(n.ljust(w) for n, w in zip(names, widths)))
    print("-|-".join("-" * w for w in widths))
    for r in rows:
        print(" | ".join(str(r[n]).ljust(w) for n, w in zip(names, widths)))


def new_figure(width: float, height: float):
    """A matplotlib Figure on the Agg canvas (inches), or None with one line printed if matplotlib is
    missing."""
    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    except ImportError:
        print("petroll bench: matplotlib is not installed: no PNG (pip install matplotlib)")
        return None
    figure = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(figure)
    return figure


def save_figure(figure, path: pathlib.Path) -> None:
    """Write the figure as PNG to ``path`` and say so."""
    write_figure(figure, path, dpi=110)
    print(f"petroll bench: wrote {path}")


def plot_lines(series: dict[str, list], path: pathlib.Path, xlabel: str, ylabel: str, title: str) -> None:
    """One line per entry of ``series`` (values against their index + 1) in a PNG."""
    figure = new_figure(6, 4)
    if figure is None:
        return
    ax = figure.subplots()
    for label, values in series.items():
        ax.plot(range(1, len(values) + 1), values, label=label)
    ax.set(xlabel=xlabel, ylabel=ylabel, title=title)
    ax.legend()
    save_figure(figure, path)

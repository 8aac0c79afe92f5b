"""Figures from petroll's files (``petroll plot``): a run's results.h5 (:mod:`.runs`), a sweep
(:mod:`.sweep`), a stress.h5 (:mod:`.stress`), a DMA fit (:mod:`.fit`); PNG, PDF or SVG by the file's
suffix. matplotlib (Agg canvas) is imported only inside these modules' functions, so the solver does not
depend on it.

Rules: reads files through petroll.io and draws; imports nothing of petroll.studies (a sweep's table is
passed in).
"""

from petroll.plot.fit import plot_fit, plot_shifts
from petroll.plot.runs import field_times, plot_results, select_fields
from petroll.plot.stress import plot_stress
from petroll.plot.sweep import plot_family, plot_sweep

__all__ = ["field_times", "plot_fit", "plot_results", "plot_shifts", "plot_family", "plot_stress", "plot_sweep", "select_fields"]

"""A tally of the FFT work of the solver's convolutions, the unit of the benchmarks' counts (petroll bench
steady): every convolution or correlation applied adds the cost of its forward-and-inverse transform
pair, points x log2(transformed length) (a 2-D transform: points x log2(points)), for the whole field
(the same on every rank, whatever its share). Counted: the influence operator's applications (the QPs'
Hessian, a history's or wake's convolution, the steady solve's wake-extended grid), the preconditioner's
circulant, and the steady memory's correlations along the motion and its far wake. Not counted: the
transforms that make a kernel's spectrum (once per window shape), and the QP's elementwise work.
"""

from __future__ import annotations

import math


class FFTWork:
    """The tally: ``FFTWork.total`` only grows; the difference between two readings is the work done."""

    total = 0.0


def fft_cost(points: int, length: int) -> float:
    """The cost of a forward-and-inverse transform pair over ``points`` values transformed along lengths
    whose product is ``length`` (a batch of 1-D transforms: their length)."""
    return points * math.log2(max(length, 2))


def tally(cost: float) -> None:
    """Add ``cost`` (:func:`fft_cost`) to the tally."""
    FFTWork.total += cost

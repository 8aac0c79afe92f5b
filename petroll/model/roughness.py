"""Self-affine random rough surfaces: their power spectrum, their generation, and the spectrum of a field.

Power spectral density in Persson's convention (Persson et al., J. Phys.: Condens. Matter 17, R1, 2005):
C(q) = (2 pi)^-2 * integral <h(x) h(0)> exp(-i q.x) d^2x (m^4), so that for an isotropic surface

    h_rms^2 = 2 pi * integral q C(q) dq,    (rms slope)^2 = <|grad h|^2> = 2 pi * integral q^3 C(q) dq.

A self-affine surface with a rolloff (:class:`SelfAffinePSD`): C = C0 for q < q_r, C0 (q / q_r)^(-2 (1 + H))
for q_r <= q <= q_s and 0 beyond, with H the Hurst exponent, q_r = 2 pi / (rolloff wavelength) and
q_s = 2 pi / (short cut-off wavelength); wavenumbers q in rad/m.

On a periodic nx x ny grid of spacing (hx, hy), h(x) = sum_k a_k exp(i k.x) with
<|a_k|^2> = (2 pi)^2 C(|k|) / (Lx Ly), Lx = nx hx, Ly = ny hy (:func:`self_affine_heights` draws such a
Gaussian field; :func:`radial_psd` estimates C back from any field).
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

import numpy as np
import scipy.fft

from petroll.errors import MISSING, SceneError
from petroll.model.limits import heights_out_of_scale

__all__ = ["ROUGH_KEYS", "SelfAffinePSD", "TabulatedPSD", "radial_psd", "self_affine_heights", "self_affine_psd"]

ROUGH_KEYS: dict[str, str] = {
    "hurst": "Hurst exponent H, 0 < H <= 1: C(q) ~ q^(-2 (1 + H)) between rolloff and cutoff (required)",
    "rolloff": "rolloff wavelength, m: C(q) is flat at longer wavelengths (default: the surface's longer "
               "side, no plateau)",
    "cutoff": "short cut-off wavelength, m, at least 2 cells: no roughness at shorter wavelengths (default: "
              "2 cells)",
    "rms_height": "rms height of the surface, m (give this or rms_slope)",
    "rms_slope": "rms slope sqrt(<|grad h|^2>) of the surface, dimensionless (give this or rms_height)",
    "seed": "seed of the random numbers, an integer >= 0: the same keys give the same surface (default 0)",
}
"""The keys of a generated self-affine surface, with their meaning and units."""


@dataclass(frozen=True)
class SelfAffinePSD:
    """C(q) = c0 (m^4) for q_long <= q < q_rolloff, c0 (q / q_rolloff)^(-2 (1 + hurst)) up to q_cutoff,
    0 outside [q_long, q_cutoff] (wavenumbers in rad/m, q_long <= q_rolloff <= q_cutoff)."""

    hurst: float
    q_rolloff: float
    q_cutoff: float
    q_long: float = 0.0
    c0: float = 1.0

    def __call__(self, q) -> np.ndarray:
        q = np.asarray(q, dtype=float)
        ratio = np.maximum(q, self.q_rolloff) / self.q_rolloff
        inside = (q >= self.q_long) & (q <= self.q_cutoff)
        return np.where(inside, self.c0 * ratio ** (-2.0 * (1.0 + self.hurst)), 0.0)

    def moment(self, order: int) -> float:
        """2 pi * integral q^(order + 1) C(q) dq in closed form: order 0 is h_rms^2 (m^2), order 2 the mean
        square slope, order 4 the mean square curvature (1/m^2)."""
        n = order + 2  # power of q in the plateau's integrand's antiderivative
        q0, qr, qs = self.q_long, self.q_rolloff, self.q_cutoff
        plateau = (qr**n - q0**n) / n
        e = n - 2.0 * (1.0 + self.hurst)  # the power law's integrand is qr^(2 + 2H) q^(e - 1)
        tail = qr ** (2.0 + 2.0 * self.hurst) * (
            math.log(qs / qr) if e == 0.0 else (qs**e - qr**e) / e)
        return 2.0 * math.pi * self.c0 * (plateau + tail)

    def scaled(self, rms_height: float | None = None, rms_slope: float | None = None) -> SelfAffinePSD:
        """The same shape with c0 set for the given rms height (m) or rms slope."""
        order, target = (0, rms_height) if rms_height is not None else (2, rms_slope)
        unit = SelfAffinePSD(self.hurst, self.q_rolloff, self.q_cutoff, self.q_long, 1.0)
        return SelfAffinePSD(self.hurst, self.q_rolloff, self.q_cutoff, self.q_long,
                             target**2 / unit.moment(order))


@dataclass(frozen=True, eq=False)
class TabulatedPSD:
    """C(q) (m^4) given at wavenumbers ``q`` (rad/m, non-decreasing), interpolated linearly in log-log, 0
    outside [q_long, q_cutoff] = [q[0], q[-1]] and on a segment with an end where C = 0. A wavenumber given
    twice is a jump: C's values just below and just above it. A measured surface's spectrum:
    :meth:`of`."""

    q: np.ndarray
    C: np.ndarray

    def __post_init__(self):
        q, c = np.asarray(self.q, dtype=float), np.asarray(self.C, dtype=float)
        if q.ndim != 1 or q.shape != c.shape or q.size < 2:
            raise ValueError(f"q and C must be 1-D arrays of the same length >= 2, got shapes {q.shape}, "
                             f"{c.shape}")
        step = np.diff(q)
        if not (np.all(np.isfinite(q)) and q[0] > 0.0 and np.all(step >= 0.0) and q[-1] > q[0]
                and not np.any((step[1:] == 0.0) & (step[:-1] == 0.0))):
            raise ValueError("q must be finite, > 0 and non-decreasing (a value at most twice: a jump), "
                             f"got {q!r}")
        if not np.all(np.isfinite(c) & (c >= 0.0)):
            raise ValueError(f"C must be finite and >= 0, got {c!r}")
        object.__setattr__(self, "q", q)
        object.__setattr__(self, "C", c)

    @property
    def q_long(self) -> float:
        return float(self.q[0])

    @property
    def q_cutoff(self) -> float:
        return float(self.q[-1])

    def __call__(self, q) -> np.ndarray:
        q = np.asarray(q, dtype=float)
        inside = (q >= self.q[0]) & (q <= self.q[-1])
        at = np.clip(q, self.q[0], self.q[-1])
        j = np.clip(np.searchsorted(self.q, at, side="right") - 1, 0, self.q.size - 2)  # q[j] < q[j + 1]
        lo, hi = self.C[j], self.C[j + 1]
        logq = np.log(self.q)
        t = (np.log(at) - logq[j]) / (logq[j + 1] - logq[j])
        positive = inside & (lo > 0.0) & (hi > 0.0)
        log_lo, log_hi = np.log(np.where(positive, lo, 1.0)), np.log(np.where(positive, hi, 1.0))
        return np.where(positive, np.exp(log_lo + t * (log_hi - log_lo)), 0.0)

    @classmethod
    def of(cls, heights: np.ndarray, cell: tuple[float, float], per_decade: int = 10) -> TabulatedPSD:
        """The radially averaged spectrum of periodic ``heights`` (m) at spacing ``cell`` (m), with the
        surface's mean square height and mean square slope (of its trigonometric interpolant) exactly.

        Every mode of the grid but the mean is used (the lattice k = 2 pi (m / Lx, n / Ly), Nyquist and
        corner modes included). Wavenumber bins 1/``per_decade`` decade wide, from the lowest mode to the
        highest, are given the area in the plane of wavenumbers their modes stand for: a bin holding the
        n-th to the m-th mode by |k| spans the radii r with pi r^2 = (n .. m + 1) dkx dky (the mean, the
        0-th mode, holding the disc of radius sqrt(dkx dky / pi) at the origin), so that q_long is
        sqrt(dkx dky / pi), 0.56 of the lowest wavenumber of a square cell. On each bin C is a power law
        whose two moments 2 pi integral q C dq and 2 pi integral q^3 C dq are the bin's modes' sums of
        |h_k|^2 and |k|^2 |h_k|^2 (a bin where that cannot be is merged with the next); C jumps at the bins'
        edges. Bins holding less than 1e-20 of the total power (the round-off of a surface with no
        roughness there) have C = 0, and are left out at the ends.

        (A radial average interpolated in log-log through each bin's mean would lose 4-40 % of h_rms^2 and
        2-8 % of the mean square slope: the table would start above the lowest modes and end below the
        highest, a sparse bin's modes stand for more area than its annulus, and log-log interpolation
        through noisy values takes their geometric mean, below their mean.)
        """
        nx, ny = heights.shape
        area = nx * cell[0] * ny * cell[1]
        kx, ky = _wavenumbers(heights.shape, cell)
        q = np.broadcast_to(np.hypot(kx, ky), (nx, ny // 2 + 1))
        # |h_k|^2 of every mode of the plane, each counted with its conjugate twin: the rfft2's columns ky = 0
        # and (even ny) Nyquist hold both of a pair, the others one of two
        weight = np.full(q.shape, 2.0)
        weight[:, 0] = 1.0
        if ny % 2 == 0:
            weight[:, -1] = 1.0
        power = np.abs(scipy.fft.rfft2(heights) / (nx * ny)) ** 2 * weight
        mode = q > 0.0
        q, power, weight = q[mode], power[mode], weight[mode]
        order = np.argsort(q, kind="stable")
        q, power, weight = q[order], power[order], weight[order]
        total = power.sum()
        if not total > _EMPTY * np.mean(heights**2):  # round-off of a constant
            raise ValueError("a flat surface (every height the same) has no spectrum")
        bins = max(int(np.ceil(per_decade * np.log10(q[-1] / q[0]))), 1)
        nominal = q[0] * (q[-1] / q[0]) ** (np.arange(1, bins) / bins)
        cuts = np.unique(np.concatenate([[0], np.searchsorted(q, nominal), [q.size]]))
        before = np.concatenate([[1.0], 1.0 + np.cumsum(weight)])  # modes of the plane below, the mean's 1
        dk2 = (2.0 * np.pi) ** 2 / area
        radius = np.sqrt(before[cuts] * dk2 / np.pi)
        radius[0] = min(radius[0], q[0] / math.sqrt(2.0))  # a cell over 1.6 times as long as wide
        moment0 = np.add.reduceat(power, cuts[:-1])
        moment2 = np.add.reduceat(power * q**2, cuts[:-1])
        # a bin whose modes' mean |k|^2 no power law of exponent within +-_STEEPEST on its radii has is
        # merged with the neighbour on the side of its mean (at the ends, the one neighbour)
        while True:
            full = moment0 > _EMPTY * total
            mean = np.divide(moment2, moment0, out=np.zeros(moment0.shape), where=full)
            span = np.log(radius[1:] / radius[:-1])
            ratio = np.log(np.where(full, mean, 1.0) / radius[:-1] ** 2)
            low = ratio < [_mean_log_ratio(-_STEEPEST, s) for s in span]
            high = ratio > [_mean_log_ratio(_STEEPEST, s) for s in span]
            bad = np.flatnonzero(full & (low | high))
            if bad.size == 0:
                break
            if moment0.size == 1:
                raise ValueError("no radial spectrum holds this surface's mean square slope: its power lies "
                                 "at wavenumbers beyond the disc of its modes' area (e.g. a checkerboard)")
            i = int(bad[0])
            i = min(max(i - 1 if low[i] else i, 0), moment0.size - 2)  # merge bins i and i + 1
            cuts, radius = np.delete(cuts, i + 1), np.delete(radius, i + 1)
            moment0 = np.concatenate([moment0[:i], [moment0[i] + moment0[i + 1]], moment0[i + 2:]])
            moment2 = np.concatenate([moment2[:i], [moment2[i] + moment2[i + 1]], moment2[i + 2:]])
        from scipy.optimize import brentq  # here: scipy.optimize takes ~0.1 s to import, a run needs it not

        left, right = np.zeros(moment0.size), np.zeros(moment0.size)
        for i in np.flatnonzero(full):
            alpha = brentq(lambda a: _mean_log_ratio(a, span[i]) - ratio[i], -_STEEPEST, _STEEPEST, xtol=1e-13,
                           rtol=1e-15)
            left[i] = moment0[i] / (2.0 * np.pi * radius[i] ** 2 * math.exp(_log_integral(alpha + 1.0, span[i])))
            right[i] = left[i] * math.exp(alpha * span[i])
        first, last = np.flatnonzero(full)[[0, -1]]
        keep = slice(first, last + 1)
        q = np.repeat(radius, 2)[1:-1].reshape(-1, 2)[keep].ravel()
        return cls(q, np.column_stack([left, right])[keep].ravel())


_EMPTY = 1e-20
"""A bin of :meth:`TabulatedPSD.of` holding less than this fraction of the surface's power is empty."""

_STEEPEST = 24.0
"""The largest |exponent| of :meth:`TabulatedPSD.of`'s power law on a bin (6 times a self-affine
spectrum's steepest, q^-4); a bin that would need more is merged with a neighbour."""


def _mean_log_ratio(alpha: float, span: float) -> float:
    """ln(<q^2> / a^2) over [a, a e^span] weighted by q C(q) dq, C ~ q^alpha."""
    return _log_integral(alpha + 3.0, span) - _log_integral(alpha + 1.0, span)


def _log_integral(power: float, span: float) -> float:
    """ln of integral_1^exp(span) x^power dx (span > 0), without overflow for any power."""
    e = power + 1.0
    y = e * span
    if abs(y) < 1e-8:
        return math.log(span) + math.log1p(y / 2.0)
    if y > 0.0:
        return y + math.log(-math.expm1(-y)) - math.log(e)
    return math.log(-math.expm1(y)) - math.log(-e)


def _wavenumbers(shape: tuple[int, int], cell: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """(kx, ky) in rad/m of a real FFT's half spectrum, shaped to broadcast (nx, 1) and (1, ny//2 + 1)."""
    kx = 2.0 * np.pi * scipy.fft.fftfreq(shape[0], cell[0])
    ky = 2.0 * np.pi * scipy.fft.rfftfreq(shape[1], cell[1])
    return kx[:, None], ky[None, :]


def _number(prefix: str, key: str, value: object, source: str, allowed: str) -> float:
    if not isinstance(value, numbers.Real) or isinstance(value, bool) or not math.isfinite(value):
        raise SceneError(source, f"{prefix}{key}", value, allowed)
    return float(value)


def _checked_keys(keys: dict, shape, cell, source: str, prefix: str) -> tuple[SelfAffinePSD, str, float, int]:
    """(unit-c0 PSD, "rms_height" or "rms_slope", its value, seed) from the keys, or SceneError."""
    for key in keys:
        if key not in ROUGH_KEYS:
            raise SceneError(source, f"{prefix}{key}", keys[key], "unknown key; allowed keys: "
                             + ", ".join(ROUGH_KEYS))
    if "hurst" not in keys:
        raise SceneError(source, f"{prefix}hurst", MISSING, "required: " + ROUGH_KEYS["hurst"])
    hurst = _number(prefix, "hurst", keys["hurst"], source, "must be a number in (0, 1]")
    if not 0.0 < hurst <= 1.0:
        raise SceneError(source, f"{prefix}hurst", keys["hurst"], "must be a number in (0, 1]")
    longest, shortest = max(shape[0] * cell[0], shape[1] * cell[1]), 2.0 * max(cell)
    cutoff = _number(prefix, "cutoff", keys.get("cutoff", shortest), source, "must be a wavelength in m")
    if not shortest * (1 - 1e-12) <= cutoff <= longest:
        raise SceneError(source, f"{prefix}cutoff", keys["cutoff"], f"must be a wavelength between 2 cells "
                         f"({shortest!r} m) and the surface's longer side ({longest!r} m)")
    rolloff = _number(prefix, "rolloff", keys.get("rolloff", longest), source, "must be a wavelength in m")
    if not cutoff <= rolloff:
        raise SceneError(source, f"{prefix}rolloff", keys["rolloff"], f"must be a wavelength >= cutoff "
                         f"({cutoff!r} m)")
    given = [key for key in ("rms_height", "rms_slope") if key in keys]
    if len(given) != 1:
        raise SceneError(source, f"{prefix}rms_height", keys.get("rms_height", MISSING),
                         "give exactly one of rms_height (m) and rms_slope")
    target = _number(prefix, given[0], keys[given[0]], source, "must be a number > 0")
    if target <= 0.0:
        raise SceneError(source, f"{prefix}{given[0]}", keys[given[0]], "must be a number > 0")
    seed = keys.get("seed", 0)
    if not isinstance(seed, numbers.Integral) or isinstance(seed, bool) or seed < 0:
        raise SceneError(source, f"{prefix}seed", seed, "must be an integer >= 0")
    psd = SelfAffinePSD(hurst, 2.0 * np.pi / rolloff, 2.0 * np.pi / cutoff)
    return psd, given[0], target, int(seed)


def self_affine_psd(keys: dict, shape: tuple[int, int], cell: tuple[float, float], *,
                    source: str = "<python>", prefix: str = "[body] ") -> SelfAffinePSD:
    """The continuum spectrum of the surfaces :func:`self_affine_heights` draws from the same keys, shape
    and cell: q_long = 2 pi / (the longer side), c0 such that its rms height or rms slope is the one the
    keys ask for (Persson's theory takes it: petroll.studies.persson)."""
    psd, kind, target, _ = _checked_keys(keys, shape, cell, source, prefix)
    longest = max(shape[0] * cell[0], shape[1] * cell[1])
    psd = SelfAffinePSD(psd.hurst, psd.q_rolloff, psd.q_cutoff, q_long=2.0 * np.pi / longest)
    return psd.scaled(**{kind: target})


def self_affine_heights(keys: dict, shape: tuple[int, int], cell: tuple[float, float], *,
                        source: str = "<python>", prefix: str = "[body] ") -> np.ndarray:
    """A periodic Gaussian self-affine surface of ``shape`` = (nx, ny) heights (m) at spacing ``cell`` (m).

    ``keys``: those of :data:`ROUGH_KEYS` (a scene table's; errors name them after ``prefix``). White noise
    from ``numpy.random.default_rng(seed)``, filtered by sqrt(C(q)) with :class:`SelfAffinePSD`'s shape
    (the mean and the Nyquist frequencies removed), then scaled so that the surface has exactly the rms
    height, or the rms slope of its trigonometric interpolant (the continuum slope Persson's theory
    uses), that the keys ask for. The same keys, shape and cell give the same surface on any machine.
    """
    psd, kind, target, seed = _checked_keys(keys, shape, cell, source, prefix)
    nx, ny = shape
    noise = np.random.default_rng(seed).standard_normal((nx, ny))
    kx, ky = _wavenumbers(shape, cell)
    spectrum = scipy.fft.rfft2(noise) * np.sqrt(psd(np.hypot(kx, ky)))
    spectrum[0, 0] = 0.0
    if nx % 2 == 0:
        spectrum[nx // 2, :] = 0.0
    if ny % 2 == 0:
        spectrum[:, -1] = 0.0
    heights = scipy.fft.irfft2(spectrum, s=shape)
    if kind == "rms_height":
        scale = target / math.sqrt(np.mean(heights**2))
    else:
        slope_x = scipy.fft.irfft2(1j * kx * spectrum, s=shape)
        slope_y = scipy.fft.irfft2(1j * ky * spectrum, s=shape)
        scale = target / math.sqrt(np.mean(slope_x**2 + slope_y**2))
    with np.errstate(over="ignore", under="ignore"):  # judged just below
        heights = heights * scale
    if not (math.isfinite(scale) and scale > 0) or (why := heights_out_of_scale(heights)) is not None:
        why = why if math.isfinite(scale) and scale > 0 else "a surface that cannot be scaled to it"
        raise SceneError(source, f"{prefix}{kind}", keys[kind], f"gives a surface of {why}")
    return heights


def radial_psd(field: np.ndarray, cell: tuple[float, float], edges) -> tuple[np.ndarray, np.ndarray,
                                                                             np.ndarray]:
    """The radially averaged power spectrum of a periodic field (C(q) in Persson's convention, units of
    the field^2 m^2) over the wavenumber bins ``edges`` (rad/m): (mean |k| of each bin's modes, mean C,
    number of independent modes). Each mode of a real field is counted once (the half spectrum without
    its conjugate twins; the mean is left out)."""
    nx, ny = field.shape
    area = nx * cell[0] * ny * cell[1]
    kx, ky = _wavenumbers(field.shape, cell)
    amplitude = scipy.fft.rfft2(field) / (nx * ny)
    power = np.abs(amplitude) ** 2 * area / (2.0 * np.pi) ** 2
    q = np.broadcast_to(np.hypot(kx, ky), power.shape)
    # independent modes: ky > 0 (below Nyquist), and ky = 0 or Nyquist with kx > 0
    own = np.ones(power.shape, dtype=bool)
    own[:, 0] = kx[:, 0] > 0
    if ny % 2 == 0:
        own[:, -1] = kx[:, 0] > 0
    which = np.digitize(q[own], edges) - 1
    inside = (which >= 0) & (which < len(edges) - 1)
    bins = len(edges) - 1
    count = np.bincount(which[inside], minlength=bins)
    with np.errstate(invalid="ignore"):
        mean_q = np.bincount(which[inside], q[own][inside], bins) / count
        mean_c = np.bincount(which[inside], power[own][inside], bins) / count
    return mean_q, mean_c, count

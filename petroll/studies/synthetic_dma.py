"""Synthetic DMA tables that look like instrument output, made from materials whose truth is known.

Not measurements: petroll uses them to show and test the route from raw multi-temperature DMA data to a
scene (docs/materials.md; ``runs/polymer-dma.csv`` is :data:`POLYMER` written by :func:`write_table`).
A material is a Havriliak-Negami modulus at its reference temperature,

    E*(w) = Eg - (Eg - Einf) / (1 + (i w tau0)^alpha)^beta,   w = 2 pi f (rad/s),

with a time-temperature shift law: a_T(T) multiplies every time at T, so a sweep at T measures
E*(2 pi f a_T(T)). :func:`sweeps` measures it as an instrument does: frequency sweeps from the highest
frequency down, one per nominal temperature (plus, optionally, a repeated sweep), the recorded temperature
wandering along each sweep (an offset per sweep and a random walk from row to row, the material following
it: each row is at its recorded temperature), and relative Gaussian noise on E' and E''.

    .venv/bin/python -m petroll.studies.synthetic_dma runs/polymer-dma.csv            # writes the table
    .venv/bin/python -m petroll.studies.synthetic_dma OUT.csv --material rubber --seed 3
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import pathlib
from dataclasses import dataclass, field

import numpy as np

from petroll.io.results import atomic_write
from petroll.model import materials


@dataclass(frozen=True)
class GlassKink:
    """A shift law that is not WLF: WLF (C1, C2 about T_ref) above the glass transition Tg, Arrhenius
    (activation energy Ea, J/mol) below it, continuous at Tg. log10 a_T, T in K."""

    C1: float
    C2: float
    T_ref: float
    Tg: float
    Ea: float

    def log10(self, T: float) -> float:
        above = materials.WLF(self.C1, self.C2, self.T_ref)
        if T >= self.Tg:
            return above.log10(T)
        slope = self.Ea / (materials.GAS_CONSTANT * math.log(10))  # K
        return above.log10(self.Tg) + slope * (1 / T - 1 / self.Tg)


@dataclass(frozen=True)
class Synthetic:
    """A Havriliak-Negami material (Pa, s at T_ref, exponents) with its shift law and the measurement plan
    (nominal temperatures, K; frequencies, Hz; noise, relative; temperature wander, K)."""

    name: str
    Einf: float
    Eg: float
    tau0: float
    alpha: float
    beta: float
    law: materials.WLF | GlassKink
    temperatures: tuple[float, ...]
    frequencies: tuple[float, ...] = tuple(float(f"{f:.4g}") for f in np.logspace(-1, 2, 16))
    noise: float = 0.01
    offset: float = 0.1  # K, standard deviation of a sweep's temperature offset
    wander: float = 0.04  # K, standard deviation of the temperature's step from row to row
    repeat: tuple[float, ...] = field(default=())  # nominal temperatures measured a second time

    def modulus(self, reduced) -> np.ndarray:
        """E*(f) at the reference temperature (Pa) at the reduced frequencies ``reduced`` (Hz)."""
        iwt = 2j * np.pi * np.asarray(reduced, dtype=float) * self.tau0
        return self.Eg - (self.Eg - self.Einf) / (1 + iwt**self.alpha) ** self.beta

    def log10_aT(self, T) -> np.ndarray:
        """The true log10 a_T at the temperatures T (K)."""
        return np.array([self.law.log10(float(t)) for t in np.atleast_1d(T)])


POLYMER = Synthetic("polymer", Einf=90e6, Eg=10e9, tau0=1e-3, alpha=0.5, beta=0.2,
                    law=GlassKink(C1=12.0, C2=80.0, T_ref=268.15, Tg=263.15, Ea=250e3),
                    temperatures=tuple(223.15 + 7.5 * k for k in range(21)), repeat=(268.15,))
"""A glassy polymer with a broad glass transition (E' 0.09 ... 10 GPa over about 20 decades at 268.15 K,
-5 degC), measured at 21 temperatures -50 ... 100 degC; shift: WLF above Tg = 263.15 K, Arrhenius below."""

RUBBER = Synthetic("rubber", Einf=3e6, Eg=1e9, tau0=3e-6, alpha=0.55, beta=0.35,
                   law=materials.WLF(8.86, 101.6, 293.15),
                   temperatures=tuple(238.15 + 5.0 * k for k in range(20)))
"""A rubber (3 MPa ... 1 GPa) shifted by WLF's universal constants about 293.15 K, at 20 temperatures."""

MATERIALS = {m.name: m for m in (POLYMER, RUBBER)}


def sweeps(material: Synthetic, seed: int = 2026) -> dict[str, np.ndarray]:
    """The rows an instrument would record (module docstring): columns frequency (Hz), storage, loss
    (Pa), temperature (K, 4 decimals) and sweep (the index of each row's sweep, in measuring order)."""
    rng = np.random.default_rng(seed)
    f = np.array(material.frequencies)[::-1]  # from the highest frequency down
    nominal = [*material.temperatures, *material.repeat]
    columns = {name: [] for name in ("frequency", "storage", "loss", "temperature", "sweep")}
    for k, T0 in enumerate(nominal):
        steps = rng.normal(0.0, material.wander, len(f))
        T = np.round(T0 + rng.normal(0.0, material.offset) + np.cumsum(steps) - steps[0], 4)
        E = material.modulus(f * 10 ** material.log10_aT(T))
        columns["frequency"].append(f)
        columns["storage"].append(E.real * (1 + material.noise * rng.standard_normal(len(f))))
        columns["loss"].append(E.imag * (1 + material.noise * rng.standard_normal(len(f))))
        columns["temperature"].append(T)
        columns["sweep"].append(np.full(len(f), k))
    return {name: np.concatenate(values) for name, values in columns.items()}


def write_table(material: Synthetic, path: str | pathlib.Path, seed: int = 2026, sets: bool = False,
                style: str = "petroll") -> dict:
    """Write :func:`sweeps` as a DMA CSV (atomically) with a comment header saying how it was made; with
    ``sets``, a set column names each sweep. The noise is ``material.noise`` (``dataclasses.replace(
    POLYMER, noise=0.1)`` for another). ``style="pyvisco"`` writes it as pyvisco's user format instead
    (NREL/pyvisco, pyvisco/load.py): a UTF-8 byte-order mark (Excel's "CSV UTF-8"), the header
    ``f,E_stor,E_loss,T,Set``, the units row ``Hz,MPa,MPa,C,-``, the moduli in MPa, the temperatures in
    degrees Celsius, each sweep numbered from 0, no comment. Returns the rows (Hz, Pa, K)."""
    rows = sweeps(material, seed)
    if style == "pyvisco":
        body = [f"{f:.6g},{e1 / 1e6:.6g},{e2 / 1e6:.6g},{T - 273.15:.4f},{k}"
                for f, e1, e2, T, k in zip(*(rows[n] for n in ("frequency", "storage", "loss", "temperature",
                                                                 "sweep")))]
        text = "\ufeff" + "\n".join(["f,E_stor,E_loss,T,Set", "Hz,MPa,MPa,C,-", *body]) + "\n"
        atomic_write(pathlib.Path(path), lambda tmp: tmp.write_text(text, encoding="utf-8"))
        return rows
    law = ", ".join(f"{k} = {v:g}" for k, v in vars(material.law).items())
    head = [f"# SYNTHETIC DMA table ({material.name}): not a measurement. Made by",
            f"#   .venv/bin/python -m petroll.studies.synthetic_dma {path} --material {material.name} --seed "
            f"{seed}{' --sets' if sets else ''}",
            "# from a Havriliak-Negami modulus E*(w) = Eg - (Eg - Einf) / (1 + (i w tau0)^alpha)^beta,",
            f"# Einf = {material.Einf:g} Pa, Eg = {material.Eg:g} Pa, tau0 = {material.tau0:g} s, alpha = "
            f"{material.alpha:g}, beta = {material.beta:g},",
            f"# shifted by {type(material.law).__name__} ({law}; K, J/mol); sweeps from "
            f"{max(material.frequencies):g} Hz down to {min(material.frequencies):g} Hz,",
            f"# the temperature wandering along each, {100 * material.noise:g} % noise on E' and E''.",
            "frequency,storage,loss,temperature" + (",set" if sets else "")]
    body = [f"{f:.4g},{e1:.5g},{e2:.5g},{T:.4f}" + (f",sweep{k + 1}" if sets else "")
            for f, e1, e2, T, k in zip(*(rows[n] for n in ("frequency", "storage", "loss", "temperature",
                                                             "sweep")))]
    path = pathlib.Path(path)
    atomic_write(path, lambda tmp: tmp.write_text("\n".join(head + body) + "\n", encoding="utf-8"))
    return rows


def master_curve(material: Synthetic, seed: int = 2026, phase: float = 0.0) -> dict[str, np.ndarray]:
    """A master curve as users have one, merged from :func:`sweeps`: every row at its reduced frequency
    f a_T(T) by the true law (Hz at T_ref), in measuring order (unsorted), E' and E'' with an instrument's
    phase offset ``phase`` (rad: the loss angle read that much too high, a loss floor on a plateau); the
    repeated sweeps hold their first sweep's temperatures, their reduced frequencies computed another
    way (10^(log10 f + log10 a_T)): near-duplicates of the first's in the last digits."""
    rows = sweeps(material, seed)
    count = len(material.temperatures)
    first = {T0: k for k, T0 in enumerate(material.temperatures)}
    T = rows["temperature"].copy()
    for j, T0 in enumerate(material.repeat):
        T[rows["sweep"] == count + j] = T[rows["sweep"] == first[T0]]
    shift = material.log10_aT(T)
    repeated = rows["sweep"] >= count
    reduced = np.where(repeated, 10 ** (np.log10(rows["frequency"]) + shift), rows["frequency"] * 10**shift)
    E = np.hypot(rows["storage"], rows["loss"])
    angle = np.arctan2(rows["loss"], rows["storage"]) + phase
    return {"frequency": reduced, "storage": E * np.cos(angle), "loss": E * np.sin(angle)}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m petroll.studies.synthetic_dma", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("out", help="the CSV to write")
    parser.add_argument("--material", choices=sorted(MATERIALS), default="polymer")
    parser.add_argument("--seed", type=int, default=2026, help="the noise's and the wander's seed")
    parser.add_argument("--sets", action="store_true", help="add a set column naming each sweep")
    parser.add_argument("--noise", type=float, help="relative noise on E' and E'' (default: the material's, "
                        "0.01)")
    parser.add_argument("--style", choices=("petroll", "pyvisco"), default="petroll",
                        help="petroll's CSV, or pyvisco's user format (BOM, f,E_stor,E_loss,T,Set, a units row "
                        "Hz,MPa,MPa,C,-)")
    args = parser.parse_args(argv)
    material = MATERIALS[args.material]
    if args.noise is not None:
        material = dataclasses.replace(material, noise=args.noise)
    rows = write_table(material, args.out, args.seed, args.sets, args.style)
    print(f"wrote {args.out}: {len(rows['frequency'])} rows")


if __name__ == "__main__":
    main()

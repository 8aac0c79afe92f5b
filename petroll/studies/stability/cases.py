"""The runs of the map, one :class:`Case` each, grouped by the axis along which the method is pushed."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from petroll.studies.stability.scenes import (
    DELTA,
    E0,
    NU,
    A,
    R,
    T,
    hertz_force,
    load_scene,
    rolling_scene,
    scaled,
    scene,
    sls,
)


@dataclass
class Case:
    """One run of the map. ``dts``: an explicit step sequence after the sudden start (instead of the
    scene's clock); ``monotone``: the penetration never decreases and the motion never reverses (the
    lower Lee-Radok bound and V . F_res >= 0 are asserted); ``refuse``: the case must end in a PetrollError
    whose message contains each of these words."""

    axis: str
    name: str
    raw: dict
    fast: bool = False
    dts: list[float] | None = None
    monotone: bool = False
    refuse: tuple[str, ...] = ()
    warn: bool = False  # the scene must draw a PetrollWarning
    hertz: float | None = None  # the first step's force must be Hertz's (sphere, J0) to this relative error
    trend: str | None = None  # "force down": the force never increases (a held penetration relaxes);
    #                           "delta up": the penetration never decreases (a held load creeps)
    max_steps: int = 300


def cases() -> list[Case]:
    """Every run of the map, axis by axis; ``fast`` marks the subset the test suite runs."""
    return [*time_step_cases(), *stiffness_cases(), *speed_cases(), *program_cases(), *grid_cases(),
            *large_cases(), *magnitude_cases()]


F0 = hertz_force(DELTA, (1 - NU**2) / E0)
"""The reference scene's instantaneous Hertz force, N."""


def time_step_cases() -> list[Case]:
    """The time step: a step penetration or load held at fixed dt from 1e-4 T to 1e3 T, growing and random
    steps, a varying speed, the creep integrators."""
    out: list[Case] = []
    add = out.append
    for x in (1e-4, 1e-2, 1e-1, 1.0, 10.0, 1e3):
        add(Case("dt", f"held penetration, dt = {x:g} T", scene(time={"dt": x * T, "end": 8 * x * T}),
                 fast=x in (1e-2, 1e3), monotone=True, trend="force down"))
    for x in (1e-4, 1.0, 1e3):
        add(Case("dt", f"held load, dt = {x:g} T", load_scene(F0, dt=x * T, end=8 * x * T), fast=x == 1.0,
                 trend="delta up"))
    growing = list(np.geomspace(1e-4 * T, 1e3 * T, 16))
    rng = np.random.default_rng(6)
    jumping = list(rng.choice([1e-4 * T, 1e-2 * T, 1e3 * T], size=20))
    add(Case("dt", "held penetration, dt growing 1e-4 T -> 1e3 T", scene(time={"dt": T, "end": T}),
             dts=growing, monotone=True, fast=True, trend="force down"))
    add(Case("dt", "held penetration, dt random in {1e-4, 1e-2, 1e3} T", scene(time={"dt": T, "end": T}),
             dts=jumping, monotone=True, trend="force down"))
    add(Case("dt", "held load, dt random in {1e-4, 1e-2, 1e3} T", load_scene(F0), dts=jumping, fast=True,
             trend="delta up"))
    sinus = {"kind": "sinusoidal", "mean": [A / T, 0.0], "amplitude": [0.9 * A / T, 0.0], "period": 2 * T}
    add(Case("dt", "rolling, speed 0.1..1.9 a/T, dt = dx / (2 |V|) varying",
             scene(length=4, motion={"velocity": sinus, "penetration": DELTA},
                   time={"steps_per_cell": 2, "distance": 4 * A}), monotone=True))
    for integrator, x in (("exponential", 1.0), ("paper", 1.0), ("exponential", 1e-2), ("paper", 1e-2)):
        ok = x < 0.1
        add(Case("dt", f"held penetration, integrator {integrator}, dt = {x:g} T",
                 scene(time={"dt": x * T, "end": 8 * x * T}, integrator=integrator), monotone=True,
                 refuse=() if ok else ("cannot hold a penetration", "time step <=", "relaxation"),
                 fast=not ok))
    return out


def stiffness_cases() -> list[Case]:
    """The stiffness ratio E0/Einf from 1 to 1e4, and Prony series spread over 8 decades."""
    out: list[Case] = []
    add = out.append
    for ratio in (1, 10, 100, 1e3, 1e4):
        add(Case("ratio", f"held penetration, E0/Einf = {ratio:g}, dt = T/10",
                 scene(material=sls(ratio), time={"dt": T / 10, "end": 2 * T}), monotone=True,
                 fast=ratio in (1, 1e4), trend="force down"))
        add(Case("ratio", f"rolling V T/a = 1, E0/Einf = {ratio:g}", rolling_scene(1.0, ratio=ratio),
                 monotone=True, fast=ratio == 1e4))
    times = [float(t) for t in np.geomspace(1e-4 * T, 1e4 * T, 9)]
    kelvin = {"model": "prony", "series": "kelvin", "Einf": E0 / 100, "nu": NU, "times": times,
              "compliances": [99 / E0 / 9] * 9}
    maxwell = {"model": "prony", "series": "maxwell", "Einf": E0 / 100, "nu": NU, "times": times,
               "moduli": [0.99 * E0 / 9] * 9}
    for label, material in (("kelvin", kelvin), ("maxwell", maxwell)):
        add(Case("ratio", f"held penetration, 9-term {label} series over 8 decades, dt 1e-4 T -> 1e4 T",
                 scene(material=material, time={"dt": T, "end": T}),
                 dts=list(np.geomspace(1e-4 * T, 1e4 * T, 25)), monotone=True, fast=label == "maxwell",
                 trend="force down"))
        motion = {"velocity": [A / T, 0.0], "penetration": DELTA}
        add(Case("ratio", f"rolling V T/a = 1, 9-term {label} series",
                 scene(length=3, material=material, motion=motion,
                       time={"steps_per_cell": 1, "distance": 3 * A}),
                 monotone=True))
    return out


def speed_cases() -> list[Case]:
    """The speed V T/a from 1e-3 to 1e3, a speed reversing through zero, a diagonal motion."""
    out: list[Case] = []
    add = out.append
    for v in (1e-3, 1e-2, 1e-1, 1.0, 10.0, 1e2, 1e3):
        add(Case("speed", f"rolling V T/a = {v:g}", rolling_scene(v), monotone=True, fast=v in (1e-3, 1e3)))
    reverse = {"kind": "sinusoidal", "mean": [0.0, 0.0], "amplitude": [A / T, 0.0], "period": 4 * T}
    add(Case("speed", "speed reversing: V = (a/T) sin(2 pi t / 4T), rolls back over its wake",
             scene(length=2, back=0, motion={"velocity": reverse, "penetration": DELTA},
                   time={"dt": T / 10, "end": 8 * T}), fast=True))
    diagonal = scene(n=16, length=2, ny=22, motion={"velocity": [A / T / math.sqrt(2), A / T / math.sqrt(2)],
                                                     "penetration": DELTA},
                     time={"steps_per_cell": 1, "distance": 1.5 * A})
    diagonal["grid"]["y"] = [-2 * A, 3.5 * A]
    add(Case("speed", "rolling diagonally (45 degrees), V T/a = 1", diagonal, monotone=True))
    return out


def program_cases() -> list[Case]:
    """Penetrations shrinking to zero and lost, loads going to zero and below, rolling under load."""
    out: list[Case] = []
    add = out.append
    shrink = {"kind": "ramp", "start": DELTA, "end": 0.0, "duration": 2 * T}
    add(Case("load", "penetration shrinking to zero over 2T", scene(motion={"penetration": shrink},
                                                                    time={"dt": T / 10, "end": 3 * T}),
             fast=True))
    dip = {"kind": "sinusoidal", "mean": 0.3 * DELTA, "amplitude": DELTA, "period": 2 * T}
    add(Case("load", "penetration 0.3 + sin: contact lost and regained",
             scene(motion={"penetration": dip}, time={"dt": T / 20, "end": 4 * T}), fast=True))
    roll_dip = {"velocity": [A / T, 0.0], "penetration": dip}
    add(Case("load", "rolling while contact is lost and regained",
             scene(length=4, motion=roll_dip, time={"dt": T / 10, "end": 4 * T})))
    to_zero = {"kind": "ramp", "start": F0, "end": 1e-9 * F0, "duration": 2 * T}
    add(Case("load", "load ramp to 1e-9 F", load_scene(to_zero, dt=T / 10, end=3 * T), fast=True))
    from_zero = {"kind": "ramp", "start": 0.0, "end": F0, "duration": 2 * T}
    add(Case("load", "load ramp from 0", load_scene(from_zero, dt=T / 10, end=2 * T), fast=True))
    pulling = {"kind": "sinusoidal", "mean": 0.5 * F0, "amplitude": F0, "period": 2 * T}
    add(Case("load", "load going negative (pulling)", load_scene(pulling, dt=T / 10, end=2 * T),
             refuse=("[motion] load", "adhesion"), fast=True))
    rolling_load = {"velocity": [A / T, 0.0], "load": F0}
    add(Case("load", "rolling under load control, V T/a = 1",
             load_scene(F0, dt=T / 10, end=1.0 * T) | {"motion": rolling_load}))
    return out


def grid_cases() -> list[Case]:
    """Coarse, fine and elongated cells, and a contact reaching the grid's edge."""
    out: list[Case] = []
    add = out.append
    for cells in (2, 4, 16):
        n = 4 * cells
        add(Case("grid", f"rolling, a/dx = {cells}", rolling_scene(1.0, n=n), monotone=True, fast=cells == 2))
    for k in (2, 4, 8):
        raw = scene(n=32, ny=32)
        raw["grid"]["nx"] = 32 // k  # dx = k dy
        add(Case("grid", f"held penetration, dx/dy = {k}", raw | {"time": {"dt": T / 10, "end": T}},
                 monotone=True, fast=k == 8))
        raw = scene(n=32 // k, ny=32, time={"dt": T / 10, "end": T})
        raw["grid"]["nx"], raw["grid"]["ny"] = 32, 32 // k  # dy = k dx
        add(Case("grid", f"held penetration, dy/dx = {k}", raw, monotone=True))
    edge = scene(n=16, half=1.2)
    add(Case("grid", "penetration whose interference reaches the grid edge", edge,
             refuse=("[grid]", "edge")))
    add(Case("grid", "rolling off the end of the grid", rolling_scene(1.0, length=1.0) | {
        "time": {"steps_per_cell": 1, "distance": 3 * A}}, refuse=("[grid]", "edge"), fast=True))
    add(Case("grid", "load control relaxing past the grid edge",
             scene(motion={"load": F0}, material=sls(1e3), time={"dt": T, "end": 5 * T}),
             refuse=("[grid]", "edge")))
    return out


def large_cases() -> list[Case]:
    """Large penetrations: the contact slope (a/R for a sphere) beyond the linear theory."""
    out: list[Case] = []
    add = out.append
    for ratio in (1e-2, 0.1, 0.5, 1.0):
        delta = ratio * R
        add(Case("large", f"penetration delta/R = {ratio:g} (a/R = {math.sqrt(ratio):.2g})",
                 scene(delta=delta, motion={"penetration": delta}, time={"dt": T / 2, "end": T}),
                 monotone=True, fast=ratio >= 0.1, warn=0.05 < ratio < 1,
                 refuse=("[motion] penetration", "slope", "small slopes") if ratio >= 1 else ()))
    return out


def magnitude_cases() -> list[Case]:
    """Extreme magnitudes: tiny penetrations under large radii (Hertz), and the rolling scene at other moduli
    and radii."""
    out: list[Case] = []
    add = out.append
    for radius, delta in ((10.0, 1e-14), (10.0, 1e-12), (1e-6, 1e-12), (10.0, 1e-4)):
        add(Case("scale", f"elastic sphere R = {radius:g} m, delta = {delta:g} m (a/dx = 4): Hertz's force",
                 scene(n=16, radius=radius, delta=delta, motion={"penetration": delta}, material=sls(1)),
                 hertz=0.01, fast=radius == 10 and delta < 1e-13))
    for modulus in (1e-3, 1e12):
        for radius in (1e-6, 10.0):
            add(Case("scale", f"rolling V T/a = 1, E0 = {modulus:g} Pa, R = {radius:g} m",
                     scaled(rolling_scene(1.0), modulus, radius), monotone=True))
    return out

"""The map's scenes: a sphere pressed into a standard linear solid on small grids (the reference scene
and its variants as scene dicts), and the same scenes at other moduli, radii and time scales."""

from __future__ import annotations

import copy
import math

# the reference scene: a sphere on an SLS half-space (nu = 0.5: J = 0.75 / E)
R, NU, E0, DELTA, T = 0.01, 0.5, 10e6, 2e-5, 0.05  # m, -, Pa, m, s (T: the creep, retardation, time)
A = math.sqrt(R * DELTA)  # Hertz contact radius, m


def sls(ratio: float = 5.0, e0: float = E0, tau: float = T) -> dict:
    """An SLS [material] with E0 / Einf = ratio and creep time tau; ratio 1 is elastic."""
    if ratio == 1:
        return {"model": "elastic", "E": e0, "nu": NU}
    return {"model": "sls", "E0": e0, "Einf": e0 / ratio, "nu": NU, "tau_creep": tau}


def scene(n: int = 16, half: float = 2.0, length: float = 0.0, material: dict | None = None,
          motion: dict | None = None, time: dict | None = None, radius: float = R, delta: float = DELTA,
          ny: int | None = None, tol: float = 1e-8, integrator: str | None = None, back: float = 0.0) -> dict:
    """A sphere scene dict: n cells over [-half a, half a] along X, ny (default n) over the same along Y,
    and X longer by ``length`` a ahead (rolling) and ``back`` a behind; a = sqrt(radius delta)."""
    a = math.sqrt(radius * delta)
    ny = ny or n
    dx = 2 * half * a / n
    behind = int(round(back * a / dx))
    nx = n + int(round(length * a / dx)) + behind
    x0 = -half * a - behind * dx
    raw = {
        "grid": {"nx": nx, "ny": ny, "x": [x0, x0 + nx * dx], "y": [-half * a, half * a]},
        "material": material or sls(),
        "body": {"shape": "sphere", "radius": radius},
        "motion": motion or {"penetration": delta},
        "solver": {"tol": tol},
    }
    if integrator:
        raw["solver"]["integrator"] = integrator
    if time:
        raw["time"] = time
    return raw


def hertz_force(delta: float, J: float, radius: float = R) -> float:
    return 4 * math.sqrt(radius) * delta**1.5 / (3 * J)


def R_of(scene) -> float:
    return float(getattr(scene.body, "radius", None) or scene.body.radius_hint)


def rolling_scene(v: float, n: int = 16, length: float = 3.0, ratio: float = 5.0, steps: float = 1.0,
             **kw) -> dict:
    """Rolling along +X at V = v a / T (v = V T / a), steps_per_cell steps per cell, over ``length`` a."""
    motion = {"velocity": [v * A / T, 0.0], "penetration": DELTA}
    return scene(n=n, length=length, material=sls(ratio), motion=motion,
                 time={"steps_per_cell": steps, "distance": length * A}, **kw)


def load_scene(load_program, ratio: float = 5.0, n: int = 16, end: float = 2 * T, dt: float = T / 10,
                **kw) -> dict:
    """Load control on a grid that holds the relaxed contact of the largest load."""
    peak = load_program if isinstance(load_program, (int, float)) else max(
        abs(load_program.get("mean", 0)) + abs(load_program.get("amplitude", 0)),
        abs(load_program.get("start", 0)), abs(load_program.get("end", 0)))
    j_inf = (1 - NU**2) * ratio / E0
    a_inf = (3 * peak * R * j_inf / 4) ** (1 / 3)
    delta_inf = a_inf**2 / R
    raw = scene(n=n, half=2.0, material=sls(ratio), motion={"load": load_program}, delta=delta_inf,
                time={"dt": dt, "end": end}, **kw)
    return raw


def scaled(raw: dict, modulus: float, radius: float, time_scale: float = 1.0) -> dict:
    """The scene ``raw`` (built on E0, R, T) with moduli times modulus/E0, lengths times radius/R and times
    times time_scale: forces scale by (modulus/E0)(radius/R)^2, pressures by modulus/E0."""
    raw = copy.deepcopy(raw)
    k, lam = modulus / E0, radius / R
    g = raw["grid"]
    g["x"] = [v * lam for v in g["x"]]
    g["y"] = [v * lam for v in g["y"]]
    m = raw["material"]
    for key in ("E", "E0", "Einf"):
        if key in m:
            m[key] *= k
    for key in ("tau_creep", "tau_relax"):
        if key in m:
            m[key] *= time_scale
    raw["body"]["radius"] *= lam
    motion = raw["motion"]
    if isinstance(motion.get("penetration"), (int, float)):
        motion["penetration"] *= lam
    if isinstance(motion.get("load"), (int, float)):
        motion["load"] *= k * lam**2
    if "velocity" in motion and isinstance(motion["velocity"], list):
        motion["velocity"] = [v * lam / time_scale for v in motion["velocity"]]
    t = raw.get("time", {})
    for key in ("dt", "end"):
        if key in t:
            t[key] *= time_scale
    if "distance" in t:
        t["distance"] *= lam
    return raw

"""A run's clock: the length of each step and the body's path over the whole run, from the scene alone.

The time loop (petroll.solver.simulation) takes its steps from :func:`step_length`; :func:`path` walks the
same clock without solving anything, so that the steps and the path are known before step 1 (``petroll
check``, the path check of petroll.model.preflight). A steady solve ([time] mode = "steady") has no clock,
only its integrator's step (:func:`steady_dt`). :func:`moves`: how far the body goes in each step, what
the time-resolution check of petroll.model.preflight weighs against the contact. Times in s, lengths in m.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

import numpy as np

from petroll.errors import SceneError


class TimeMode(Enum):
    """[time] mode: how a run goes in time. TRANSIENT marches from the start in steps of this clock;
    STEADY solves the steady state at constant velocity directly, one step without a clock (which steady
    solve, rolling or sliding, is the grid topology's: petroll.solver.steady_state)."""

    TRANSIENT = "transient"
    STEADY = "steady"


def step_length(scene, t: float, distance: float) -> float | None:
    """Length (s) of the step after time ``t`` with ``distance`` (m) rolled so far; None: the run is over
    ([time] end or distance reached, or a scene without [time] dt or steps_per_cell: one step).

    ``steps_per_cell`` = k: dt = cell / (k max(|V(t)|, 0.1 peak |V|)), the floor keeping a reversing body
    from taking huge steps; the last step is shortened to land on ``end`` or ``distance``."""
    tm = scene.time
    if tm.dt is None and tm.steps_per_cell is None:
        return None
    if tm.end is not None and t >= tm.end * (1 - 1e-12):
        return None
    if tm.distance is not None and distance >= tm.distance * (1 - 1e-12):
        return None
    speed = float(np.hypot(*scene.velocity(t)))
    if tm.dt is not None:
        dt = tm.dt
    else:
        scale = scene.velocity.peak()
        if scale == 0:
            raise SceneError(scene.source, "[time] steps_per_cell", tm.steps_per_cell,
                             "needs a moving body: give [time] dt for a body at rest")
        dt = _cell_time(scene, max(speed, 0.1 * scale))
    if tm.end is not None:
        dt = min(dt, tm.end - t)
    elif speed > 0:
        dt = min(dt, (tm.distance - distance) / speed * (1 + 1e-9))
    return dt


@dataclass(frozen=True)
class Path:
    """The body's reference point at every step of the whole run (no steady stop): times ``t`` (s),
    positions ``sx``, ``sy`` (m), rolled ``distance`` (m, summed step by step like the time loop's).
    ``complete`` is False when the walk stopped at [time] max_steps + 1 steps (the run would need more)."""

    t: np.ndarray
    sx: np.ndarray
    sy: np.ndarray
    distance: np.ndarray
    complete: bool

    @property
    def steps(self) -> int:
        """Steps after the sudden start (step 0)."""
        return len(self.t) - 1


def path(scene) -> Path:
    """Walk the clock of :func:`step_length` from t = 0 to the run's end (at most [time] max_steps + 1
    steps), the body at position + integral of V. A steady scene ([time] mode = "steady") is its start."""
    times, points, rolled = [0.0], [np.asarray(scene.position, dtype=float)], [0.0]
    t, distance, complete = 0.0, 0.0, True
    dt = None if scene.time.mode is TimeMode.STEADY else step_length(scene, t, distance)
    while dt is not None:
        if len(times) > scene.time.max_steps + 1:
            complete = False
            break
        t += dt
        point = np.asarray(scene.position, dtype=float) + scene.velocity.integral(t)
        distance += float(np.hypot(*(point - points[-1])))
        times.append(t)
        points.append(point)
        rolled.append(distance)
        dt = step_length(scene, t, distance)
    xy = np.array(points)
    return Path(np.array(times), xy[:, 0], xy[:, 1], np.array(rolled), complete)


def steady_dt(scene) -> float:
    """The integrator's step (s) of a steady solve ([time] mode = "steady", petroll.solver.steady and
    petroll.solver.sliding): [time] dt, else the time to cross min(dx, dy) over [time] steps_per_cell
    (default 1) at the speed |V(0)| (which must be > 0: the scene checks it)."""
    tm = scene.time
    if tm.dt is not None:
        return tm.dt
    return _cell_time(scene, float(np.hypot(*scene.velocity(0.0))))


def _cell_time(scene, speed: float) -> float:
    """The time (s) to cross a cell over [time] steps_per_cell (default 1) at ``speed`` (m/s, > 0); a
    SceneError on steps_per_cell where that is no finite number (the steps per second underflow to 0, or
    so near it that a cell's time overflows)."""
    k = scene.time.steps_per_cell or 1.0
    rate = k * speed  # cells per second; 0 when it underflows
    dt = scene.grid.cell / rate if rate > 0 else math.inf
    if not math.isfinite(dt):
        raise SceneError(scene.source, "[time] steps_per_cell", k, "gives no finite step (the steps per second "
                         "underflow double precision); give a value near 1 (docs/accuracy.md)")
    return dt


def moves(scene, walked: Path) -> np.ndarray:
    """(steps, 2): the body's displacement (m, along X and Y) over each step of the run: those of
    ``walked`` (its path, :func:`path`), or a steady solve's V(0) times :func:`steady_dt` (one row). Empty
    for a run of one step at t = 0 (no [time] step) or a steady solve at rest."""
    if scene.time.mode is TimeMode.STEADY:
        velocity = np.asarray(scene.velocity(0.0), dtype=float)
        if not np.any(velocity):
            return np.zeros((0, 2))
        return (velocity * steady_dt(scene))[None, :]
    return np.column_stack([np.diff(walked.sx), np.diff(walked.sy)])

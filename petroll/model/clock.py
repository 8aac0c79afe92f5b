"""A run's clock: the length of each step and the body's path over the whole run, from the scene alone.

The time loop (petroll.solver.simulation) takes its steps from :func:`step_length`; :func:`path` walks the
same clock without solving anything, so that the steps and the path are known before step 1 (``petroll
check``, the path check of petroll.model.preflight). Times in s, lengths in m.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from petroll.errors import SceneError


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
        dt = scene.grid.cell / (tm.steps_per_cell * max(speed, 0.1 * scale))
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
    dt = None if scene.time.mode == "steady" else step_length(scene, t, distance)
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

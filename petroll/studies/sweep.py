"""Parameter sweeps: one scene run over a list or a range of values of one key (``petroll sweep``).

    petroll sweep SCENE.toml --vary KEY=SPEC [--out DIR]

SPEC (docs/sweep.md): ``V1,V2,...`` (the listed values), ``START..STOP:log:N`` (N values evenly spaced in
log) or ``START..STOP:lin:N`` (evenly spaced), e.g. ``motion.velocity=1e-5..10:log:25``. KEY is a scene
key ``section.key`` holding a number. A vector key (``motion.velocity``, ``body.position``) varies its
magnitude along the scene's own direction: the scene's ``velocity = [0.01, 0]`` with the value 0.5 runs
``velocity = [0.5, 0]``. Varying one key of an exclusive pair drops the other (penetration/load,
tau_creep/tau_relax, dt/steps_per_cell, end/distance).

Each point is the scene with that value, at steady state. Where the steady state can be solved directly
(a [time] table, a constant non-zero velocity along X or Y, a constant penetration or load, a Prony/SLS
material: docs/rolling.md), the point's scene is the scene with [time] mode = "steady" (its steps_per_cell
or dt kept, its clock dropped), one step, and its solve starts from the previous point's pressure
(continuation). Otherwise, or with ``transient=True`` (``--transient``), it is run from rest to steady
state: a scene with a [time] table but no ``steady`` gets ``steady = 1e-3`` (:data:`DEFAULT_STEADY`); the
scene's ``distance`` (or ``end``) must leave room to reach it, and a point that ends before is flagged
(column ``steady`` = 0, a warning). A scene without [time] gives one instantaneous step per point (a
static sweep, e.g. force against penetration).

Output in DIR (default: the scene's output directory + ``-sweep``): points/KEY=VALUE/results.h5 (each
point's run, docs/results.md; checkpoints as the scene asks), sweep.csv and sweep.h5 (one row per point:
the steady values and the derived ones, COLUMNS), sweep.png (petroll.plot.sweep). A point whose complete
results.h5 holds the same scene is not run again, so an interrupted sweep (or one extended by more values)
resumes where it stopped; a point interrupted by SIGTERM/SIGINT continues from its checkpoint. Every
point builds its own contact solver (kernels: about 1-3 % of a point's run, docs/sweep.md). A family of
such sweeps over a second key, and the command: petroll.studies.family.

All functions here are collective over ``comm`` (every rank calls them with the same arguments) and
return the same values on every rank.
"""

from __future__ import annotations

import math
import pathlib
import re
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field

import h5py
import numpy as np
from mpi4py import MPI

from petroll import __version__
from petroll.model import motion as motions
from petroll.errors import PetrollError, SceneError, reason, shown
from petroll.model.materials import Prony, Tabulated, loss_peak_time
from petroll.io.hdf5 import atomic_hdf5, reading_as
from petroll.io.results import Results, atomic_write, results_identity
from petroll.io.rundir import clean_temporaries
from petroll.model.clock import TimeMode
from petroll.model.friction import creep_coefficient
from petroll.model.schema import DEFAULT_STEADY, SCHEMA
from petroll.model.scene import Scene
from petroll.studies.target import asks_target, targeted

"""[time] steady given to every point of a sweep whose scene has a [time] table without one."""

FORMS = "KEY=V1,V2,... or KEY=START..STOP:log:N or KEY=START..STOP:lin:N (docs/sweep.md)"

MAX_POINTS = 1000
"""The most values a sweep takes (each is a run; every point's scene is built before the first runs)."""

EXCLUSIVE = {
    "motion.penetration": "motion.load", "motion.load": "motion.penetration",
    "material.tau_creep": "material.tau_relax", "material.tau_relax": "material.tau_creep",
    "time.dt": "time.steps_per_cell", "time.steps_per_cell": "time.dt",
    "time.end": "time.distance", "time.distance": "time.end",
}
"""Keys of which a scene gives exactly one: varying one removes the other."""

COLUMNS: dict[str, tuple[str, str]] = {
    "value": ("(of KEY)", "the varied value (a vector key: its magnitude)"),
    "force": ("N", "normal force at the last step"),
    "mu_r": ("-", "rolling-resistance coefficient at the last step (steady sliding: friction, dissipation's)"),
    "delta": ("m", "penetration at the last step"),
    "area": ("m^2", "contact area at the last step"),
    "area_fraction": ("-", "A/A0: contact area / the cell's area (a grid periodic along X and Y; else NaN)"),
    "lead": ("m", "leading patch edge along the motion, relative to the body"),
    "trail": ("m", "trailing patch edge along the motion, relative to the body"),
    "p_max": ("Pa", "peak pressure at the last step"),
    "force_change": ("-", "|relative change| of the force over the last contact length of rolling"),
    "mu_r_change": ("-", "|relative change| of mu_r over the last contact length of rolling"),
    "resisting_change": ("-", "change of mu_r x force over the last contact length, / force"),
    "steady": ("-", "1: the run stopped on its [time] steady criterion; 0: at its end or distance"),
    "steps": ("-", "number of steps (step 0 included)"),
    "t": ("s", "time at the last step"),
    "distance": ("m", "path length rolled"),
    "solve_time": ("s", "wall time of the point's steps (their sum; file writes excluded)"),
    "speed": ("m/s", "|V| of a constant velocity (NaN otherwise)"),
    "tau": ("s", "characteristic time of the material: 1/omega at the peak of its loss compliance J''(omega) "
            "(an SLS: its creep time; NaN for an elastic material)"),
    "a_T": ("-", "time-temperature shift factor at the point's [material] temperature (1 without one)"),
    "a": ("m", "Hertz radius of the first step: sqrt(R delta_0) for a sphere, else sqrt(area_0/pi) (line "
          "contact: half the width); a point solved directly has no first step: Hertz with J0 at its "
          "force (sphere under load control, cylinder in line contact)"),
    "v_tau_a": ("-", "V tau / a (NaN where speed or tau is)"),
    "mu_r_slow": ("-", "slow-rolling limit V sum(dJ_r tau_r) / (Jinf R) (sphere, Prony; = V tau (1 - "
                  "J0/Jinf)/R for an SLS)"),
    "force_J0": ("N", "Hertz force with J0 at the last penetration (sphere): the fast-rolling limit "
                 "under displacement control"),
    "force_Jinf": ("N", "Hertz force with Jinf at the last penetration (sphere): the slow-rolling limit"),
    "delta_J0": ("m", "Hertz penetration with J0 at the last force (sphere): the fast limit under load "
                 "control"),
    "delta_Jinf": ("m", "Hertz penetration with Jinf at the last force (sphere): the slow limit"),
    "traction_x": ("N", "with [friction]: the tangential force on the body along X at the last step (NaN without)"),
    "traction_y": ("N", "with [friction]: along Y"),
    "creepage_x": ("-", "with [friction]: the creepage along X at the last step (given, or found)"),
    "creepage_y": ("-", "with [friction]: along Y"),
    "stick_area": ("m^2", "with [friction]: the stick area at the last step"),
    "friction_power": ("W", "with [friction]: the slip's power at the last step"),
    "creep_coefficient": ("-", "with [friction] on a sphere under a creepage (no spin): Kalker's creep "
                          "coefficient as the traction curve's secant (petroll.model.friction.creep_coefficient); "
                          "its initial slope at a small creepage (NaN otherwise)"),
    **{f"{name}_error": (unit, f"estimated discretisation error of {name} at the last step (only with "
                               "--estimate-error; NaN where the grids are not in the asymptotic range)")
       for name, unit in (("force", "N"), ("delta", "m"), ("mu_r", "-"), ("p_max", "Pa"), ("area", "m^2"),
                          ("lead", "m"), ("trail", "m"))},
}
"""The table's columns: name -> (unit, meaning). One row per point, in the order of the values."""

FRICTION_COLUMNS = ("traction_x", "traction_y", "creepage_x", "creepage_y", "stick_area", "friction_power")
"""The columns of a sweep with [friction] (NaN without)."""

LINE_UNITS = {"force": "N/m", "area": "m", "force_J0": "N/m", "force_Jinf": "N/m", "traction_x": "N/m",
              "traction_y": "N/m", "stick_area": "m", "friction_power": "W/m"}
"""The columns whose unit differs in a line-contact sweep (per unit length; area is the contact width)."""


class SweepError(PetrollError):
    """A --vary specification or a sweep that cannot be run (one line: what is wrong, what is allowed)."""


class SweepInterrupted(Exception):
    """SIGTERM/SIGINT stopped the sweep (finished points are kept; the same call resumes it)."""

    def __init__(self, signum: int, index: int, total: int, label: str):
        import signal

        self.signum, self.index, self.total, self.label = signum, index, total, label
        name = signal.Signals(signum).name if signum in signal.Signals._value2member_map_ else str(signum)
        super().__init__(f"interrupted by {name} at point {index + 1} of {total} ({label}); finished points "
                         "are kept: the same command resumes the sweep")

    @property
    def exit_code(self) -> int:
        return 128 + self.signum


@dataclass(frozen=True)
class Vary:
    """What a sweep varies: ``key`` (section.key) over ``values`` (in the key's unit)."""

    key: str
    values: tuple[float, ...]
    spec: str = ""  # the text it was parsed from


_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_RANGE = re.compile(rf"^({_NUMBER})\.\.({_NUMBER}):(log|lin):(\d+)$")


def parse_vary(text: str) -> Vary:
    """Read ``KEY=SPEC`` (module docstring); SweepError with one line for anything else."""
    def bad(reason: str) -> SweepError:
        return SweepError(f"--vary {shown(text)}: {reason}; allowed: {FORMS}")

    key, eq, spec = (part.strip() for part in str(text).partition("="))
    if not eq or not key or not spec:
        raise bad("must be KEY=VALUES")
    section, dot, name = key.partition(".")
    if not dot or not section or not name:
        raise bad(f"KEY must be written section.key (e.g. motion.velocity), not {key!r}")
    if section not in SCHEMA:
        raise bad(f"unknown section [{section}]; sections: " + ", ".join(SCHEMA))
    spec = "".join(spec.split())
    found = _RANGE.match(spec)
    if found:
        start, stop, kind = float(found[1]), float(found[2]), found[3]
        count = int(found[4]) if len(found[4].lstrip("0")) <= 6 else MAX_POINTS + 1  # not 10^5000: int()
        if count < 2:
            raise bad("a range needs N >= 2 values")
        if count > MAX_POINTS:
            n = found[4] if len(found[4]) <= 30 else f"{found[4][:20]}... ({len(found[4])} digits)"
            raise bad(f"N = {n}: a sweep takes at most {MAX_POINTS} values (each one a run)")
        if not (math.isfinite(start) and math.isfinite(stop)) or start == stop:
            raise bad("a range needs finite START != STOP")
        if kind == "log":
            if start <= 0 or stop <= 0:
                raise bad("a log range needs START > 0 and STOP > 0")
            values = np.geomspace(start, stop, count)
            values[0], values[-1] = start, stop
        else:
            values = np.linspace(start, stop, count)
        return Vary(key, tuple(float(v) for v in values), text)
    if ".." in spec or ":" in spec:
        raise bad("a range is START..STOP:log:N or START..STOP:lin:N, with numbers START, STOP and N")
    items = spec.split(",")
    if len(items) > MAX_POINTS:
        raise bad(f"{len(items)} values: a sweep takes at most {MAX_POINTS} (each one a run)")
    if not all(re.fullmatch(_NUMBER, item) for item in items):
        raise bad("a list must hold numbers separated by commas")
    values = tuple(float(item) for item in items)
    if not all(math.isfinite(v) for v in values):
        raise bad("values must be finite")
    if len(set(values)) != len(values):
        raise bad("values must differ")
    return Vary(key, values, text)


def key_unit(scene: Scene, key: str) -> str:
    """The unit of a scene key (``section.key``, or ``section.key.field`` in an inline table), from the
    schema ("-" when unknown)."""
    section, _, name = key.partition(".")
    name, _, field = name.partition(".")
    spec = SCHEMA.get(section, {}).get(name)
    if spec is not None:
        return dict(spec.fields).get(field, "-") if field else spec.unit
    from petroll.model.bodies import BODY_KEYS

    doc = BODY_KEYS.get(str(scene.raw.get("body", {}).get("shape")), {}).get(name, "")
    return "m" if re.search(r", m\b", doc) else "-"


STEADY_DROPPED = ("end", "distance", "steady", "max_steps")
"""The [time] keys a sweep point solved directly drops (the clock of a transient run)."""


def point_scene(scene: Scene, key: str, value: float, transient: bool = False) -> Scene:
    """The scene of one sweep point: ``key`` set to ``value`` (module docstring); solved directly ([time]
    mode = "steady") where that applies and ``transient`` is False, else [time] steady added."""
    point = valued_scene(scene, key, value)
    time = point.raw.get("time")
    if transient or not time or time.get("mode") == "steady":
        return point
    changes = {f"time.{name}": None for name in STEADY_DROPPED}
    changes["time.mode"] = "steady"
    try:
        return point.replace(changes)
    except SceneError:  # not a constant-velocity steady state: run from rest
        return point


def valued_scene(scene: Scene, key: str, value: float) -> Scene:
    """The scene with ``key`` set to ``value``, [time] steady added (run from rest to steady state)."""
    section, _, name = key.partition(".")
    current = scene.raw.get(section, {}).get(name)
    if isinstance(current, dict):
        raise SweepError(f"--vary {key}: the scene gives {key} as a program ({current.get('kind')!r}); only "
                         "a number or a constant [x, y] can be varied")
    new: object = value
    if isinstance(current, list):
        norm = math.hypot(*current) if len(current) == 2 else 0.0
        if norm == 0:
            raise SweepError(f"--vary {key}: the scene's {key} = {current!r} gives no direction to vary its "
                             "magnitude along; give it a non-zero [x, y] in the scene")
        new = [value * c / norm for c in current]
    elif key == "motion.velocity" and current is None:
        raise SweepError(f"--vary {key}: the scene gives no velocity, hence no direction; write "
                         "velocity = [1.0, 0.0] (any magnitude) in its [motion]")
    elif getattr(SCHEMA.get(section, {}).get(name), "kind", "") == "integer":  # (a number key written 1: not)
        if abs(value - round(value)) > 1e-9 * max(abs(value), 1.0):
            raise SweepError(f"--vary {key}: {value!r} is not an integer, and {key} is one")
        new = int(round(value))
    changes: dict[str, object] = {key: new}
    if key in EXCLUSIVE:
        changes[EXCLUSIVE[key]] = None
    time = scene.raw.get("time")
    if time is not None and "steady" not in time and time.get("mode") != "steady" and key != "time.steady":
        changes["time.steady"] = DEFAULT_STEADY
    return scene.replace(changes)


def point_name(key: str, value: float) -> str:
    """The directory of a point under DIR/points (the value, so that a longer list reuses points)."""
    return f"{key}={value:.10g}"


@dataclass
class SweepTable:
    """A sweep's table: ``columns[name]`` (numpy arrays, one value per point; units in :data:`COLUMNS`,
    the varied value in ``unit``), with where it was written. Returned on every rank."""

    key: str
    unit: str  # unit of the varied value
    columns: dict[str, np.ndarray]
    scene_text: str  # the swept scene (before the value is set)
    points: list[str]  # each point's directory, relative to the sweep directory
    directory: pathlib.Path
    computed: list[int] = field(default_factory=list)  # points run by this call (others: found finished)

    @property
    def line(self) -> bool:
        """A line-contact (plane-strain) sweep: its scene's [grid] has no ny (units: LINE_UNITS)."""
        import tomllib

        return "ny" not in tomllib.loads(self.scene_text).get("grid", {})

    @property
    def csv(self) -> pathlib.Path:
        return self.directory / "sweep.csv"

    @property
    def h5(self) -> pathlib.Path:
        return self.directory / "sweep.h5"

    @property
    def png(self) -> pathlib.Path:
        return self.directory / "sweep.png"

    @classmethod
    def open(cls, path: str | pathlib.Path) -> "SweepTable":
        """Read ``sweep.h5`` (or the sweep directory holding it)."""
        path = pathlib.Path(path)
        if path.is_dir():
            path = path / "sweep.h5"
        with reading_as(path, "petroll sweep file"), h5py.File(path, "r") as f:
            table = f["table"]
            columns = {name: table[name][()] for name in COLUMNS if name in table}
            return cls(str(f.attrs["key"]), str(f.attrs["unit"]), columns, str(f.attrs["scene"]),
                       [str(p) for p in f.attrs["points"]], path.parent)


def sweep(scene: Scene, vary: Vary | str, out: str | pathlib.Path | None = None,
          comm: MPI.Comm = MPI.COMM_WORLD, progress: bool = False, stop=None,
          log: Callable[[str], None] | None = None, plot: bool = True, transient: bool = False,
          estimate_error: bool = False) -> SweepTable:
    """Run ``scene`` at every value of ``vary`` (a :class:`Vary` or its ``KEY=SPEC`` text), each point to
    steady state, and write the table (sweep.csv, sweep.h5) and the plot (sweep.png) in ``out`` (default:
    the scene's output directory + ``-sweep``). Points already finished there are read, not run again.

    Collective. ``progress``: each run's status line on rank 0's stderr; ``stop``: a
    :class:`petroll.io.checkpoint.StopRequest` (SIGTERM/SIGINT): the sweep then raises
    :class:`SweepInterrupted` after the running point's checkpoint; ``log(line)``: called on rank 0 after
    each point. Every point's scene is built and validated before the first run. ``transient``: run every
    point from rest, even where its steady state can be solved directly (module docstring).
    ``estimate_error``: each point run also estimates its discretisation error (petroll.driver.run's
    estimate_error): the table gains the columns ``<quantity>_error``; a point finished earlier without
    its estimate (a call without it, or killed while it was made) is not finished: it is run again (from
    its last checkpoint where it has one) and estimated.
    """
    from petroll.io.checkpoint import RunInterrupted
    from petroll.model.limits import PetrollWarning
    from petroll.driver import prepare_output

    if isinstance(vary, str):
        vary = parse_vary(vary)
    if out is None:
        out = scene.output_dir.with_name(scene.output_dir.name + "-sweep")
    out = pathlib.Path(out)
    scenes = [point_scene(scene, vary.key, v, transient) for v in vary.values]
    names = [point_name(vary.key, v) for v in vary.values]
    if len(set(names)) != len(names):
        raise SweepError(f"--vary {vary.spec or vary.key}: values closer than 10 significant digits")
    prepare_output(out, comm)
    unit = key_unit(scene, vary.key)
    rows, computed = [], []
    total = len(scenes)
    start = None  # the previous point's steady state (pressure, penetration): the next one starts there
    for index, (value, point, name) in enumerate(zip(vary.values, scenes, names)):
        label = f"{vary.key} = {value:.6g}" + (f" {unit}" if unit != "-" else "")
        signum = stop.agreed(comm) if stop is not None else 0
        if signum:
            raise SweepInterrupted(signum, index, total, label)
        directory = out / "points" / name
        if asks_target(point):  # its grid chosen here: the point's text as run, to resume it by
            point = targeted(point, comm)
        results = _finished(directory, point, comm, estimate_error)
        if results is None:
            try:
                results = _run_point(point, directory, comm, progress, stop, start, estimate_error)
            except RunInterrupted as exc:
                raise SweepInterrupted(exc.signum, index, total, label) from None
            computed.append(index)
        direct = point.time.mode is TimeMode.STEADY
        following = scenes[index + 1].grid if index + 1 < total else None
        same_grid = following is not None and (following.nx, following.ny) == (point.grid.nx, point.grid.ny)
        start = (results.pressure[-1], float(results.series["delta"][-1])) if direct and same_grid else None
        row = table_row(point, results, value, estimate_error)
        rows.append(row)
        if point.time.steady is not None and not row["steady"]:
            warnings.warn(PetrollWarning(
                f"sweep point {label}: not steady at the end of the run ({row['distance']:.4g} m rolled; "
                f"force changed by {row['force_change']:.2g}, mu_r by {row['mu_r_change']:.2g} over the last "
                f"contact length): lengthen its [time] distance or end (and the grid)"), stacklevel=2)
        if log is not None and comm.rank == 0:
            done = "ran" if computed and computed[-1] == index else "kept (finished earlier)"
            static = point.time.dt is None and point.time.steps_per_cell is None
            state = ("steady (solved directly)" if direct else "steady" if row["steady"] else
                     "one step (no [time])" if static else "NOT steady")
            rough = (f"friction mu {row['mu_r']:.4e}, A/A0 {row['area_fraction']:.4g}"
                     if math.isfinite(row["area_fraction"]) else f"mu_r {row['mu_r']:.4e}")
            log(f"point {index + 1}/{total} {label}: {done}; {rough}, force "
                f"{row['force']:.5g} N, {int(row['steps'])} steps, {state}"
                + (f", V tau/a {row['v_tau_a']:.3g}" if math.isfinite(row["v_tau_a"]) else "")
                + (f", grid {point.grid.nx} x {point.grid.ny} (sized)" if point.sizing is not None else ""))
    columns = {name: np.array([row[name] for row in rows], dtype=float) for name in COLUMNS if name in rows[0]}
    table = SweepTable(vary.key, unit, columns, scene.text, [f"points/{n}" for n in names], out, computed)
    on_rank0(comm, lambda: write_table(table))
    if plot:
        on_rank0(comm, lambda: _plot(table))
    return table


def _finished(directory: pathlib.Path, scene: Scene, comm: MPI.Comm, estimate_error: bool = False
              ) -> Results | None:
    """The point's results if its results.h5 is complete and holds this very scene, and with
    ``estimate_error`` its error estimate (a point without it is not finished: it is run again, from its
    last checkpoint where it has one, and estimated); rank 0 decides."""
    path = directory / "results.h5"
    done = False
    if comm.rank == 0 and path.is_file():
        held = results_identity(path)  # None: unreadable, run it again
        done = (held is not None and held["complete"] and held["scene"] == scene.text
                and (held["estimated"] or not estimate_error))
    if not comm.bcast(done, root=0):
        return None
    return Results.open(path)


def _run_point(scene: Scene, directory: pathlib.Path, comm: MPI.Comm, progress: bool, stop,
               start=None, estimate_error: bool = False) -> Results:
    """Run one point, continuing from its newest checkpoint if that holds this scene; ``start``: the
    first guess of a steady solve (petroll.driver.run's steady_start)."""
    from petroll.io.checkpoint import CheckpointError, list_checkpoints, read_checkpoint, restart_scene
    from petroll.driver import run

    found = list_checkpoints(directory / "checkpoints") if comm.rank == 0 else None
    found = comm.bcast([str(p) for p in found] if found is not None else None, root=0)
    if found:
        try:
            check = read_checkpoint(found[-1], comm)
            if check.scene_text == scene.text:
                return run(restart_scene(check), comm, directory, progress=progress, restart=check, stop=stop,
                           overwrite=True, estimate_error=estimate_error)
        except CheckpointError:
            pass  # a damaged checkpoint (raised on every rank): run the point from its start
    return run(scene, comm, directory, progress=progress, stop=stop, steady_start=start, overwrite=True,
               estimate_error=estimate_error)


def table_row(scene: Scene, results: Results, value: float, estimate_error: bool = False) -> dict[str, float]:
    """One row of the table (COLUMNS) for a point's scene and results (``estimate_error``: with the
    ``<quantity>_error`` columns, from results.h5's error_estimate group)."""
    from petroll.model.bodies import CylinderSection, Sphere
    from petroll.solver.contact import hertz_penetration

    s, st = results.series, results.steady
    row: dict[str, float] = {
        "value": value, "force": st.force, "mu_r": st.mu_r, "delta": st.delta, "area": st.area,
        "lead": st.lead, "trail": st.trail, "p_max": st.p_max, "force_change": st.force_change,
        "mu_r_change": st.mu_r_change, "resisting_change": st.resisting_change, "steady": float(st.reached),
        "steps": float(len(s["t"])), "t": st.t, "distance": st.distance,
        "solve_time": float(np.sum(s["solve_time"])),
    }
    velocity = scene.velocity
    speed = float(np.hypot(*velocity.value)) if isinstance(velocity, motions.Constant) else math.nan
    material = scene.material
    viscous = isinstance(material, Tabulated) or (isinstance(material, Prony) and len(material.tau) > 0)
    tau = loss_peak_time(material) if viscous else math.nan
    sphere = isinstance(scene.body, Sphere)
    g, line = scene.grid, scene.grid.line  # plane strain: force per length, area a width, delta to the datum
    cell = g.topology.statistics  # a periodic cell: its area fraction, no Hertz radius
    row["area_fraction"] = st.area / ((g.x1 - g.x0) * (g.y1 - g.y0)) if cell else math.nan
    delta0 = float(s["delta"][0])
    direct = scene.time.mode is TimeMode.STEADY  # no first (instantaneous) step: Hertz with J0 at its load
    if direct and line and isinstance(scene.body, CylinderSection) and isinstance(material, Prony):
        a = math.sqrt(4 * st.force * scene.body.radius * material.J0 / math.pi)
    elif direct and sphere and scene.load is not None and isinstance(material, Prony):
        a = (0.75 * st.force * scene.body.radius * material.J0) ** (1 / 3)
    elif line:
        a = float(s["area"][0]) / 2
    elif sphere and delta0 > 0:
        a = math.sqrt(scene.body.radius * delta0)
    else:
        a = math.sqrt(float(s["area"][0]) / math.pi)
    a = math.nan if cell else a
    row.update(speed=speed, tau=tau, a_T=scene.shift_factor, a=a,
               v_tau_a=speed * tau / a if a > 0 and speed > 0 else math.nan)
    nan = math.nan
    row.update(mu_r_slow=nan, force_J0=nan, force_Jinf=nan, delta_J0=nan, delta_Jinf=nan)
    if (sphere or isinstance(scene.body, CylinderSection)) and isinstance(material, Prony):
        radius = scene.body.radius
        if material.tau and math.isfinite(speed):  # mu_r -> e/R in 3-D and in plane strain (docs/line-contact.md)
            creep = sum(d * t for d, t in zip(material.dJ, material.tau))
            row["mu_r_slow"] = speed * creep / (material.Jinf * radius)
        for name, J in (("J0", material.J0), ("Jinf", material.Jinf)):
            if line:
                if st.force > 0:
                    row[f"delta_{name}"] = hertz_penetration(scene.grid, J, st.force, radius)
                continue
            if st.delta > 0:
                row[f"force_{name}"] = 4 * math.sqrt(radius) * st.delta**1.5 / (3 * J)
            if st.force > 0:
                row[f"delta_{name}"] = (3 * J * st.force / (4 * math.sqrt(radius))) ** (2 / 3)
    for name in FRICTION_COLUMNS:  # a run with friction (line contact: no _y series)
        row[name] = float(s[name][-1]) if name in s else nan
    row["creep_coefficient"] = creep_coefficient(scene, row["force"], row["delta"],
                                                 (row["traction_x"], row["traction_y"]))
    if estimate_error:
        found = results.error_estimate or {}
        for name in COLUMNS:
            if name.endswith("_error"):
                row[name] = float(found.get(name[: -len("_error")], {}).get("error", math.nan))
    return row


def csv_rows(table: SweepTable, before: tuple[str, str, float] | None = None) -> tuple[str, list[str]]:
    """(header, rows) of a table's CSV (COLUMNS, in order; ``before``: a first column (name, unit, value)
    of every row, a family's second key)."""
    names = [n for n in COLUMNS if n in table.columns]
    line = LINE_UNITS if table.line else {}  # a line-contact sweep: per unit length
    units = [table.unit if n == "value" else line.get(n, COLUMNS[n][0]) for n in names]
    header = ",".join(f"{table.key if n == 'value' else n} ({u})" for n, u in zip(names, units))
    first = "" if before is None else f"{before[2]:.10g},"
    rows = [first + ",".join(f"{table.columns[n][i]:.10g}" for n in names) for i in range(len(table.points))]
    return (header if before is None else f"{before[0]} ({before[1]}),{header}"), rows


def write_table(table: SweepTable) -> None:
    """Write sweep.csv and sweep.h5 (each atomically). Call on one rank."""
    names = [n for n in COLUMNS if n in table.columns]
    line = LINE_UNITS if table.line else {}  # a line-contact sweep: per unit length
    units = [table.unit if n == "value" else line.get(n, COLUMNS[n][0]) for n in names]
    header, rows = csv_rows(table)
    text = "\n".join([header, *rows]) + "\n"
    clean_temporaries(table.directory, [table.csv.name, table.h5.name])  # of a writer killed earlier
    atomic_write(table.csv, lambda tmp: tmp.write_text(text, encoding="utf-8"))

    def fill(f: h5py.File, failed) -> None:
        f.attrs["format"] = "petroll-sweep"
        f.attrs["petroll_version"] = __version__
        f.attrs["key"] = table.key
        f.attrs["unit"] = table.unit
        f.attrs["scene"] = table.scene_text
        f.attrs["points"] = np.array(table.points, dtype=h5py.string_dtype())
        group = f.create_group("table")
        for n, u in zip(names, units):
            dataset = group.create_dataset(n, data=table.columns[n])
            dataset.attrs["units"] = u
            dataset.attrs["meaning"] = COLUMNS[n][1]

    atomic_hdf5(table.h5, fill)


def _plot(table: SweepTable) -> None:
    from petroll.model.limits import PetrollWarning

    try:
        import matplotlib  # noqa: F401
    except ImportError:
        warnings.warn(PetrollWarning("sweep: matplotlib is not installed: the table is written, not the "
                                     "plot"), stacklevel=3)
        return
    from petroll.plot import plot_sweep

    plot_sweep(table, table.png)


def on_rank0(comm: MPI.Comm, action: Callable[[], None]) -> None:
    """Run ``action`` on rank 0; an OSError or PetrollError there is raised on every rank (one line)."""
    message = None
    if comm.rank == 0:
        try:
            action()
        except OSError as exc:
            message = f"{getattr(exc, 'filename', None) or 'sweep output'}: cannot write ({reason(exc)})"
        except PetrollError as exc:
            message = str(exc)
    message = comm.bcast(message, root=0)
    if message is not None:
        raise SweepError(message)

"""Friction benchmarks (docs/friction.md): what a tangential solve costs, for the verb ``petroll bench
friction`` (:func:`bench_friction`), and the measurements behind the solvers' choice
(:func:`compare_solvers`).

The cases are Hertzian contacts with the pressure at the cell centres (a = 1, n cells per radius or
half-width, a margin of 4 cells), nu = 0.3, two bodies of one material (compliance 1/G), mu = 0.3:

- normal: the normal QP of the same sphere under load control (pk from Hertz's pressure, the default
  solver's cold start): the reference of the "3 x the normal solve" target; a rolling step of it (the
  last pressure moved: its answer); its load ramped in 4 steps (a normal step whose answer changes);
- shift: Cattaneo's shift by Q = mu P/2 in one step (force control; from Cattaneo and Mindlin's
  tractions), and the same load in 4 steps;
- transient: rolling one cell a step at that force after the shift, over five contact lengths (per step:
  the first, third and fifth contact length: the transient fades by about 0.15 a contact length), and
  half a cell a step (2 steps per cell: the third contact length);
- steady: the steady state at that force solved directly (cold; and on bodies of an SLS at V tau/a = 1,
  the wake 2 radii behind), and a 30-point creep-force curve (creepage
  up to 3 times the linear theory's saturation, each point started from the last) at 16 cells per radius
  (32 x 32 cells in the contact);
- steady scenes: two SLS spheres of one material at V tau/a = 1 with ``[time] mode = "steady"``, 32 cells
  per relaxed radius (64 x 64 cells in the relaxed contact), solved as ``petroll run`` solves them
  (Simulation.solve_steady): frictionless, and under the tangential force mu P/2 (the normal steady
  solve, then the tangential one on its pressure): the reference and the subject of the "under 3 x the
  frictionless steady solve" target, their ratio in the second row's note.

Applications count each problem's own operator, the preconditioner's transforms left out in both: the
normal QP's K p (one zero-padded FFT pair on its window), the tangential one's u = c K q (two components:
two FFT pairs on its window in 3-D, one in line contact; the displacement u' of the last steps' tractions
enters its gradient, H (q - q') + W, so a step has no convolution besides its QP's); ``fft pairs`` counts
both alike (LEGEND, printed under the table). Times are wall times on this rank (the machine's load
matters: say it where quoted).
"""

from __future__ import annotations

import math
import pathlib
import time

import numpy as np
from mpi4py import MPI

from petroll.model.grid import Grid, line_grid
from petroll.solver.friction import SteadyRolling, Stepping
from petroll.solver.tangential import DiskPCG, TangentialSolver, project
from petroll.studies.tables import write_table

NU, MU = 0.3, 0.3

LEGEND = ("applications: the normal QP's K p (1 FFT pair) / the tangential QP's u = c K q (2 FFT pairs in "
          "3-D: one per traction component), preconditioners not counted; fft_pairs counts both alike")


def hertz_case(n: int, comm: MPI.Comm, line: bool = False, length: float = 0.0, tol: float = 1e-8):
    """(grid, tangential solver, bound(centre)) for a Hertz contact of radius (half-width) 1 with n cells per
    radius, 4 cells of margin, ``length`` radii of track along +x; the bound mu p (p0 = 1)."""
    dx = 1.0 / n
    margin = 4
    if line:
        grid = line_grid(2 * (n + margin), -1 - margin * dx, 1 + margin * dx)
    else:
        nx = int(round(length * n)) + 2 * (n + margin)
        grid = Grid(nx, 2 * (n + margin), -1 - margin * dx, -1 - margin * dx + nx * dx, -(n + margin) * dx,
                    (n + margin) * dx)
    solver = TangentialSolver(grid, comm, NU, 1.0, tol=tol)

    def bound(centre: float = 0.0) -> np.ndarray:
        x = grid.x[solver.r0 : solver.r1, None] - centre
        r2 = x * x if line else x * x + grid.y[None, :] ** 2
        return MU * np.sqrt(np.clip(1 - r2, 0.0, None))

    return grid, solver, bound


def _force(comm, field, grid) -> float:
    return comm.allreduce(float(field.sum())) * grid.cell_area


def _timed(call):
    start = time.perf_counter()
    out = call()
    return out, time.perf_counter() - start


def normal_reference(n: int, comm: MPI.Comm) -> list[tuple[float, float]]:
    """The normal QP of the benchmark's sphere under load control (pk): (applications, wall time) from
    Hertz's pressure (a cold step), from the previous step's pressure moved one cell with the body (a
    rolling step of an elastic run), and per step of the load ramped from 0 in 4 steps, each from the
    last pressures as a run starts it (petroll.solver.warm.WarmStart; the first from Hertz's): the normal
    problem's step when its answer changes, as the tangential ramp's does."""
    from petroll.solver.contact import ContactSolver
    from petroll.solver.partition import shift_field
    from petroll.solver.warm import WarmStart

    dx = 1.0 / n
    cells = n + max(4, n // 2)  # the load-control guess's interference must stay off the edge
    half = cells * dx
    grid = Grid(2 * cells + 1, 2 * cells, -half, half + dx, -half, half)
    radius, compliance = 100.0, 1.0
    solver = ContactSolver(grid, comm, tol=1e-8)
    x, y = grid.x[solver.r0 : solver.r1, None], grid.y[None, :]
    load = 4 / (3 * radius * compliance)  # a = 1

    def solve(centre: float, warm=None):
        height = ((x - centre) ** 2 + y * y) / (2 * radius)
        return _timed(lambda: solver.solve_load(height, compliance, load, radius, warm=warm))

    cold, cold_time = solve(0.0)
    moved = shift_field(cold.pressure, 1, 0, solver.rows, comm)
    warm, warm_time = solve(dx, moved)
    starts, ramp, ramp_time = WarmStart(grid, solver.rows, comm), 0, 0.0
    height = (x * x + y * y) / (2 * radius)
    for k in range(1, 5):
        step, seconds = _timed(lambda: solver.solve_load(height, compliance, load * k / 4, radius,
                                                         warm=starts.guess(0.0, 0.0)))
        starts.record(step.pressure, 0.0, 0.0)
        ramp, ramp_time = ramp + step.applications, ramp_time + seconds
    return [(cold.applications, cold_time), (warm.applications, warm_time), (ramp / 4, ramp_time / 4)]


def bench_friction(out: pathlib.Path | None = None, quick: bool = False, comm: MPI.Comm = MPI.COMM_WORLD,
                   n: int = 16, scene_n: int = 32) -> list[dict]:
    """The table of the module docstring (rows: case, applications, fft pairs, seconds, iterations, note)
    at ``n`` cells per radius, the steady scenes' at ``scene_n`` per relaxed radius (``quick``: 4 both, a
    3-point curve: it runs and measures nothing). Rank 0 prints it and writes DIR/friction.csv when ``out``
    is given."""
    if quick:
        n = scene_n = 4
    rows = []
    (apps, seconds), (moved, moved_seconds), (ramp, ramp_seconds) = normal_reference(n, comm)
    rows.append(dict(case="normal QP, load control (reference)", applications=apps, fft_pairs=apps,
                     seconds=seconds, iterations="", note="pk from Hertz's pressure"))
    rows.append(dict(case="normal QP, rolling step (reference)", applications=moved, fft_pairs=moved,
                     seconds=moved_seconds, iterations="", note="from the last pressure, moved"))
    rows.append(dict(case="normal QP, load 0 to P in 4 steps (per step, reference)", applications=ramp,
                     fft_pairs=ramp, seconds=ramp_seconds, iterations="", note="from the last pressures"))
    grid, solver, bound = hertz_case(n, comm, length=10.0)  # five contact lengths of track
    force = np.array([-0.5 * _force(comm, bound(), grid), 0.0])
    stepping = Stepping(solver)
    solution, seconds = _timed(lambda: stepping.shift(bound(), force=force))
    rows.append(dict(case="shift Q = mu P/2, one step", applications=solution.applications,
                     fft_pairs=2 * solution.applications, seconds=seconds, iterations=solution.iterations,
                     note=f"shift {stepping.shift_total[0]:.6g}"))
    steps = Stepping(solver)
    start, total = time.perf_counter(), 0
    for k in range(1, 5):
        total += steps.shift(bound(), force=force * k / 4).applications
    rows.append(dict(case="shift Q = mu P/2, 4 steps (per step)", applications=total / 4, fft_pairs=total / 2,
                     seconds=(time.perf_counter() - start) / 4, iterations="", note="from the last three, extrapolated"))
    rows += _transient(stepping, bound, force, n, (1, 3, 5))
    halves = Stepping(solver)
    halves.shift(bound(), force=force)
    rows += _transient(halves, bound, force, n, (3,), per_cell=2)
    steady = SteadyRolling(solver, 0, 1)
    result, seconds = _timed(lambda: steady.solve(bound(), force=force))
    rows.append(dict(case="steady, force control, cold", applications=result.applications,
                     fft_pairs=2 * result.applications, seconds=seconds, iterations=result.iterations,
                     note=f"creepage {result.creepage[0]:.6g}"))
    rows.append(steady_viscoelastic(n, comm, force))
    rows += steady_scene_rows(scene_n, comm)
    rows.append(creep_curve(n, comm, 3 if quick else 30))
    if out is not None and comm.rank == 0:
        out.mkdir(parents=True, exist_ok=True)
        write_table(rows, out / "friction.csv")
        print(LEGEND)
    return rows


def steady_viscoelastic(n: int, comm: MPI.Comm, force: np.ndarray) -> dict:
    """The steady state at ``force`` solved directly on bodies of an SLS (E0/Einf = 5, tau = 1, rolling at
    V tau/a = 1: one cell per step is dt = 1/n), on the elastic case's grid with 2 radii of wake behind the
    contact: the tangential operator with the integrator's response along the motion."""
    from petroll.model.materials import sls
    from petroll.solver.history import state_space

    grid, solver, bound = hertz_case(n, comm, length=2.0)
    factor = 1 / (1 - NU)
    h0, s1, M, c = state_space(sls(5.0, 1.0, NU, 1.0), "relaxation", 1.0 / n)
    steady = SteadyRolling(solver, 0, -1)  # moving towards -x: the track (+x) is the wake
    result, seconds = _timed(lambda: steady.solve(bound(), force=force, memory=(factor * h0, s1, M, factor * c)))
    return dict(case="steady, viscoelastic (SLS, V tau/a = 1), force control, cold",
                applications=result.applications, fft_pairs=2 * result.applications, seconds=seconds,
                iterations=result.iterations, note=f"creepage {result.creepage[0]:.6g}")


SLS_SCENE = {"model": "sls", "E0": 10e6, "Einf": 2e6, "nu": 0.3, "tau_creep": 0.05}
"""The material of both bodies of :func:`steady_scenes` (E0/Einf = 5)."""


def steady_scene(n: int, friction: bool) -> dict:
    """Two SLS bodies of one material (:data:`SLS_SCENE`, a sphere R = 10 mm under 1 N) rolling along +X
    at V tau/a = 1, ``[time] mode = "steady"``, ``n`` cells per relaxed Hertz radius a (2n x 2n cells in the
    contact at most), the grid 5 a behind the body (the wake), 1.5 a ahead and to the sides; ``friction``:
    mu = 0.3 and the tangential force mu P/2 (the scene's dict, for petroll.model.scene.parse_scene)."""
    nu, radius, load = SLS_SCENE["nu"], 0.01, 1.0
    a = (3 * load * radius * 2 * (1 - nu**2) / SLS_SCENE["Einf"] / 4) ** (1 / 3)
    h = a / n
    behind, ahead, side = 5 * n, round(1.5 * n), round(1.5 * n)
    raw = {"grid": {"nx": behind + ahead, "ny": 2 * side, "x": [-behind * h, ahead * h], "y": [-side * h, side * h]},
           "material": dict(SLS_SCENE),
           "body": {"shape": "sphere", "radius": radius, "material": "same", "position": [0.0, 0.0]},
           "motion": {"load": load, "velocity": [a / SLS_SCENE["tau_creep"], 0.0]},
           "time": {"mode": "steady"}, "solver": {"tol": 1e-8}}
    if friction:
        raw["friction"] = {"coefficient": MU}
        raw["motion"]["tangential_force"] = [-0.5 * MU * load, 0.0]
    return raw


def steady_scenes(n: int, comm: MPI.Comm):
    """The steady state of :func:`steady_scene` without and with friction, each a new Simulation solved
    directly (Simulation.solve_steady at the scene's tol, as ``petroll run`` does; the simulations' set-up,
    their kernels, left out of the time; the same first guess): ((simulation, record, seconds) without,
    the same with friction)."""
    from petroll.model.scene import parse_scene
    from petroll.solver.simulation import Simulation

    out = []
    for friction in (False, True):
        sim = Simulation(parse_scene(steady_scene(n, friction), source="petroll bench friction"), comm)
        comm.Barrier()
        record, seconds = _timed(lambda: sim.solve_steady(tol=sim.scene.solver.tol))
        out.append((sim, record, comm.allreduce(seconds, op=MPI.MAX)))
    return out


def steady_scene_rows(n: int, comm: MPI.Comm) -> list[dict]:
    """The rows of :func:`steady_scenes`: the frictionless steady solve (the normal QPs' applications, one
    FFT pair each), the same with friction (its tangential QPs' applications besides, two FFT pairs each;
    note: the time's ratio to the frictionless one, the target under 3)."""
    (_, plain, plain_s), (sim, both, both_s) = steady_scenes(n, comm)
    tangential = sim.friction.records[-1]
    where = f"two SLS spheres, V tau/a = 1, {n} cells per relaxed radius"
    return [dict(case=f"steady scene, frictionless ({where})", applications=plain.applications,
                 fft_pairs=plain.applications, seconds=plain_s, iterations="", note="Simulation.solve_steady"),
            dict(case=f"steady scene, force mu P/2 ({where})",
                 applications=both.applications + tangential.friction_applications,
                 fft_pairs=both.applications + 2 * tangential.friction_applications, seconds=both_s,
                 iterations=tangential.friction_iterations,
                 note=f"time {both_s / plain_s:.3g} x frictionless; creepage {tangential.creepage_x:.6g}")]


def _transient(stepping: Stepping, bound, force, n: int, lengths, per_cell: int = 1) -> list[dict]:
    """Rolling 1/``per_cell`` of a cell a step after the shift: per step over each contact length of
    ``lengths`` (counted from 1)."""
    dx = 1.0 / (n * per_cell)
    records = []
    for k in range(1, 2 * max(lengths) * n * per_cell + 1):
        solution, seconds = _timed(lambda: stepping.roll(bound(k * dx), (k * dx, 0.0), dx, (1.0, 0.0), force=force))
        records.append((solution.applications, seconds, solution.iterations))
    rows, steps = [], 2 * n * per_cell
    for length in lengths:
        part = records[steps * (length - 1) : steps * length]
        apps = sum(r[0] for r in part) / len(part)
        every = "" if per_cell == 1 else f", {per_cell} steps per cell"
        rows.append(dict(case=f"transient rolling{every}, contact length {length} (per step)", applications=apps,
                         fft_pairs=2 * apps, seconds=sum(r[1] for r in part) / len(part),
                         iterations=sum(r[2] for r in part) / len(part),
                         note=f"from {per_cell}, {2 * per_cell}, {3 * per_cell} steps back, carried"))
    return rows


def creep_curve(n: int, comm: MPI.Comm, points: int = 30) -> dict:
    """A steady creep-force curve of the circular contact (16 cells per radius: 32 x 32 in the contact):
    ``points`` creepages up to 3 x mu p0/(G C11) (C11 = 4.12 nearly: nu = 0.3), each from the last."""
    grid, solver, bound = hertz_case(n, comm)
    steady = SteadyRolling(solver, 0, 1)
    saturation = MU / 4.12
    start, apps, newton, last = time.perf_counter(), 0, 0, []
    forces = []
    for xi in np.linspace(0.0, 3 * saturation, points + 1)[1:]:  # started from the last two, extrapolated
        warm = None if not last else last[-1] if len(last) == 1 else 2 * last[-1] - last[-2]
        result = steady.solve(bound(), creepage=(xi, 0.0), start=warm)
        last = (last + [result.solution.traction])[-2:]
        apps, newton = apps + result.applications, newton + result.iterations
        forces.append(result.solution.force[0])
    seconds = time.perf_counter() - start
    capacity = _force(comm, bound(), grid)
    return dict(case=f"creep curve, {points} points, steady, warm", applications=apps, fft_pairs=2 * apps,
                seconds=seconds, iterations=newton, note=f"last F/mu P = {-forces[-1] / capacity:.4f}")


# -- the solvers' choice -------------------------------------------------------------------------------------

def fista(apply, g: np.ndarray, b: np.ndarray, norm: float, tol: float, comm: MPI.Comm,
          max_iterations: int = 20000) -> tuple[np.ndarray, int]:
    """The disk QP of petroll.solver.tangential by an accelerated projected gradient (FISTA, step 1/|H|_inf,
    restarted when the objective's model rises: O'Donoghue and Candes 2015): the alternative measured
    against the projected CG. Returns q and the applications to the natural residual ``tol`` (checked every
    tenth iteration, at one more application)."""
    q = np.zeros_like(b)
    y, t = q.copy(), 1.0
    r = apply(y) + b
    applications = 1
    for _ in range(max_iterations):
        new = project(y - r / norm, g)
        step = new - q
        t_next = 0.5 * (1 + math.sqrt(1 + 4 * t * t))
        if comm.allreduce(float(np.vdot(r, step)), op=MPI.SUM) > 0:  # restart the momentum
            t_next, y = 1.0, new
        else:
            y = new + ((t - 1) / t_next) * step
        q, t = new, t_next
        r = apply(y) + b
        applications += 1
        if applications % 10 == 0:  # the natural residual at q, checked every tenth iteration
            s = apply(q) + b
            applications += 1
            residual = comm.allreduce(float(np.abs(q - project(q - s, g)).max(initial=0.0)), op=MPI.MAX)
            if residual <= tol:
                return q, applications
    return q, applications


def _scaled_problem(solver: TangentialSolver, bound: np.ndarray, rigid: np.ndarray):
    """The scaled QP of ``solver.solve`` on the bound's box: (apply, precondition, g, b, norm) on flattened
    (m, cells) arrays."""
    problem = solver.scaled(bound, solver.box(bound > 0))
    m, ny = solver.m, problem.ny
    b = solver.to_box(rigid, problem.box).reshape(m, -1) / problem.s_ref
    return (lambda d: problem.apply(d.reshape(m, -1, ny)).reshape(m, -1),
            lambda r: problem.precondition(r.reshape(m, -1, ny)).reshape(m, -1), problem.g.ravel() / problem.q_ref,
            b, problem.norm)


def compare_solvers(comm: MPI.Comm = MPI.COMM_WORLD, n: int = 16, tol: float = 1e-8) -> list[dict]:
    """Applications to the natural residual ``tol`` of the disk QP by: the projected CG (DiskPCG, as
    shipped), without its preconditioner, without the disk edge's curvature (kappa = 0: the step along a
    slip cell's edge then ignores that turning pulls its traction inwards), and FISTA; on a 3-D shift
    (creepage control: the rigid slip of Cattaneo's Q = mu P/2) and a spin-dominated shift, and in line
    contact on the box by TAO (pk with the inverse circulant, bqnls, blmvm). Rows: case, solver,
    applications (None: not converged within 2000 iterations)."""
    rows = []
    for name, spin in (("3-D shift, Cattaneo", 0.0), ("3-D shift with spin", 1.0)):
        grid, solver, bound = hertz_case(n, comm)
        x, y = grid.x[solver.r0 : solver.r1, None], grid.y[None, :]
        reference = solver.solve(bound(), force=[-0.5 * _force(comm, bound(), grid), 0.0])
        w = reference.shift[0]
        rigid = np.stack(np.broadcast_arrays(w - spin * w * y, spin * w * x)).astype(float)
        apply, precondition, g, b, norm = _scaled_problem(solver, bound(), rigid)
        for label, kwargs in (("DiskPCG", {}), ("DiskPCG, no preconditioner", {"plain": True}),
                              ("DiskPCG, kappa = 0", {"flat": True})):
            rows.append(dict(case=name, solver=label,
                             applications=_disk(apply, precondition, g, b, norm, comm, tol, **kwargs)))
        rows.append(dict(case=name, solver="FISTA (restarted)",
                         applications=_converged(*fista(apply, g, b, norm, tol, comm, 4000), 4000)))
    rows += _tao_line(comm, n, tol)
    return rows


def _converged(q, applications, limit):
    return None if applications >= limit else applications


def _disk(apply, precondition, g, b, norm, comm, tol, plain=False, flat=False):
    from petroll.errors import SolverError

    solver = DiskPCG(apply, (lambda r: r) if plain else precondition, g, comm, tol, 2000, None, norm)
    if flat:
        solver.direction = _flat_direction(solver)
    try:
        return solver.solve(np.zeros_like(b), b).applications
    except SolverError:
        return None


def _flat_direction(solver: DiskPCG):
    """DiskPCG.direction with the disk edge's curvature left out (kappa = 0)."""
    original = solver.direction

    def direction(st, d, z_prev, pgz_prev):
        d, z, pgz, kappa = original(st, d, z_prev, pgz_prev)
        return d, z, pgz, np.zeros_like(kappa)

    return direction


def _tao_line(comm: MPI.Comm, n: int, tol: float) -> list[dict]:
    """Line contact's QP (a shift at Cattaneo's Q = mu P/2 as creepage control) on the box -g <= q <= g:
    DiskPCG against TAO's types on petroll's shell matrix (the normal QP's machinery: pk with the inverse
    circulant, bqnls, blmvm), each to the natural residual ``tol`` (TAO's gatol tightened until met)."""
    grid, solver, bound = hertz_case(n, comm, line=True)
    reference = solver.solve(bound(), force=[-0.5 * _force(comm, bound(), grid)])
    rigid = np.full((1, *solver.local_shape), reference.shift[0])
    apply, precondition, g, b, norm = _scaled_problem(solver, bound(), rigid)
    rows = [dict(case="line contact shift", solver="DiskPCG (box)",
                 applications=_disk(apply, precondition, g, b, norm, comm, tol))]
    for kind in ("pk", "bqnls", "blmvm"):
        rows.append(dict(case="line contact shift", solver=f"TAO {kind}",
                         applications=_tao_box(solver, bound(), b, g, kind, tol)))
    return rows


def _tao_box(solver: TangentialSolver, bound, b, g, kind: str, tol: float):
    """Applications of TAO ``kind`` on the scaled box QP to the natural residual ``tol``."""
    from petsc4py import PETSc

    from petroll.solver.influence import Convolution
    from petroll.solver.petsc import CirculantInverse, shell_matrix
    from petroll.solver.kernels.cerruti import strip_tangential
    from petroll.solver.pk import PolonskyKeer

    box = solver.box(bound > 0)
    nx = box[1] - box[0]
    grid, comm = solver.grid, solver.comm
    table = strip_tangential(2 * nx, grid.dx, grid.datum, NU)[:, None]
    conv = Convolution(table, nx, 1, comm)
    inverse = Convolution(table, nx, 1, comm, inverse=True)
    mat = shell_matrix(conv, 1.0 / conv.diagonal, inverse)
    x, rhs = mat.createVecs()
    grad, lower, upper = x.duplicate(), x.duplicate(), x.duplicate()
    lower.setArray(-g)
    upper.setArray(g)
    rhs.setArray(b[0])
    applications = 0
    for gatol in (tol, tol / 10, tol / 100):
        tao = PETSc.TAO().create(comm)
        if kind == "pk":
            tao.setType("python")
            tao.setPythonContext(PolonskyKeer())
        else:
            tao.setType(kind)

        def objective_gradient(tao, v, out):
            mat.mult(v, out)
            out.axpy(1.0, rhs)
            return 0.5 * (v.dot(out) + v.dot(rhs))

        tao.setObjectiveGradient(objective_gradient, grad)
        tao.setHessian(lambda *args: None, mat, mat)
        tao.setVariableBounds((lower, upper))
        tao.setTolerances(gatol=gatol, grtol=0.0, gttol=0.0)
        tao.setMaximumIterations(2000)
        tao.setFromOptions()
        if kind == "pk":
            tao.getKSP().getPC().setType("python")
            tao.getKSP().getPC().setPythonContext(CirculantInverse())
        x.set(0.0)
        before = mat.getPythonContext().applications
        tao.solve(x)
        applications += mat.getPythonContext().applications - before
        mat.mult(x, grad)
        grad.axpy(1.0, rhs)
        q, s = x.getArray(readonly=True), grad.getArray(readonly=True)
        residual = comm.allreduce(float(np.abs(q - np.clip(q - s, -g, g)).max(initial=0.0)), op=MPI.MAX)
        converged = tao.getConvergedReason() > 0
        tao.destroy()
        if residual <= tol or not converged:
            break
    for v in (x, rhs, grad, lower, upper, mat):
        v.destroy()
    return applications if residual <= tol else None


def free_set_conditioning(n: int = 16) -> dict[str, float]:
    """Condition numbers behind the tangential QP's rate (docs/friction.md, Speed), on the final sets of the
    shift Q = mu P/2 at ``n`` cells per radius (one process; dense matrices of the window's operator H and
    preconditioner M, 2 N x 2 N for N window cells): M H on the window and on the contact's cells, and on
    DiskPCG's free directions with its sets fixed (the stick cells' two components, the slip cells' edge
    direction tau, the edge's curvature kappa = -t.s/g on them: A = Z^T (H + kappa) Z) preconditioned by
    its D M D (D = (1 + kappa)^-1/2 on slip cells), by M without D, by the exact inverses of the stick and
    the slip blocks (block Jacobi), and on the stick cells alone; with ``exact`` A's own inverse (1: the
    check of the construction)."""
    grid, solver, bound = hertz_case(n, MPI.COMM_SELF)
    final = {}
    solver.monitor = lambda iteration, state, objective: final.update(state=state)
    solution = Stepping(solver).shift(bound(), force=np.array([-0.5 * _force(MPI.COMM_SELF, bound(), grid), 0.0]))
    st, problem = final["state"], solver.scaled(bound(), solution.window)
    shape, size = (2, problem.nx, problem.ny), 2 * problem.nx * problem.ny
    cells = size // 2

    def dense(operator):
        columns = [operator(np.eye(1, size, k).reshape(shape)).ravel() for k in range(size)]
        matrix = np.array(columns).T
        return 0.5 * (matrix + matrix.T)

    def condition(a, p):
        lower = np.linalg.cholesky(0.5 * (p + p.T))
        values = np.linalg.eigvalsh(lower.T @ a @ lower)
        return float(values.max() / values.min())

    h, m = dense(problem.apply), dense(problem.precondition)
    g = problem.g.ravel() / problem.q_ref
    stick, slip = np.flatnonzero(st.stick), np.flatnonzero(st.slip)
    kappa = np.zeros(cells)
    kappa[slip] = -(st.s[:, slip] * st.t[:, slip]).sum(axis=0) / g[slip]
    z = np.zeros((size, 2 * len(stick) + len(slip)))
    z[stick, 2 * np.arange(len(stick))] = z[cells + stick, 2 * np.arange(len(stick)) + 1] = 1.0
    columns = 2 * len(stick) + np.arange(len(slip))
    z[slip, columns], z[cells + slip, columns] = st.tau[0, slip], st.tau[1, slip]
    a = z.T @ (h + np.diag(np.tile(kappa, 2))) @ z
    d = np.diag(np.tile(np.where(st.slip, 1 / np.sqrt(1 + kappa), 1.0), 2))
    contact = np.flatnonzero(np.tile(g > 0, 2))
    blocks = np.zeros_like(a)
    for part in (slice(0, 2 * len(stick)), slice(2 * len(stick), None)):
        blocks[part, part] = np.linalg.inv(a[part, part])
    lone = slice(0, 2 * len(stick))
    return {"window": condition(h, m), "contact": condition(h[np.ix_(contact, contact)], m[np.ix_(contact, contact)]),
            "free set, D M D": condition(a, z.T @ d @ m @ d @ z), "free set, M": condition(a, z.T @ m @ z),
            "free set, block Jacobi": condition(a, blocks),
            "stick cells alone": condition(z[:, lone].T @ h @ z[:, lone], z[:, lone].T @ m @ z[:, lone]),
            "exact": condition(a, np.linalg.inv(a)), "stick": len(stick), "slip": len(slip)}

"""pk as a TAO solver like any other: random SPD bound-constrained QPs (dense PETSc matrices) against a
dense primal-dual active-set solver written here; what it reports to TAO's monitors; its stop reasons."""

import numpy as np
import pytest
from petsc4py import PETSc

from petroll.solver import pk
from petroll.solver.pk import PolonskyKeer

N = 60


def random_qp(seed: int, bounds: str):
    """H = Q Q^T / n + I/2 (SPD), b, and bounds of the given kind: 'finite' (l < u, some l = u),
    'infinite' (none: -inf, +inf), 'mixed' (each variable's bounds drawn from -inf/finite/+inf), 'none'
    (no bounds set on the TAO at all)."""
    rng = np.random.default_rng(seed)
    q = rng.standard_normal((N, N))
    h = q @ q.T / N + 0.5 * np.eye(N)
    b = 2 * rng.standard_normal(N)
    lo, hi = np.full(N, -np.inf), np.full(N, np.inf)
    if bounds == "finite":
        lo = rng.uniform(-1.0, 0.0, N)
        hi = lo + rng.uniform(0.0, 1.5, N)
        hi[:3] = lo[:3]  # fixed variables
    elif bounds == "mixed":
        kind = rng.integers(0, 4, N)  # 0: free, 1: lower only, 2: upper only, 3: both
        lo = np.where((kind == 1) | (kind == 3), rng.uniform(-0.5, 0.5, N), -np.inf)
        hi = np.where((kind == 2) | (kind == 3), rng.uniform(-0.5, 0.5, N), np.inf)
        hi = np.where(kind == 3, np.maximum(hi, lo + 0.1), hi)
    return h, b, lo, hi


def active_set_oracle(h, b, lo, hi):
    """min 1/2 x.Hx + b.x on lo <= x <= hi by a primal-dual active-set (semismooth Newton) method: guess
    which variables sit at which bound from x - (Hx + b), solve the free ones exactly, repeat until the
    guess repeats. Dense, independent of pk; its KKT conditions are checked by the caller."""
    x = np.clip(np.zeros(len(b)), lo, hi)
    previous = None
    for _ in range(200):
        trial = x - (h @ x + b)
        at_lo, at_hi = trial <= lo, trial >= hi
        key = (at_lo.tobytes(), at_hi.tobytes())
        if key == previous:
            return x
        previous = key
        free = ~(at_lo | at_hi)
        x = np.where(at_lo, lo, np.where(at_hi, hi, 0.0))
        fixed = ~free
        x[free] = np.linalg.solve(h[np.ix_(free, free)], -b[free] - h[np.ix_(free, fixed)] @ x[fixed])
    raise AssertionError("the active-set oracle cycled")


def natural_residual(h, b, x, lo, hi):
    return np.abs(x - np.clip(x - (h @ x + b), lo, hi)).max()


@pytest.fixture
def taos():
    """TAOs made by a test, destroyed after it (one still alive when PETSc finalises crashes it)."""
    made = []
    yield made
    for tao in made:
        tao.destroy()


def dense_tao(comm, h, b, lo, hi, gatol=1e-13, max_it=10000, set_bounds=True, made=None, grtol=0.0, gttol=0.0,
              calls=None):
    """A pk TAO on the dense QP (rows split over comm) and its solution Vec; the TAO appended to made;
    ``calls`` (a list) gets one entry per objective-gradient evaluation."""
    mat = PETSc.Mat().createDense([(PETSc.DECIDE, N), (PETSc.DECIDE, N)], comm=comm)
    mat.setUp()
    r0, r1 = mat.getOwnershipRange()
    mat.setValues(np.arange(r0, r1, dtype=PETSc.IntType), np.arange(N, dtype=PETSc.IntType), h[r0:r1])
    mat.assemble()
    x, rhs = mat.createVecs()
    rhs.setArray(b[r0:r1])

    def objective_gradient(tao, p, grad):
        if calls is not None:
            calls.append(1)
        mat.mult(p, grad)
        grad.axpy(1.0, rhs)
        return 0.5 * (p.dot(grad) + p.dot(rhs))

    tao = PETSc.TAO().create(comm)
    tao.setOptionsPrefix("pktest_")
    tao.setType("python")
    tao.setPythonContext(PolonskyKeer())
    tao.setObjectiveGradient(objective_gradient, x.duplicate())
    tao.setHessian(lambda tao, p, H, P: None, mat, mat)
    if set_bounds:
        lower, upper = x.duplicate(), x.duplicate()
        lower.setArray(np.where(np.isfinite(lo), lo, PETSc.NINFINITY)[r0:r1])
        upper.setArray(np.where(np.isfinite(hi), hi, PETSc.INFINITY)[r0:r1])
        tao.setVariableBounds((lower, upper))
    tao.setTolerances(gatol=gatol, grtol=grtol, gttol=gttol)
    tao.setMaximumIterations(max_it)
    tao.setFromOptions()
    x.set(0.0)
    made.append(tao)
    return tao, x, (r0, r1)


@pytest.mark.parametrize("seed", [1, 2])
def test_pk_takes_uniform_bounds_from_its_context_where_tao_has_none(comm, taos, seed):
    """x >= 0 given as PolonskyKeer's ``bounds`` (0, inf), with no bound vectors on the TAO (the contact QP's
    way: 16 bytes per variable less): the active-set oracle's solution on those bounds, many of them
    active; a vector TAO holds wins over the context (its 'finite' bounds below)."""
    h, b, _, _ = random_qp(seed, "none")
    lo, hi = np.zeros(N), np.full(N, np.inf)
    reference = active_set_oracle(h, b, lo, hi)
    assert np.count_nonzero(reference == 0.0) >= 5
    tao, x, _ = dense_tao(comm, h, b, lo, hi, set_bounds=False, made=taos)
    tao.getPythonContext().bounds = (0.0, np.inf)
    tao.solve(x)
    assert tao.getConvergedReason() == PETSc.TAO.Reason.CONVERGED_GATOL
    ours = np.concatenate(comm.allgather(x.array_r.copy()))
    assert np.abs(ours - reference).max() <= 1e-10 * max(1.0, np.abs(reference).max())
    _, _, flo, fhi = random_qp(seed, "finite")
    tao, x, _ = dense_tao(comm, h, b, flo, fhi, made=taos)
    tao.getPythonContext().bounds = (0.0, np.inf)
    tao.solve(x)
    ours = np.concatenate(comm.allgather(x.array_r.copy()))
    finite = active_set_oracle(h, b, flo, fhi)
    assert np.abs(ours - finite).max() <= 1e-10 * max(1.0, np.abs(finite).max())


@pytest.fixture(params=["one", 7])
def block(request, monkeypatch):
    """pk's passes over a rank's values in one block, or in blocks of 7 (several, the last one shorter)."""
    if request.param != "one":
        monkeypatch.setattr(pk, "BLOCK", request.param)
    assert pk.BLOCK >= N or N % pk.BLOCK
    return pk.BLOCK


@pytest.mark.parametrize("bounds", ["finite", "infinite", "mixed", "none"])
@pytest.mark.parametrize("seed", [1, 2])
def test_pk_agrees_with_a_dense_active_set_solver(comm, taos, bounds, seed, block):
    h, b, lo, hi = random_qp(seed, bounds)
    reference = active_set_oracle(h, b, lo, hi)
    assert natural_residual(h, b, reference, lo, hi) <= 1e-12  # the oracle solved its KKT conditions
    if bounds != "infinite" and bounds != "none":
        assert np.count_nonzero((reference == lo) | (reference == hi)) >= 5  # bounds really are active
    tao, x, _ = dense_tao(comm, h, b, lo, hi, set_bounds=bounds != "none", made=taos)
    reported = []

    def monitor(tao):
        its, f, res = tao.getSolutionStatus()[:3]
        full = np.concatenate(comm.allgather(tao.getSolution().array_r.copy()))
        reported.append((its, f, res, 0.5 * full @ h @ full + b @ full, natural_residual(h, b, full, lo, hi)))

    tao.setMonitor(monitor)
    tao.solve(x)
    assert tao.getConvergedReason() == PETSc.TAO.Reason.CONVERGED_GATOL
    ours = np.concatenate(comm.allgather(x.array_r.copy()))
    assert np.abs(ours - reference).max() <= 1e-10 * max(1.0, np.abs(reference).max())
    # every monitor line: the true objective and projected-gradient (natural) residual at that iterate
    assert [r[0] for r in reported] == list(range(len(reported))) and len(reported) >= 3
    for its, f, res, true_f, true_res in reported:
        assert f == pytest.approx(true_f, rel=1e-10, abs=1e-12)
        assert res == pytest.approx(true_res, rel=1e-8, abs=1e-14)
    assert reported[-1][1] < reported[0][1]
    # it ends with TAO's gradient vector holding the exact gradient at the solution
    gradient = np.concatenate(comm.allgather(tao.getGradient()[0].array_r.copy()))
    assert np.abs(gradient - (h @ ours + b)).max() <= 1e-12 * np.abs(b).max()


def test_pk_stop_reasons_mean_what_they_say(comm, taos):
    h, b, lo, hi = random_qp(3, "mixed")
    tao, x, _ = dense_tao(comm, h, b, lo, hi, max_it=2, made=taos)
    tao.solve(x)
    assert tao.getConvergedReason() == PETSc.TAO.Reason.DIVERGED_MAXITS and tao.getIterationNumber() == 2

    tao, x, _ = dense_tao(comm, -np.eye(N), b, lo, hi, made=taos)  # negative definite: curvature d.Hd < 0
    tao.solve(x)
    assert tao.getConvergedReason() == PETSc.TAO.Reason.DIVERGED_USER
    assert "not positive definite" in tao.getPythonContext().breakdown


@pytest.mark.parametrize("which", ["grtol", "gttol"])
def test_pk_stops_on_tao_relative_tolerances_where_they_are_first_met(comm, taos, which):
    """gatol 0 and grtol (|r| <= grtol |f|) or gttol (|r| <= gttol |r_0|) set: pk stops with TAO's reason
    for it at the first iterate that meets it, judged here on the monitor's true f and natural residual
    (recomputed from the dense QP), not on what pk reports."""
    h, b, lo, hi = random_qp(7, "mixed")
    tao, x, _ = dense_tao(comm, h, b, lo, hi, gatol=0.0, made=taos, **{which: 1e-6})
    seen = []

    def monitor(tao):
        full = np.concatenate(comm.allgather(tao.getSolution().array_r.copy()))
        seen.append((0.5 * full @ h @ full + b @ full, natural_residual(h, b, full, lo, hi)))

    tao.setMonitor(monitor)
    tao.solve(x)
    met = [res <= 1e-6 * (abs(f) if which == "grtol" else seen[0][1]) for f, res in seen]
    reason = {"grtol": PETSc.TAO.Reason.CONVERGED_GRTOL, "gttol": PETSc.TAO.Reason.CONVERGED_GTTOL}[which]
    assert tao.getConvergedReason() == reason
    assert met[-1] and not any(met[:-1]) and len(seen) >= 5
    assert seen[-1][1] > 1e-12  # it stopped before the absolute tolerance of the other tests would have


def test_pk_counts_its_evaluations_in_tao_and_stops_at_its_limit(comm, taos, tmp_path):
    """TAO's own counter of function/gradient evaluations (as -tao_view prints it) equals the calls of the
    objective-gradient routine counted by the routine itself; -tao_max_funcs stops pk at that many."""
    h, b, lo, hi = random_qp(8, "finite")
    calls = []
    tao, x, _ = dense_tao(comm, h, b, lo, hi, made=taos, calls=calls)
    tao.solve(x)
    path = comm.bcast(str(tmp_path / "view.txt"))
    viewer = PETSc.Viewer().createASCII(path, comm=comm)
    tao.view(viewer)
    viewer.destroy()
    text = open(path).read() if comm.rank == 0 else ""
    counted = comm.bcast(int(text.split("total number of function/gradient evaluations=")[-1].split(",")[0])
                         if comm.rank == 0 else None)
    assert counted == len(calls) > 3
    limited = []
    tao, x, _ = dense_tao(comm, h, b, lo, hi, made=taos, calls=limited)
    tao.setMaximumFunctionEvaluations(3)
    tao.solve(x)
    assert tao.getConvergedReason() == PETSc.TAO.Reason.DIVERGED_MAXFCN and len(limited) == 3


def test_pk_view_shows_its_own_settings(comm, taos, tmp_path):
    h, b, lo, hi = random_qp(4, "finite")
    tao, x, _ = dense_tao(comm, h, b, lo, hi, made=taos)
    tao.solve(x)
    path = comm.bcast(str(tmp_path / "view.txt"))
    viewer = PETSc.Viewer().createASCII(path, comm=comm)
    tao.view(viewer)
    viewer.destroy()
    if comm.rank == 0:
        text = open(path).read()
        assert "Polonsky-Keer" in text and "preconditioner: none" in text and "restart:" in text
        assert "type: preonly" in text and "type: none" in text  # its KSP only applies its PC
        assert "gmres" not in text and "ilu" not in text and "bjacobi" not in text
        assert "converged" in text


def load_oracle(h, b, total):
    """min 1/2 x.Hx + b.x on x >= 0 with sum x = total: the active-set oracle on b - lam, lam found by
    bisection so that sum x(lam) = total (sum x grows with lam). Returns x and lam."""
    lo, hi = np.zeros(N), np.full(N, np.inf)
    a, c = -1e3, 1e3
    for _ in range(200):
        lam = 0.5 * (a + c)
        if active_set_oracle(h, b - lam, lo, hi).sum() < total:
            a = lam
        else:
            c = lam
    return active_set_oracle(h, b - lam, lo, hi), lam


@pytest.mark.parametrize("seed", [5, 6])
def test_pk_load_control_agrees_with_an_oracle(comm, taos, seed, block):
    """pk with ``total`` (sum x held): the solution and the multiplier against bisection on the multiplier
    around the dense active-set solver, and the force exactly held."""
    h, b, _, _ = random_qp(seed, "none")
    total = 3.0
    reference, lam = load_oracle(h, b, total)
    assert 5 <= np.count_nonzero(reference == 0) <= N - 5  # bounds active and inactive
    lo, hi = np.zeros(N), np.full(N, np.inf)
    tao, x, _ = dense_tao(comm, h, b, lo, hi, made=taos)
    tao.getPythonContext().total = total
    tao.solve(x)
    assert tao.getConvergedReason() == PETSc.TAO.Reason.CONVERGED_GATOL
    ours = np.concatenate(comm.allgather(x.array_r.copy()))
    assert np.abs(ours - reference).max() <= 1e-10 * np.abs(reference).max()
    assert tao.getPythonContext().multiplier == pytest.approx(lam, abs=1e-10 * abs(lam))
    assert ours.sum() == pytest.approx(total, rel=1e-13)

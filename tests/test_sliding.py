"""Steady sliding on a periodic grid solved directly ([time] mode = "steady" on a periodic grid,
petroll/solver/sliding.py): the integrator's transfer function, the closed forms of full contact of
sinusoidal surfaces on an SLS and a Prony series (docs/rough.md), a small rough contact against a dense
solution of the same complementarity problem, and a rough surface against the transient run to its
steady state."""

import math

import numpy as np
import pytest
from mpi4py import MPI

from petroll.errors import SceneError
from petroll.model import materials
from petroll.model.roughness import self_affine_heights
from petroll.model.scene import parse_scene
from petroll.solver.history import transfer
from petroll.solver.simulation import Simulation
from petroll.solver.steady import pulse_response

NU = 0.5
SLS = {"model": "sls", "E0": 10e6, "Einf": 2e6, "nu": NU, "tau_relax": 2e-3}
PRONY = {"model": "prony", "series": "maxwell", "Einf": 1e6, "moduli": [3e6, 10e6, 30e6],
         "times": [1e-1, 1e-3, 1e-5], "nu": NU}


def plane_strain_modulus(table: dict, omega: float) -> complex:
    """E*(omega) / (1 - nu^2) from the scene's own relaxation (Maxwell) form: an oracle independent of
    petroll's creep series and its integrators."""
    if table["model"] == "sls":
        moduli, times, einf = [table["E0"] - table["Einf"]], [table["tau_relax"]], table["Einf"]
    else:
        moduli, times, einf = table["moduli"], table["times"], table["Einf"]
    w = 1j * omega
    return (einf + sum(e * w * t / (1 + w * t) for e, t in zip(moduli, times))) / (1 - NU**2)


def gathered(comm, local):
    return np.concatenate(comm.allgather(local))


def save(comm, path, array):
    if comm.rank == 0:
        np.save(path, array)
    comm.Barrier()
    return str(path)


@pytest.mark.parametrize("integrator", ["relaxation", "exponential", "paper"])
def test_the_transfer_function_is_the_pulse_responses_sum_and_tends_to_the_complex_compliance(integrator):
    material = materials.sls(10e6, 2e6, NU, tau_creep=0.01)
    dt, z = 1e-4, np.exp(1j * np.array([0.3, 1.0, 2.5]))
    h = pulse_response(material, integrator, dt, 40000)
    direct = np.array([np.sum(h * zz ** -np.arange(len(h))) for zz in z])
    assert np.abs(transfer(material, integrator, dt, z) - direct).max() <= 1e-12 * np.abs(direct).max()
    omega = 50.0
    errors = [abs(transfer(material, integrator, step, np.exp(1j * omega * step))
                  - material.complex_compliance(omega)) for step in (1e-4, 5e-5)]
    order = math.log2(errors[0] / errors[1])
    assert order == pytest.approx(1.0 if integrator == "paper" else 2.0, abs=0.1)


@pytest.mark.parametrize("integrator", ["relaxation", "exponential", "paper"])
def test_every_integrator_loses_energy_at_every_phase_per_step(integrator):
    """The sliding friction's sign (petroll.solver.sliding, the "dissipation" kernel): a pressure
    oscillating by a phase theta per step in (-pi, pi], z = e^{-i theta}, gets a response H(z) with
    theta Im H >= 0 (the response lags: the material takes energy), for an SLS and a 3-term Prony series
    from steps far below to far above their times, where the integrator accepts the step; 0 for an elastic
    material."""
    from petroll.errors import SolverError

    theta = np.linspace(-np.pi, np.pi, 4001)
    elastic = materials.elastic(10e6, NU)
    assert np.all(transfer(elastic, integrator, 1e-3, np.exp(-1j * theta)).imag == 0)
    sls = materials.sls(10e6, 2e6, NU, tau_relax=2e-3)
    prony = materials.maxwell(PRONY["Einf"], NU, PRONY["moduli"], PRONY["times"])
    tried = 0
    for material in (sls, prony):
        for dt in np.geomspace(1e-7, 10.0, 9):
            try:
                h = transfer(material, integrator, dt, np.exp(-1j * theta))
            except SolverError:  # a step the integrator refuses ("exponential", "paper" beyond their bounds)
                continue
            tried += 1
            loss = theta * h.imag
            assert loss.min() >= -1e-12 * np.abs(h).max() * np.pi and loss.max() > 0
    assert tried >= 8


def sinusoid_scene(comm, dirpath, material, speed, two_d=False, n=128, amplitude=1e-6, wavelength=1e-3,
                   steps_per_cell=None):
    """D (1 - cos kx) (invariant along y on 4 cells) or D (1 - cos kx cos ky) (on a square cell), pressed
    to twice the mean pressure of full contact at the instantaneous modulus."""
    x = (np.arange(n) + 0.5) * wavelength / n
    if two_d:
        z = amplitude * (1 - np.outer(np.cos(2 * np.pi * x / wavelength), np.cos(2 * np.pi * x / wavelength)))
        ny, width = n, wavelength
    else:
        z = np.repeat((amplitude * (1 - np.cos(2 * np.pi * x / wavelength)))[:, None], 4, axis=1)
        ny, width = 4, 4 * wavelength / n
    k = 2 * np.pi / wavelength * (math.sqrt(2) if two_d else 1)
    full = k * amplitude / 2 * abs(plane_strain_modulus(material, 1e12))
    time = {"mode": "steady"} if steps_per_cell is None else {"mode": "steady", "steps_per_cell": steps_per_cell}
    raw = {"grid": {"nx": n, "ny": ny, "x": [0, wavelength], "y": [0, width], "periodic": True},
           "material": material, "motion": {"load": 2 * full * wavelength * width, "velocity": [speed, 0.0]},
           "body": {"shape": "heightmap", "file": save(comm, dirpath / f"z{n}{two_d}.npy", z),
                    "cell": wavelength / n},
           "time": time}
    return parse_scene(raw), x, 2 * full, k


@pytest.mark.slow
@pytest.mark.parametrize("two_d", [False, True])
@pytest.mark.parametrize("name", ["sls", "prony"])
def test_full_contact_of_a_sliding_sinusoid_is_the_closed_form(comm, shared_dir, name, two_d):
    """docs/rough.md: p = p_mean + (|k| D / 2) Re(E*(kx V) e^{i k.x}) (E* the plane-strain modulus; for
    D cos kx cos ky its two modes), mu_r = |k| kx D^2 E''(kx V) / (8 p_mean) (2-D; 1-D: k^2 D^2 E'' /
    (4 p_mean)), to 1e-3 at 128 cells per wavelength with the default integrator at its default step (one
    cell per step), at speeds V tau = 0.1, 1, 10 wavelengths."""
    material = SLS if name == "sls" else PRONY
    tau = material["tau_relax"] if name == "sls" else material["times"][1]
    for speed in (0.1e-3 / tau, 1e-3 / tau, 10e-3 / tau):
        scene, x, mean, k = sinusoid_scene(comm, shared_dir, material, speed, two_d)
        sim = Simulation(scene, comm)
        record = next(sim.steps())
        kx = 2 * np.pi / 1e-3
        modulus = plane_strain_modulus(material, kx * speed)
        factor = (8 if two_d else 4) * mean
        mu = (k * kx if two_d else k * k) * 1e-12 * modulus.imag / factor
        assert record.force == pytest.approx(mean * scene.grid.cell_area * scene.grid.nx * scene.grid.ny,
                                             rel=1e-9)
        assert record.mu_r == pytest.approx(mu, rel=1e-3)
        assert record.dissipation == pytest.approx(record.mu_r * record.force * speed, rel=1e-12)
        across = np.cos(kx * x) if two_d else np.ones(1)
        harmonic = (np.cos(kx * x)[:, None] * modulus.real + np.sin(kx * x)[:, None] * modulus.imag) * across
        exact = mean + k * 1e-6 / 2 * harmonic
        p = gathered(comm, sim.pressure)
        assert np.abs(p - exact).max() <= 1e-3 * np.abs(exact - mean).max()


def rough_raw(comm, dirpath, n=32, material=None, speed=0.5, **motion) -> dict:
    length = 1e-3
    z = self_affine_heights({"hurst": 0.8, "rms_slope": 0.3, "cutoff": 4 * length / n, "seed": 2}, (n, n),
                            (length / n, length / n))
    return {"grid": {"nx": n, "ny": n, "x": [0, length], "y": [0, length], "periodic": True},
            "material": material or SLS,
            "body": {"shape": "heightmap", "file": save(comm, dirpath / f"rough{n}.npy", z), "cell": length / n},
            "motion": {**(motion or {"load": 0.02 * 10e6 * 0.3 * length**2}), "velocity": [speed, 0.0]},
            "solver": {"tol": 1e-10}}


def dense_sliding_operator(scene) -> np.ndarray:
    """K of the steady sliding operator on a small grid, summed from its definition (module docstring of
    petroll/solver/sliding.py) with explicit Fourier sums: S_k = (2/|k|) H(e^{-i kx V dt}), H the
    integrator's transfer function, 0 at k = 0 and real where a mode is its own conjugate."""
    g = scene.grid
    speed = float(scene.velocity(0.0)[0])
    dt = g.cell / speed
    mx, my = np.arange(g.nx) - g.nx // 2, np.arange(g.ny) - g.ny // 2
    kx, ky = 2 * np.pi * mx / (g.x1 - g.x0), 2 * np.pi * my / (g.y1 - g.y0)
    k = np.hypot(kx[:, None], ky[None, :])
    h = transfer(scene.material, scene.solver.integrator, dt, np.exp(-1j * kx * speed * dt))[:, None]
    h = np.where((2 * mx[:, None] % g.nx == 0) & (2 * my[None, :] % g.ny == 0), h.real, h)
    symbol = np.divide(2.0, k, out=np.zeros(k.shape), where=k > 0) * h
    ix, iy = np.divmod(np.arange(g.nx * g.ny), g.ny)
    dx, dy = ix[:, None] - ix[None, :], iy[:, None] - iy[None, :]
    phase = np.exp(2j * np.pi * (mx[None, None, :, None] * dx[:, :, None, None] / g.nx
                                 + my[None, None, None, :] * dy[:, :, None, None] / g.ny))
    return ((phase * symbol).sum(axis=(2, 3)) / (g.nx * g.ny)).real


def dense_complementarity(matrix, heights, total, iterations=200):
    """p >= 0, g = K p + h - delta >= 0, p g = 0, sum p = total, by the primal-dual active set method with
    dense solves (the active set a cell's p - g > 0; stops when it repeats)."""
    n = len(heights)
    active = heights <= np.quantile(heights, 0.3)
    for _ in range(iterations):
        idx = np.flatnonzero(active)
        system = np.zeros((len(idx) + 1, len(idx) + 1))
        system[:-1, :-1] = matrix[np.ix_(idx, idx)]
        system[:-1, -1], system[-1, :-1] = -1.0, 1.0
        solution = np.linalg.solve(system, np.concatenate([-heights[idx], [total]]))
        p = np.zeros(n)
        p[idx] = solution[:-1]
        gap = matrix @ p + heights - solution[-1]
        new = p - gap * (p.max() / np.abs(heights).max()) > 0
        if np.array_equal(new, active):
            return p, solution[-1]
        active = new
    raise AssertionError("the dense active-set iteration did not settle")


@pytest.mark.parametrize("name", ["sls", "prony"])
def test_a_small_rough_contact_is_the_dense_complementarity_solution(comm, shared_dir, name):
    scene = parse_scene({**rough_raw(comm, shared_dir, n=12, material=SLS if name == "sls" else PRONY),
                         "time": {"mode": "steady"}})
    sim = Simulation(scene, comm)
    record = next(sim.steps())
    g = scene.grid
    heights = scene.body.height(*g.offsets(g.x[:, None], g.y[None, :], 0.0, 0.0)).ravel()
    p, delta = dense_complementarity(dense_sliding_operator(scene), heights, float(scene.load(0.0)) / g.cell_area)
    assert np.abs(gathered(comm, sim.pressure).ravel() - p).max() <= 1e-7 * p.max()
    assert record.delta == pytest.approx(delta, rel=1e-7)
    assert 0.05 < record.area / (g.nx * g.ny * g.cell_area) < 0.9  # a partial contact


def symbol(scene, speed: float, dt: float):
    """(kx, S) of a periodic 3-D grid's steady sliding along +X, independently of petroll's kernels: the
    modes of a real field (kx signed, fftfreq; ky >= 0, rfftfreq; the others their conjugates), S_k =
    (2/|k|) H(e^{-i kx V dt}), H the integrator's transfer function, real where a mode is its own
    conjugate, 0 at k = 0."""
    g = scene.grid
    kx = 2 * np.pi * np.fft.fftfreq(g.nx, g.dx)
    ky = 2 * np.pi * np.fft.rfftfreq(g.ny, g.dy)
    k = np.hypot(kx[:, None], ky[None, :])
    h = transfer(scene.material, scene.solver.integrator, dt, np.exp(-1j * kx * speed * dt))[:, None]
    own = (np.arange(g.nx) * 2 % g.nx == 0)[:, None] & (np.arange(len(ky)) * 2 % g.ny == 0)[None, :]
    return kx, np.divide(2.0, k, out=np.zeros(k.shape), where=k > 0) * np.where(own, h.real, h)


def dissipation_friction(p, kx, s) -> float:
    """The material's dissipated power under the whole grid's pressure p over F V: mean(p dw/dt) / (V
    mean(p)), w's modes S_k p_k oscillating at kx V (docs/rough.md), by numpy's FFTs."""
    rate = np.fft.irfft2(kx[:, None] * s.imag * np.fft.rfft2(p), s=p.shape)  # -dw/dt / V
    return float((p * rate).sum() / p.sum())


def spectral_slope(z, kx) -> np.ndarray:
    return np.fft.irfft2(1j * kx[:, None] * np.fft.rfft2(z), s=z.shape)


ELASTIC = {"model": "elastic", "E": 10e6, "nu": NU}


def test_elastic_sliding_has_no_friction_where_the_lateral_force_has_some(comm, shared_dir):
    """An elastic half-space dissipates nothing: the friction of a rough surface sliding on it (mu_r, from
    the dissipated power) is 0 to round-off at every speed, where the lateral force sum p dZ/dx / sum p
    of the same pressure is not (its discretisation error, the old mu_r: -2.2e-4 on this surface)."""
    from petroll.records import lateral_friction

    for speed in (1e-3, 1.0, 100.0):
        scene = parse_scene({**rough_raw(comm, shared_dir, n=64, material=ELASTIC, speed=speed),
                             "time": {"mode": "steady"}})
        sim = Simulation(scene, comm)
        record = next(sim.steps())
        assert abs(record.mu_r) < 1e-10 and abs(record.dissipation) < 1e-10 * record.force * speed
        assert abs(lateral_friction(record, sim.direction)) > 1e-5


@pytest.mark.slow
def test_viscoelastic_sliding_friction_is_the_dissipation_and_never_negative(comm, shared_dir):
    """A rough surface (64^2) sliding on an SLS at 12 speeds across its loss peak (V tau_relax from 1e-3 to
    10 times the cell's length): mu_r is the dissipated power of the saved pressure computed by numpy's
    FFTs from the integrator's transfer function (to 1e-10; on 2 ranks too), never negative, and the lateral
    force's coefficient (force_x / force) is the same quantity within the discretisation's difference."""
    from petroll.records import lateral_friction

    raw = rough_raw(comm, shared_dir, n=64)
    speeds = np.geomspace(1e-3, 10.0, 12)
    mus = []
    for speed in speeds:
        scene = parse_scene({**raw, "motion": {**raw["motion"], "velocity": [speed, 0.0]},
                             "time": {"mode": "steady"}})
        sim = Simulation(scene, comm)
        record = next(sim.steps())
        p = gathered(comm, sim.pressure)
        kx, s = symbol(scene, speed, scene.grid.cell / speed)
        assert record.mu_r == pytest.approx(dissipation_friction(p, kx, s), rel=1e-10)
        assert record.dissipation == pytest.approx(record.mu_r * record.force * speed, rel=1e-12)
        z = scene.body.height(*scene.grid.offsets(scene.grid.x[:, None], scene.grid.y[None, :], 0.0, 0.0))
        lateral = lateral_friction(record, sim.direction)
        assert lateral == pytest.approx((p * spectral_slope(z, kx)).sum() / p.sum(), rel=1e-10)
        assert abs(record.mu_r - lateral) <= 0.5 * max(record.mu_r, 1e-3)
        mus.append(record.mu_r)
    mus = np.array(mus)
    assert mus.min() > 0 and 0 < np.argmax(mus) < len(mus) - 1  # the loss peak lies inside the range


@pytest.mark.parallel
def test_the_sliding_friction_and_its_lateral_diagnostic_are_the_same_on_every_rank_count(comm, shared_dir):
    """A 64^2 rough surface sliding steadily on an SLS near its loss peak and far above it: mu_r (the
    dissipated power's), the dissipation and the lateral force's coefficient (petroll.records.
    lateral_friction, rough/mu_lateral's) on ``comm`` are those of the same solve on a single rank (the
    oracle) to 1e-10."""
    from petroll.records import lateral_friction

    raw = rough_raw(comm, shared_dir, n=64)
    for speed in (0.01, 10.0):
        scene = parse_scene({**raw, "motion": {**raw["motion"], "velocity": [speed, 0.0]},
                             "time": {"mode": "steady"}})
        ours, alone = Simulation(scene, comm), Simulation(scene, MPI.COMM_SELF)
        mine, oracle = next(ours.steps()), next(alone.steps())
        for name in ("mu_r", "dissipation", "force"):
            assert getattr(mine, name) == pytest.approx(getattr(oracle, name), rel=1e-10), name
        assert ours.rough_outputs().mu_lateral == pytest.approx(lateral_friction(oracle, alone.direction),
                                                                rel=1e-10)


def test_the_dissipation_friction_of_a_sliding_sinusoid_in_full_contact_is_the_closed_form(comm, shared_dir):
    """D (1 - cos kx) in full contact on an SLS at V tau = one wavelength (docs/rough.md): mu_r (the
    dissipated power's) = k^2 D^2 E''(k V) / (4 p_mean), to 1e-3 at 128 cells per wavelength and one step
    per cell (the integrator's phase error (k V dt)^2 / 12 = 2.0e-4), to 1e-6 at 100 steps per cell; in
    full contact the lateral force's is the same number (w = delta - Z on every cell)."""
    from petroll.records import lateral_friction

    speed = 1e-3 / SLS["tau_relax"]
    k = 2 * np.pi / 1e-3
    for steps, tol in ((None, 1e-3), (100, 1e-6)):
        scene, _, mean, _ = sinusoid_scene(comm, shared_dir, SLS, speed, steps_per_cell=steps)
        sim = Simulation(scene, comm)
        record = next(sim.steps())
        exact = k * k * 1e-12 * plane_strain_modulus(SLS, k * speed).imag / (4 * mean)
        assert record.mu_r == pytest.approx(exact, rel=tol)
        assert lateral_friction(record, sim.direction) == pytest.approx(record.mu_r, rel=1e-8)


@pytest.mark.slow
@pytest.mark.parametrize("control", ["load", "penetration"])
def test_the_direct_steady_state_is_the_transient_run_to_steady_state(comm, shared_dir, control):
    """A rough surface sliding on an SLS at V tau_relax = half the cell's length, one cell per step: the
    transient run over 30 periods of the cell (0.12 s: 12 creep times) and the direct solve agree to 1e-5
    in force and in the lateral force's coefficient (the transient's mu_r; the same steady state: the
    direct solve's memory is the integrator's); the direct solve's mu_r, the dissipated power's, within
    their discretisation's difference."""
    from petroll.records import lateral_friction

    raw = rough_raw(comm, shared_dir, speed=0.25)
    if control == "penetration":
        direct = Simulation(parse_scene({**raw, "time": {"mode": "steady"}}), comm)
        delta = next(direct.steps()).delta
        raw["motion"] = {"penetration": delta, "velocity": raw["motion"]["velocity"]}
    direct = Simulation(parse_scene({**raw, "time": {"mode": "steady"}}), comm)
    steady = next(direct.steps())
    transient = Simulation(parse_scene({**raw, "time": {"steps_per_cell": 1, "distance": 30e-3}}), comm)
    last = list(transient.steps())[-1]
    assert last.force == pytest.approx(steady.force, rel=1e-5)
    assert last.mu_r == pytest.approx(lateral_friction(steady, direct.direction), rel=1e-5)
    assert last.mu_r == pytest.approx(steady.mu_r, rel=0.15)  # 4 cells per cut-off: 11 % apart
    assert 0.0 < steady.mu_r and 0.02 < steady.area / 1e-6 < 0.5


def test_steady_sliding_scenes_are_checked(comm, shared_dir):
    raw = rough_raw(comm, shared_dir, n=8)
    with pytest.raises(SceneError, match=r"\[motion\] velocity .* non-zero \[vx, vy\]"):
        parse_scene({**raw, "motion": {"load": 1.0}, "time": {"mode": "steady"}})
    one_axis = {**raw, "grid": {**raw["grid"], "periodic": ["x"]}, "time": {"mode": "steady"},
                "motion": {"load": 1.0, "velocity": [0.0, 1.0]}}
    with pytest.raises(SceneError, match=r"periodic along x only it must be a constant non-zero \[vx, 0\]"):
        parse_scene(one_axis)


@pytest.mark.slow
def test_a_sliding_run_writes_the_contact_fraction_mean_gap_and_pressure_spectrum(comm, shared_dir):
    """results.h5's group rough: the pressure's spectrum as petroll.model.roughness.radial_psd computes it
    from the whole saved field (serially), the contact's fraction of the cell and the mean of the saved
    gap field, the lateral force's coefficient; the dissipation is mu_r times the force and the speed."""
    import petroll
    from petroll.model.roughness import radial_psd
    from petroll.solver.rough import spectrum_edges

    raw = {**rough_raw(comm, shared_dir), "time": {"mode": "steady", "steps_per_cell": 8},
           "output": {"fields": ["pressure", "displacement", "gap"]}}
    scene = parse_scene(raw)
    results = petroll.run(scene, comm, out=shared_dir / "out")
    rough, p = results.rough, results.pressure[-1]
    g = scene.grid
    q, spectrum, modes = radial_psd(p, (g.dx, g.dy), spectrum_edges(g))
    assert np.array_equal(rough["modes"][-1], modes) and modes.sum() == (g.nx * g.ny - 4) // 2  # complex pairs
    finite = modes > 0
    assert np.abs(rough["spectrum"][-1][finite] - spectrum[finite]).max() <= 1e-12 * spectrum[finite].max()
    assert np.allclose(rough["q"][-1][finite], q[finite], rtol=1e-14, atol=0)
    assert rough["area_fraction"][-1] == np.count_nonzero(p > 0) / p.size
    assert rough["mean_gap"][-1] == pytest.approx(results.field("gap")[-1].mean(), rel=1e-10)
    series = results.series
    assert series["dissipation"][-1] == pytest.approx(series["mu_r"][-1] * series["force"][-1] * 0.5, rel=1e-12)
    assert rough["mu_lateral"][-1] == pytest.approx(series["force_x"][-1] / series["force"][-1], rel=1e-12)
    if comm.rank == 0:  # petroll plot draws the contact islands and the spectrum
        from petroll.plot import plot_results

        islands = [path for path in plot_results(shared_dir / "out") if path.name == "islands.png"]
        assert islands and islands[0].read_bytes()[:4] == b"\x89PNG"


@pytest.mark.slow
def test_the_shipped_rough_rubber_scene_slides_to_its_steady_state(comm, shared_dir):
    """runs/rough-rubber.toml (a periodic cell of a road-like self-affine surface, the 39-term tread rubber
    of runs/sphere-dma.toml, 3.2 N, steady sliding at 10 mm/s, 8 steps per cell, petroll's defaults) on
    64^2 cells instead of its 256^2, the surface's short-wavelength cutoff at 4 cells as shipped (the same
    code at a sixteenth of the cells; docs/rough.md runs the scene as shipped): the
    load is carried; the saved pressure closes the gap of an independent operator (numpy FFTs of
    S_k = (2/|k|) H(e^{-i kx V dt}), H the integrator's transfer function; its mean from the load) on its
    contact and leaves it open elsewhere; mu_r is the saved pressure's dissipated power under that
    operator over F V, the lateral friction its resisting force on the surface's slope differentiated
    spectrally; the surface is the one its keys draw."""
    import petroll
    from petroll.model.scene import load_scene, shipped_scene

    scene = load_scene(shipped_scene("rough-rubber.toml"))
    scene = scene.replace({"output.fields": ["pressure"], "grid.nx": 64, "grid.ny": 64,
                           "body.cutoff": 4 * scene.grid.dx * 256 / 64})
    results = petroll.run(scene, comm, out=shared_dir / "rough-rubber")
    if comm.rank:
        return
    g, p = scene.grid, results.pressure[-1]
    series = results.series
    assert series["force"][-1] == pytest.approx(3.2, rel=1e-6)
    z = scene.body.height(*g.offsets(g.x[:, None], g.y[None, :], 0.0, 0.0))
    keys = {key: scene.raw["body"][key] for key in ("hurst", "rolloff", "cutoff", "rms_slope", "seed")}
    drawn = self_affine_heights(keys, (g.nx, g.ny), (g.dx, g.dy))
    assert np.ptp(z - drawn) <= 1e-12 * np.ptp(drawn)  # the keys' surface, up to a constant
    speed = float(scene.velocity(0.0)[0])
    dt = g.cell / (scene.time.steps_per_cell * speed)
    kx, s = symbol(scene, speed, dt)
    w = np.fft.irfft2(s * np.fft.rfft2(p), s=p.shape)
    contact = p > 0
    delta = float(np.mean((z + w)[contact]))
    gap = z + w - delta
    scale = np.ptp(z)
    assert np.abs(gap[contact]).max() <= 1e-8 * scale
    assert gap[~contact].min() >= -1e-8 * scale and 0.2 < contact.mean() < 0.6  # a partial contact
    assert series["mu_r"][-1] == pytest.approx(dissipation_friction(p, kx, s), rel=1e-10)
    assert results.rough["mu_lateral"][-1] == pytest.approx((p * spectral_slope(z, kx)).sum() / p.sum(), rel=1e-6)
    assert series["mu_r"][-1] > 0.01


NUMPY_ONLY = """
import inspect, json, sys
import numpy as np
from mpi4py import MPI
from scipy.sparse.linalg import LinearOperator, gmres
from petroll.model.scene import parse_scene
from petroll.solver.influence import Convolution
from petroll.solver.kernels import grid_kernel
from petroll.solver.history import Transfer
from petroll.solver.sliding import ContactSystem, SlidingKernel
from petroll.solver.steady import steady_step

scene = parse_scene(json.loads(sys.argv[1]))
g, comm = scene.grid, MPI.COMM_SELF
velocity, dt = steady_step(scene)
transfer = Transfer(scene.material, scene.solver.integrator, dt)
made = {form: SlidingKernel(grid_kernel(g), transfer, velocity, form) for form in ("operator", "modulus")}
operator = Convolution(made["operator"], g.nx, g.ny, comm)
system = ContactSystem(operator, Convolution(made["modulus"], g.nx, g.ny, comm, inverse=True), (g.nx, g.ny),
                       comm, border=True)
contact = np.asarray(json.loads(sys.argv[2]), dtype=bool).reshape(g.nx, g.ny)
local, total = system.set_contact(contact)
x = np.random.default_rng(3).standard_normal(local)
b = np.random.default_rng(4).standard_normal(local)
matrix = LinearOperator((local, local), matvec=system.mult)
preconditioner = LinearOperator((local, local), matvec=system.apply)
tolerance = {"rtol" if "rtol" in inspect.signature(gmres).parameters else "tol": 1e-13}  # scipy >= 1.12: rtol
solution, info = gmres(matrix, b, M=preconditioner, atol=0.0, restart=60, maxiter=200, **tolerance)
print(json.dumps({"product": system.mult(x).tolist(), "solution": solution.tolist(), "info": info,
                  "c": system.c, "weight": system.weight, "petsc": "petsc4py.PETSc" in sys.modules}))
"""


@pytest.mark.serial
def test_the_sliding_contact_equations_are_numpy_and_solve_without_petsc(tmp_path):
    """The steady sliding contact's bordered equations (ContactSystem: K_CC p_C - delta = b, the force's
    row) and their preconditioner are plain numpy: a process that never imports PETSc applies them, and
    scipy's GMRES solves them, against the dense operator summed from its Fourier definition."""
    import json
    import subprocess
    import sys

    from mpi4py import MPI

    raw = {**rough_raw(MPI.COMM_SELF, tmp_path, n=8), "time": {"mode": "steady"}}
    scene = parse_scene(raw)
    g = scene.grid
    contact = np.random.default_rng(5).random((g.nx, g.ny)) < 0.4
    done = subprocess.run([sys.executable, "-c", NUMPY_ONLY, json.dumps(raw), json.dumps(contact.ravel().tolist())],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    out = json.loads(done.stdout)
    assert out["petsc"] is False and out["info"] == 0
    cells = np.flatnonzero(contact.ravel())
    dense = dense_sliding_operator(scene)[np.ix_(cells, cells)]
    n, c = len(cells), out["c"]
    bordered = np.zeros((n + 1, n + 1))  # unknowns p_C and delta / c; rows the gap on C and the force
    bordered[:n, :n], bordered[:n, n], bordered[n, :n] = dense, -c, out["weight"]
    x = np.random.default_rng(3).standard_normal(n + 1)
    b = np.random.default_rng(4).standard_normal(n + 1)
    assert np.abs(np.array(out["product"]) - bordered @ x).max() <= 1e-12 * np.abs(bordered @ x).max()
    exact = np.linalg.solve(bordered, b)
    assert np.abs(np.array(out["solution"]) - exact).max() <= 1e-9 * np.abs(exact).max()


def test_the_pressure_spectrum_binned_in_blocks_of_rows_is_the_whole_fields(comm, monkeypatch):
    """petroll.solver.rough.radial_spectrum bins its half spectrum a few rows at a time (3 here): the
    same bins as petroll.model.roughness.radial_psd of the whole field (serially, a second algorithm)."""
    from petroll.model.roughness import radial_psd
    from petroll.model.grid import Grid
    from petroll.solver.influence import Convolution
    from petroll.solver.kernels.periodic import HalfSpace
    from petroll.solver.partition import RowPartition
    from petroll.solver.rough import radial_spectrum, spectrum_edges

    monkeypatch.setattr("petroll.solver.rough.SPECTRUM_BLOCK", 3 * 9)
    nx, ny = 20, 16
    g = Grid(nx=nx, ny=ny, x0=0.0, x1=1.9e-3, y0=0.0, y1=1.5e-3, periodic=(True, True))
    field = np.random.default_rng(5).random((nx, ny))
    conv = Convolution(HalfSpace(g.dx, g.dy, nx, ny), nx, ny, comm)
    r0, r1 = RowPartition(nx, comm.size).range(comm.rank)
    q, spectrum, modes = radial_spectrum(conv, field[r0:r1], g, spectrum_edges(g))
    q_ref, spectrum_ref, modes_ref = radial_psd(field, (g.dx, g.dy), spectrum_edges(g))
    assert np.array_equal(modes, modes_ref) and modes.sum() == (nx * ny - 4) // 2
    finite = modes > 0
    assert np.abs(spectrum[finite] - spectrum_ref[finite]).max() <= 1e-12 * spectrum_ref[finite].max()
    assert np.allclose(q[finite], q_ref[finite], rtol=1e-14, atol=0)

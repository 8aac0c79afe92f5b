"""The stability suite: sweep small scenes over the axes where a method like petroll's breaks, and check
every run's physics, not only that it finished (modules: scenes, cases, checks, runs).

    petroll stability [--fast] [--out DIR]      (writes DIR/stability.csv and DIR/stability.md)

Axes: the time step (1e-4 T ... 1e3 T, fixed and varying), the stiffness ratio E0/Einf (1 ... 1e4) and
Prony series spread over 8 decades, the speed V tau / a (1e-3 ... 1e3) and a speed reversing through zero,
penetrations shrinking to zero / lost and regained, loads going to zero, coarse, fine and elongated grids
and a body reaching the grid edge, large penetrations, extreme magnitudes (moduli 1e-3 ... 1e12 Pa,
radii 1e-6 ... 10 m) that must scale as the analytic scalings say, and refinement in dt and dx.

Every step of every run is checked independently of the solver's own convergence test:

- ``finite``: no NaN/inf in the per-step series;
- ``contact``: the contact conditions on the *whole* grid (not only the solver's window), recomputed from
  the solved pressure: max |min(p_hat, gap_hat)| in the solver's own scaling (p_hat = p J_eff A_00 / w_ref,
  gap_hat = gap / w_ref, w_ref the largest rigid interference) <= 10 tol, and pressure >= 0 everywhere;
- ``dissipation``: the energy dissipated in the material, the work of the pressure on the surface
  (trapezoidal in time) minus the energy stored in the material's internal state, never decreases (to
  1e-6 of the work done); Prony materials;
- ``bounds`` (displacement control, Prony): the force never exceeds the same-grid elastic force with J0 at
  the same body position and penetration; where the penetration never decreases and the motion never
  reverses it is also at least the one with Jinf (Lee-Radok; with V . F_res >= 0 there too);
- ``smooth``: between two steps the force changes by at most what the elastic response changes plus the
  relaxation possible in that time, 2 (F_0 - F_inf)(1 - exp(-dt / theta_min)), the resisting force
  likewise (times the largest slope of the profile in contact); no zig-zag (more than two alternating
  increments larger than 1e-3 of the scale); the scene's own jumps (t = 0) are exempt;
- refused cases: a PetrollError whose one-line message contains the expected words.

Each run is one row of the map; the refinement and scaling studies add rows with measured errors.
"""

from petroll.studies.stability.cases import Case, cases
from petroll.studies.stability.checks import Row
from petroll.studies.stability.runs import command, refinement, run_case, scaling, sweep, write_map

__all__ = ["Case", "Row", "cases", "command", "refinement", "run_case", "scaling", "sweep", "write_map"]

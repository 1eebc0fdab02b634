"""A specimen let go from flat until it is still: the fabric tests' one way of running the solver."""
from __future__ import annotations

from vfit_engine.sim.solver_pd import SolverPD
from vfit_engine.sim.solver_settings import PDSettings
from vfit_engine.sim.solver_verlet import SolverVerlet

#: Simulated time between stillness checks, s.
CHUNK = 0.02
#: The projective solver's settings in the fabric tests: its quasi-Newton iterations (a still specimen is then at
#: its equilibrium, not where the plain iterations stop: the cantilever -80 % at 1/120 s) and the bend springs'
#: compression share on the edges (as bend springs they stiffen the bending: silk's cantilever +41 % at 10 mm).
PD_SETTINGS = dict(iterations=5, history=5, edge_compression=True)


def specimen_solver(model, kind, settings):
    """The solver of a fabric test: ``kind`` "verlet" (:class:`SolverVerlet` with ``settings``, a
    :class:`VerletSettings`) or "pd" (:class:`SolverPD` with the same constraint bands and air damping and
    :data:`PD_SETTINGS`)."""
    if kind == "verlet":
        return SolverVerlet(model, settings)
    if kind == "pd":
        keep = ("gravity", "air_damping", "slack", "compression", "bend_limit", "shear_limit_deg", "shear_restore")
        return SolverPD(model, PDSettings(**{f: getattr(settings, f) for f in keep}, **PD_SETTINGS))
    raise ValueError(f"solver must be 'verlet' or 'pd', got {kind!r}")


def fall_still(solver, max_dt, max_time, still, calm, after=0.0, dt=None):
    """Run ``solver``'s model from rest at its rest shape until every vertex has been slower than ``still``
    (m/s) for ``calm`` checks in a row (one every :data:`CHUNK` s, none before ``after`` s), or ``max_time`` s.

    The step is ``dt`` if given, else the largest at which every hinge is explicit
    (:meth:`SolverVerlet.max_stable_dt`), at most ``max_dt``: the bending is the material's explicit force.

    Returns
    -------
    state : State
    dt : float, s
    sim_time : float, s
    settled : bool
    """
    dt = min(solver.max_stable_dt(), max_dt) if dt is None else float(dt)
    state = solver.init_state(dt)
    chunk = max(1, int(round(CHUNK / dt)))
    quiet, t = 0, 0.0
    while t < max_time and quiet < calm:
        solver.step_frame(state, chunk * dt, chunk)
        t += chunk * dt
        quiet = quiet + 1 if t > after and solver.max_speed(state) < still else 0
    return state, dt, t, quiet >= calm

"""What changes each step of a cloth simulation (Newton-style ``State``)."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


def _writable_c(a, shape, name):
    a = np.array(a, dtype=np.float64, copy=True, order="C")
    if a.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {a.shape}")
    return a


@dataclass(eq=False)
class State:
    """Positions of a Verlet cloth now and one step ago, plus pin targets.

    Build it with :meth:`vfit_engine.sim.solver_verlet.SolverVerlet.init_state`,
    which starts ``pos_prev`` consistently from an initial velocity.

    Attributes
    ----------
    pos : (n, 3) float64, m
        Positions now (C-contiguous; kernels write it in place).
    pos_prev : (n, 3) float64, m
        Positions one step of ``dt`` ago.
    dt : float, s
        The step ``pos_prev`` belongs to; velocity is ``(pos - pos_prev) / dt``.
    time : float, s
        Simulated time.
    step_count : int
        Substeps taken.
    pin_target : (p, 3) float64, m, or None
        Where the pinned particles (``model.pin_indices`` order) must be at the
        end of the next :meth:`~SolverVerlet.step` or frame; the solver moves
        them there linearly over the substeps. None: pins stay put.
    """

    pos: np.ndarray
    pos_prev: np.ndarray
    dt: float
    time: float = 0.0
    step_count: int = 0
    pin_target: np.ndarray | None = field(default=None)

    def __post_init__(self):
        self.pos = _writable_c(self.pos, np.shape(self.pos), "pos")
        if self.pos.ndim != 2 or self.pos.shape[1] != 3:
            raise ValueError(f"pos must have shape (n, 3), got {self.pos.shape}")
        self.pos_prev = _writable_c(self.pos_prev, self.pos.shape, "pos_prev")
        self.dt = float(self.dt)
        if not self.dt > 0:
            raise ValueError("dt must be > 0")
        if self.pin_target is not None:
            self.set_pin_target(self.pin_target)

    @property
    def particle_count(self):
        return int(self.pos.shape[0])

    def velocity(self):
        """(n, 3) float64, m/s: the backward difference ``(pos - pos_prev) / dt``."""
        return (self.pos - self.pos_prev) / self.dt

    def change_step(self, dt):
        """Take steps of ``dt`` (s) from now on, keeping the velocity: ``pos_prev`` becomes one *new* step back."""
        if dt != self.dt:
            self.pos_prev[:] = self.pos - (self.pos - self.pos_prev) * (dt / self.dt)
            self.dt = dt

    def set_pin_target(self, target):
        """Set where pinned particles go next, (p, 3) m; None keeps them still."""
        self.pin_target = None if target is None else np.array(target, dtype=np.float64, order="C").reshape(-1, 3)

    def copy(self):
        """A deep copy."""
        return State(self.pos.copy(), self.pos_prev.copy(), self.dt, self.time, self.step_count,
                     None if self.pin_target is None else self.pin_target.copy())

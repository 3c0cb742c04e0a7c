"""Dynamics of the reduced model (docs/dynamics.md): the consistent mass matrix (:mod:`.mass`), damping
(:mod:`.damping`), modal analysis about an equilibrium (:mod:`.modes`) and time integration (generalized-α,
:mod:`.integrator`; the equations of motion and energy bookkeeping in :mod:`.transient`)."""

from .damping import UndampedWarning
from .mass import consistent_mass, tip_mass_matrix
from .modes import ModalResult, modes
from .transient import Simulation, rayleigh_about, simulate

__all__ = ["consistent_mass", "tip_mass_matrix", "ModalResult", "modes", "Simulation", "simulate", "rayleigh_about",
           "UndampedWarning"]

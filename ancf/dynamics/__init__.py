"""Dynamics of the reduced model (docs/dynamics.md): the consistent mass matrix (:mod:`.mass`) and modal
analysis about an equilibrium (:mod:`.modes`).  Time integration is not here yet."""

from .mass import consistent_mass, tip_mass_matrix
from .modes import ModalResult, modes

__all__ = ["consistent_mass", "tip_mass_matrix", "ModalResult", "modes"]

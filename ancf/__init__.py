"""Reduced ANCF kinetostatic model of a tendon-pneumatic bellows actuator.

Where the paper's equations live:

================================  ====================================================
paper                             module
================================  ====================================================
Sec. II-B stiffness k(λ)          :mod:`ancf.stiffness`
Sec. II-C kinematics, Hermite S   :mod:`ancf.kinematics`
eq. (1) Q_t axial                 :mod:`ancf.forces.axial`
eq. (1) Q_b bending               :mod:`ancf.forces.bending`
eq. (1) Q_g gravity               :mod:`ancf.forces.gravity`
eq. (1) Q_c tendons, eq. (5)      :mod:`ancf.forces.tendon`
eq. (1) Q_p pressure              :mod:`ancf.forces.pressure`
eq. (1) Q_f tip load, eq. (2b)    :mod:`ancf.forces.tip_load`, :mod:`ancf.kinematics`
assembly of eq. (1)               :mod:`ancf.assembly`
FK, IK (2), locked FK (3)–(6)     :mod:`ancf.model`, :mod:`ancf.solvers`
================================  ====================================================
"""

from .errors import (BellowsError, ConfigError, ConvergenceError, InfeasibleTargetError, InputError)
from .stiffness import StiffnessLaw
from .params import ActuatorParams, Tendon
from . import presets
from .model import Model, Equilibrium

__all__ = ["ActuatorParams", "Tendon", "StiffnessLaw", "Model", "Equilibrium", "presets", "BellowsError",
           "ConfigError", "ConvergenceError", "InfeasibleTargetError", "InputError"]

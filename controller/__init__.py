"""Quasi-static tip-position controllers of the bellows actuator (docs/design.md §4).

================================  ==========================================================
paper                             module
================================  ==========================================================
Sec. III-E, Algorithm 1 (LACC)    :mod:`controller.lacc`
Sec. IV-B, VF-CC baseline [25]    :mod:`controller.vfcc`
simulated rig (locked FK + load)  :mod:`controller.plant`
loops (Table I, Sec. V-E timing)  :mod:`controller.loop`
errors                            :mod:`controller.errors`
================================  ==========================================================

All quantities SI (m, N, Pa, s).  Typical use::

    from ancf import Model, presets
    from controller import LACC, SimulatedPlant, run_iterations
    m = Model(presets.paper())
    plant = SimulatedPlant(m, 60e3, load=(0, 0, -0.49))        # 50 g the controller does not know
    res = run_iterations(LACC(m, 60e3), plant, target, iterations=10)
"""

from .errors import ControllerError, NotConvergedError
from .base import Controller, StepReport
from .lacc import LACC, COMPLIANCE_METHODS
from .vfcc import VFCC
from .plant import Plant, PlantOptions, SimulatedPlant
from .loop import EpisodeResult, TimedResult, run_iterations, run_timed

__all__ = ["ControllerError", "NotConvergedError", "Controller", "StepReport", "LACC", "COMPLIANCE_METHODS",
           "VFCC", "Plant", "PlantOptions", "SimulatedPlant", "EpisodeResult", "TimedResult", "run_iterations",
           "run_timed"]

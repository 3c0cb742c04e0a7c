"""Quasi-static tip-position controllers of the bellows actuator (docs/design.md §4).

================================  ==========================================================
paper                             module
================================  ==========================================================
Sec. III-E, Algorithm 1 (LACC)    :mod:`controller.lacc`
LACC with tendon friction         :mod:`controller.friction_aware` (docs/friction.md)
dynamic LACC (1 kHz, observer)    :mod:`controller.dynamic_lacc`, :mod:`controller.observer`,
                                  :mod:`controller.periodic` (a periodic load's frequency)
Sec. IV-B, VF-CC baseline [25]    :mod:`controller.vfcc`
plant protocol                    :mod:`controller.plant` (the simulated rig: :mod:`hardware.simulated`)
loops (Table I, Sec. V-E timing)  :mod:`controller.loop`
runs on a rig, with a run log     :mod:`controller.run`
Sec. V-B open-loop IK tracking     :mod:`controller.feedforward`
errors                            :mod:`controller.errors`
================================  ==========================================================

All quantities SI (m, N, Pa, s).  Typical use::

    from ancf import Model, presets
    from hardware import SimulatedRig
    from controller import LACC, RunOptions, run_on_rig
    m = Model(presets.paper())
    rig = SimulatedRig(m, load=(0, 0, -0.49), seed=0)          # 50 g the controller does not know
    res = run_on_rig(LACC(m, 60e3), rig, target, RunOptions(log="run.h5", max_iterations=20))
"""

from .errors import ControllerError, NotConvergedError
from .base import Controller, StepReport
from .lacc import LACC, COMPLIANCE_METHODS
from .friction_aware import FrictionAwareLACC
from .vfcc import VFCC
from .plant import Plant
from .loop import EpisodeResult, TimedResult, run_iterations, run_periodic, run_timed
from .run import RunOptions, RunResult, run_on_rig
from .feedforward import OpenLoopResult, run_open_loop
from .shaping import zv_shaper
from .observer import LoadObserver, ModalModel, modal_model
from .dynamic_lacc import DynamicLACC
from .periodic import PeriodEstimator

__all__ = ["ControllerError", "NotConvergedError", "Controller", "StepReport", "LACC", "COMPLIANCE_METHODS",
           "FrictionAwareLACC",
           "VFCC", "Plant", "PlantOptions", "SimulatedPlant", "EpisodeResult", "TimedResult", "run_iterations",
           "run_timed", "run_periodic", "DynamicLACC", "PeriodEstimator", "LoadObserver", "ModalModel", "modal_model", "RunOptions", "RunResult", "run_on_rig", "OpenLoopResult", "run_open_loop", "zv_shaper"]


def __getattr__(name):
    """``SimulatedPlant`` / ``PlantOptions``: the one simulated rig, :mod:`hardware.simulated` (imported on
    first use, so that importing ``controller`` never imports ``hardware``)."""
    if name in ("SimulatedPlant", "PlantOptions"):
        from . import plant
        return getattr(plant, name)
    raise AttributeError(f"module 'controller' has no attribute {name!r}")

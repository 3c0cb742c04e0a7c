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
multi-segment chain (statics)     :mod:`ancf.chain`, :mod:`ancf.chain_model` (docs/multisegment.md)
multi-segment chain IK            :mod:`ancf.chain_ik`
================================  ====================================================

``ancf.__version__`` is the installed distribution's version.  The package attributes are loaded lazily (PEP 562): ``import ancf.errors`` costs only that module (no
numba, no scipy), so every other package can use the one exception tree without loading the model.
"""

from __future__ import annotations

import importlib

from .errors import (BellowsError, CollapsedStateError, ConfigError, ConvergenceError, InfeasibleTargetError,
                     InputError, LimitError, OutputExistsError, UnstableEquilibriumError)

_LAZY = {
    "StiffnessLaw": ("ancf.stiffness", "StiffnessLaw"),
    "ActuatorParams": ("ancf.params", "ActuatorParams"),
    "Tendon": ("ancf.params", "Tendon"),
    "presets": ("ancf.presets", None),
    "compliance": ("ancf.compliance", None),
    "Model": ("ancf.model", "Model"),
    "Equilibrium": ("ancf.model", "Equilibrium"),
    "ChainParams": ("ancf.chain", "ChainParams"),
    "Cap": ("ancf.chain", "Cap"),
    "load_actuator": ("ancf.chain", "load_actuator"),
    "ChainModel": ("ancf.chain_model", "ChainModel"),
    "ChainEquilibrium": ("ancf.chain_model", "ChainEquilibrium"),
    "ChainIKEquilibrium": ("ancf.chain_ik", "ChainIKEquilibrium"),
}

__all__ = ["ActuatorParams", "Tendon", "StiffnessLaw", "Model", "Equilibrium", "presets", "ChainParams", "Cap",
           "load_actuator", "ChainModel", "ChainEquilibrium", "ChainIKEquilibrium", "BellowsError",
           "ConfigError", "ConvergenceError", "InfeasibleTargetError", "InputError", "LimitError", "OutputExistsError",
           "UnstableEquilibriumError",
           "CollapsedStateError"]


def distribution_version() -> str:
    """The installed ``bellows`` distribution's version (its metadata, the one ``pip`` reports), or
    ``"0+unknown"`` for a source tree that was never installed (no metadata to read)."""
    from importlib.metadata import PackageNotFoundError, version
    try:
        return version("bellows")
    except PackageNotFoundError:
        return "0+unknown"


def __getattr__(name: str):
    if name == "__version__":                   # read on first use: importlib.metadata is not free
        globals()[name] = value = distribution_version()
        return value
    try:
        module, attr = _LAZY[name]
    except KeyError:
        raise AttributeError(f"module 'ancf' has no attribute {name!r}") from None
    mod = importlib.import_module(module)
    value = mod if attr is None else getattr(mod, attr)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_LAZY) | {"__version__"})

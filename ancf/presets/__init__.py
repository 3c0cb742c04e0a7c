"""Built-in actuator presets (TOML files beside this module).

``paper()``        the paper's actuator (docs/design.md §2), linear stiffness law, 3 tendons.
``paper_constant()`` the same actuator with the constant law EA = k(1), EI = D_a² k(1)/8.
``four_tendon()``  paper geometry with four tendons at 90° and a constant law.
"""

from __future__ import annotations

import pathlib

from ..errors import ConfigError
from ..params import ActuatorParams
from ..stiffness import StiffnessLaw

_HERE = pathlib.Path(__file__).parent


def _load(name: str) -> ActuatorParams:
    return ActuatorParams.from_toml(_HERE / f"{name}.toml")


def paper() -> ActuatorParams:
    """The paper's actuator: L = 160 mm, n = 6, D_a = 29.59 mm, D_eff = 26.05 mm, k = 1336 λ − 568.8 N."""
    return _load("paper")


def paper_constant() -> ActuatorParams:
    """The paper's actuator with constant EA, EI equal to the linear law's values at λ = 1."""
    p = paper()
    law = p.stiffness
    return p.replace(name="paper_constant", stiffness=StiffnessLaw.constant(EA=float(law.EA(1.0)),
                                                                           EI=float(law.EI(1.0))))


def four_tendon() -> ActuatorParams:
    """Paper geometry with four tendons at 90° and a constant stiffness law."""
    return _load("four_tendon")


NAMES = {"paper": paper, "paper_constant": paper_constant, "four_tendon": four_tendon}


def get(name: str) -> ActuatorParams:
    """Preset by name, or parameters from a TOML file if ``name`` ends in ``.toml``."""
    if name.endswith(".toml"):
        return ActuatorParams.from_toml(name)
    try:
        return NAMES[name]()
    except KeyError:
        raise ConfigError(f"unknown preset '{name}'; known: {', '.join(NAMES)} (or a path to a .toml file)") from None

"""Built-in actuator presets (TOML files beside this module, and readings of the paper derived from them).

The paper (Sec. II-B) identifies ``k(λ) = 1336 λ − 568.8`` and writes ``k_t = k(λ) l_0``,
``k_b = D_a² l_0 λ k(λ)/8`` without saying what ``l_0`` multiplies out to in its energy.  The presets
below are the defensible readings of that sentence (docs/paper-readings.md has the evidence for each):

``paper()``            the product's default reading of the paper's actuator (see ``PAPER_READING``).
``paper_unscaled()``   EA(λ) = k(λ) [N], EI = D_a² λ k(λ)/8: ``l_0`` cancels against the element
                       energy written over ξ = x/l_0 (EA(1) = 767 N, EI(1) = 0.084 N m²).
``paper_scaled()``     EA(λ) = k(λ)·L, EI = D_a² L λ k(λ)/8 with L = 0.16 m, the actuator length: ``k`` is
                       read as a stiffness per unit length (EA(1) = 123 N, EI(1) = 0.0134 N m²).
``paper_scaled_020()`` the same with a length factor of 0.20 m (EA(1) = 153 N, EI(1) = 0.0168 N m²), the
                       upper end of the factors that reproduce the paper's workspace gain.
``paper_diameter()``   today's law with the tendons at 13.75 mm (27.5 mm read as a diameter).
``paper_constant()``   the default reading with constant EA = EA(1), EI = EI(1).
``four_tendon()``      paper geometry with four tendons at 90° and a constant law.

Multi-segment actuators (:class:`ancf.chain.ChainParams`, docs/multisegment.md; ``CHAIN_NAMES``, :func:`get_any`):

``two_segment()``      two segments, each the ``paper`` bellows at half length (80 mm, 3 elements, the same section
                       law), one chamber and three tendons each (segment 2's turned 60°), a 10 mm, 10 g cap.

Every linear reading keeps the law's zero at λ₀ = −b/a = 0.426: a length scaling changes the stiffness,
not where it vanishes.
"""

from __future__ import annotations

import pathlib

from ..errors import ConfigError
from ..params import ActuatorParams, Tendon
from ..stiffness import StiffnessLaw

_HERE = pathlib.Path(__file__).parent

#: Length of the paper's actuator [m]; the factor of the length-scaled reading.
PAPER_LENGTH = 0.16


def _load(name: str) -> ActuatorParams:
    return ActuatorParams.from_toml(_HERE / f"{name}.toml")


def paper_unscaled() -> ActuatorParams:
    """EA = k(λ) = 1336 λ − 568.8 N, EI = D_a² λ k(λ)/8; L = 160 mm, n = 6, D_a = 29.59 mm, D_eff = 26.05 mm."""
    return _load("paper").replace(name="paper_unscaled")


def length_scaled(factor: float, name: str = "") -> ActuatorParams:
    """The paper's actuator with both laws multiplied by a length ``factor`` [m]: EA = k(λ)·factor,
    EI = D_a² factor λ k(λ)/8 (``k`` read as a stiffness per unit length)."""
    if not (0.0 < factor <= 10.0):
        raise ConfigError(f"length factor {factor} m must be in (0, 10] m (the paper's actuator: 0.16)")
    base = paper_unscaled()
    s = base.stiffness.source
    law = StiffnessLaw.linear(a=s["a"] * factor, b=s["b"] * factor, D_a=s["D_a"])
    return base.replace(name=name or f"paper_scaled_{factor * 1e3:g}mm", stiffness=law,
                        description=f"k_t = k(λ)·{factor:g} m, k_b = D_a²·{factor:g} m·λ k(λ)/8")


def paper_scaled() -> ActuatorParams:
    """EA = k(λ)·L, EI = D_a² L λ k(λ)/8, L = 0.16 m (EA(1) = 122.8 N, EI(1) = 0.0134 N m²)."""
    return length_scaled(PAPER_LENGTH, "paper_scaled")


def paper_scaled_020() -> ActuatorParams:
    """Length factor 0.20 m (EA(1) = 153.5 N, EI(1) = 0.0168 N m²)."""
    return length_scaled(0.20, "paper_scaled_020")


def paper_diameter() -> ActuatorParams:
    """The unscaled law with the tendons at 13.75 mm from the axis (27.5 mm read as a diameter)."""
    base = paper_unscaled()
    return base.replace(name="paper_diameter", tendons=tuple(Tendon(distance=t.distance / 2, angle=t.angle)
                                                             for t in base.tendons),
                        description="EA = k(λ), tendons at 13.75 mm")


#: The reading the default ``paper`` preset follows (docs/paper-readings.md gives the evidence).
PAPER_READING = paper_scaled


def paper() -> ActuatorParams:
    """The paper's actuator in the product's default reading (``PAPER_READING``)."""
    return PAPER_READING().replace(name="paper")


def paper_constant() -> ActuatorParams:
    """The paper's actuator with constant EA, EI equal to the default reading's values at λ = 1."""
    p = paper()
    law = p.stiffness
    return p.replace(name="paper_constant", stiffness=StiffnessLaw.constant(EA=float(law.EA(1.0)),
                                                                           EI=float(law.EI(1.0))))


def four_tendon() -> ActuatorParams:
    """Paper geometry with four tendons at 90° and a constant stiffness law."""
    return _load("four_tendon")


NAMES = {"paper": paper, "paper_unscaled": paper_unscaled, "paper_scaled": paper_scaled,
         "paper_scaled_020": paper_scaled_020, "paper_diameter": paper_diameter,
         "paper_constant": paper_constant, "four_tendon": four_tendon}

#: The readings of the paper's stiffness law compared by ``bellows paper compare``.
READINGS = ("paper_unscaled", "paper_scaled", "paper_scaled_020", "paper_diameter")


def two_segment():
    """Two half-length ``paper`` segments in series (``two_segment.toml``) → :class:`ancf.chain.ChainParams`."""
    from ..chain import ChainParams
    return ChainParams.from_toml(_HERE / "two_segment.toml")


#: multi-segment presets (a :class:`ancf.chain.ChainParams` each; ``bellows params`` prints them)
CHAIN_NAMES = {"two_segment": two_segment}


def get_any(name: str):
    """A preset of either kind by name (``NAMES`` or ``CHAIN_NAMES``), or an actuator file (today's format →
    ActuatorParams, a file with [[segment]] tables → ChainParams)."""
    if name.endswith(".toml"):
        from ..chain import load_actuator
        return load_actuator(name)
    if name in CHAIN_NAMES:
        return CHAIN_NAMES[name]()
    if name in NAMES:
        return NAMES[name]()
    raise ConfigError(f"unknown preset '{name}'; known: {', '.join([*NAMES, *CHAIN_NAMES])} (or a path to a .toml "
                      "file)")


def get(name: str) -> ActuatorParams:
    """Preset by name, or parameters from a TOML file if ``name`` ends in ``.toml`` (one segment: a multi-segment
    preset or file is a ConfigError saying so)."""
    if name.endswith(".toml") or name in CHAIN_NAMES:
        out = get_any(name)
        if not isinstance(out, ActuatorParams):
            raise ConfigError(f"'{name}' is a multi-segment actuator ({out.n_segments} segments); this takes a "
                              "one-segment actuator (ancf.chain_model.ChainModel models chains)")
        return out
    try:
        return NAMES[name]()
    except KeyError:
        raise ConfigError(f"unknown preset '{name}'; known: {', '.join(NAMES)} (or a path to a .toml file)") from None

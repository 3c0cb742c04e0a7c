"""Identification of the reduced model's parameters (k(λ), D_a, D_eff, …) from the FEM or from rig data.

================== ===============================================================================
module             job
================== ===============================================================================
``forms``          the model forms (which parameters, which laws) and their parameter vectors
``fit``            the weighted least-squares fit, its intervals and identifiability
``information``    what the data can tell before a fit: coverage, the scaled sensitivities, what to hold
``identify``       the protocol: from the FEM (:func:`~validation.identification.identify.from_fem`) or
                   from measured static states (``from_measurements``), form selection, results
``design_select``  informative training cases by D-optimality
``cap_compliance`` the locked compliance from the cap compliance; the shear term
``calibrate``      an FEM design fitted to target rod values
``damping``        damping (and a mass check) from a free decay of the tip
``friction``       the tendons' friction μ from a pull-through test or a tension cycle's tip data
================== ===============================================================================

Imports :mod:`validation.infra` and :mod:`validation.reference` only (inside :mod:`validation`).
"""

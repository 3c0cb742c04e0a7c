"""The identified model checked: against the FEM on held-out states, the FEM's own error, the modes, the
locked-compliance gap, and the compliance forms against finite differences.

==================== =============================================================================
module               job
==================== =============================================================================
``compare``          held-out tips, shapes and compliance matrices: model vs FEM, with targets
``fem_error``        the FEM's discretisation error by mesh refinement (Richardson)
``modes_compare``    the rod's vibration modes beside the FEM's, per pressure
``locked_gap``       why the locked compliance differs between the FEM and the rod
``compliance_check`` every compliance form of the rod against finite differences of its solvers
==================== =============================================================================

Imports :mod:`validation.infra`, :mod:`validation.reference` and :mod:`validation.identification` only.
"""

"""The paper's simulation studies, one module per study; they run on any actuator preset.

==================  ===========================================================================
module              study
==================  ===========================================================================
``workspace``       Sec. IV-A, Fig. 4: TD vs TPHD workspace volume (Monte Carlo, convex hulls)
``stiffness``       Sec. V-C, Fig. 9: tip stiffness vs T1, locked vs constant tension
``convergence``     Sec. V-A: tip error vs the number of elements n
``loads``           Sec. V-D/E: locked drift under a payload, holding a payload, IK time
``comparison``      every headline number for several presets beside the paper's
``criteria``        the one "reproduces the paper" criterion of the comparison's table and figure
``hulls``           convex-hull volume and distance helpers
``states``          state diagnostics: stretch range, collapse of a stiffness law
``plots``/``tables`` figures and printed tables (no computation)
==================  ===========================================================================

Every study returns a plain ``dict`` (SI units, the unit in each key name).  The paper's numbers live in
:mod:`validation.paper_numbers` only.
"""

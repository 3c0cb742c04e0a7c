"""Identification, validation against the FEM reference, and reproductions of the paper's studies.

The public Python API — what the ``bellows identify | validate | report`` commands do, as functions
(README.md, "Python API"):

=============================== ===========================================================================
name                            what
=============================== ===========================================================================
``identify_from_fem``           identify the reduced model from virtual experiments on an FEM design
                                (:func:`validation.identification.identify.from_fem`)
``identify_from_measurements``  … from measured static states (``from_measurements``)
``validate``                    the reduced model against the FEM on held-out states
                                (:func:`validation.checks.compare.validate`)
``stiffness_vs_tension``        the report's vertical tip stiffness vs tension study, both models
``build_report``                the HTML report as a string; ``write_report``: to a file (+ figures)
``run_report``                  ``bellows report`` as one call: identify, validate, study, write the folder
``load_design``                 an FEM design (preset name or .toml) as (geometry, material);
                                ``DESIGN_PRESETS``: the preset names; ``FemSpec``: a design and its mesh
``IdentificationResult``,       the result types (``ReportRun``: what ``run_report`` made)
``ValidationResult``
=============================== ===========================================================================

Every name is imported on first use (PEP 562): ``import validation`` loads none of the subpackages.
"""

from __future__ import annotations

import importlib

_LAZY = {
    "identify_from_fem": ("validation.identification.identify", "from_fem"),
    "identify_from_measurements": ("validation.identification.identify", "from_measurements"),
    "IdentificationResult": ("validation.identification.identify", "IdentificationResult"),
    "validate": ("validation.checks.compare", "validate"),
    "stiffness_vs_tension": ("validation.checks.compare", "stiffness_vs_tension"),
    "ValidationResult": ("validation.checks.compare", "ValidationResult"),
    "build_report": ("validation.report.build", "build_report"),
    "write_report": ("validation.report.build", "write_report"),
    "run_report": ("validation.report.pipeline", "run_report"),
    "ReportRun": ("validation.report.pipeline", "ReportRun"),
    "load_design": ("validation.reference.designs", "load_design"),
    "DESIGN_PRESETS": ("validation.reference.designs", "PRESETS"),
    "FemSpec": ("validation.reference.fem_sweep", "FemSpec"),
}

__all__ = ["identify_from_fem", "identify_from_measurements", "IdentificationResult", "validate",
           "stiffness_vs_tension", "ValidationResult", "build_report", "write_report", "run_report", "ReportRun",
           "load_design", "DESIGN_PRESETS", "FemSpec"]


def __getattr__(name: str):
    if name == "__version__":                   # the installed distribution's (ancf.distribution_version)
        from ancf import distribution_version
        globals()[name] = value = distribution_version()
        return value
    try:
        module, attr = _LAZY[name]
    except KeyError:
        raise AttributeError(f"module 'validation' has no attribute {name!r}") from None
    value = getattr(importlib.import_module(module), attr)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_LAZY) | {"__version__"})

"""The FEM reference as data: the bellows designs, the load cases run on them, the sweep that solves them.

=============== ====================================================================================
module          job
=============== ====================================================================================
``designs``     bellows designs for the FEM: named presets and TOML files with explicit units
``experiments`` virtual experiments: the load cases (training / held-out) stated as shares of the range
``fem_sweep``   every load case solved by :mod:`fem_reference`, in parallel, cached on disk
=============== ====================================================================================

Imports :mod:`validation.infra` only (inside :mod:`validation`).
"""

"""Infrastructure every sweep shares: the task runner (local processes or dask, cached, interruptible) and
the provenance stamped on results.  Imports nothing else of :mod:`validation`.

=============  ===================================================================
module         job
=============  ===================================================================
``runner``     one task runner for the FEM virtual experiments and the paper's studies
``provenance`` package versions, git revision and time of a result
=============  ===================================================================
"""

"""The ``bellows`` command line: the one entry point and the subcommands that live in :mod:`validation`.

============ ====================================================================================
module       job
============ ====================================================================================
``main``     the ``bellows`` app: every package's subcommands, the one-line error contract
``identify`` ``bellows identify | validate | report | calibrate | damping``
``paper``    ``bellows paper ...``: the paper's studies
``fem``      ``bellows fem solve | info``: the FEM reference's command line
``control``  ``bellows control``: a controller on a rig (above both :mod:`controller` and :mod:`hardware`)
============ ====================================================================================

The top of :mod:`validation`: nothing in it imports these modules.
"""

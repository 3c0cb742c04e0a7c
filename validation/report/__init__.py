"""One self-contained HTML report of an identification and its checks (``templates/report.html.j2``).

============ =========================================================
module       job
============ =========================================================
``build``    :func:`~validation.report.build.build_report`: the page
``figures``  its figures (matplotlib, no computation)
``pipeline`` :func:`~validation.report.pipeline.run_report`: ``bellows report`` as one call
============ =========================================================

Imports the layers below it (:mod:`validation.checks`, :mod:`validation.identification`, …), never
:mod:`validation.commands` or :mod:`validation.paper`.
"""

from typing import Any

__all__ = ["build_report", "run_report"]


def __getattr__(name: str) -> Any:
    if name == "build_report":
        from validation.report.build import build_report
        return build_report
    if name == "run_report":
        from validation.report.pipeline import run_report
        return run_report
    raise AttributeError(f"module 'validation.report' has no attribute {name!r}")

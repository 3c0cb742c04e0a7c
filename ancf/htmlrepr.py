"""Small HTML tables for the rich display of results in Jupyter (``_repr_html_``): text cells only, every cell
escaped, no style sheet or script (the notebook's own table style applies).

``table("Equilibrium", [("tip", "(160.0, 0.0, -1.2) mm"), ...])`` → ``<table>`` with a caption and one row per
(name, value, …) tuple; ``header`` names the columns.
"""

from __future__ import annotations

import html
from typing import Iterable, Optional, Sequence

__all__ = ["table"]


def _cell(tag: str, value, left: bool) -> str:
    align = "left" if left else "right"
    return f'<{tag} style="text-align:{align}">{html.escape(str(value))}</{tag}>'


def table(title: str, rows: Iterable[Sequence], header: Optional[Sequence[str]] = None) -> str:
    """An HTML table: ``title`` as its caption, the first column (names) left-aligned, the others right-aligned."""
    out = [f"<table><caption>{html.escape(title)}</caption>"]
    if header:
        out.append("<thead><tr>" + "".join(_cell("th", h, i == 0) for i, h in enumerate(header)) + "</tr></thead>")
    out.append("<tbody>")
    for row in rows:
        out.append("<tr>" + "".join(_cell("th" if i == 0 else "td", v, i == 0) for i, v in enumerate(row)) + "</tr>")
    out.append("</tbody></table>")
    return "".join(out)

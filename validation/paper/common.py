"""Small helpers shared by the studies: preset resolution, figure saving, constants."""

from __future__ import annotations

import pathlib
from typing import Union

from ancf import ActuatorParams, presets

G = 9.81

ParamsLike = Union[str, ActuatorParams, None]


def resolve_params(preset: ParamsLike) -> ActuatorParams:
    """``None`` → the default ``paper`` preset; a name or ``.toml`` path → that preset; params as given."""
    if preset is None:
        return presets.paper()
    if isinstance(preset, ActuatorParams):
        return preset
    return presets.get(str(preset))


def pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def save_figure(fig, out: Union[str, pathlib.Path], stem: str) -> list[pathlib.Path]:
    """Write ``<stem>.png`` and ``<stem>.svg`` into ``out`` and close the figure."""
    import matplotlib.pyplot as plt
    out = pathlib.Path(out)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for ext in ("png", "svg"):
        p = out / f"{stem}.{ext}"
        fig.savefig(p, dpi=130)
        paths.append(p)
    plt.close(fig)
    return paths

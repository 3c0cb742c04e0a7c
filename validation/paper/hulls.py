"""Convex-hull volume and signed distance (Qhull through scipy.spatial)."""

from __future__ import annotations

import numpy as np


def hull_volume(points) -> float:
    """Volume of the convex hull of ``points`` (k, 3) [m³ for m]; 0.0 for fewer than 4 points or a flat
    (coplanar / collinear) cloud.  NaN rows are ignored."""
    from scipy.spatial import ConvexHull, QhullError

    P = np.asarray(points, float).reshape(-1, 3)
    P = P[np.all(np.isfinite(P), axis=1)]
    if len(P) < 4:
        return 0.0
    try:
        return float(ConvexHull(P).volume)
    except QhullError:
        return 0.0


def hull_distance(points, hull_points) -> np.ndarray:
    """Signed distance [m] of each of ``points`` (k, 3) to the convex hull of ``hull_points``: the largest
    facet-plane offset, ≤ 0 inside (its magnitude is then the distance to the nearest facet plane), > 0
    outside (a lower bound of the Euclidean distance to the hull, exact where the nearest hull point lies
    on a facet's interior)."""
    from scipy.spatial import ConvexHull

    H = ConvexHull(np.asarray(hull_points, float))
    P = np.asarray(points, float).reshape(-1, 3)
    return np.max(P @ H.equations[:, :3].T + H.equations[:, 3], axis=1)

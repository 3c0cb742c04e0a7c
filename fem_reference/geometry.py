r"""Parametric bellows geometry (SI units, metres).

The wall is a surface of revolution about the actuator axis (world ``+x``; base face in the plane
``x = 0``, distal face in ``x = L``).  It is described by its **mid-wall profile** in the meridian
half-plane, parametrised by the axial coordinate :math:`\zeta \in [0, L]`:

.. math::

    r_m(\zeta) = \begin{cases}
        r_0 & \zeta < c \ \text{or}\ \zeta > L - c \quad\text{(end collars)} \\
        r_0 + \tfrac{1}{2}(r_1 - r_0)\,(1 - \cos\varphi),\ \ \varphi = 2\pi(\zeta - c)/p
            & \text{otherwise (convolutions, pitch } p = (L - 2c)/n)
    \end{cases}

with :math:`r_0 = r_\text{root} + t/2` and :math:`r_1 = r_\text{crest} - t/2` the mid-wall radii at
the roots (valleys) and crests.  ``r_root`` is the *inner* radius at a root and ``r_crest`` the *outer*
radius at a crest (the two numbers one reads off a drawing).  The profile is :math:`C^1`, and
:math:`r_m'(0) = r_m'(L) = 0`, so the offset surfaces meet the caps in flat annuli.

A material point of the wall is mapped from lattice coordinates :math:`(\zeta, \tau, \theta)`,
:math:`\tau \in [-t/2, t/2]` through the wall, :math:`\theta` the angle about the axis measured from
the reference direction ``+z`` (right-handed about ``+x``):

.. math::

    X = (\zeta + \tau n_z)\,e_x + (r_m + \tau n_r)\,e_r(\theta), \qquad
    (n_r, n_z) = \frac{(1, -r_m')}{\sqrt{1 + r_m'^2}}, \qquad
    e_r(\theta) = \cos\theta\, e_z + \sin\theta\,(e_x \times e_z) = (0, -\sin\theta, \cos\theta).

The offset is along the exact profile normal, so the wall thickness is exactly ``t``; the offset is
free of self-intersection when the smallest radius of curvature of the mid-profile,
:math:`1/\max|r_m''|`, exceeds ``t/2`` (checked in validation).  A straight tube is the limit
``r_crest = r_root + t`` (zero convolution depth).

**A profile given as data.**  ``profile`` may instead be a :class:`~fem_reference.profile.TableProfile`
(the inner and outer outline as point tables; :meth:`BellowsGeometry.from_profile`).  The lattice row ``ζ``
is then the mid-wall axial coordinate of the through-wall segment along the inner outline's normal, and
``τ`` the position along it, ``X = P_i + (τ/t + ½)(P_o − P_i)`` (``t = wall_thickness``, the thinnest wall):
for the sine profile's own outlines this is the map above, so the mesh, the caps, the pressure faces and the
tendon guides follow unchanged.  ``length``, ``root_radius`` (smallest inner radius), ``crest_radius``
(largest outer radius) and ``wall_thickness`` are then read off the table; ``n_convolutions`` and
``collar_length`` still split the axis into mesh blocks and place the roots (tendon guides).

Tendons are routed at distance ``tendon_radius`` from the axis at angles ``tendon_angles`` (same
convention as θ): they leave the base cap, pass through one guide point at every *interior* root
(the guide is the wall point at that angle, extrapolated radially to ``tendon_radius`` with the ring
of the root: see :mod:`fem_reference.loads.tendons`) and are anchored on the distal cap.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Literal

import numpy as np

from .errors import ConfigError

from ._checks import validated
from .profile import TableProfile

__all__ = ["N_CONVOLUTIONS_MAX", "N_TENDONS_MAX", "BellowsGeometry", "e_radial"]

#: most convolutions a bellows may have (a larger count is a typing or unit mistake, and its mesh would not fit)
N_CONVOLUTIONS_MAX = 100
#: most tendons a bellows may carry
N_TENDONS_MAX = 16
#: smallest angular distance between two tendons [rad] (coincident tendons make the tension → tip map singular)
_MIN_TENDON_GAP = 1e-3

_trapezoid = getattr(np, "trapezoid", None) or np.trapz  # numpy < 2 fallback


def e_radial(theta) -> np.ndarray:
    """Unit radial direction(s) ``e_r(θ) = (0, -sin θ, cos θ)``; shape ``(3,) + θ.shape``."""
    th = np.asarray(theta, float)
    return np.stack([np.zeros_like(th), -np.sin(th), np.cos(th)])


@dataclass(frozen=True)
class BellowsGeometry:
    """Immutable bellows description (all lengths in metres, masses in kg, angles in rad).

    Parameters
    ----------
    length : float
        Bellows body length between the two cap faces, ``L`` [m].
    n_convolutions : int
        Number of convolutions (full sine periods) between the two end collars.
    root_radius : float
        Inner wall radius at a root (valley) [m].
    crest_radius : float
        Outer wall radius at a crest [m]; ``root_radius + wall_thickness`` gives a straight tube.
    wall_thickness : float
        Wall thickness ``t`` measured along the profile normal [m].
    collar_length : float
        Straight collar at each end (at the root radius) where the wall is bonded to the cap [m].
    profile : "sine" or TableProfile
        Shape of the convolution profile: the built-in sine, or the outlines as data (module docstring;
        build such a geometry with :meth:`from_profile`).
    tendon_radius : float
        Routing distance ``d`` of the tendons from the axis [m].
    tendon_angles : tuple of float
        Tendon angles θ_i about ``+x`` from ``+z`` [rad].
    cap_mass : float
        Mass of the distal rigid cap (PLA) [kg], weight applied at ``cap_com_offset`` with gravity.
    cap_com_offset : float
        Distance of the distal cap's centre of mass from the cap face along the cap axis [m].
    tip_offset : float
        Distance of the reported tip point from the cap face along the cap axis [m].
    """

    length: float
    n_convolutions: int
    root_radius: float
    crest_radius: float
    wall_thickness: float
    collar_length: float = 0.0
    profile: Literal["sine"] | TableProfile = "sine"
    tendon_radius: float = 0.0275
    tendon_angles: tuple[float, ...] = (0.0, 2 * np.pi / 3, 4 * np.pi / 3)
    cap_mass: float = 0.0
    cap_com_offset: float = 0.0
    tip_offset: float = 0.0

    def __post_init__(self):
        validated(self, "BellowsGeometry")

    def _validate(self):
        try:
            angles = tuple(float(a) for a in self.tendon_angles)
        except TypeError:
            raise ConfigError(f"tendon_angles must be a list of angles in rad, got {self.tendon_angles!r}") from None
        object.__setattr__(self, "tendon_angles", angles)
        pos = dict(length=self.length, root_radius=self.root_radius, crest_radius=self.crest_radius,
                   wall_thickness=self.wall_thickness, tendon_radius=self.tendon_radius)
        for k, v in pos.items():
            if not np.isfinite(v) or v <= 0:
                raise ConfigError(f"BellowsGeometry.{k} must be a positive length in metres, got {v!r}")
        for k in ("collar_length", "cap_mass", "cap_com_offset", "tip_offset"):
            v = getattr(self, k)
            if not np.isfinite(v) or v < 0:
                raise ConfigError(f"BellowsGeometry.{k} must be finite and >= 0, got {v!r}")
        if (isinstance(self.n_convolutions, bool) or int(self.n_convolutions) != self.n_convolutions
                or not 1 <= self.n_convolutions <= N_CONVOLUTIONS_MAX):
            raise ConfigError(f"n_convolutions must be an integer in 1 … {N_CONVOLUTIONS_MAX}, "
                              f"got {self.n_convolutions!r}")
        self._validate_tendons()
        if self.length > 5.0 or self.root_radius > 1.0:
            raise ConfigError("BellowsGeometry takes metres: length/radii look like millimetres")
        if 2 * self.collar_length >= self.length:
            raise ConfigError("2 * collar_length must be < length")
        if isinstance(self.profile, TableProfile):
            self._validate_table()
        elif self.profile != "sine":
            raise ConfigError(f"profile {self.profile!r} not implemented (available: 'sine' or a TableProfile)")
        else:
            self._validate_sine()

    def _validate_tendons(self):
        a = np.array(self.tendon_angles)
        if a.size > N_TENDONS_MAX or not np.all(np.isfinite(a)):
            raise ConfigError(f"tendon_angles: at most {N_TENDONS_MAX} finite angles, got {self.tendon_angles!r}")
        for i in range(a.size):
            for j in range(i):
                gap = abs((a[i] - a[j] + np.pi) % (2 * np.pi) - np.pi)
                if gap < _MIN_TENDON_GAP:
                    raise ConfigError(
                        f"tendon_angles: tendons {j + 1} and {i + 1} coincide ({np.degrees(a[j]):g}° and "
                        f"{np.degrees(a[i]):g}°, {np.degrees(gap):.3g}° apart; at least "
                        f"{np.degrees(_MIN_TENDON_GAP):.3g}° needed): their tensions could not be told apart")

    def _validate_sine(self):
        if self.crest_radius < self.root_radius + self.wall_thickness - 1e-12:
            raise ConfigError("crest_radius (outer, at a crest) must be >= root_radius + wall_thickness")
        kmax = self.max_curvature()
        if kmax * self.wall_thickness / 2 >= 0.95:
            raise ConfigError(
                f"convolutions too tight for the wall: min profile radius {1 / kmax:.4g} m "
                f"<= t/2 = {self.wall_thickness / 2:.4g} m (offset surface would self-intersect)")

    def _validate_table(self):
        derived = self.profile.summary()
        off = [k for k, v in derived.items() if abs(getattr(self, k) - v) > 1e-12 * max(abs(v), 1e-300)]
        if off:
            raise ConfigError(f"{', '.join(off)} of a design with a profile table are read off the table "
                              f"({self.profile.source or 'TableProfile'}); build it with BellowsGeometry.from_profile")

    # ---------------------------------------------------------------- constructors
    @classmethod
    def straight_tube(cls, length: float, mean_radius: float, wall_thickness: float,
                      n_segments: int = 8, **kw) -> BellowsGeometry:
        """Straight circular tube (zero convolution depth) of mid-wall radius ``mean_radius`` [m].

        ``n_segments`` plays the role of ``n_convolutions`` (axial mesh blocks, tendon guides).
        """
        kw.setdefault("tendon_radius", mean_radius)
        return cls(length=length, n_convolutions=n_segments,
                   root_radius=mean_radius - wall_thickness / 2,
                   crest_radius=mean_radius + wall_thickness / 2,
                   wall_thickness=wall_thickness, **kw)

    @classmethod
    def from_profile(cls, profile: TableProfile, n_convolutions: int, collar_length: float = 0.0,
                     **kw) -> BellowsGeometry:
        """Bellows whose wall is the table ``profile``; ``length``, ``root_radius``, ``crest_radius`` and
        ``wall_thickness`` are read off the table (module docstring), the other fields as in the constructor."""
        if not isinstance(profile, TableProfile):
            raise ConfigError(f"profile must be a TableProfile, got {type(profile).__name__}")
        return cls(n_convolutions=n_convolutions, collar_length=collar_length, profile=profile,
                   **profile.summary(), **kw)

    @property
    def is_table(self) -> bool:
        """True when the wall profile is given as data (a :class:`TableProfile`)."""
        return isinstance(self.profile, TableProfile)

    def replace(self, **changes) -> BellowsGeometry:
        """Copy with some fields changed (validated again)."""
        return replace(self, **changes)

    # ---------------------------------------------------------------- derived quantities
    @property
    def r_root_mid(self) -> float:
        """Mid-wall radius at a root [m]."""
        return self.root_radius + self.wall_thickness / 2

    @property
    def r_crest_mid(self) -> float:
        """Mid-wall radius at a crest [m]."""
        return self.crest_radius - self.wall_thickness / 2

    @property
    def pitch(self) -> float:
        """Axial length of one convolution [m]."""
        return (self.length - 2 * self.collar_length) / self.n_convolutions

    @property
    def is_straight(self) -> bool:
        return not self.is_table and abs(self.r_crest_mid - self.r_root_mid) < 1e-15

    @property
    def cap_inner_radius(self) -> float:
        """Inner radius where the wall meets the distal cap [m] (the cap's pressurised disc)."""
        return self.profile.cap_inner_radius if self.is_table else self.root_radius

    def root_positions(self) -> np.ndarray:
        """Axial positions ζ of all roots, ends included, shape ``(n_convolutions + 1,)`` [m]."""
        return self.collar_length + self.pitch * np.arange(self.n_convolutions + 1)

    def max_curvature(self) -> float:
        """Largest curvature of the mid-profile [1/m] (0 for a straight tube)."""
        a = 0.5 * (self.r_crest_mid - self.r_root_mid)
        k = 2 * np.pi / self.pitch
        # curvature of r = a(1 - cos kz): |r''| / (1 + r'^2)^1.5 is largest at a crest or root
        return abs(a) * k * k

    def profile_mid(self, zeta) -> tuple[np.ndarray, np.ndarray]:
        """Mid-wall radius ``r_m(ζ)`` [m] and slope ``dr_m/dζ`` [-] of the sine profile at axial positions
        ``zeta`` (a table profile has no single mid-curve formula: :meth:`map_points` serves both)."""
        if self.is_table:
            raise ConfigError("profile_mid is the sine profile's formula; a table profile maps through map_points")
        z = np.asarray(zeta, float)
        c, p = self.collar_length, self.pitch
        phi = 2 * np.pi * (z - c) / p
        inside = (z > c) & (z < self.length - c)
        a = 0.5 * (self.r_crest_mid - self.r_root_mid)
        r = self.r_root_mid + np.where(inside, a * (1 - np.cos(phi)), 0.0)
        dr = np.where(inside, a * np.sin(phi) * 2 * np.pi / p, 0.0)
        return r, dr

    def map_points(self, zeta, tau, theta) -> np.ndarray:
        """Map lattice coordinates (broadcast arrays) to reference positions, shape ``(3,) + shape``."""
        zeta, tau, theta = np.broadcast_arrays(*(np.asarray(a, float) for a in (zeta, tau, theta)))
        if self.is_table:
            return self._map_table(zeta, tau, theta)
        r, dr = self.profile_mid(zeta)
        s = np.sqrt(1 + dr * dr)
        nr, nz = 1 / s, -dr / s
        X = np.empty((3,) + zeta.shape)
        X[0] = zeta + tau * nz
        er = e_radial(theta)
        X[1:] = (r + tau * nr) * er[1:]
        return X

    def _map_table(self, zeta, tau, theta) -> np.ndarray:
        """map_points of a table profile: ``P_i + (τ/t + ½)(P_o − P_i)`` on the segment of row ζ."""
        flat = np.unique(zeta)
        pi, po = self.profile.wall_points(flat)
        k = np.searchsorted(flat, zeta)
        s = tau / self.wall_thickness + 0.5
        z = pi[0][k] + s * (po[0][k] - pi[0][k])
        r = pi[1][k] + s * (po[1][k] - pi[1][k])
        X = np.empty((3,) + zeta.shape)
        X[0] = z
        X[1:] = r * e_radial(theta)[1:]
        return X

    def wall_volume(self, n: int = 40001) -> float:
        """Wall volume [m³] by Pappus on the exact offset map (5-point Gauss through the wall,
        trapezoid on ``n`` points along the axis; converges as O(n⁻²))."""
        z = np.linspace(0, self.length, n)
        g, w = np.polynomial.legendre.leggauss(5)
        t = self.wall_thickness
        vol = 0.0
        for gi, wi in zip(g, w):
            tau = 0.5 * t * gi
            X = self.map_points(z, tau, 0.0)
            dXdz = np.gradient(X[0], z), np.gradient(X[2], z)
            X2 = self.map_points(z, tau + 1e-7, 0.0)
            dXdt = (X2[0] - X[0]) / 1e-7, (X2[2] - X[2]) / 1e-7
            jac = np.abs(dXdz[0] * dXdt[1] - dXdz[1] * dXdt[0])
            vol += 0.5 * t * wi * _trapezoid(2 * np.pi * X[2] * jac, z)
        return float(vol)

    def cavity_volume(self, n: int = 20001) -> float:
        """Undeformed cavity volume bounded by the inner wall and the two cap planes [m³]."""
        tau = -self.wall_thickness / 2
        z = np.linspace(0, self.length, n)
        X = self.map_points(z, tau, 0.0)
        return float(abs(_trapezoid(np.pi * X[2] ** 2, X[0])))

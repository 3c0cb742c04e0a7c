"""The cap's centre-of-mass offset along the tip tangent: its share of the self-weight sag.

The FEM hangs the cap's weight m g at its centre of mass, c beyond the tip point along the tip tangent; the rod
hangs it at the tip point.  For a horizontal cantilever (small deflection) the offset adds the end moment m g c:
extra tip deflection m g c L² / (2 EI), against m g L³ / (3 EI) of the tip weight and w L⁴ / (8 EI) of the line
weight w.  The rod's tip load at the tool point (tool_offset = c) reproduces this closed form, and on the paper
preset's masses the offset's share of the sag is < 1 % — why the rod carries no separate offset term."""

import numpy as np
import pytest

from ancf import Model, StiffnessLaw, presets
from ancf import kinematics as kin

L, EI, G = 0.16, 0.5, 9.81


def _end_sag(params) -> float:
    """Vertical deflection [m] of the rod's end point (not the tool point) under its weight, tendons slack."""
    eq = Model(params).fk((0.0, 0.0, 0.0), 0.0, (0.0, 0.0, 0.0), check_limits=False)
    return -float(kin.tip_position(eq.q, 0.0)[2])


def _stiff(line_mass: float, tip_mass: float, offset: float):
    return presets.paper().replace(stiffness=StiffnessLaw.constant(EA=1e5, EI=EI), line_mass=line_mass,
                                   tip_mass=tip_mass, tool_offset=offset, gravity=(0.0, 0.0, -G), n_elements=8)


def test_offset_tip_weight_matches_the_beam_closed_form():
    m, c = 0.018, 0.0025
    d0, d1 = _end_sag(_stiff(0.0, m, 0.0)), _end_sag(_stiff(0.0, m, c))
    assert d0 == pytest.approx(m * G * L ** 3 / (3 * EI), rel=2e-3)
    assert d1 - d0 == pytest.approx(m * G * c * L ** 2 / (2 * EI), rel=2e-2)


def test_offset_share_of_the_self_weight_sag_is_below_one_percent_on_the_paper_masses():
    """85.1 g wall over 160 mm and the 18 g cap 2.5 mm beyond the tip (the paper design): closed form 0.73 %."""
    w, m, c = 0.0850568 / L, 0.018, 0.0025
    closed = (m * G * c * L ** 2 / 2) / (w * G * L ** 4 / 8 + m * G * L ** 3 / 3)
    d0, d1 = _end_sag(_stiff(w, m, 0.0)), _end_sag(_stiff(w, m, c))
    share = (d1 - d0) / d0
    assert share == pytest.approx(closed, rel=3e-2) and share < 0.01
    # and on the large-deflection paper preset itself (47 mm sag at 0 kPa)
    p = presets.paper().replace(line_mass=w, tip_mass=m, tool_offset=0.0)
    big0, big1 = _end_sag(p), _end_sag(p.replace(tool_offset=c))
    assert 0.0 < (big1 - big0) / big0 < 0.01
    assert np.isfinite(big0) and big0 > 0.03

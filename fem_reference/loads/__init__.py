"""Loads and constraints of the bellows model, one module each (contribution + Jacobian).

- :mod:`.caps` — rigid caps: clamped base, distal cap as a 6-DOF nonlinear reduction, point loads on it.
- :mod:`.pressure` — follower cavity pressure: the cap force (the wall part is in
  :class:`fem_reference.assembly.PressureAssembler`).
- :mod:`.tendons` — frictionless sliding cables through guide points (tension or locked length).
- :mod:`.gravity` — dead body load of the wall and the cap weight.
"""

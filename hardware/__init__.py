"""Rig layer: device interfaces, a simulated rig, real drivers, safety limits, run logs, and the static-states
file format (:mod:`hardware.static_states`; docs/data-formats.md)."""

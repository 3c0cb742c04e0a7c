"""Fake drives and instruments for tests: they speak the real protocols (CANopen CiA 402 on python-can's
virtual bus, serial lines through a pseudo-terminal, NatNet UDP packets)."""

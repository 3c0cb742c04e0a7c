r"""EPOS4 in **profile position** mode (CiA 402, 0x6060 = 1) over SDO: the drive ramps each move itself.

Enable: mode 1 (confirmed on 0x6061), profile velocity / acceleration / deceleration from the rig file
(written and read back: :meth:`Epos4Drive._write_profile`), then shutdown → switch on → enable operation.  A drive
that is already enabled in profile position is left as it is (no power-stage cycle), but its profile is still
written — a move never runs at a speed the drive had stored.

Move (:meth:`Epos4ProfileDrive.move_to`): check the travel, write the target 0x607A, then the new-setpoint
handshake — controlword bit 4 (new setpoint) with bit 5 (change set immediately), wait for statusword bit 12
(setpoint acknowledge), clear bit 4.  Bit 10 (target reached) with bit 12 = 0 means the move is done; bit 8
(halt) holds the drive where it is.  Every set-point and read-back is a confirmed SDO round trip (about a
millisecond each on a 1 Mbit/s bus): right for slow, quasi-static moves.

Fault and recovery: a fault (statusword bit 3, following error bit 13, an EMCY) stops the drive by itself and
is a :class:`~hardware.errors.DriveFault` at the next check; :meth:`fault_reset` then :meth:`enable` bring it back
(SWITCH ON DISABLED → OPERATION ENABLED).  The drive does not move until the next :meth:`move_to`: in profile
position a target is taken only through the new-setpoint handshake, so a target left in 0x607A is never
followed on enable.
"""

from __future__ import annotations

import threading
import time

from .epos4 import (CW_CHANGE_IMMEDIATELY, CW_ENABLE, CW_HALT, CW_NEW_SETPOINT, CURRENT, FOLLOWING_ERROR,
                    MODE_DISPLAY, POSITION, PROFILE_POSITION, STATUSWORD, SW_SETPOINT_ACK, SW_TARGET_REACHED, TARGET,
                    Epos4Drive, state_of)
from .errors import DriveFault, LimitError


class Epos4ProfileDrive(Epos4Drive):
    """One EPOS4 tendon drive in profile position over SDO (see :class:`Epos4Drive` for the shared parameters).

    ack_timeout : seconds to wait for the setpoint acknowledge
    """

    mode, mode_name = PROFILE_POSITION, "profile position"

    def __init__(self, node_id: int, channel: str = "can0", interface: str = "socketcan", bitrate: int = 1_000_000, *,
                 ack_timeout: float = 0.5, cyclic: bool = False, **kw):
        if cyclic:
            raise LimitError("Epos4ProfileDrive is profile position; use Epos4CyclicDrive for cyclic operation")
        super().__init__(node_id, channel, interface, bitrate, **kw)
        self.ack_timeout = float(ack_timeout)
        self._lock = threading.RLock()

    def enable(self) -> None:
        """Profile position mode, the profile from the rig file, then the power state machine (module docstring)."""
        self.check()
        enabled = self.state() == "OPERATION ENABLED" and self._read(MODE_DISPLAY) == self.mode
        if not enabled:
            self._enter_mode()
        self._write_profile()
        if not enabled:
            self._power_up()

    def move_to(self, length: float) -> None:
        """Check the travel, send the target and complete the new-setpoint handshake."""
        counts = self._checked_counts(length)
        with self._lock:
            self.check()
            if state_of(self.statusword()) != "OPERATION ENABLED":
                raise DriveFault(f"move commanded in state {self.state()}", device=self.name)
            self._write(TARGET, counts)
            self._control(CW_ENABLE | CW_NEW_SETPOINT | CW_CHANGE_IMMEDIATELY)
            t0 = time.monotonic()
            while not self.statusword() & SW_SETPOINT_ACK:
                if time.monotonic() - t0 > self.ack_timeout:
                    self._control(CW_ENABLE)
                    raise DriveFault(f"setpoint not acknowledged within {self.ack_timeout:g} s", device=self.name)
                time.sleep(0.001)
            self._control(CW_ENABLE | CW_CHANGE_IMMEDIATELY)

    def position(self) -> float:
        return self.to_length(self._read(POSITION))

    def current(self) -> float:
        """Motor current [A] (EPOS4 0x30D1:02, mA)."""
        return self._read(CURRENT, 2) * 1e-3

    def following_error(self) -> float:
        """Following error actual value [m] (0x60F4)."""
        return self._read(FOLLOWING_ERROR) / self.counts_per_metre

    def target_reached(self) -> bool:
        sw = self.statusword()
        return bool(sw & SW_TARGET_REACHED) and not sw & SW_SETPOINT_ACK

    def hold(self) -> None:
        """Halt (controlword bit 8): decelerate and hold position, still enabled.

        Only an OPERATION ENABLED drive is halted.  A drive in any other state (QUICK STOP ACTIVE, FAULT,
        switched off) is already stopped and is left alone: the halt controlword 0x10F carries *enable
        operation*, which would take a quick-stopped drive back to OPERATION ENABLED — a safe-stop path must
        never re-enable a stopped drive."""
        with self._lock:
            if state_of(self._read(STATUSWORD)) == "OPERATION ENABLED":
                self._control(CW_ENABLE | CW_HALT)

    def disable(self) -> None:
        with self._lock:
            super().disable()


__all__ = ["Epos4ProfileDrive"]

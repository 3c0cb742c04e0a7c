r"""One CAN bus of the rig, shared by the drives on it: one ``canopen.Network``, one SYNC producer, the host's
heartbeat.

Drives on one bus (the same python-can ``interface`` and ``channel``) share one :class:`CanBus`
(:func:`hardware.build.build_rig` makes one per bus): one socket, one SYNC producer however many cyclic drives
there are, and one *master heartbeat* — the heartbeat the host produces (COB-ID 0x700 + :data:`MASTER_NODE_ID`)
and the cyclic drives consume (0x1016), so that a silent host stops them.

* **SYNC** is started with ``network.sync.start(period)``, which python-can runs as a periodic task of the bus:
  on socketcan the kernel's broadcast manager sends it, so it keeps ticking while the Python process stalls —
  the drives keep their timing, and the host's set-point rule (:mod:`hardware.setpoints`) makes the stall a
  pause, not a jump.  It is started once every cyclic drive of the bus is enabled
  (:meth:`CanBus.start_sync`), and a second request for another period is an error.
* **The master heartbeat** is sent by the cyclic drives' set-point callbacks (:meth:`CanBus.beat`), i.e. by
  the same code path that sends set-points: when the host's set-point path stops — a stall, a crash, a
  deadlock — the heartbeat stops with it, and each drive stops itself after its consumer heartbeat time.  A
  heartbeat from an independent timer would say "alive" while no set-point is sent.

The bus is reference-counted: every drive opens and closes it; the last close stops SYNC and disconnects
(a network passed in by the caller is never disconnected).
"""

from __future__ import annotations

import logging
import threading
import time
from typing import Optional

from .errors import CommunicationError, LimitError

__all__ = ["CanBus", "MASTER_NODE_ID", "MASTER_HEARTBEAT_PERIOD"]

#: the node id the host's heartbeat is sent as (COB-ID 0x77F); no drive on a cyclic bus may use it
MASTER_NODE_ID = 127
#: period of the host's heartbeat [s]
MASTER_HEARTBEAT_PERIOD = 0.05
_OPERATIONAL = 0x05


class CanBus:
    """A CAN bus (python-can ``interface`` + ``channel`` at ``bitrate``), or an already connected
    ``canopen.Network`` passed as ``network``."""

    def __init__(self, interface: str = "socketcan", channel: str = "can0", bitrate: int = 1_000_000, *,
                 network=None):
        if isinstance(bitrate, bool) or not isinstance(bitrate, int) or bitrate <= 0:
            raise LimitError(f"CAN bitrate must be a positive integer [bit/s], got {bitrate!r}")
        if not (isinstance(interface, str) and interface and isinstance(channel, str) and channel):
            raise LimitError(f"CAN interface and channel must be non-empty text, got {interface!r}, {channel!r}")
        self.interface, self.channel, self.bitrate = interface, channel, bitrate
        self.network = network
        self._own = network is None
        self._users = 0
        self._lock = threading.Lock()
        self.sync_period: Optional[float] = None
        self._last_beat = 0.0

    @property
    def name(self) -> str:
        return f"CAN {self.interface}:{self.channel}"

    def open(self):
        """Connect (on the first call) and count one user; returns the ``canopen.Network``."""
        with self._lock:
            if self.network is None:
                import canopen
                logging.getLogger("canopen").setLevel(logging.ERROR)
                net = canopen.Network()
                net.NOTIFIER_CYCLE = 0.1                      # close within 0.1 s, not 1 s
                try:
                    net.connect(interface=self.interface, channel=self.channel, bitrate=self.bitrate)
                except (OSError, ValueError, ImportError, NotImplementedError) as exc:
                    raise CommunicationError(f"cannot open CAN {self.interface}:{self.channel}: {exc}",
                                             device=self.name) from None
                except Exception as exc:                       # noqa: BLE001 - python-can's CanError family
                    raise CommunicationError(f"cannot open CAN {self.interface}:{self.channel}: {exc}",
                                             device=self.name) from None
                self.network = net
            self._users += 1
            return self.network

    def close(self) -> None:
        """One user less; the last one stops SYNC and disconnects a network this bus connected."""
        with self._lock:
            self._users = max(0, self._users - 1)
            if self._users:
                return
            self._stop_sync()
            if self._own and self.network is not None:
                try:
                    self.network.disconnect()
                except Exception:                              # noqa: BLE001 - closing must not raise
                    pass
                self.network = None

    # ----------------------------------------------------------------------------------- SYNC
    def start_sync(self, period: float) -> None:
        """Start the bus's SYNC producer at ``period`` [s] (idempotent for the same period)."""
        if isinstance(period, bool) or not isinstance(period, (int, float)) or not 1e-4 <= period <= 0.1:
            raise LimitError(f"SYNC period must be 0.1 ms … 100 ms, got {period!r} s", device=self.name)
        with self._lock:
            if self.network is None:
                raise CommunicationError("the bus is not open", device=self.name)
            if self.sync_period is not None:
                if abs(self.sync_period - period) > 1e-12:
                    raise LimitError(f"SYNC already runs at {self.sync_period * 1e3:g} ms; a drive asks for "
                                     f"{period * 1e3:g} ms (one SYNC per bus)", device=self.name)
                return
            self.network.sync.start(period)
            self.sync_period = float(period)

    def _stop_sync(self) -> None:
        if self.sync_period is not None and self.network is not None:
            try:
                self.network.sync.stop()
            except Exception:                                  # noqa: BLE001 - stopping must not raise
                pass
        self.sync_period = None

    # ----------------------------------------------------------------------------------- heartbeat
    def beat(self, now: Optional[float] = None) -> None:
        """Send the host's heartbeat if one is due (called from the set-point path; never raises)."""
        now = time.monotonic() if now is None else now
        if now - self._last_beat < MASTER_HEARTBEAT_PERIOD:
            return
        self._last_beat = now
        net = self.network
        if net is not None:
            try:
                net.send_message(0x700 + MASTER_NODE_ID, bytes([_OPERATIONAL]))
            except Exception:                                  # noqa: BLE001 - a closed bus: the drives stop
                pass

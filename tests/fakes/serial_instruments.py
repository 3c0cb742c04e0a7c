"""Serial instruments on a pseudo-terminal: a thread on the pty master plays a load-cell board and a
valve controller speaking the protocol of :mod:`hardware.serial_devices`.

    with FakeSerialInstrument(forces=[1200, 800, 800]) as inst:
        sensor = SerialForceSensor(inst.port, channel=1, scale=1e-3)

Fault switches: ``silent`` (no replies → SensorTimeout), ``corrupt`` (bad checksum), ``overshoot_Pa``
(pressure reads the set point plus this), ``refuse`` (ERR replies to valve commands).
"""

from __future__ import annotations

import os
import pty
import select
import threading
import tty

from hardware.serial_devices import frame


class FakeSerialInstrument:
    def __init__(self, forces=(0, 0, 0)):
        self.forces = list(forces)
        self.pressure = 0.0
        self.setpoint = 0.0
        self.valves = "HOLD"
        self.seq = 0
        self.silent = False
        self.corrupt = False
        self.overshoot_Pa = 0.0
        self.refuse = False
        self.log: list = []
        self._stop = threading.Event()

    def __enter__(self):
        self.master, self.slave = pty.openpty()
        tty.setraw(self.master)
        tty.setraw(self.slave)
        self.port = os.ttyname(self.slave)
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join(timeout=1)
        os.close(self.master)
        os.close(self.slave)
        return False

    def reply(self, text: str) -> bytes:
        if self.refuse and not text.startswith(("F ", "P ")):
            text = "ERR valve driver overcurrent"
        out = frame(text)
        if self.corrupt:
            out = out.replace(b"*", b"0*", 1)
        return out

    def handle(self, line: str) -> bytes:
        cmd = line.split("*")[0]
        self.log.append(cmd)
        self.seq += 1
        if cmd == "F?":
            return self.reply("F %d %s" % (self.seq, " ".join(str(c) for c in self.forces)))
        if cmd == "P?":
            return self.reply("P %d %.1f" % (self.seq, self.pressure + self.overshoot_Pa))
        if cmd.startswith("PSET "):
            self.setpoint = self.pressure = float(cmd.split()[1])
            return self.reply(f"OK PSET {self.setpoint:.1f}")
        if cmd in ("HOLD", "VENT"):
            self.valves = cmd
            if cmd == "VENT":
                self.pressure = self.setpoint = 0.0
            return self.reply(f"OK {cmd}")
        return frame("ERR unknown command")

    def _serve(self):
        buf = b""
        while not self._stop.is_set():
            r, _, _ = select.select([self.master], [], [], 0.02)
            if not r:
                continue
            try:
                buf += os.read(self.master, 1024)
            except OSError:
                return
            while b"\n" in buf:
                line, buf = buf.split(b"\n", 1)
                if self.silent:
                    continue
                os.write(self.master, self.handle(line.decode("ascii", "replace")))

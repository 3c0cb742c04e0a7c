"""The out-of-process fake drives (``fakes.drive_process`` + ``fakes.canbridge``) against the CiA 301 /
CiA 402 specification, from the host side with nothing but ``canopen`` (no product code): SDO, the power
state machine, profile position at the profile velocity, cyclic synchronous position (the last RPDO
before a SYNC wins; a stale 0x607A jumps on enabling; software position limits), the heartbeat consumer
and the following error window faulting the drive, and the hub's SYNC clock that keeps ticking while the
host holds the GIL (and a lost SYNC)."""

import contextlib
import logging
import sys
import threading
import time

import pytest

canopen = pytest.importorskip("canopen")

from canopen import objectdictionary as odm  # noqa: E402
from canopen.objectdictionary import datatypes as dt  # noqa: E402
from canopen.sdo import SdoAbortedError  # noqa: E402
from fakes.canbridge import register  # noqa: E402
from fakes.drive_process import DriveProcess  # noqa: E402

CPT = 4096                                        # encoder counts per motor turn
MASTER = 0x7F                                     # node id of the host's heartbeat
STATE_MASK = 0x6F
SOD, RTSO, SO, OE, QSA, FAULT = 0x40, 0x21, 0x23, 0x27, 0x07, 0x08   # statusword & 0x6F (FAULT: & 0x4F)


@pytest.fixture(scope="module", autouse=True)
def bridge():
    register()
    register()                                    # idempotent
    logging.getLogger("canopen").setLevel(logging.ERROR)
    yield


def host_od() -> odm.ObjectDictionary:
    """The host's own object dictionary of the drive (CiA 301 / CiA 402 indices)."""
    od = odm.ObjectDictionary()

    def var(index, sub, name, dtype, access="rw"):
        v = odm.ODVariable(name, index, sub)
        v.data_type, v.access_type = dtype, access
        return v

    for index, name, dtype in ((0x6040, "Controlword", dt.UNSIGNED16), (0x6041, "Statusword", dt.UNSIGNED16),
                               (0x6060, "Modes of operation", dt.INTEGER8),
                               (0x6061, "Modes of operation display", dt.INTEGER8),
                               (0x607A, "Target position", dt.INTEGER32),
                               (0x6064, "Position actual value", dt.INTEGER32),
                               (0x6062, "Position demand value", dt.INTEGER32),
                               (0x6081, "Profile velocity", dt.UNSIGNED32),
                               (0x6083, "Profile acceleration", dt.UNSIGNED32),
                               (0x6084, "Profile deceleration", dt.UNSIGNED32),
                               (0x6065, "Following error window", dt.UNSIGNED32),
                               (0x6066, "Following error time out", dt.UNSIGNED16),
                               (0x60F4, "Following error actual value", dt.INTEGER32),
                               (0x603F, "Error code", dt.UNSIGNED16),
                               (0x1017, "Producer heartbeat time", dt.UNSIGNED16),
                               (0x2000, "Not there", dt.UNSIGNED16)):
        od.add_object(var(index, 0, name, dtype))
    for index, name, subs in ((0x1016, "Consumer heartbeat time", [(1, "Consumer 1", dt.UNSIGNED32)]),
                              (0x1018, "Identity", [(1, "Vendor-ID", dt.UNSIGNED32)]),
                              (0x607D, "Software position limit", [(1, "Min", dt.INTEGER32), (2, "Max", dt.INTEGER32)]),
                              (0x30D1, "Current actual values", [(2, "Current actual value", dt.INTEGER32)])):
        rec = odm.ODRecord(name, index)
        for sub, sname, dtype in [(0, "Highest sub-index", dt.UNSIGNED8)] + subs:
            rec.add_member(var(index, sub, sname, dtype))
        od.add_object(rec)
    for n in range(2):
        for com, mp in ((0x1400 + n, 0x1600 + n), (0x1800 + n, 0x1A00 + n)):
            rec = odm.ODRecord(f"PDO com {com:X}", com)
            for sub, sname, dtype in ((0, "Highest", dt.UNSIGNED8), (1, "COB-ID", dt.UNSIGNED32),
                                      (2, "Transmission type", dt.UNSIGNED8), (3, "Inhibit", dt.UNSIGNED16),
                                      (5, "Event timer", dt.UNSIGNED16)):
                rec.add_member(var(com, sub, sname, dtype))
            od.add_object(rec)
            rec = odm.ODRecord(f"PDO map {mp:X}", mp)
            for sub in range(9):
                rec.add_member(var(mp, sub, f"Entry {sub}", dt.UNSIGNED8 if sub == 0 else dt.UNSIGNED32))
            od.add_object(rec)
    return od


@contextlib.contextmanager
def connected(proc, *node_ids):
    net = canopen.Network()
    net.NOTIFIER_CYCLE = 0.05
    net.connect(interface="bellows-bridge", channel=proc.channel)
    nodes = [net.add_node(canopen.RemoteNode(n, host_od())) for n in node_ids]
    try:
        yield net, nodes
    finally:
        net.sync.stop()
        net.disconnect()


def drive(node_id, initial, target, max_cps):
    return {"node_id": node_id, "initial_counts": initial, "target_counts": target, "max_counts_per_s": max_cps}


def wait_for(pred, timeout=2.0, what="condition"):
    t0 = time.monotonic()
    while not pred():
        assert time.monotonic() - t0 < timeout, f"timed out waiting for {what}"
        time.sleep(0.005)


def emcy(node, code, timeout=2.0):
    """The first EMCY with ``code`` in the node's log (canopen's ``emcy.wait`` misses one that came already)."""
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        for e in list(node.emcy.log):
            if e.code == code:
                return e
        time.sleep(0.005)
    return None


def sw(node) -> int:
    return node.sdo[0x6041].raw


def enable(node):
    for cw, want in ((0x06, RTSO), (0x07, SO), (0x0F, OE)):
        node.sdo[0x6040].raw = cw
        assert sw(node) & STATE_MASK == want


def map_csp_pdos(node):
    """RPDO 1 = controlword + target, TPDO 1 = statusword + position, both on every SYNC (PRE-OPERATIONAL)."""
    node.nmt.send_command(0x80)
    for pdo, entries in ((node.rpdo[1], (0x6040, 0x607A)), (node.tpdo[1], (0x6041, 0x6064))):
        pdo.clear()
        for index in entries:
            pdo.add_variable(index)
        pdo.cob_id = pdo.predefined_cob_id
        pdo.trans_type = 1
        pdo.enabled = True
        pdo.save()
    node.sdo[0x6060].raw = 8


# --------------------------------------------------------------------------------------------- SDO, NMT
def test_sdo_round_trip_aborts_and_heartbeat():
    with DriveProcess([drive(5, 1234, -77, 1e5)]) as proc, \
            connected(proc, 5) as (net, (node,)):
        assert node.sdo[0x6064].raw == 1234 and proc.positions() == {5: 1234}
        assert node.sdo[0x607A].raw == -77 == proc.od(5, 0x607A)          # the stored (stale) target
        assert node.sdo[0x6081].raw == 1000                                 # stored profile velocity [rpm]
        assert node.sdo[0x1018][1].raw == 0xFB                              # maxon vendor id
        node.sdo[0x6081].raw = 2345
        node.sdo[0x607D][1].raw, node.sdo[0x607D][2].raw = -5000, 90000
        assert node.sdo[0x6081].raw == 2345 == proc.od(5, 0x6081)
        assert (node.sdo[0x607D][1].raw, proc.od(5, 0x607D, 2)) == (-5000, 90000)
        for write, code in ((lambda: setattr(node.sdo[0x6041], "raw", 0), 0x06010002),      # read-only
                            (lambda: setattr(node.sdo[0x2000], "raw", 1), 0x06020000),      # no such object
                            (lambda: setattr(node.sdo[0x6060], "raw", 42), 0x06090030)):    # unsupported mode
            with pytest.raises(SdoAbortedError) as info:
                write()
            assert info.value.code == code
        # a PDO mapping may only change while the PDO is invalid and, on the EPOS4, in PRE-OPERATIONAL
        node.nmt.send_command(0x01)
        wait_for(lambda: proc.nmt_state(5) == "OPERATIONAL")
        with pytest.raises(SdoAbortedError) as info:
            node.sdo[0x1A00][0].raw = 0
        assert info.value.code == 0x08000022
        node.nmt.send_command(0x80)
        node.sdo[0x1800][1].raw = 0x80000185
        node.sdo[0x1A00][0].raw = 0
        with pytest.raises(SdoAbortedError) as info:                       # 0x6065 is not PDO-mappable
            node.sdo[0x1A00][1].raw = 0x60650020
        assert info.value.code == 0x06040041
        node.sdo[0x1A00][1].raw = 0x60410010                                 # the statusword is
        # heartbeat producer 0x1017 (the hub's clock), then a silenced drive
        node.sdo[0x1017].raw = 20
        assert node.nmt.wait_for_heartbeat(1.0) == "PRE-OPERATIONAL"
        proc.silence(5)
        time.sleep(0.1)
        last = node.nmt.timestamp
        time.sleep(0.2)
        assert node.nmt.timestamp == last
        assert node.sdo[0x6064].raw == 1234                                  # SDO still answers


# --------------------------------------------------------------------------------------------- CiA 402 states
def test_power_state_machine_quick_stop_and_fault_reset():
    with DriveProcess([{"node_id": 2, "initial_counts": 0, "target_counts": 0, "max_counts_per_s": 1e5}]) as proc, \
            connected(proc, 2) as (net, (node,)):
        assert sw(node) & STATE_MASK == SOD and proc.state(2) == "SWITCH ON DISABLED"
        node.sdo[0x6040].raw = 0x0F                                         # enable from SWITCH ON DISABLED: no
        assert sw(node) & STATE_MASK == SOD
        node.sdo[0x6040].raw = 0x07                                         # switch on without shutdown: no
        assert sw(node) & STATE_MASK == SOD
        node.sdo[0x6060].raw = 1
        enable(node)
        assert proc.state(2) == "OPERATION ENABLED" and sw(node) & 0x10     # voltage enabled
        node.sdo[0x6040].raw = 0x02                                         # quick stop
        assert sw(node) & STATE_MASK == QSA and proc.state(2) == "QUICK STOP ACTIVE"
        node.sdo[0x6040].raw = 0x06                                         # shutdown is no way out of quick stop
        assert sw(node) & STATE_MASK == QSA
        node.sdo[0x6040].raw = 0x0F                                         # option code 6: enable operation is
        assert sw(node) & STATE_MASK == OE
        node.sdo[0x6040].raw = 0x07                                         # disable operation
        assert sw(node) & STATE_MASK == SO
        node.sdo[0x6040].raw = 0x00                                         # disable voltage
        assert sw(node) & STATE_MASK == SOD
        node.sdo[0x6040].raw = 0x06
        node.sdo[0x6040].raw = 0x0F                                         # READY TO SWITCH ON → enabled (3+4)
        assert sw(node) & STATE_MASK == OE
        node.emcy.reset()
        proc.inject_fault(2, 0x3210)
        err = emcy(node, 0x3210)
        assert err is not None and err.register & 0x01
        assert sw(node) & 0x4F == FAULT and node.sdo[0x603F].raw == 0x3210
        assert any("0x3210" in text for _, text in proc.events(2))
        node.sdo[0x6040].raw = 0x0F                                         # no way out but a fault reset
        assert sw(node) & 0x4F == FAULT
        node.sdo[0x6040].raw = 0x80                                         # rising edge of bit 7
        assert sw(node) & STATE_MASK == SOD and node.sdo[0x603F].raw == 0
        assert emcy(node, 0x0000) is not None              # "error reset" EMCY
        node.sdo[0x6040].raw = 0x80                                         # held high: no edge, nothing happens
        assert sw(node) & STATE_MASK == SOD


# --------------------------------------------------------------------------------------------- profile position
def test_profile_position_moves_at_the_profile_velocity():
    dist = 20480
    with DriveProcess([{"node_id": 1, "initial_counts": 1000, "target_counts": 0, "max_counts_per_s": 5e5},
                       {"node_id": 2, "initial_counts": -3000, "target_counts": 0, "max_counts_per_s": 5e5}],
                      counts_per_turn=CPT) as proc, connected(proc, 1, 2) as (net, nodes):
        n1, n2 = nodes
        n1.sdo[0x6081].raw = 600                                            # rpm; node 2 keeps its stored 1000 rpm
        for n in nodes:
            n.sdo[0x6083].raw = n.sdo[0x6084].raw = 100_000                 # rpm/s
            n.sdo[0x6060].raw = 1
            enable(n)
            assert sw(n) & 0x0400                                           # target reached: nothing to do
        start = {1: 1000, 2: -3000}
        samples = {1: [], 2: []}
        t_go = {}
        for nid, n in zip((1, 2), nodes):
            n.sdo[0x607A].raw = start[nid] + dist
            n.sdo[0x6040].raw = 0x3F                                        # new set-point, change immediately
            t_go[nid] = time.monotonic()
            assert sw(n) & 0x1000                                           # set-point acknowledged
            n.sdo[0x6040].raw = 0x2F
            assert not sw(n) & 0x1000
        done = {}
        while len(done) < 2:
            assert time.monotonic() - min(t_go.values()) < 3.0, "moves did not finish"
            now = time.monotonic()
            pos = proc.positions()
            for nid, n in zip((1, 2), nodes):
                samples[nid].append((now, pos[nid]))
                if nid not in done and sw(n) & 0x0400:
                    done[nid] = time.monotonic() - t_go[nid]
            time.sleep(0.01)
        for nid, rpm in ((1, 600), (2, 1000)):
            v = rpm * CPT / 60.0                                            # counts/s
            a = 100_000 * CPT / 60.0
            mid = [(t, p) for t, p in samples[nid] if 0.2 * dist < p - start[nid] < 0.8 * dist]
            assert len(mid) >= 5
            tm = sum(t for t, _ in mid) / len(mid)
            pm = sum(p for _, p in mid) / len(mid)
            slope = sum((t - tm) * (p - pm) for t, p in mid) / sum((t - tm) ** 2 for t, _ in mid)
            assert slope == pytest.approx(v, rel=0.08), f"node {nid}: {slope:.0f} counts/s, expected {v:.0f}"
            expected = dist / v + v / a                                     # trapezoid, equal acc / dec
            assert expected * 0.95 - 0.01 < done[nid] < expected * 1.1 + 0.06, (nid, done[nid], expected)
            assert proc.positions()[nid] == start[nid] + dist


# --------------------------------------------------------------------------------------------- CSP
def test_csp_the_last_rpdo_before_a_sync_wins():
    with DriveProcess([drive(3, 7000, 7000, 1e6)]) as proc, \
            connected(proc, 3) as (net, (node,)):
        map_csp_pdos(node)
        enable(node)
        node.nmt.send_command(0x01)
        wait_for(lambda: proc.nmt_state(3) == "OPERATIONAL")
        rp = node.rpdo[1]
        net.sync.transmit()                                                  # SYNC 1: nothing new
        wait_for(lambda: len(proc.records(3)) == 1, what="first record")
        rp["Controlword"].raw = 0x0F
        rp["Target position"].raw = 7100
        rp.transmit()
        rp["Target position"].raw = 7350
        rp.transmit()
        time.sleep(0.05)
        assert proc.od(3, 0x6062) == 7000                                    # synchronous RPDO: waits for the SYNC
        net.sync.transmit()                                                  # SYNC 2
        wait_for(lambda: len(proc.records(3)) == 2, what="second record")
        first, second = proc.records(3)
        assert first["step"] == 0 and first["rpdos"] == 0 and first["demand"] == 7000
        assert second["demand"] == 7350 and second["step"] == 350 and second["rpdos"] == 2
        assert second["state"] == "OPERATION ENABLED" and proc.max_step(3) == 350
        # TPDO 1 answered the SYNC with the statusword and the position
        wait_for(lambda: node.tpdo[1].timestamp is not None, what="TPDO 1")
        assert node.tpdo[1]["Statusword"].raw & STATE_MASK == OE
        wait_for(lambda: proc.positions()[3] == 7350, what="motor at the demand")
        # software position limits 0x607D: a demand outside is clamped (statusword bit 11, an event)
        node.sdo[0x607D][1].raw, node.sdo[0x607D][2].raw = 0, 8000
        rp["Target position"].raw = 9000
        rp.transmit()
        net.sync.transmit()
        wait_for(lambda: len(proc.records(3)) == 3, what="third record")
        assert proc.records(3)[-1]["demand"] == 8000 == proc.od(3, 0x6062)
        assert sw(node) & 0x0800
        assert any("software position limit" in text for _, text in proc.events(3))


def test_a_stale_target_makes_the_motor_jump_when_enabled_in_csp():
    drives = [{"node_id": 1, "initial_counts": 50_000, "target_counts": 0, "max_counts_per_s": 2e5},
              {"node_id": 2, "initial_counts": 50_000, "target_counts": 0, "max_counts_per_s": 2e5}]
    with DriveProcess(drives) as proc, connected(proc, 1, 2) as (net, (stale, fresh)):
        for n in (stale, fresh):
            map_csp_pdos(n)
        fresh.sdo[0x607A].raw = fresh.sdo[0x6064].raw                       # the safe order: target := actual first
        enable(stale)                                                         # 0x607A still holds its power-on 0
        enable(fresh)
        for n in (stale, fresh):
            n.nmt.send_command(0x01)
        net.sync.start(0.002)
        wait_for(lambda: len(proc.records(1)) > 20 and len(proc.records(2)) > 20, what="SYNC records")
        assert proc.max_step(1) == 50_000 and proc.max_step(2) == 0
        jump = [r for r in proc.records(1) if r["step"]]
        assert jump[0]["demand"] == 0 and jump[0]["step"] == -50_000
        assert any("jumps" in text for _, text in proc.events(1))
        pos = proc.positions()
        assert pos[1] < 50_000 - 1000 and pos[2] == 50_000                   # node 1 runs at its speed limit


# --------------------------------------------------------------------------------------------- faults
def test_consumer_heartbeat_loss_faults_and_stops_the_drive():
    with DriveProcess([{"node_id": 4, "initial_counts": 0, "target_counts": 0, "max_counts_per_s": 1e5}]) as proc, \
            connected(proc, 4) as (net, (node,)):
        node.sdo[0x1016][1].raw = (MASTER << 16) | 100                       # producer 0x7F, 100 ms
        node.sdo[0x6060].raw = 1
        enable(node)
        time.sleep(0.25)                                                     # no heartbeat seen yet: not monitored
        assert proc.state(4) == "OPERATION ENABLED"
        beat = net.send_periodic(0x700 + MASTER, [0x05], 0.02)               # the host's heartbeat (hub-produced)
        time.sleep(0.3)
        assert proc.state(4) == "OPERATION ENABLED"
        node.sdo[0x607A].raw = 40_000
        node.sdo[0x6040].raw = 0x3F
        node.sdo[0x6040].raw = 0x2F
        node.emcy.reset()
        beat.stop()
        t_stop = time.time()
        err = emcy(node, 0x8130)
        assert err is not None, "no heartbeat-error EMCY"
        assert 0.075 < err.timestamp - t_stop < 0.25                         # 100 ms after the last beat
        assert proc.state(4) == "FAULT" and node.sdo[0x603F].raw == 0x8130
        assert any("heartbeat" in text for _, text in proc.events(4))
        p = proc.positions()[4]
        time.sleep(0.05)
        assert proc.positions()[4] == p and 0 < p < 40_000                   # stopped mid-move


def test_following_error_window_faults_the_drive():
    with DriveProcess([drive(6, 1000, 1000, 20_000)]) as proc, \
            connected(proc, 6) as (net, (node,)):
        map_csp_pdos(node)
        node.sdo[0x6065].raw = 1000                                          # counts
        node.sdo[0x6066].raw = 20                                            # ms
        enable(node)
        node.nmt.send_command(0x01)
        net.sync.start(0.002)
        node.sdo[0x607A].raw = 1500                                          # inside the window: fine
        time.sleep(0.1)
        assert proc.state(6) == "OPERATION ENABLED" and proc.positions()[6] == 1500
        node.emcy.reset()
        node.sdo[0x607A].raw = 6500                                          # 5000 counts at 20000 counts/s: lags
        err = emcy(node, 0x8611)
        assert err is not None, "no following-error EMCY"
        status = sw(node)
        assert status & 0x4F == FAULT and status & 0x2000                    # fault + following error bit
        assert node.sdo[0x603F].raw == 0x8611
        text = [t for _, t in proc.events(6) if "following error" in t]
        assert text and "0x8611" in text[0]
        p = proc.positions()[6]
        assert 1500 < p < 6500 - 1000 and proc.od(6, 0x6062) == p           # demand frozen at the actual position
        time.sleep(0.05)
        assert proc.positions()[6] == p


# --------------------------------------------------------------------------------------------- the hub's clock
def test_sync_keeps_ticking_while_the_host_holds_the_gil():
    period = 0.002
    with DriveProcess([{"node_id": 7, "initial_counts": 0, "target_counts": 0, "max_counts_per_s": 1e5}]) as proc, \
            connected(proc, 7) as (net, (node,)):
        map_csp_pdos(node)
        enable(node)
        node.nmt.send_command(0x01)
        net.sync.start(period)
        host_rx = []                                                         # (arrival, SYNC timestamp) at the host
        net.subscribe(0x80, lambda cob, data, ts: host_rx.append((time.time(), ts)))
        wait_for(lambda: len(proc.records(7)) > 10, what="SYNC records")
        host_gaps = []

        def watch():                                                         # a host thread that wants to run every ms
            last = time.perf_counter()
            end = last + 0.5
            while last < end:
                time.sleep(0.001)
                now = time.perf_counter()
                host_gaps.append(now - last)
                last = now

        def hog(seconds):                                                    # pure Python: keeps the GIL
            end = time.perf_counter() + seconds
            while time.perf_counter() < end:
                pass

        watcher = threading.Thread(target=watch)
        old = sys.getswitchinterval()
        watcher.start()
        time.sleep(0.1)
        sys.setswitchinterval(0.5)
        try:
            t0 = time.time()
            h = threading.Thread(target=hog, args=(0.2,))
            h.start()
            h.join()
            t1 = time.time()
        finally:
            sys.setswitchinterval(old)
        watcher.join()
        assert max(host_gaps) > 0.15, f"the host was not stalled ({max(host_gaps) * 1e3:.0f} ms)"
        times = [r["t"] for r in proc.records(7) if t0 <= r["t"] <= t1]
        # the hub kept its clock (a loaded 2-core machine delays some ticks, but nothing like the stall) ...
        assert len(times) >= 0.4 * (t1 - t0) / period, f"{len(times)} SYNCs in {1e3 * (t1 - t0):.0f} ms"
        gaps = [b - a for a, b in zip([t0] + times, times + [t1])]
        assert max(gaps) < 0.1, f"SYNC gap {1e3 * max(gaps):.0f} ms while the host was stalled"
        # ... while the host itself only saw those SYNCs when it ran again
        late = [rx - ts for rx, ts in host_rx if t0 <= ts <= t1]
        assert late and max(late) > 0.1
        # a lost SYNC: the producer pauses (then resumes on its grid), the drive sees the gap
        n0, t2 = proc.syncs(), time.time()
        proc.pause_sync(0.15)
        time.sleep(0.3)
        assert proc.hub_stats()["paused"] >= 0.5 * 0.15 / period
        assert proc.syncs() - n0 < 0.3 / period
        ts = [r["t"] for r in proc.records(7) if r["t"] >= t2 - 0.05]
        assert max(b - a for a, b in zip(ts, ts[1:])) >= 0.14
        assert ts[-1] > t2 + 0.2                                             # ticking again

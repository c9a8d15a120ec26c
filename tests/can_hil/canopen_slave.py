"""A CiA 402 servo drive built on the `canopen` package's LocalNode, written from the CiA 301 and CiA
402 texts (not from iotad's simulated drive), for the tests that put iotad's master against a
CANopen stack other than its own: `python canopen_slave.py NODE_ID EDS` on the bus of the
environment (IOTAD_CAN_INTERFACE / IOTAD_CAN_CHANNEL), until SIGTERM.

What is `canopen`'s (the other stack): NMT slave (commands, boot-up, heartbeat producer from
0x1017), SDO server (expedited and segmented, aborts), EMCY producer, the object dictionary.
What is written here from the standards:
- CiA 402's device control: the state machine driven by controlword 0x6040 (by SDO or RPDO),
  statusword 0x6041 as the standard's table sets it, fault reset on bit 7's rising edge;
- CiA 301 PDOs by their communication and mapping parameters as the master wrote them: RPDO1
  taken at the next SYNC (transmission type 0..240) or at once (254/255), TPDO1/TPDO2 at every n-th
  SYNC; PDOs only in OPERATIONAL;
- the heartbeat consumer 0x1016.1 and the error behaviour 0x1029.1 (0: OPERATIONAL ->
  PRE-OPERATIONAL) on a heartbeat event, with EMCY 0x8130 and the fault reaction;
- a motor that follows its target at once (position actual = the target taken at SYNC).
`SIGUSR1` makes it fault (EMCY 0x2310, over-current) for the tests of clear-errors.
"""
from __future__ import annotations

import os
import signal
import sys
import threading
import time

import canopen

SOD, RTSO, SO, OE, QSA, FRA, FAULT = (0x0040, 0x0021, 0x0023, 0x0027, 0x0007, 0x000F, 0x0008)
VOLTAGE, REMOTE = 0x0010, 0x0200


class Cia402Slave:
    def __init__(self, network: canopen.Network, node_id: int, eds: str):
        self.node = canopen.LocalNode(node_id, eds)
        self.id = node_id
        network.add_node(self.node)
        self.network = network
        self.lock = threading.RLock()
        self.state = SOD
        self.controlword = 0
        self.position = 0
        self.target = 0
        self.latched: bytes | None = None
        self.syncs = 0
        self.master_heard: float | None = None
        self.node.add_write_callback(self.on_write)
        self.node.add_read_callback(self.on_read)
        network.subscribe(0x080, self.on_sync)
        network.subscribe(0x200 + node_id, self.on_rpdo)
        for master in range(1, 128):  # the consumer watches the node id 0x1016 names (read when heard)
            network.subscribe(0x700 + master, self.on_heartbeat)
        self.node.nmt.state = "RESET"            # INITIALISING: canopen sends the boot-up message
        self.node.nmt.state = "PRE-OPERATIONAL"  # then its heartbeat producer runs (0x1017)

    # ---- object dictionary hooks
    def u(self, index: int, sub: int = 0) -> int:
        return int.from_bytes(self.node.get_data(index, sub), "little")

    def on_read(self, index, subindex, od):
        if index == 0x6041:
            return self.statusword()
        if index == 0x6064:
            return self.position
        if index in (0x6077, 0x606C):
            return 0
        if index == 0x6061:
            return self.u(0x6060)
        return None

    def on_write(self, index, subindex, od, data):
        if index == 0x6040:
            self.control(int.from_bytes(data, "little"))

    def statusword(self) -> int:
        word = self.state | REMOTE
        if self.state in (SO, OE, QSA, FRA):
            word |= VOLTAGE
        return word

    # ---- CiA 402 device control (the standard's state machine, transitions 2-12 and 15-16)
    def control(self, word: int) -> None:
        with self.lock:
            previous, self.controlword = self.controlword, word
            if self.state == FAULT:
                if word & 0x80 and not previous & 0x80:
                    self.state = SOD  # transition 15
                    self.node.set_data(0x603F, 0, b"\0\0")
                    self.node.set_data(0x1001, 0, b"\0")
                    self.node.emcy.reset()
                return
            if word & 0x80:
                return
            shutdown, switch_on = word & 0x87 == 0x06, word & 0x8F == 0x07
            enable, quick_stop, disable_voltage = word & 0x8F == 0x0F, word & 0x86 == 0x02, not word & 0x02
            if self.state == SOD and shutdown:
                self.state = RTSO                                      # 2
            elif self.state == RTSO:
                if switch_on or enable:
                    self.state = OE if enable else SO                  # 3 (+4)
                elif disable_voltage or quick_stop:
                    self.state = SOD                                   # 7
            elif self.state == SO:
                if enable:
                    self.state = OE                                    # 4
                elif shutdown:
                    self.state = RTSO                                  # 6
                elif disable_voltage or quick_stop:
                    self.state = SOD                                   # 10
            elif self.state == OE:
                if switch_on:
                    self.state = SO                                    # 5
                elif shutdown:
                    self.state = RTSO                                  # 8
                elif disable_voltage:
                    self.state = SOD                                   # 9
                elif quick_stop:
                    self.state = SOD                                   # 11 then 12 (option code 2)
            if self.state == OE and previous & 0x0F != 0x0F:
                self.target = self.position  # enabled where it stands

    def fault(self, code: int) -> None:
        with self.lock:
            if self.state != FAULT:
                self.state = FAULT  # fault reaction (13), done at once: the motor is still (14)
                self.node.set_data(0x603F, 0, code.to_bytes(2, "little"))  # CiA 402: the error code
                self.node.set_data(0x1001, 0, b"\x01")                     # CiA 301: the error register
                self.node.emcy.send(code, 0x01)

    # ---- PDOs and SYNC (CiA 301)
    def mapping(self, index: int) -> list[tuple[int, int, int]]:
        return [(w >> 16, (w >> 8) & 0xFF, w & 0xFF) for w in (self.u(index, k) for k in range(1, self.u(index, 0) + 1))]

    def on_rpdo(self, can_id, data, timestamp):
        if self.node.nmt.state != "OPERATIONAL" or self.u(0x1400, 1) & 0x80000000:
            return
        if self.u(0x1400, 2) <= 240:
            self.latched = bytes(data)
        else:
            self.apply(bytes(data))

    def apply(self, data: bytes) -> None:
        entries = self.mapping(0x1600)
        if sum(bits for _, _, bits in entries) // 8 != len(data):
            self.node.emcy.send(0x8210, 0x11)  # PDO not processed: length error
            return
        at = 0
        for index, sub, bits in entries:
            chunk = data[at:at + bits // 8]
            at += bits // 8
            if index == 0x607A:
                self.target = int.from_bytes(chunk, "little", signed=True)
            self.node.set_data(index, sub, chunk)

    def on_sync(self, can_id, data, timestamp):
        if self.node.nmt.state != "OPERATIONAL":
            return
        with self.lock:
            self.syncs += 1
            if self.latched is not None:
                data, self.latched = self.latched, None
                self.apply(data)
            if self.state == OE:
                self.position = self.target
            for comm in (0x1800, 0x1801):
                cob, kind = self.u(comm, 1), self.u(comm, 2)
                if not cob & 0x80000000 and 1 <= kind <= 240 and self.syncs % kind == 0:
                    payload = b"".join(self.node.get_data(i, s)[:bits // 8] for i, s, bits in self.mapping(comm + 0x200))
                    self.network.send_message(cob & 0x7FF, payload)

    # ---- heartbeat consumer (0x1016) and error behaviour (0x1029)
    def on_heartbeat(self, can_id, data, timestamp):
        if (self.u(0x1016, 1) >> 16) & 0x7F == can_id - 0x700:
            self.master_heard = time.monotonic()

    def watch(self, stop: threading.Event) -> None:
        while not stop.wait(0.005):
            consumer = self.u(0x1016, 1)
            timeout = (consumer & 0xFFFF) / 1000.0
            heard = self.master_heard
            if timeout and heard is not None and time.monotonic() - heard > timeout:
                self.master_heard = None
                self.fault(0x8130)
                if self.u(0x1029, 1) == 0 and self.node.nmt.state == "OPERATIONAL":
                    self.node.nmt.state = "PRE-OPERATIONAL"


def main() -> int:
    node_id, eds = int(sys.argv[1]), sys.argv[2]
    interface, channel = os.environ["IOTAD_CAN_INTERFACE"], os.environ["IOTAD_CAN_CHANNEL"]
    extra = {"port": 43113, "hop_limit": 1, "fd": False} if interface == "udp_multicast" else {}
    network = canopen.Network()
    network.connect(interface=interface, channel=channel, **extra)
    slave = Cia402Slave(network, node_id, eds)
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    signal.signal(signal.SIGUSR1, lambda *_: slave.fault(0x2310))
    print("slave ready", flush=True)
    try:
        slave.watch(stop)
    finally:
        network.disconnect()
    return 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python3
"""plcd's remote I/O client (`[[remote]]`, docs/REMOTE.md) against Modbus servers nobody here
wrote: pymodbus TCP and RTU servers, reached directly, through tests/remote/faulty_proxy.py
(which breaks answers on demand), and over socat pty pairs for the serial lines. Started by
tests/remote/run-pymodbus-remote, which makes the venv and builds plcd and plcctl.

The peers, in this process or beside it:

    rack      tcp, direct   pymodbus server A, unit 1: all four tables both ways, swaps
    px_clear  tcp, proxied  pymodbus server B, unit 1, through the TCP fault proxy
    px_hold   tcp, proxied  the same, on_loss = "hold"
    rtu3      rtu, line A   pymodbus serial server C, unit 3 } one port, polled in turn
    rtu4      rtu, line A   the same server, unit 4          }
    rtu5      rtu, line B   pymodbus serial server D, unit 5, through the RTU fault proxy:
                            plcd <-> pty pair <-> proxy <-> pty pair <-> pymodbus

Prints `PASS  name` or `FAIL  name: detail` per check and `N passed, M failed`; exits 1
unless every check passed. Every wait is a poll until a condition or a deadline; nothing
asserts how fast anything was.
"""

import argparse
import asyncio
import json
import logging
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time

from pymodbus import FramerType
from pymodbus.server import ModbusSerialServer, ModbusTcpServer
from pymodbus.simulator import DataType, SimData, SimDevice

HERE = os.path.dirname(os.path.abspath(__file__))
PATIENCE = 10.0
POLL = 0.05
passed = 0
failed = []

# Function codes that select pymodbus's datastore blocks.
COILS, DISCRETE, HOLDING, INPUT = 1, 2, 3, 4


def check(name, ok, detail=""):
    global passed
    if ok:
        passed += 1
        print(f"PASS  {name}", flush=True)
    else:
        failed.append(name)
        print(f"FAIL  {name}: {detail}", flush=True)
    return ok


def wait_for(probe, patience=PATIENCE):
    """Polls `probe` every 50 ms until it returns something true or the deadline passes;
    returns its last result (a probe that raises counts as false)."""
    until = time.monotonic() + patience
    while True:
        try:
            result = probe()
        except Exception:  # noqa: BLE001 - a probe may fail while waiting
            result = None
        if result or time.monotonic() >= until:
            return result
        time.sleep(POLL)


# --- The pymodbus servers, on an event loop thread of this process ---------------------------


def sim_device(unit):
    """A device with 64 of each table, all zero (coils and discrete inputs bit-addressed)."""
    return SimDevice(
        id=unit,
        simdata=(
            [SimData(0, values=[False] * 64, datatype=DataType.BITS)],
            [SimData(0, values=[False] * 64, datatype=DataType.BITS)],
            [SimData(0, count=64, values=0, datatype=DataType.REGISTERS)],
            [SimData(0, count=64, values=0, datatype=DataType.REGISTERS)],
        ),
    )


class Peers:
    """The pymodbus servers' event loop, and their datastores read and written from the test
    (in the servers' own process, as a device's own logic would)."""

    def __init__(self):
        self.loop = asyncio.new_event_loop()
        threading.Thread(target=self.loop.run_forever, daemon=True).start()
        self.servers = []

    def call(self, coro):
        return asyncio.run_coroutine_threadsafe(coro, self.loop).result(timeout=PATIENCE)

    def tcp(self, units, port=0):
        async def start():
            server = ModbusTcpServer([sim_device(u) for u in units], address=("127.0.0.1", port))
            await server.serve_forever(background=True)
            return server

        server = self.call(start())
        server.port = server.transport.sockets[0].getsockname()[1]
        self.servers.append(server)
        return server

    def serial(self, units, port):
        async def start():
            server = ModbusSerialServer(
                [sim_device(u) for u in units],
                framer=FramerType.RTU,
                port=port,
                baudrate=115200,
                parity="N",
                stopbits=1,
            )
            await server.serve_forever(background=True)
            return server

        server = self.call(start())
        self.servers.append(server)
        return server

    def stop(self, server):
        self.call(server.shutdown())
        self.servers.remove(server)

    def set(self, server, unit, table, address, values):
        error = self.call(server.context.async_setValues(unit, table, address, list(values)))
        assert error is None, f"datastore write refused: {error}"

    def get(self, server, unit, table, address, count=1):
        values = self.call(server.context.async_getValues(unit, table, address, count))
        assert isinstance(values, list), f"datastore read refused: {values}"
        return [int(v) for v in values]

    def close(self):
        for server in list(self.servers):
            try:
                self.stop(server)
            except Exception:  # noqa: BLE001 - closing what is left
                pass
        self.loop.call_soon_threadsafe(self.loop.stop)


# --- socat pty pairs and the fault proxies -----------------------------------------------------


class PtyPair:
    """`socat pty,raw,echo=0,link=A pty,raw,echo=0,link=B`: two ends of a virtual serial
    line."""

    def __init__(self, directory, name):
        self.a = os.path.join(directory, f"{name}-a")
        self.b = os.path.join(directory, f"{name}-b")
        self.proc = subprocess.Popen(
            ["socat", "-d", "-d", f"pty,raw,echo=0,link={self.a}", f"pty,raw,echo=0,link={self.b}"],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
        )
        if not wait_for(lambda: os.path.exists(self.a) and os.path.exists(self.b)):
            self.stop()
            sys.exit(f"socat made no pty pair: {self.proc.stderr.read()}")

    def stop(self):
        if self.proc.poll() is None:
            self.proc.terminate()
        try:
            self.proc.wait(timeout=PATIENCE)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()


class Proxy:
    """tests/remote/faulty_proxy.py in a process of its own, switched over its control
    socket."""

    def __init__(self, directory, name, args):
        self.control = os.path.join(directory, f"{name}.sock")
        self.proc = subprocess.Popen(
            [sys.executable, os.path.join(HERE, "faulty_proxy.py"), *args, "--control", self.control],
            stdout=subprocess.PIPE,
            text=True,
        )
        self.first_line = self.proc.stdout.readline().strip()
        if not self.first_line.startswith("faulty_proxy: "):
            self.stop()
            sys.exit(f"faulty_proxy did not start: {self.first_line!r}")
        self.port = int(self.first_line.rsplit(":", 1)[1]) if "listening" in self.first_line else None

    def command(self, line):
        with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
            s.settimeout(PATIENCE)
            s.connect(self.control)
            s.sendall(line.encode() + b"\n")
            answer = b""
            while not answer.endswith(b"\n"):
                chunk = s.recv(4096)
                if not chunk:
                    break
                answer += chunk
        return answer.decode().strip()

    def mode(self, name, arg=None):
        answer = self.command(f"mode {name}" + (f" {arg}" if arg is not None else ""))
        assert answer == "ok", f"faulty_proxy: {answer}"

    def stats(self):
        return json.loads(self.command("stats"))

    def stop(self):
        if self.proc.poll() is None:
            self.proc.terminate()
        try:
            self.proc.wait(timeout=PATIENCE)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()


# --- plcd and plcctl -------------------------------------------------------------------------


class Daemon:
    """`plcd run` on the generated project, its log collected from stderr."""

    def __init__(self, plcd, plcctl, config):
        self.plcctl_path = plcctl
        self.socket = os.path.join(os.path.dirname(config), "plcd.sock")
        self.log = []
        self.proc = subprocess.Popen(
            [plcd, "run", "--config", config],
            stderr=subprocess.PIPE,
            stdout=subprocess.DEVNULL,
            text=True,
            env={
                k: v
                for k, v in os.environ.items()
                if k not in ("NOTIFY_SOCKET", "WATCHDOG_USEC", "JOURNAL_STREAM", "PLCD_SOCKET")
            },
        )
        threading.Thread(target=self._read_log, daemon=True).start()
        if not wait_for(lambda: self.alive() and self.status()):
            code = self.stop()
            sys.exit(f"plcd did not start (exit {code}):\n" + "\n".join(self.log))

    def _read_log(self):
        for line in self.proc.stderr:
            self.log.append(line.rstrip("\n"))

    def alive(self):
        return self.proc.poll() is None

    def plcctl(self, *args):
        out = subprocess.run(
            [self.plcctl_path, "--socket", self.socket, "--json", *args],
            capture_output=True,
            text=True,
            timeout=PATIENCE,
        )
        if out.returncode != 0:
            raise RuntimeError(f"plcctl {' '.join(args)}: exit {out.returncode}: {out.stdout}{out.stderr}")
        return json.loads(out.stdout)

    def status(self):
        return self.plcctl("status")

    def remotes(self):
        """Each remote's figures by name, its `faults` as a dict."""
        figures = {}
        for remote in self.status().get("remotes", []):
            remote = dict(remote)
            remote["faults"] = {kind: n for kind, n in remote.get("faults", [])}
            figures[remote["name"]] = remote
        return figures

    def get(self, *names):
        """Device values by name; words as unsigned 16-bit numbers."""
        answer = self.plcctl("get", *names)
        return {v["dev"]: int(v["value"]) & 0xFFFF for v in answer["values"]}

    def set(self, *writes):
        return self.plcctl("set", *writes)

    def stop(self):
        if self.alive():
            self.proc.send_signal(signal.SIGTERM)
        try:
            return self.proc.wait(timeout=PATIENCE)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            return self.proc.wait()


# --- The project ---------------------------------------------------------------------------

PROGRAM = """\
; tests/remote: remote inputs to remote outputs, through the program.
LOAD _ON                ; the moves run at every scan
MOV D00100 D00200       ; rack holding register 10 -> rack holding register 0
MOV D00110 D00201       ; rack input register 0 -> rack holding register 1
DMOV D00120 D00210      ; rack input registers 4-5 (32 bits) -> rack holding registers 20-21
MOV D00400 D00420       ; rtu3 holding register 0 -> rtu4 holding register 20
MOV D00431 D00421       ; rtu4 holding register 1 -> rtu4 holding register 21
LOAD P0100              ; rack discrete input 0 -> rack coil 0
OUT P0140
LOAD P0101              ; rack discrete input 1 -> rack coil 1
OUT P0141
LOAD M0200              ; rack coil 16 (read back) -> rack coil 2
OUT P0142
LOAD M0300              ; rtu4 discrete input 0 -> rtu3 coil 0
OUT M0320
END
"""


def project(directory, rack_port, proxy_port, line_a, line_b):
    fast_tcp = """\
period_ms = 25
timeout_ms = 150
loss_after = 1
reconnect_ms = 20
reconnect_max_ms = 160"""
    rtu_line = """\
baud = 115200
parity = "none"
stop_bits = 1"""
    config = f"""\
# Generated by tests/remote/check_remote.py.
[plc]
scan_period_ms = 2

[rt]
policy = "other"
lock_memory = false

[control]
socket = "plcd.sock"

[[program]]
file = "main.il"

[[remote]]
name = "rack"
transport = "tcp"
address = "127.0.0.1:{rack_port}"
unit_id = 1
{fast_tcp}
status = "M0100"

[[remote.read]]
table = "discrete_inputs"
address = 0
count = 16
device = "P0100"

[[remote.read]]
table = "coils"
address = 16
count = 16
device = "M0200"

[[remote.read]]
table = "holding_registers"
address = 10
count = 4
device = "D00100"

[[remote.read]]
table = "holding_registers"
address = 14
count = 1
device = "D00104"
swap_bytes = true

[[remote.read]]
table = "input_registers"
address = 0
count = 4
device = "D00110"

[[remote.read]]
table = "input_registers"
address = 4
count = 2
device = "D00120"
swap_words = true

[[remote.write]]
table = "coils"
address = 0
count = 16
device = "P0140"

[[remote.write]]
table = "holding_registers"
address = 0
count = 4
device = "D00200"

[[remote.write]]
table = "holding_registers"
address = 20
count = 2
device = "D00210"
swap_words = true

[[remote]]
name = "px_clear"
transport = "tcp"
address = "127.0.0.1:{proxy_port}"
{fast_tcp}
on_loss = "clear"
status = "M0101"

[[remote.read]]
table = "holding_registers"
address = 0
count = 2
device = "D00300"

[[remote.read]]
table = "discrete_inputs"
address = 0
count = 8
device = "P0200"

[[remote]]
name = "px_hold"
transport = "tcp"
address = "127.0.0.1:{proxy_port}"
{fast_tcp}
on_loss = "hold"
status = "M0102"

[[remote.read]]
table = "holding_registers"
address = 0
count = 2
device = "D00310"

[[remote.read]]
table = "discrete_inputs"
address = 0
count = 8
device = "P0210"

[[remote]]
name = "rtu3"
transport = "rtu"
port = "{line_a}"
{rtu_line}
unit_id = 3
period_ms = 25
timeout_ms = 150
status = "M0103"

[[remote.read]]
table = "holding_registers"
address = 0
count = 2
device = "D00400"

[[remote.write]]
table = "coils"
address = 0
count = 8
device = "M0320"

[[remote]]
name = "rtu4"
transport = "rtu"
port = "{line_a}"
{rtu_line}
unit_id = 4
period_ms = 25
timeout_ms = 150
status = "M0104"

[[remote.read]]
table = "discrete_inputs"
address = 0
count = 8
device = "M0300"

[[remote.read]]
table = "holding_registers"
address = 0
count = 2
device = "D00430"

[[remote.write]]
table = "holding_registers"
address = 20
count = 2
device = "D00420"

[[remote]]
name = "rtu5"
transport = "rtu"
port = "{line_b}"
{rtu_line}
unit_id = 5
period_ms = 25
timeout_ms = 100
loss_after = 1
# Longer than the late answers' delay, so that a late answer is always on the line before the
# next request (and dropped as late), never inside the next exchange.
reconnect_ms = 300
reconnect_max_ms = 300
on_loss = "clear"
status = "M0105"

[[remote.read]]
table = "holding_registers"
address = 0
count = 2
device = "D00500"

[[remote.read]]
table = "discrete_inputs"
address = 0
count = 8
device = "P0300"
"""
    with open(os.path.join(directory, "plcd.toml"), "w") as f:
        f.write(config)
    with open(os.path.join(directory, "main.il"), "w") as f:
        f.write(PROGRAM)
    return os.path.join(directory, "plcd.toml")


# --- The checks ----------------------------------------------------------------------------


def equal_within(what, probe, expected):
    """Waits until probe() == expected; the check passes if it came to that."""
    got = [None]

    def probe_equal():
        got[0] = probe()
        return got[0] == expected

    if not wait_for(probe_equal):
        try:
            got[0] = probe()
        except Exception as e:  # noqa: BLE001
            got[0] = e
    return check(what, got[0] == expected, f"expected {expected!r}, got {got[0]!r}")


def states(daemon, names):
    figures = daemon.remotes()
    return {name: figures[name]["state"] for name in names}


def all_online(daemon, names):
    return wait_for(lambda: all(s == "online" for s in states(daemon, names).values()))


def tcp_values(t):
    d, peers, a = t.daemon, t.peers, t.server_a
    print("-- Modbus TCP: values both ways (rack, pymodbus server A)", flush=True)
    peers.set(a, 1, DISCRETE, 0, [True, False])
    equal_within("tcp: a discrete input set in pymodbus reaches P0100", lambda: d.get("P0100", "P0101"), {"P0100": 1, "P0101": 0})
    equal_within(
        "tcp: the program's output P0140 reaches pymodbus coil 0 (FC 15)",
        lambda: peers.get(a, 1, COILS, 0, 3),
        [1, 0, 0],
    )
    peers.set(a, 1, COILS, 16, [True])
    equal_within("tcp: a coil read back (coil 16) reaches M0200 (FC 1)", lambda: d.get("M0200")["M0200"], 1)
    equal_within("tcp: ... and through the program coil 2", lambda: peers.get(a, 1, COILS, 2), [1])
    peers.set(a, 1, HOLDING, 10, [12345, 1, 2, 3, 0x1234])
    equal_within(
        "tcp: holding registers 10-13 reach D00100-D00103 (FC 3)",
        lambda: [d.get(f"D0010{k}")[f"D0010{k}"] for k in range(4)],
        [12345, 1, 2, 3],
    )
    equal_within("tcp: swap_bytes: holding register 14 = 0x1234 reads as 0x3412", lambda: d.get("D00104")["D00104"], 0x3412)
    equal_within(
        "tcp: the program's D00200 reaches holding register 0 (FC 16)",
        lambda: peers.get(a, 1, HOLDING, 0),
        [12345],
    )
    peers.set(a, 1, INPUT, 0, [54321, 7, 8, 9, 0x1234, 0x5678])
    equal_within(
        "tcp: input registers 0-3 reach D00110-D00113 (FC 4)",
        lambda: [v for _, v in sorted(d.get("D00110", "D00111", "D00112", "D00113").items())],
        [54321, 7, 8, 9],
    )
    equal_within("tcp: ... and through the program holding register 1", lambda: peers.get(a, 1, HOLDING, 1), [54321])
    equal_within(
        "tcp: swap_words read: 0x12345678 high word first on the wire is D00120=0x5678 D00121=0x1234",
        lambda: d.get("D00120", "D00121"),
        {"D00120": 0x5678, "D00121": 0x1234},
    )
    equal_within(
        "tcp: swap_words write: DMOV to D00210 goes out high word first (HR 20=0x1234, 21=0x5678)",
        lambda: peers.get(a, 1, HOLDING, 20, 2),
        [0x1234, 0x5678],
    )
    d.set("D00202=777", "D00203=hFFFE")
    equal_within(
        "tcp: plcctl set D00202 D00203 reaches holding registers 2-3",
        lambda: peers.get(a, 1, HOLDING, 2, 2),
        [777, 0xFFFE],
    )
    peers.set(a, 1, DISCRETE, 0, [False, True])
    equal_within("tcp: a discrete input cleared in pymodbus clears P0100", lambda: d.get("P0100", "P0101"), {"P0100": 0, "P0101": 1})
    equal_within("tcp: ... and coils 0-1 follow", lambda: peers.get(a, 1, COILS, 0, 2), [0, 1])
    rack = d.remotes()["rack"]
    check("tcp: rack is online, status bit M0100 ON", rack["state"] == "online" and d.get("M0100")["M0100"] == 1, rack)
    check("tcp: rack wrote (writes > 0) and never failed", rack["writes"] > 0 and rack["failures"] == 0, rack)


def rtu_values(t):
    d, peers, c = t.daemon, t.peers, t.server_c
    print("-- Modbus RTU: two units on one line (rtu3, rtu4, pymodbus serial server C)", flush=True)
    peers.set(c, 3, HOLDING, 0, [3001, 3002])
    peers.set(c, 4, HOLDING, 0, [4001, 4002])
    equal_within(
        "rtu: unit 3's holding registers reach D00400-D00401, unit 4's D00430-D00431",
        lambda: d.get("D00400", "D00401", "D00430", "D00431"),
        {"D00400": 3001, "D00401": 3002, "D00430": 4001, "D00431": 4002},
    )
    equal_within(
        "rtu: through the program to unit 4's holding registers 20-21 (FC 16)",
        lambda: peers.get(c, 4, HOLDING, 20, 2),
        [3001, 4002],
    )
    check("rtu: unit 3's holding registers 20-21 untouched", peers.get(c, 3, HOLDING, 20, 2) == [0, 0], peers.get(c, 3, HOLDING, 20, 2))
    peers.set(c, 4, DISCRETE, 0, [True])
    equal_within("rtu: unit 4's discrete input 0 reaches M0300 (FC 2)", lambda: d.get("M0300")["M0300"], 1)
    equal_within("rtu: ... and through the program unit 3's coil 0 (FC 15)", lambda: peers.get(c, 3, COILS, 0, 2), [1, 0])
    check("rtu: unit 4's coil 0 untouched", peers.get(c, 4, COILS, 0) == [0], peers.get(c, 4, COILS, 0))
    peers.set(c, 4, DISCRETE, 0, [False])
    equal_within("rtu: ... and cleared again", lambda: peers.get(c, 3, COILS, 0), [0])
    figures = d.remotes()
    for name, bit in (("rtu3", "M0103"), ("rtu4", "M0104")):
        f = figures[name]
        check(
            f"rtu: {name} online, status bit {bit} ON, no failures",
            f["state"] == "online" and f["failures"] == 0 and d.get(bit)[bit] == 1,
            f,
        )
    before = d.remotes()
    time.sleep(0.3)  # not a wait for a condition: a span over which both must be polled
    after = d.remotes()
    check(
        "rtu: both units on the line are polled (their request counts both grow)",
        all(after[n]["requests"] > before[n]["requests"] for n in ("rtu3", "rtu4")),
        {n: (before[n]["requests"], after[n]["requests"]) for n in ("rtu3", "rtu4")},
    )


# The text each fault's log line carries (docs/REMOTE.md, "Faults").
FAULT_TEXT = {
    "timeout": "no answer in time",
    "exception": "exception 02",
    "wrong_unit": "an answer from unit 99",
    "wrong_transaction": "an answer with transaction id",
    "garbage": "not a Modbus answer",
    "closed": "the device closed the connection",
    "bad_crc": "an answer with a bad CRC",
}


class Watched:
    """A device under a fault: its name, status bit, what on_loss does, and the devices its
    inputs feed with the values they hold while it answers."""

    def __init__(self, name, status, on_loss, inputs):
        self.name, self.status, self.on_loss, self.inputs = name, status, on_loss, inputs


def fault_episode(t, label, proxy, mode, arg, kind, devices, set_inputs, late=False, bystanders=()):
    """Switches `proxy` to `mode`, waits until every device is lost with its `kind` counter 3
    or more higher, checks the status bits, the inputs and the counters, switches back to pass,
    waits until they are back, and counts the log lines of the episode."""
    d = t.daemon
    print(f"-- {label}: {mode}{f' {arg} ms' if arg else ''} -> {kind}", flush=True)
    before = d.remotes()
    log_from = len(d.log)
    proxy.mode(mode, arg)

    def lost_enough():
        now = d.remotes()
        return all(
            now[w.name]["state"] == "lost"
            and now[w.name]["faults"].get(kind, 0) >= before[w.name]["faults"].get(kind, 0) + 3
            for w in devices
        ) and now

    during = wait_for(lost_enough)
    now = during or d.remotes()
    for w in devices:
        f, b = now[w.name], before[w.name]
        check(
            f"{label} {mode}: {w.name} lost, `{kind}` counted 3+ times",
            bool(during),
            f"state {f['state']}, faults {b['faults']} -> {f['faults']}, last_error {f.get('last_error')!r}",
        )
        if late:
            check(f"{label} {mode}: {w.name}: late answers counted", f["late"] > b["late"], f"late {b['late']} -> {f['late']}")
    bits = [w.status for w in devices]
    check(
        f"{label} {mode}: status bits {', '.join(bits)} OFF",
        wait_for(lambda: all(v == 0 for v in d.get(*bits).values())),
        d.get(*bits),
    )
    for w in devices:
        # Read with the status bit, in one get: the values of the same input refresh.
        values = d.get(w.status, *w.inputs)
        held = {k: v for k, v in values.items() if k != w.status}
        if w.on_loss == "clear":
            want = {k: 0 for k in w.inputs}
            check(f"{label} {mode}: {w.name} (on_loss = clear) inputs cleared", held == want, f"{values}, want {want}")
        else:
            check(f"{label} {mode}: {w.name} (on_loss = hold) inputs held", held == w.inputs, f"{values}, want {w.inputs}")
    # New values while it is lost: after it is back they must be read.
    new_inputs = set_inputs()
    proxy.mode("pass")
    back = wait_for(
        lambda: all(s == "online" for s in states(d, [w.name for w in devices]).values())
        and all(v == 1 for v in d.get(*bits).values())
    )
    check(f"{label} {mode}: back online, status bits ON, without a restart", bool(back), states(d, [w.name for w in devices]))
    for w in devices:
        want = new_inputs[w.name]
        equal_within(f"{label} {mode}: {w.name} reads the values set while it was lost", lambda w=w: d.get(*w.inputs), want)
        w.inputs = want

    def log_lines(w, *texts):
        return [l for l in d.log[log_from:] if f"remote {w.name} (" in l and all(x in l for x in texts)]

    for w in devices:
        wait_for(lambda w=w: log_lines(w, "answering again"))
        faults = log_lines(w, "failed:")
        n = now[w.name]["failures"] - before[w.name]["failures"]
        check(
            f"{label} {mode}: {w.name}: ONE log line for {n} failed requests, naming the fault",
            len(faults) == 1 and FAULT_TEXT[kind] in faults[0],
            faults[:5],
        )
        lost = log_lines(w, "lost after")
        check(f"{label} {mode}: {w.name}: ONE `lost` log line", len(lost) == 1, lost[:5])
        again = log_lines(w, "answering again")
        check(f"{label} {mode}: {w.name}: ONE `answering again` log line", len(again) == 1, again[:5])
    after = d.remotes()
    for name in bystanders:
        check(
            f"{label} {mode}: {name} (another device) untouched",
            after[name]["state"] == "online" and after[name]["failures"] == before[name]["failures"],
            after[name],
        )


def tcp_faults(t):
    d, peers, b, proxy = t.daemon, t.peers, t.server_b, t.proxy_tcp
    print("-- Modbus TCP faults (px_clear, px_hold through faulty_proxy.py to pymodbus server B)", flush=True)
    counter = [1000]

    def set_inputs():
        counter[0] += 1
        value = counter[0]
        bit = value % 2
        peers.set(b, 1, HOLDING, 0, [value, value + 1])
        peers.set(b, 1, DISCRETE, 0, [bool(bit), True])
        return {
            "px_clear": {"D00300": value, "D00301": value + 1, "P0200": bit, "P0201": 1},
            "px_hold": {"D00310": value, "D00311": value + 1, "P0210": bit, "P0211": 1},
        }

    first = set_inputs()
    devices = [
        Watched("px_clear", "M0101", "clear", first["px_clear"]),
        Watched("px_hold", "M0102", "hold", first["px_hold"]),
    ]
    ok = all_online(d, ["px_clear", "px_hold"])
    check("tcp faults: px_clear and px_hold online through the proxy", bool(ok), states(d, ["px_clear", "px_hold"]))
    for w in devices:
        equal_within(f"tcp faults: {w.name} reads through the proxy", lambda w=w: d.get(*w.inputs), w.inputs)
    for mode, arg, kind, late in (
        ("drop", None, "timeout", False),
        ("delay", 400, "timeout", True),
        ("exception", None, "exception", False),
        ("wrong_unit", None, "wrong_unit", False),
        ("wrong_transaction", None, "wrong_transaction", False),
        ("garbage", None, "garbage", False),
        ("close", None, "closed", False),
    ):
        fault_episode(t, "tcp", proxy, mode, arg, kind, devices, set_inputs, late=late, bystanders=("rack", "rtu3", "rtu4"))
    stats = proxy.stats()
    check("tcp faults: the proxy broke frames of each kind", len(stats["broken"]) == 7, stats)


def rtu_faults(t):
    d, peers, srv, proxy = t.daemon, t.peers, t.server_d, t.proxy_rtu
    print("-- Modbus RTU faults (rtu5 through faulty_proxy.py between two pty pairs, pymodbus server D)", flush=True)
    counter = [5000]

    def set_inputs():
        counter[0] += 1
        value = counter[0]
        peers.set(srv, 5, HOLDING, 0, [value, value + 1])
        peers.set(srv, 5, DISCRETE, 0, [False, True])
        return {"rtu5": {"D00500": value, "D00501": value + 1, "P0300": 0, "P0301": 1}}

    first = set_inputs()
    devices = [Watched("rtu5", "M0105", "clear", first["rtu5"])]
    ok = all_online(d, ["rtu5"])
    check("rtu faults: rtu5 online through the proxy", bool(ok), states(d, ["rtu5"]))
    equal_within("rtu faults: rtu5 reads through the proxy", lambda: d.get(*devices[0].inputs), devices[0].inputs)
    for mode, arg, kind, late in (
        ("bad_crc", None, "bad_crc", False),
        ("wrong_unit", None, "wrong_unit", False),
        ("garbage", None, "garbage", False),
        ("drop", None, "timeout", False),
        ("delay", 180, "timeout", True),
        ("exception", None, "exception", False),
    ):
        fault_episode(t, "rtu", proxy, mode, arg, kind, devices, set_inputs, late=late, bystanders=("rack", "rtu3", "rtu4"))


def reconnection(t):
    d, peers = t.daemon, t.peers
    print("-- Reconnection: pymodbus server A stopped and started again on its port", flush=True)
    port = t.server_a.port
    log_from = len(d.log)
    peers.stop(t.server_a)
    lost = wait_for(lambda: d.remotes()["rack"]["state"] == "lost")
    check("reconnect: rack lost when its server stops", bool(lost), d.remotes()["rack"])
    check("reconnect: status bit M0100 OFF", wait_for(lambda: d.get("M0100")["M0100"] == 0), d.get("M0100"))
    equal_within("reconnect: rack's inputs cleared (on_loss default: clear)", lambda: d.get("D00100", "D00110"), {"D00100": 0, "D00110": 0})
    # Let it fail a few times more (refused connections) before the server comes back.
    base = d.remotes()["rack"]["failures"]
    wait_for(lambda: d.remotes()["rack"]["failures"] >= base + 3)
    t.server_a = peers.tcp([1], port=port)
    peers.set(t.server_a, 1, HOLDING, 10, [4242])
    back = wait_for(lambda: d.remotes()["rack"]["state"] == "online" and d.get("M0100")["M0100"] == 1)
    check("reconnect: rack online again on the restarted server, M0100 ON, no restart of plcd", bool(back), d.remotes()["rack"])
    equal_within("reconnect: fresh values read from the restarted server", lambda: d.get("D00100")["D00100"], 4242)
    equal_within(
        "reconnect: the restarted server gets its outputs back (refresh_ms), D00202-D00203 in HR 2-3",
        lambda: peers.get(t.server_a, 1, HOLDING, 2, 2),
        [777, 0xFFFE],
    )
    lines = [l for l in d.log[log_from:] if "remote rack (" in l]
    check(
        "reconnect: logged once lost and once answering again",
        len([l for l in lines if "lost after" in l]) == 1 and len([l for l in lines if "answering again" in l]) == 1,
        lines[:8],
    )
    rack = d.remotes()["rack"]
    check("reconnect: rack's losses counted (1)", rack["losses"] == 1, rack)


class Test:
    pass


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--plcd", required=True)
    ap.add_argument("--plcctl", required=True)
    args = ap.parse_args()
    for tool in ("socat",):
        if not shutil.which(tool):
            sys.exit(f"check_remote: {tool} is missing")
    logging.getLogger("pymodbus").setLevel(logging.CRITICAL)
    started = time.monotonic()
    tmp = tempfile.mkdtemp(prefix="plcd-remote-")
    t = Test()
    t.peers = Peers()
    stoppable = []
    code = None
    try:
        t.server_a = t.peers.tcp([1])
        t.server_b = t.peers.tcp([1])
        t.proxy_tcp = Proxy(tmp, "px-tcp", ["tcp", "--listen", "127.0.0.1:0", "--upstream", f"127.0.0.1:{t.server_b.port}"])
        stoppable.append(t.proxy_tcp)
        line_a = PtyPair(tmp, "line-a")
        stoppable.append(line_a)
        t.server_c = t.peers.serial([3, 4], line_a.b)
        line_b1, line_b2 = PtyPair(tmp, "line-b1"), PtyPair(tmp, "line-b2")
        stoppable += [line_b1, line_b2]
        t.proxy_rtu = Proxy(tmp, "px-rtu", ["rtu", "--client", line_b1.b, "--server", line_b2.a])
        stoppable.insert(0, t.proxy_rtu)
        t.server_d = t.peers.serial([5], line_b2.b)
        config = project(tmp, t.server_a.port, t.proxy_tcp.port, line_a.a, line_b1.a)
        t.daemon = Daemon(args.plcd, args.plcctl, config)
        names = ["rack", "px_clear", "px_hold", "rtu3", "rtu4", "rtu5"]
        ok = all_online(t.daemon, names)
        check("every remote device comes online", bool(ok), states(t.daemon, names))
        tcp_values(t)
        rtu_values(t)
        tcp_faults(t)
        rtu_faults(t)
        reconnection(t)
        print("-- Shutdown", flush=True)
        code = t.daemon.stop()
        check("plcd stops cleanly (exit 0)", code == 0, f"exit {code}")
        check(
            "at shutdown every write table is written with zeros (rack coils, HR 0-3, HR 20-21; rtu4 HR 20-21)",
            t.peers.get(t.server_a, 1, COILS, 0, 3) == [0, 0, 0]
            and t.peers.get(t.server_a, 1, HOLDING, 0, 4) == [0, 0, 0, 0]
            and t.peers.get(t.server_a, 1, HOLDING, 20, 2) == [0, 0]
            and t.peers.get(t.server_c, 4, HOLDING, 20, 2) == [0, 0],
            [
                t.peers.get(t.server_a, 1, COILS, 0, 3),
                t.peers.get(t.server_a, 1, HOLDING, 0, 4),
                t.peers.get(t.server_a, 1, HOLDING, 20, 2),
                t.peers.get(t.server_c, 4, HOLDING, 20, 2),
            ],
        )
    finally:
        daemon = getattr(t, "daemon", None)
        if daemon and code is None:
            daemon.stop()
        for thing in stoppable:
            thing.stop()
        t.peers.close()
        shutil.rmtree(tmp, ignore_errors=True)
    elapsed = time.monotonic() - started
    print(f"remote I/O against pymodbus: {passed} passed, {len(failed)} failed in {elapsed:.1f} s")
    if failed:
        if daemon:
            print("plcd log (last 60 lines):\n" + "\n".join(daemon.log[-60:]))
        sys.exit(1)


if __name__ == "__main__":
    main()

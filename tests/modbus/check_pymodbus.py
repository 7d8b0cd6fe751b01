#!/usr/bin/env python3
"""plcd's Modbus TCP server against clients nobody here wrote: pymodbus and (if installed)
mbpoll. Started by tests/modbus/run-pymodbus, which makes the venv and builds plcd.

Starts `plcd run` on a copy of tests/modbus/project on a free port, then checks every function
code, every exception, 20 concurrent clients polling every 10 ms, and malformed frames (the
connection is closed or answered with an exception, and the daemon goes on scanning and
answering). Prints one line per check and `N passed, M failed`; exits 1 unless all passed.
Waits are bounded; nothing asserts how fast anything was.
"""

import argparse
import os
import random
import re
import shutil
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import threading
import time

from pymodbus.client import ModbusTcpClient

PATIENCE = 20.0
passed = 0
failed = []


def check(name, ok, detail=""):
    global passed
    if ok:
        passed += 1
        print(f"ok    {name}")
    else:
        failed.append(name)
        print(f"FAIL  {name}: {detail}")


def wait_for(what, probe, patience=PATIENCE):
    until = time.monotonic() + patience
    while time.monotonic() < until:
        try:
            if probe():
                return True
        except Exception:  # noqa: BLE001 - a probe may fail while waiting
            pass
        time.sleep(0.01)
    print(f"gave up waiting for {what}")
    return False


class Daemon:
    """`plcd run` on a copy of `project`, listening on a free port, with `extra` appended to
    its config."""

    def __init__(self, plcd, project, extra=""):
        self.dir = tempfile.mkdtemp(prefix="plcd-pymodbus-")
        for name in os.listdir(project):
            shutil.copy(os.path.join(project, name), self.dir)
        config = os.path.join(self.dir, "plcd.toml")
        with open(config) as f:
            text = f.read()
        with open(config, "w") as f:
            f.write(re.sub(r'listen = "[^"]*"', 'listen = "127.0.0.1:0"', text) + extra)
        self.log = []
        self.proc = subprocess.Popen(
            [plcd, "run", "--log-level", "debug", "--config", config],
            stderr=subprocess.PIPE,
            stdout=subprocess.DEVNULL,
            text=True,
            env={k: v for k, v in os.environ.items() if k not in ("NOTIFY_SOCKET", "WATCHDOG_USEC", "JOURNAL_STREAM")},
        )
        threading.Thread(target=self._read_log, daemon=True).start()
        self.port = None

        def serving():
            for line in self.log:
                m = re.search(r"modbus: serving 127\.0\.0\.1:(\d+)", line)
                if m:
                    self.port = int(m.group(1))
                    return True
            return False

        if not wait_for("the daemon to serve Modbus", serving):
            self.stop()
            sys.exit("plcd did not start:\n" + "\n".join(self.log))

    def _read_log(self):
        for line in self.proc.stderr:
            self.log.append(line.rstrip("\n"))

    def alive(self):
        return self.proc.poll() is None

    def stop(self):
        if self.alive():
            self.proc.send_signal(signal.SIGTERM)
        try:
            code = self.proc.wait(timeout=PATIENCE)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            code = self.proc.wait()
        shutil.rmtree(self.dir, ignore_errors=True)
        return code


def client(port):
    c = ModbusTcpClient("127.0.0.1", port=port, timeout=5, retries=0)
    if not c.connect():
        raise RuntimeError("cannot connect")
    return c


def scans(c):
    return c.read_holding_registers(1050, count=1).registers[0]


def exc(result):
    """The exception code of an exception response, or None."""
    return result.exception_code if result.isError() else None


def raw(port, frame, read=True):
    """Sends raw bytes on a new connection; the bytes read until the server closes or 2 s
    pass without data, and whether it closed."""
    s = socket.create_connection(("127.0.0.1", port), timeout=PATIENCE)
    data = b""
    try:
        s.sendall(frame)
        s.shutdown(socket.SHUT_WR)
        s.settimeout(PATIENCE)
        while True:
            chunk = s.recv(4096)
            if not chunk:
                return data, True
            data += chunk
    except socket.timeout:
        return data, False
    except OSError:
        # Reset, or closed before our shutdown: closed by the server either way.
        return b"", True
    finally:
        s.close()


def mbap(transaction, unit, pdu):
    return struct.pack(">HHHB", transaction, 0, len(pdu) + 1, unit) + pdu


def unharmed(c, name):
    before = scans(c)
    check(f"{name}: still scanning and answering", wait_for("scans", lambda: scans(c) != before), "")


def function_codes(port):
    c = client(port)
    r = c.write_register(1, 0xBEEF)
    check("FC 6 write single register", not r.isError(), r)
    r = c.read_holding_registers(0, count=3)
    check("FC 3 reads it back", not r.isError() and r.registers[1] == 0xBEEF, r)
    values = [(7 * i + 1) & 0xFFFF for i in range(123)]
    r = c.write_registers(1, values)
    check("FC 16 writes 123 registers", not r.isError() and r.count == 123, r)
    r = c.read_holding_registers(0, count=125)
    check("FC 3 reads 125 registers", not r.isError() and r.registers[1:124] == values, r)
    r = c.readwrite_registers(read_address=9, read_count=4, write_address=10, values=[0x1234, 0x5678])
    check(
        "FC 23 writes, then reads what it wrote",
        not r.isError() and r.registers == [values[8], 0x1234, 0x5678, values[11]],
        r,
    )
    r = c.write_coil(0, True)
    check("FC 5 write single coil", not r.isError() and r.bits[0] is True, r)
    check(
        "FC 1: the program copies coil 0 to coil 16",
        wait_for("M0010", lambda: c.read_coils(0, count=17).bits[16]),
    )
    pattern = [i % 3 == 0 for i in range(1968)]
    r = c.write_coils(0, pattern)
    check("FC 15 writes 1968 coils", not r.isError() and r.count == 1968, r)
    r = c.read_coils(0, count=1968)
    check("FC 1 reads 1968 coils", not r.isError() and r.bits[17:1968] == pattern[17:], r)
    r = c.read_discrete_inputs(0, count=16)
    check("FC 2 reads the inputs P0000..P000F", not r.isError() and r.bits[:16] == [False] * 16, r)
    r = c.read_input_registers(0, count=4)
    check("FC 4 reads _SCAN_CUR.._ERR_CODE", not r.isError() and len(r.registers) == 4 and r.registers[3] == 0, r)
    r = c.read_input_registers(10, count=2)
    check("FC 4 reads T current values", not r.isError() and r.registers == [0, 0], r)
    r = c.read_holding_registers(1050, count=1, device_id=255)
    check("unit id 255 is served", not r.isError(), r)
    r = c.read_holding_registers(1050, count=1, device_id=0)
    check("unit id 0 is served", not r.isError(), r)
    # FC 22: 0x12 AND 0xF2 OR 0x25 = 0x17 (the Modbus specification's example).
    c.write_register(7, 0x12)
    r = c.mask_write_register(address=7, and_mask=0xF2, or_mask=0x25)
    check("FC 22 mask write register", not r.isError(), r)
    r = c.read_holding_registers(7, count=1)
    check("FC 22 wrote (0x12 AND 0xF2) OR (0x25 AND NOT 0xF2)", not r.isError() and r.registers == [0x17], r)
    r = c.report_device_id()
    check("FC 17 report server id: RUN, plcd", not r.isError() and r.status and b"plcd" in r.identifier, r)
    r = c.read_device_information()
    info = getattr(r, "information", {}) if not r.isError() else {}
    check("FC 43/14 basic device identification", info.get(0) == b"plcd" and info.get(1) == b"plcd" and 2 in info, r)
    c.close()


def exceptions(port):
    c = client(port)
    cases = [
        ("01 for FC 7 read exception status", lambda: c.read_exception_status(), 1),
        ("02 for FC 22 to a read-only register", lambda: c.mask_write_register(address=125, and_mask=0xFFFF, or_mask=0), 2),
        ("02 for FC 1 unmapped", lambda: c.read_coils(1968, count=1), 2),
        ("02 for FC 1 across the end of a range", lambda: c.read_coils(1960, count=10), 2),
        ("02 for FC 2 unmapped", lambda: c.read_discrete_inputs(16, count=1), 2),
        ("02 for FC 3 across a gap", lambda: c.read_holding_registers(130, count=10), 2),
        ("02 for FC 4 unmapped", lambda: c.read_input_registers(4, count=1), 2),
        ("02 for FC 5 to a read-only coil", lambda: c.write_coil(3000, True), 2),
        ("02 for FC 6 to a read-only register", lambda: c.write_register(125, 1), 2),
        ("02 for FC 15 past the mapped coils", lambda: c.write_coils(1960, [True] * 10), 2),
        ("02 for FC 16 into read-only registers", lambda: c.write_registers(120, [1] * 10), 2),
        (
            "02 for FC 23 writing read-only registers",
            lambda: c.readwrite_registers(read_address=0, read_count=1, write_address=125, values=[1]),
            2,
        ),
        ("0B for another unit id", lambda: c.read_holding_registers(0, count=1, device_id=9), 0x0B),
    ]
    for name, call, code in cases:
        r = call()
        check(f"exception {name}", exc(r) == code, r)
    # What pymodbus refuses to send (it checks quantities itself): raw frames.
    raw_cases = [
        ("03 for FC 3 quantity 0", bytes([3, 0, 0, 0, 0]), 3),
        ("03 for FC 1 quantity 2001", bytes([1, 0, 0, 0x07, 0xD1]), 3),
        ("03 for FC 3 quantity 126", bytes([3, 0, 0, 0, 126]), 3),
        ("03 for FC 5 value 0x1234", bytes([5, 0, 0, 0x12, 0x34]), 3),
        ("03 for FC 16 byte count not 2 x quantity", bytes([16, 0, 0, 0, 2, 2, 0, 1]), 3),
        ("03 for FC 15 byte count short", bytes([15, 0, 0, 0, 9, 1, 0xFF]), 3),
        ("03 for FC 23 read quantity 126", bytes([23, 0, 0, 0, 126, 0, 0, 0, 1, 2, 0, 1]), 3),
        ("01 for FC 43 MEI type 13", bytes([43, 13, 1, 0]), 1),
    ]
    for name, pdu, code in raw_cases:
        data, _ = raw(port, mbap(0x4242, 1, pdu))
        ok = len(data) == 9 and data[:2] == b"\x42\x42" and data[7] == pdu[0] | 0x80 and data[8] == code
        check(f"exception {name}", ok, data.hex())
    r = c.read_holding_registers(0, count=1)
    check("the connection is usable after exceptions", not r.isError(), r)
    c.close()


def concurrent(port, clients=20, seconds=2.0):
    errors = []
    counts = [0] * clients

    def poll(k):
        try:
            c = client(port)
            end = time.monotonic() + seconds
            i = 0
            while time.monotonic() < end:
                value = (k * 1000 + i) & 0xFFFF
                w = c.write_register(20 + k, value)
                r = c.read_holding_registers(20 + k, count=1)
                if w.isError() or r.isError() or r.registers != [value]:
                    errors.append(f"client {k}: {w} {r}")
                    break
                counts[k] += 1
                i += 1
                time.sleep(0.01)
            c.close()
        except Exception as e:  # noqa: BLE001
            errors.append(f"client {k}: {e!r}")

    threads = [threading.Thread(target=poll, args=(k,)) for k in range(clients)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    check(
        f"{clients} concurrent clients polling every 10 ms read their own writes",
        not errors and all(n > 0 for n in counts),
        errors[:3],
    )
    print(f"      ({sum(counts)} write+read pairs in {seconds} s)")


def malformed(port, c):
    cases = [
        ("a truncated MBAP header", b"\x00\x01\x00"),
        ("a frame cut short", mbap(1, 1, bytes([3, 0, 0, 0, 1]))[:9]),
        ("a length field of 0", b"\x00\x01\x00\x00\x00\x00\x01"),
        ("a length field of 300", b"\x00\x01\x00\x00\x01\x2c\x01" + b"\x03" * 299),
        ("a length field longer than the frame", b"\x00\x01\x00\x00\x00\x20\x01\x03\x00\x00\x00\x01"),
        ("protocol id 1", b"\x00\x01\x00\x01\x00\x06\x01\x03\x00\x00\x00\x01"),
        ("an exception code as function", mbap(1, 1, bytes([0x83, 2]))),
        ("text", b"GET / HTTP/1.0\r\n\r\n"),
    ]
    for name, frame in cases:
        data, closed = raw(port, frame)
        answered = len(data) >= 9 and data[7] & 0x80
        check(f"malformed: {name}: closed or answered with an exception", closed or answered, data.hex())
        unharmed(c, f"after {name}")
    rng = random.Random(9)
    outcomes = {"closed": 0, "answered": 0}
    for _ in range(100):
        data, closed = raw(port, bytes(rng.getrandbits(8) for _ in range(rng.randint(1, 300))))
        outcomes["closed" if closed else "answered"] += 1
    check("malformed: 100 random byte strings are all closed", outcomes["closed"] == 100, outcomes)
    unharmed(c, "after random bytes")


def mbpoll_checks(port, c):
    mbpoll = shutil.which("mbpoll")
    if not mbpoll:
        print("skip  mbpoll: not installed (apt-get install mbpoll)")
        return
    base = [mbpoll, "-m", "tcp", "-p", str(port), "-a", "1", "-0", "-1", "-o", "5"]

    def run(*args):
        p = subprocess.run(base + list(args), capture_output=True, text=True, timeout=PATIENCE)
        return p.returncode, p.stdout + p.stderr

    code, out = run("-t", "4", "-r", "40", "127.0.0.1", "1234", "65531")
    check("mbpoll: FC 16 writes two holding registers", code == 0, out)
    r = c.read_holding_registers(40, count=2)
    check("mbpoll's write is in device memory", r.registers == [1234, 65531], r)
    code, out = run("-t", "4", "-r", "40", "-c", "2", "127.0.0.1")
    check("mbpoll: FC 3 reads them", code == 0 and "1234" in out and "65531" in out, out)
    code, out = run("-t", "0", "-r", "100", "127.0.0.1", "1")
    check("mbpoll: FC 5 writes a coil", code == 0 and c.read_coils(100, count=1).bits[0], out)
    code, out = run("-t", "0", "-r", "100", "-c", "3", "127.0.0.1")
    check("mbpoll: FC 1 reads coils", code == 0 and re.search(r"\[100\]:\s+1", out), out)
    code, out = run("-t", "1", "-r", "0", "-c", "8", "127.0.0.1")
    check("mbpoll: FC 2 reads discrete inputs", code == 0 and "[7]" in out, out)
    code, out = run("-t", "3", "-r", "0", "-c", "4", "127.0.0.1")
    check("mbpoll: FC 4 reads input registers", code == 0 and "[3]" in out, out)
    code, out = run("-t", "4", "-r", "200", "127.0.0.1")
    check("mbpoll: an unmapped register is an illegal data address", code != 0 and "llegal data address" in out, out)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--plcd", required=True)
    ap.add_argument("--project", required=True)
    args = ap.parse_args()
    daemon = Daemon(args.plcd, args.project)
    try:
        c = client(daemon.port)
        check("the daemon scans (D00400 counts)", wait_for("scans", lambda: scans(c) > 2))
        function_codes(daemon.port)
        exceptions(daemon.port)
        concurrent(daemon.port)
        malformed(daemon.port, c)
        mbpoll_checks(daemon.port, c)
        unharmed(c, "at the end")
        c.close()
    finally:
        code = daemon.stop()
    check("the daemon stops cleanly (exit 0)", code == 0, f"exit {code}")
    errors = [l for l in daemon.log if " ERROR " in l]
    check("the daemon logged no error", not errors, errors[:5])
    print(f"pymodbus: {passed} passed, {len(failed)} failed")
    if failed:
        print("log:\n" + "\n".join(daemon.log[-40:]))
        sys.exit(1)


if __name__ == "__main__":
    main()

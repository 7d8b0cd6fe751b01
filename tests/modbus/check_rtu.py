#!/usr/bin/env python3
"""plcd's Modbus RTU server against serial clients nobody here wrote: pymodbus's serial client
(over pyserial) and (if installed) `mbpoll -m rtu`. Started by tests/modbus/run-pymodbus after
check_pymodbus.py, in the same venv.

socat makes a pty pair; `plcd run` on a copy of tests/modbus/project with `[modbus.rtu]` added
serves one end as unit 5, the clients use the other. Checks every function code, the
exceptions, broadcasts (carried out, not answered), requests to another unit (not answered),
frames with a bad CRC and garbage (dropped, then the next request is answered), TCP and RTU on
one map, and the daemon's counters at stop. Prints one line per check and `N passed, M
failed`; exits 1 unless all passed. Waits are bounded; nothing asserts how fast anything was.
"""

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time

import serial
from pymodbus.client import ModbusSerialClient, ModbusTcpClient
from pymodbus.exceptions import ModbusIOException

import check_pymodbus as base
from check_pymodbus import PATIENCE, Daemon, check, exc, wait_for

UNIT = 5
BAUD = 19200
# No parity: a pty carries bytes, not bits, and the kernel may refuse PARENB on one (EINVAL
# from tcsetattr once another setting was made).
PARITY = "none"


def crc(frame):
    """The Modbus CRC-16 of `frame`, low byte first, as it goes on the wire."""
    c = 0xFFFF
    for byte in frame:
        c ^= byte
        for _ in range(8):
            c = (c >> 1) ^ 0xA001 if c & 1 else c >> 1
    return bytes([c & 0xFF, c >> 8])


class Socat:
    """A pty pair: `plc` for the daemon, `master` for the clients (symlinks)."""

    def __init__(self):
        self.dir = tempfile.mkdtemp(prefix="plcd-rtu-")
        self.plc = os.path.join(self.dir, "plc")
        self.master = os.path.join(self.dir, "master")
        self.proc = subprocess.Popen(
            ["socat", "-d", "-d", f"pty,raw,echo=0,link={self.plc}", f"pty,raw,echo=0,link={self.master}"],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        if not wait_for("socat's ptys", lambda: os.path.exists(self.plc) and os.path.exists(self.master)):
            self.stop()
            sys.exit("socat did not make its pty pair")

    def stop(self):
        self.proc.terminate()
        try:
            self.proc.wait(timeout=PATIENCE)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        shutil.rmtree(self.dir, ignore_errors=True)


def rtu_client(path, retries=3, timeout=2):
    c = ModbusSerialClient(port=path, baudrate=BAUD, parity="N", stopbits=1, bytesize=8, timeout=timeout, retries=retries)
    if not c.connect():
        raise RuntimeError(f"cannot open {path}")
    return c


def function_codes(c):
    r = c.write_register(1, 0xBEEF, device_id=UNIT)
    check("rtu: FC 6 write single register", not r.isError(), r)
    r = c.read_holding_registers(0, count=3, device_id=UNIT)
    check("rtu: FC 3 reads it back", not r.isError() and r.registers[1] == 0xBEEF, r)
    values = [(11 * i + 3) & 0xFFFF for i in range(123)]
    r = c.write_registers(1, values, device_id=UNIT)
    check("rtu: FC 16 writes 123 registers (a 255-byte frame)", not r.isError() and r.count == 123, r)
    r = c.read_holding_registers(0, count=125, device_id=UNIT)
    check("rtu: FC 3 reads 125 registers", not r.isError() and r.registers[1:124] == values, r)
    r = c.readwrite_registers(read_address=9, read_count=4, write_address=10, values=[0x1234, 0x5678], device_id=UNIT)
    check(
        "rtu: FC 23 writes, then reads what it wrote",
        not r.isError() and r.registers == [values[8], 0x1234, 0x5678, values[11]],
        r,
    )
    c.write_register(7, 0x12, device_id=UNIT)
    r = c.mask_write_register(address=7, and_mask=0xF2, or_mask=0x25, device_id=UNIT)
    check("rtu: FC 22 mask write register", not r.isError(), r)
    r = c.read_holding_registers(7, count=1, device_id=UNIT)
    check("rtu: FC 22 wrote (0x12 AND 0xF2) OR (0x25 AND NOT 0xF2)", not r.isError() and r.registers == [0x17], r)
    r = c.write_coil(0, True, device_id=UNIT)
    check("rtu: FC 5 write single coil", not r.isError() and r.bits[0] is True, r)
    check(
        "rtu: FC 1: the program copies coil 0 to coil 16",
        wait_for("M0010", lambda: c.read_coils(0, count=17, device_id=UNIT).bits[16]),
    )
    pattern = [i % 5 == 0 for i in range(1968)]
    r = c.write_coils(0, pattern, device_id=UNIT)
    check("rtu: FC 15 writes 1968 coils", not r.isError() and r.count == 1968, r)
    r = c.read_coils(0, count=1968, device_id=UNIT)
    check("rtu: FC 1 reads 1968 coils", not r.isError() and r.bits[17:1968] == pattern[17:], r)
    r = c.read_discrete_inputs(0, count=16, device_id=UNIT)
    check("rtu: FC 2 reads the inputs P0000..P000F", not r.isError() and r.bits[:16] == [False] * 16, r)
    r = c.read_input_registers(0, count=4, device_id=UNIT)
    check("rtu: FC 4 reads _SCAN_CUR.._ERR_CODE", not r.isError() and len(r.registers) == 4 and r.registers[3] == 0, r)
    r = c.report_device_id(device_id=UNIT)
    check(
        "rtu: FC 17 report server id: this unit, plcd, RUN",
        not r.isError() and r.status and r.identifier[:1] == bytes([UNIT]) and b"plcd" in r.identifier,
        r,
    )
    r = c.read_device_information(device_id=UNIT)
    info = getattr(r, "information", {}) if not r.isError() else {}
    check("rtu: FC 43/14 basic device identification", info.get(0) == b"plcd" and 2 in info, r)


def exceptions(c):
    cases = [
        ("01 for FC 7 read exception status", lambda: c.read_exception_status(device_id=UNIT), 1),
        ("02 for FC 1 unmapped", lambda: c.read_coils(1968, count=1, device_id=UNIT), 2),
        ("02 for FC 3 across a gap", lambda: c.read_holding_registers(130, count=10, device_id=UNIT), 2),
        ("02 for FC 5 to a read-only coil", lambda: c.write_coil(3000, True, device_id=UNIT), 2),
        ("02 for FC 6 to a read-only register", lambda: c.write_register(125, 1, device_id=UNIT), 2),
        ("02 for FC 16 into read-only registers", lambda: c.write_registers(120, [1] * 10, device_id=UNIT), 2),
    ]
    for name, call, code in cases:
        r = call()
        check(f"rtu: exception {name}", exc(r) == code, r)


def broadcasts_and_other_units(path, c):
    r = c.write_register(60, 4242, device_id=0, no_response_expected=True)
    check("rtu: a broadcast FC 6 is sent without an answer", r is None or not r.isError(), r)
    c.write_registers(61, [7, 8, 9], device_id=0, no_response_expected=True)
    r = c.read_holding_registers(60, count=4, device_id=UNIT)
    check("rtu: the broadcasts were carried out", not r.isError() and r.registers == [4242, 7, 8, 9], r)
    c.close()
    # Another unit: no answer (pymodbus gives up after its timeout), nothing written.
    other = rtu_client(path, retries=0, timeout=0.5)
    try:
        r = other.write_register(62, 1, device_id=9)
    except ModbusIOException as e:
        r = e
    check("rtu: a request to unit 9 is not answered", isinstance(r, ModbusIOException), r)
    other.close()
    c.connect()
    r = c.read_holding_registers(62, count=1, device_id=UNIT)
    check("rtu: unit 9's write was not carried out", not r.isError() and r.registers == [8], r)


def raw_frames(path):
    """What pymodbus will not send: bad CRCs, garbage, requests it refuses to build."""
    port = serial.Serial(path, BAUD, parity=serial.PARITY_NONE, timeout=0.5)

    def answer(adu, bad_crc=False, wait=0.5):
        frame = adu + crc(adu)
        if bad_crc:
            frame = frame[:-1] + bytes([frame[-1] ^ 0xFF])
        port.reset_input_buffer()
        port.write(frame)
        # Bytes until they end with their CRC (a whole response), or `wait` passes.
        got = b""
        until = time.monotonic() + wait
        while len(got) < 4 or crc(got[:-2]) != got[-2:]:
            left = until - time.monotonic()
            if left <= 0:
                break
            port.timeout = left
            got += port.read(1)
            port.timeout = 0
            got += port.read(256)
        return got

    write = bytes([UNIT, 6, 0, 70, 0, 1])
    got = answer(write, wait=PATIENCE)
    check("rtu raw: FC 6 is echoed", got == write + crc(write), got.hex())
    got = answer(bytes([UNIT, 6, 0, 70, 0, 99]), bad_crc=True)
    check("rtu raw: a frame with a bad CRC is not answered", got == b"", got.hex())
    port.write(bytes([0xFF, 0x00, 0x13, 0x37]))
    # A master waits before it sends again: the garbage ends at a silence.
    time.sleep(0.05)
    got = answer(bytes([UNIT, 3, 0, 70, 0, 1]), wait=PATIENCE)
    expected = bytes([UNIT, 3, 2, 0, 1])
    check(
        "rtu raw: after a bad frame and garbage the next request is answered, the bad write dropped",
        got == expected + crc(expected),
        got.hex(),
    )
    for name, pdu, code in [
        ("03 for FC 3 quantity 0", bytes([3, 0, 0, 0, 0]), 3),
        ("03 for FC 3 quantity 126", bytes([3, 0, 0, 0, 126]), 3),
        ("03 for FC 5 value 0x1234", bytes([5, 0, 0, 0x12, 0x34]), 3),
        ("03 for FC 16 byte count not 2 x quantity", bytes([16, 0, 0, 0, 2, 2, 0, 1]), 3),
        ("01 for FC 8 diagnostics (framed by silence)", bytes([8, 0, 0, 0x12, 0x34]), 1),
    ]:
        adu = bytes([UNIT]) + pdu
        expected = bytes([UNIT, pdu[0] | 0x80, code])
        got = answer(adu, wait=PATIENCE)
        check(f"rtu raw: exception {name}", got == expected + crc(expected), got.hex())
    port.close()


def mbpoll_checks(path, c):
    mbpoll = shutil.which("mbpoll")
    if not mbpoll:
        print("skip  mbpoll -m rtu: not installed (apt-get install mbpoll)")
        return
    base_args = [mbpoll, "-m", "rtu", "-b", str(BAUD), "-P", PARITY, "-a", str(UNIT), "-0", "-1", "-o", "2"]

    def run(*args):
        p = subprocess.run(base_args + list(args), capture_output=True, text=True, timeout=PATIENCE)
        return p.returncode, p.stdout + p.stderr

    c.close()
    code, out = run("-t", "4", "-r", "40", path, "1234", "65531")
    check("mbpoll rtu: FC 16 writes two holding registers", code == 0, out)
    code, out = run("-t", "4", "-r", "40", "-c", "2", path)
    check("mbpoll rtu: FC 3 reads them", code == 0 and "1234" in out and "65531" in out, out)
    code, out = run("-t", "0", "-r", "100", path, "1")
    check("mbpoll rtu: FC 5 writes a coil", code == 0, out)
    code, out = run("-t", "0", "-r", "100", "-c", "3", path)
    check("mbpoll rtu: FC 1 reads it", code == 0 and re.search(r"\[100\]:\s+1", out), out)
    code, out = run("-t", "1", "-r", "0", "-c", "8", path)
    check("mbpoll rtu: FC 2 reads discrete inputs", code == 0 and "[7]" in out, out)
    code, out = run("-t", "3", "-r", "0", "-c", "4", path)
    check("mbpoll rtu: FC 4 reads input registers", code == 0 and "[3]" in out, out)
    code, out = run("-u", path)
    check("mbpoll rtu: FC 17 report slave id", code == 0 and "plcd" in out, out)
    code, out = run("-t", "4", "-r", "200", path)
    check("mbpoll rtu: an unmapped register is an illegal data address", code != 0 and "llegal data address" in out, out)
    c.connect()
    r = c.read_holding_registers(40, count=2, device_id=UNIT)
    check("mbpoll's write is in device memory", not r.isError() and r.registers == [1234, 65531], r)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--plcd", required=True)
    ap.add_argument("--project", required=True)
    args = ap.parse_args()
    if not shutil.which("socat"):
        print("skip  modbus rtu: socat not installed (apt-get install socat)")
        return
    line = Socat()
    extra = f'\n[modbus.rtu]\nport = "{line.plc}"\nbaud = {BAUD}\nparity = "{PARITY}"\nunit_id = {UNIT}\n'
    daemon = Daemon(args.plcd, args.project, extra)
    try:
        check(
            "rtu: the daemon serves the pty",
            wait_for("serving rtu", lambda: any(f"modbus: serving rtu {line.plc}" in l for l in daemon.log)),
            "\n".join(daemon.log[-10:]),
        )
        c = rtu_client(line.master)
        function_codes(c)
        exceptions(c)
        broadcasts_and_other_units(line.master, c)
        c.close()
        raw_frames(line.master)
        c = rtu_client(line.master)
        mbpoll_checks(line.master, c)
        tcp = ModbusTcpClient("127.0.0.1", port=daemon.port, timeout=5, retries=0)
        tcp.connect()
        r = tcp.read_holding_registers(60, count=4)
        check("tcp reads what rtu wrote: one map, one device memory", not r.isError() and r.registers == [4242, 7, 8, 9], r)
        tcp.close()
        c.close()
    finally:
        code = daemon.stop()
        line.stop()
    check("the daemon stops cleanly (exit 0)", code == 0, f"exit {code}")
    errors = [l for l in daemon.log if " ERROR " in l]
    check("the daemon logged no error", not errors, errors[:5])
    totals = next((l for l in daemon.log if f"modbus: rtu {line.plc}:" in l and " frames: " in l), "")
    m = re.search(r"(\d+) frames: (\d+) answered, (\d+) broadcasts carried out, (\d+) ignored; (\d+) bad", totals)
    counts = tuple(int(g) for g in m.groups()) if m else None
    check(
        "the counters at stop: broadcasts, the other unit and the bad frames counted",
        counts is not None
        and counts[2] == 2
        and counts[3] == 1
        and counts[4] >= 1
        and counts[1] > 0
        and counts[0] == counts[1] + counts[2] + counts[3],
        totals,
    )
    print(f"rtu: {base.passed} passed, {len(base.failed)} failed")
    if base.failed:
        print("log:\n" + "\n".join(daemon.log[-40:]))
        sys.exit(1)


if __name__ == "__main__":
    main()

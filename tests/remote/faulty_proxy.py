#!/usr/bin/env python3
"""A Modbus proxy that injects faults, for tests/remote/check_remote.py: it sits between plcd's
remote I/O client and a pymodbus server and passes every request and answer through, or breaks
them in one of the ways a real device or network does. The fault is switched at run time over a
control socket, so plcd keeps running while the device goes bad and comes back.

    faulty_proxy.py tcp --listen 127.0.0.1:0 --upstream 127.0.0.1:5020 --control DIR/px.sock
    faulty_proxy.py rtu --client PTY --server PTY --control DIR/px.sock

tcp: listens for plcd and opens one upstream connection for each connection it accepts; frames
are cut by their MBAP length. rtu: plcd's end of one pty pair on one side (--client), the
server's end of another pair on the other (--server); requests and answers are cut by their
function code's length. It prints `faulty_proxy: listening on HOST:PORT` (tcp) or
`faulty_proxy: ready` (rtu) on standard output once the control socket is up.

The control socket is a Unix stream socket speaking lines:

    mode NAME [ARG] [unit=U] [count=N]   -> ok
        every exchange from now on gets fault NAME (only those addressed to unit U; only
        the next N, then it is back to pass); the fault of an exchange is chosen when its
        request passes, and its answer gets the same
    stats   -> {JSON}   the exchanges seen, the faults applied, connections accepted

Faults (NAME):
    pass               everything passes (the default)
    drop               requests are swallowed: no answer (silence)
    delay MS           answers are held MS milliseconds (late answers), in order
    split MS           tcp: the answer's MBAP header goes at once, the rest MS milliseconds later
    exception          the request's start address is moved to 0x8000, outside the server's
                       datastore (the CRC fixed over RTU): the server itself answers 02
    wrong_unit         the answer's unit id becomes 99 (the CRC fixed over RTU)
    wrong_transaction  tcp: the answer's transaction id is moved 0x4000 away
    bad_crc            rtu: the answer's last byte is flipped
    garbage            tcp: the answer is replaced by bytes that are no MBAP frame;
                       rtu: by the right unit id, a function code no answer has, and noise
    wrong_function     tcp: the answer's function code is another one (a well-framed answer
                       to another request)
    cut                rtu: only the answer's first 3 bytes are sent (a frame cut short)
    close              tcp: the connection is closed when a request arrives
"""

import argparse
import asyncio
import json
import os
import select
import socketserver
import struct
import sys
import termios
import threading
import time
import tty

TCP_FAULTS = {
    "pass",
    "drop",
    "delay",
    "split",
    "exception",
    "wrong_unit",
    "wrong_transaction",
    "garbage",
    "wrong_function",
    "close",
}
RTU_FAULTS = {"pass", "drop", "delay", "exception", "wrong_unit", "bad_crc", "garbage", "cut"}
PASS = ("pass", 0)
GARBAGE_TCP = b"garbage!garbage!"


class Faults:
    """The current fault and what happened, shared by the control thread and the proxy."""

    def __init__(self, allowed):
        self.allowed = allowed
        self.lock = threading.Lock()
        self.name, self.arg, self.unit, self.left = "pass", 0, None, None
        self.stats = {"requests": 0, "answers": 0, "broken": {}, "connections": 0}

    def set(self, name, arg=0, unit=None, count=None):
        if name not in self.allowed:
            raise ValueError(f"unknown fault {name!r} (one of {', '.join(sorted(self.allowed))})")
        if name in ("delay", "split") and arg <= 0:
            raise ValueError(f"{name} needs a positive number of milliseconds")
        if count is not None and count <= 0:
            raise ValueError("count needs a positive number")
        with self.lock:
            self.name, self.arg, self.unit, self.left = name, arg, unit, count

    def decide(self, unit):
        """The fault of an exchange whose request to `unit` is passing now."""
        with self.lock:
            self.stats["requests"] += 1
            if self.name == "pass" or (self.unit is not None and unit != self.unit):
                return PASS
            fault = (self.name, self.arg)
            self.stats["broken"][self.name] = self.stats["broken"].get(self.name, 0) + 1
            if self.left is not None:
                self.left -= 1
                if self.left == 0:
                    self.name, self.arg, self.unit, self.left = "pass", 0, None, None
            return fault

    def count(self, what):
        with self.lock:
            self.stats[what] += 1

    def snapshot(self):
        with self.lock:
            return json.loads(
                json.dumps(
                    {**self.stats, "mode": self.name, "arg": self.arg, "unit": self.unit, "left": self.left}
                )
            )


def parse_mode(words):
    """`NAME [ARG] [unit=U] [count=N]` as the arguments of Faults.set."""
    name, rest = words[0], words[1:]
    options = {"arg": 0}
    for word in rest:
        key, eq, value = word.partition("=")
        if not eq:
            key, value = "arg", word
        if key not in ("arg", "unit", "count"):
            raise ValueError(f"unknown option {key!r}")
        options[key] = int(value)
    return name, options


def serve_control(path, faults, extra):
    """The control socket, on a thread of its own."""

    class Handler(socketserver.StreamRequestHandler):
        def handle(self):
            for raw in self.rfile:
                words = raw.decode(errors="replace").split()
                try:
                    if words[:1] == ["mode"] and len(words) >= 2:
                        name, options = parse_mode(words[1:])
                        faults.set(name, **options)
                        answer = "ok"
                    elif words == ["stats"]:
                        answer = json.dumps({**faults.snapshot(), **extra})
                    else:
                        answer = "error: mode NAME [ARG] [unit=U] [count=N] | stats"
                except ValueError as e:
                    answer = f"error: {e}"
                self.wfile.write(answer.encode() + b"\n")

    if os.path.exists(path):
        os.unlink(path)
    server = socketserver.ThreadingUnixStreamServer(path, Handler)
    server.daemon_threads = True
    threading.Thread(target=server.serve_forever, daemon=True).start()
    return server


# --- Modbus TCP -----------------------------------------------------------------------------


async def read_adu(reader):
    """One MBAP frame, or None at the end of the stream."""
    try:
        header = await reader.readexactly(7)
        (length,) = struct.unpack(">H", header[4:6])
        return header + await reader.readexactly(max(length - 1, 0))
    except (asyncio.IncompleteReadError, ConnectionError):
        return None


def break_tcp_request(adu, fault):
    if fault == "exception" and len(adu) >= 10:
        return adu[:8] + b"\x80\x00" + adu[10:]
    return adu


def break_tcp_answer(adu, fault):
    if fault == "wrong_unit":
        return adu[:6] + bytes([99]) + adu[7:]
    if fault == "wrong_transaction":
        (tid,) = struct.unpack(">H", adu[:2])
        return struct.pack(">H", (tid + 0x4000) & 0xFFFF) + adu[2:]
    if fault == "garbage":
        return GARBAGE_TCP
    if fault == "wrong_function":
        return adu[:7] + bytes([0x03 if adu[7] == 0x04 else 0x04]) + adu[8:]
    return adu


async def tcp_connection(client_reader, client_writer, upstream, faults):
    faults.count("connections")
    try:
        up_reader, up_writer = await asyncio.open_connection(*upstream)
    except OSError:
        client_writer.close()
        return
    # Answers go out in order, each at its release time (a delay holds it back).
    outbox = asyncio.Queue()

    def close_both():
        for w in (client_writer, up_writer):
            try:
                w.close()
            except Exception:  # noqa: BLE001 - closing twice is fine
                pass

    # The fault chosen for each request in flight, by transaction id.
    chosen = {}

    async def requests():
        while True:
            adu = await read_adu(client_reader)
            if adu is None:
                break
            fault, arg = faults.decide(adu[6])
            if fault == "drop":
                continue
            if fault == "close":
                break
            chosen[adu[:2]] = (fault, arg)
            up_writer.write(break_tcp_request(adu, fault))
            await up_writer.drain()
        close_both()

    async def answers():
        while True:
            adu = await read_adu(up_reader)
            if adu is None:
                break
            fault, arg = chosen.pop(adu[:2], PASS)
            now = time.monotonic()
            if fault == "split":
                await outbox.put((now, adu[:7]))
                await outbox.put((now + arg / 1000, adu[7:]))
                continue
            release = now + (arg / 1000 if fault == "delay" else 0)
            await outbox.put((release, break_tcp_answer(adu, fault)))
        await outbox.put(None)

    async def sender():
        while (item := await outbox.get()) is not None:
            release, adu = item
            await asyncio.sleep(max(0.0, release - time.monotonic()))
            try:
                client_writer.write(adu)
                await client_writer.drain()
                faults.count("answers")
            except ConnectionError:
                break
        close_both()

    await asyncio.gather(requests(), answers(), sender(), return_exceptions=True)


async def run_tcp(listen, upstream, faults):
    host, port = listen.rsplit(":", 1)
    up_host, up_port = upstream.rsplit(":", 1)
    server = await asyncio.start_server(
        lambda r, w: tcp_connection(r, w, (up_host, int(up_port)), faults), host, int(port)
    )
    bound = server.sockets[0].getsockname()
    print(f"faulty_proxy: listening on {bound[0]}:{bound[1]}", flush=True)
    async with server:
        await server.serve_forever()


# --- Modbus RTU -----------------------------------------------------------------------------


def crc16(data):
    crc = 0xFFFF
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
    return crc


def with_crc(body):
    return body + struct.pack("<H", crc16(body))


def request_len(buf):
    """The length of the RTU request that starts buf: None until it can be told, 0 if it
    cannot be a request this proxy knows (plcd sends FC 1-4, 15 and 16)."""
    if len(buf) < 2:
        return None
    fc = buf[1]
    if fc in (1, 2, 3, 4):
        return 8
    if fc in (15, 16):
        return 9 + buf[6] if len(buf) >= 7 else None
    return 0


def answer_len(buf):
    if len(buf) < 2:
        return None
    fc = buf[1]
    if fc & 0x80:
        return 5
    if fc in (1, 2, 3, 4):
        return 5 + buf[2] if len(buf) >= 3 else None
    if fc in (15, 16):
        return 8
    return 0


def break_rtu_request(frame, fault):
    if fault == "exception":
        return with_crc(frame[:2] + b"\x80\x00" + frame[4:-2])
    return frame


def break_rtu_answer(frame, fault):
    if fault == "wrong_unit":
        return with_crc(bytes([99]) + frame[1:-2])
    if fault == "bad_crc":
        return frame[:-1] + bytes([frame[-1] ^ 0xFF])
    if fault == "garbage":
        # A function code no Modbus answer has, then noise; its unit is the right one.
        return frame[:1] + b"\x41\x13\x37garbage"
    if fault == "cut":
        return frame[:3]
    return frame


def open_raw(path):
    fd = os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    tty.setraw(fd, termios.TCSANOW)
    return fd


def run_rtu(client_path, server_path, faults):
    client, server = open_raw(client_path), open_raw(server_path)
    print("faulty_proxy: ready", flush=True)
    from_client, from_server = b"", b""
    last_client = last_server = time.monotonic()
    pending = []  # (release time, bytes) for the client, in order
    in_flight = PASS
    resync = 0.05  # a frame whose rest has not come after this long is noise: dropped
    while True:
        now = time.monotonic()
        timeout = 0.02
        if pending:
            timeout = max(0.0, min(timeout, pending[0][0] - now))
        readable, _, _ = select.select([client, server], [], [], timeout)
        now = time.monotonic()
        if client in readable:
            from_client += os.read(client, 4096)
            last_client = now
        if server in readable:
            from_server += os.read(server, 4096)
            last_server = now
        while (n := request_len(from_client)) is not None:
            if n == 0:
                from_client = b""
                break
            if len(from_client) < n:
                break
            frame, from_client = from_client[:n], from_client[n:]
            fault, arg = faults.decide(frame[0])
            if fault != "drop":
                # One exchange at a time on a serial line: the next answer is this one's.
                in_flight = (fault, arg)
                os.write(server, break_rtu_request(frame, fault))
        while (n := answer_len(from_server)) is not None:
            if n == 0:
                from_server = b""
                break
            if len(from_server) < n:
                break
            frame, from_server = from_server[:n], from_server[n:]
            fault, arg = in_flight
            in_flight = PASS
            release = now + (arg / 1000 if fault == "delay" else 0)
            pending.append((release, break_rtu_answer(frame, fault)))
        if from_client and now - last_client > resync:
            from_client = b""
        if from_server and now - last_server > resync:
            from_server = b""
        while pending and pending[0][0] <= time.monotonic():
            os.write(client, pending.pop(0)[1])
            faults.count("answers")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="transport", required=True)
    tcp = sub.add_parser("tcp")
    tcp.add_argument("--listen", required=True, help="HOST:PORT (port 0: any free port)")
    tcp.add_argument("--upstream", required=True, help="the server's HOST:PORT")
    tcp.add_argument("--control", required=True, help="the control socket's path")
    rtu = sub.add_parser("rtu")
    rtu.add_argument("--client", required=True, help="the pty the client's pair ends in")
    rtu.add_argument("--server", required=True, help="the pty the server's pair ends in")
    rtu.add_argument("--control", required=True, help="the control socket's path")
    args = ap.parse_args()
    if args.transport == "tcp":
        faults = Faults(TCP_FAULTS)
        serve_control(args.control, faults, {"transport": "tcp"})
        asyncio.run(run_tcp(args.listen, args.upstream, faults))
    else:
        faults = Faults(RTU_FAULTS)
        serve_control(args.control, faults, {"transport": "rtu"})
        run_rtu(args.client, args.server, faults)


if __name__ == "__main__":
    try:
        main()
    except KeyboardInterrupt:
        sys.exit(0)

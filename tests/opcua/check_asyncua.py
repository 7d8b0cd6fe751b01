#!/usr/bin/env python3
"""plcd's OPC UA server against a client nobody here wrote: python asyncua (with cryptography
for the secure channels). Started by tests/opcua/run-asyncua, which makes the venv and builds
plcd.

Starts `plcd run` on copies of tests/opcua/project, each on a free port with its own [opcua]
keys and pki_dir, and checks: browsing finds the status and the program's variables; reads
give the program's values (a counter that moves, a struct's members of one scan, an array's
element, a STRING, a located word, a TIME, an enumeration); a subscription's data changes come
at most two sampling intervals apart; the security rules (the None policy refused unless
listed; a client certificate refused and put in rejected/ until it is moved to trusted/, then a
Basic256Sha256 SignAndEncrypt session works; anonymous sessions refused with anonymous =
"none"); the certificate made at the first start and reused, its key 0600; writes (applied at
a scan boundary and answered after it, the program sees them, refused with the right status code
for a variable not writable, a wrong type, a STRING too long, and for a viewer) and the RUN, STOP
and Reset methods under the mode rules (RUN refused in ERROR), with the control socket off too;
a port in use stops the start. Prints one line per check and `N passed, M failed`; exits 1 unless all passed.
Every wait is bounded; the daemons are killed on any failure.
"""

import argparse
import asyncio
import logging
import os
import re
import shutil
import signal
import socket
import stat
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from asyncua import Client, ua
from asyncua.crypto import security_policies
from asyncua.crypto.cert_gen import setup_self_signed_certificate
from cryptography.x509.oid import ExtendedKeyUsageOID

PATIENCE = 20.0
# The server's min_sampling_interval_ms in these checks, and the interval subscribed with.
SAMPLING_MS = 100
# What a change may take beyond two sampling intervals (see `subscribe`).
SLACK_MS = 40
NS = "urn:plcd:plc"
CLIENT_URI = "urn:plcd:tests:asyncua"
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


class Daemon:
    """`plcd run` on a copy of `project` (or in `dir`, kept from an earlier daemon), its
    [opcua] section replaced by `opcua` with listen on a free port and pki_dir = "pki"."""

    def __init__(self, plcd, project, opcua, dir=None, port=0, control=True):
        self.dir = dir or tempfile.mkdtemp(prefix="plcd-asyncua-")
        for name in os.listdir(project):
            shutil.copy(os.path.join(project, name), self.dir)
        config = os.path.join(self.dir, "plcd.toml")
        with open(config) as f:
            text = f.read()
        section = f'[opcua]\nlisten = "127.0.0.1:{port}"\npki_dir = "pki"\n{opcua}\n'
        if not control:
            text = text.replace('[control]\nsocket = "plcd.sock"', "[control]\nenabled = false")
        with open(config, "w") as f:
            # The project's [opcua] section is its last.
            f.write(text.split("\n[opcua]\n")[0] + "\n" + section)
        self.pki = Path(self.dir) / "pki"
        self.log = []
        self.proc = subprocess.Popen(
            [plcd, "run", "--config", config],
            stderr=subprocess.PIPE,
            stdout=subprocess.DEVNULL,
            text=True,
            env={k: v for k, v in os.environ.items()
                 if k not in ("NOTIFY_SOCKET", "WATCHDOG_USEC", "JOURNAL_STREAM", "STATE_DIRECTORY")},
        )
        self.reader = threading.Thread(target=self._read_log, daemon=True)
        self.reader.start()
        self.url = None

    def _read_log(self):
        for line in self.proc.stderr:
            self.log.append(line.rstrip("\n"))

    def serving(self):
        """The endpoint URL once the log says it serves, or None if it did not in time."""
        until = time.monotonic() + PATIENCE
        while time.monotonic() < until:
            for line in list(self.log):
                m = re.search(r"opcua: serving (opc\.tcp://\S+)", line)
                if m:
                    self.url = m.group(1)
                    return self.url
            if self.proc.poll() is not None:
                return None
            time.sleep(0.02)
        return None

    def exited(self):
        """The exit status once the daemon ended by itself, or None; its log read to the end."""
        try:
            status = self.proc.wait(timeout=PATIENCE)
        except subprocess.TimeoutExpired:
            return None
        # The reader thread may not have taken the last lines yet: it ends at end of file.
        self.reader.join(timeout=PATIENCE)
        return status

    def stop(self):
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout=PATIENCE)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self.reader.join(timeout=PATIENCE)

    def kill(self):
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()


async def bounded(what, coroutine):
    return await asyncio.wait_for(coroutine, PATIENCE)


def client(url):
    c = Client(url, timeout=5)
    c.application_uri = CLIENT_URI
    c.session_timeout = 30000
    return c


async def child_names(node):
    return {(await n.read_browse_name()).Name: n for n in await node.get_children()}


async def browse_and_read(url):
    c = client(url)
    async with c:
        ns = await c.get_namespace_index(NS)
        check("plcd's namespace is index 2", ns == 2, f"{ns}")
        objects = await child_names(c.nodes.objects)
        check("Objects holds PLC", "PLC" in objects, f"{sorted(objects)}")
        plc = await child_names(c.get_node(f"ns={ns};s=PLC"))
        check("PLC holds Status and Programs", {"Status", "Programs"} <= set(plc), f"{sorted(plc)}")
        status = await child_names(plc["Status"])
        expected = {"Mode", "ErrorCode", "ScanTimeLast", "ScanTimeMin", "ScanTimeMax", "Scans",
                    "KeySwitch"}
        check("Status holds the status variables", expected <= set(status), f"{sorted(status)}")
        programs = await child_names(plc["Programs"])
        check("Programs holds the instance main", "main" in programs, f"{sorted(programs)}")
        main = await child_names(programs["main"])
        check("main holds its variables by name",
              {"counter", "axis", "table[1]", "label", "level", "elapsed", "phase"} <= set(main),
              f"{sorted(main)}")
        axis = await child_names(main["axis"])
        check("a struct is an object of its members", {"pos", "steps", "ok"} <= set(axis),
              f"{sorted(axis)}")
        check("browse names are in plcd's namespace",
              (await main["counter"].read_browse_name()).NamespaceIndex == ns)

        node = lambda name: c.get_node(f"ns={ns};s={name}")
        # The status nodes hold what the sampler last copied: until its first copy after the
        # first scan (one sampling interval after the start, longer on a loaded machine), the
        # initial STOP and zeros. Wait for that copy, bounded.
        until = time.monotonic() + PATIENCE
        while time.monotonic() < until and not await node("Status.Scans").read_value():
            await asyncio.sleep(0.02)
        mode = await node("Status.Mode").read_value()
        check("Status.Mode reads RUN", mode == "RUN", f"{mode!r}")
        scans = await node("Status.Scans").read_value()
        check("Status.Scans counts", isinstance(scans, int) and scans > 0, f"{scans!r}")
        scan_max = await node("Status.ScanTimeMax").read_value()
        check("Status.ScanTimeMax is milliseconds in a Double",
              isinstance(scan_max, float) and 0 < scan_max < 10_000, f"{scan_max!r}")
        error = await node("Status.ErrorCode").read_value()
        check("Status.ErrorCode is empty without an error", error == "", f"{error!r}")
        # The daemon's status answer: percentiles, counters, each task (here the scan task).
        p99 = await wait_until(lambda: node("Status.ScanTimeP99").read_value(), lambda v: v > 0)
        check("Status.ScanTimeP99 is milliseconds from the daemon's histogram",
              isinstance(p99, float) and 0 < p99 < 10_000, f"{p99!r}")
        check("Status.WatchdogTrips reads 0", await node("Status.WatchdogTrips").read_value() == 0)
        tasks = await child_names(node("Status.Tasks"))
        check("Status.Tasks holds the scan task", "scan" in tasks, f"{sorted(tasks)}")
        runs = await node("Status.Tasks.scan.Runs").read_value() if "scan" in tasks else None
        check("a task's Runs count", isinstance(runs, int) and runs > 0, f"{runs!r}")
        kind = await node("Status.Tasks.scan.Kind").read_value() if "scan" in tasks else None
        check("a task's Kind", kind == "scan", f"{kind!r}")
        remote = await child_names(node("Status.Remote"))
        check("Status.Remote is empty without [[remote]]", not remote, f"{sorted(remote)}")

        first = await node("main.counter").read_value()
        moved = None
        until = time.monotonic() + PATIENCE
        while time.monotonic() < until:
            moved = await node("main.counter").read_value()
            if moved > first:
                break
            await asyncio.sleep(0.02)
        check("main.counter moves", moved is not None and moved > first, f"{first} then {moved}")
        variant = await node("main.counter").read_data_type_as_variant_type()
        check("a DINT is an Int32", variant == ua.VariantType.Int32, f"{variant}")
        # One Read of both members: of one scan boundary, so they agree (never torn).
        torn = []
        for _ in range(20):
            pos, steps = await c.read_values([node("main.axis.pos"), node("main.axis.steps")])
            if pos != steps * 0.5:
                torn.append((pos, steps))
            await asyncio.sleep(0.01)
        check("a struct's members are of one scan", not torn, f"{torn[:3]}")
        check("a struct member (LREAL) reads", isinstance(pos, float) and pos > 0, f"{pos!r}")
        values = await c.read_values([node(n) for n in
                                      ("main.table[2]", "main.table[4]", "main.label",
                                       "main.level", "main.elapsed", "main.phase",
                                       "main.axis.ok")])
        check("an array's elements read", values[:2] == [20, 40], f"{values[:2]}")
        table = await node("main.table").read_value()
        check("an array is an array variable too", table == [10, 20, 30, 40], f"{table!r}")
        grid = node("main.grid")
        value = await grid.read_value()
        check("a 2-D array reads as rows", value == [[1, 2, 3], [4, 5, 6]], f"{value!r}")
        rank, dims = await grid.read_value_rank(), await grid.read_array_dimensions()
        check("its ValueRank and ArrayDimensions are 2 and [2, 3]", (rank, dims) == (2, [2, 3]),
              f"{rank}, {dims}")
        part = (await grid.read_attribute(ua.AttributeIds.Value, "1,0:1")).Value.Value
        check("an index range of two dimensions reads the sub-array", part == [[4, 5]],
              f"{part!r}")
        part = (await node("main.table").read_attribute(ua.AttributeIds.Value, "1:2")).Value.Value
        check("an index range of one dimension reads the elements", part == [20, 30], f"{part!r}")
        code = await status_of(grid.read_attribute(ua.AttributeIds.Value, "2,0"))
        check("an index range past the end reads BadIndexRangeNoData",
              code == "BadIndexRangeNoData", f"{code}")
        element = await node("main.grid[2,3]").read_value()
        check("a 2-D array's element reads by its name", element == 6, f"{element!r}")
        subscription = await c.create_subscription(SAMPLING_MS, Changes())
        items = []
        for name, index_range in (("main.table", "1:2"), ("main.grid", "1,0:1")):
            item = subscription._make_monitored_item_request(
                node(name), ua.AttributeIds.Value, None, 1, ua.MonitoringMode.Reporting,
                SAMPLING_MS)
            item.ItemToMonitor.IndexRange = index_range
            items.append(item)
        one, two = await bounded("create monitored items", subscription.create_monitored_items(items))
        check("a subscription to a range of one dimension is created", isinstance(one, int),
              f"{one!r}")
        check("one to a range of two dimensions is BadIndexRangeInvalid",
              getattr(two, "name", two) == "BadIndexRangeInvalid", f"{two!r}")
        await bounded("delete the subscription", subscription.delete())
        check("a STRING reads", values[2] == "plcd", f"{values[2]!r}")
        check("a located INT reads its device word", values[3] == 7, f"{values[3]!r}")
        check("a TIME is a Duration in milliseconds", values[4] == 1500.0, f"{values[4]!r}")
        check("an enumeration reads as its integer", values[5] == 5, f"{values[5]!r}")
        phase = node("main.phase")
        definition = await phase.read_type_definition()
        check("an enumeration is a MultiStateValueDiscreteType",
              definition == ua.NodeId(ua.ObjectIds.MultiStateValueDiscreteType), f"{definition}")
        properties = {(await p.read_browse_name()).Name: p for p in await phase.get_properties()}
        names = ([(v.Value, v.DisplayName.Text) for v in await properties["EnumValues"].read_value()]
                 if "EnumValues" in properties else None)
        check("its EnumValues name its values", names == [(0, "Idle"), (5, "Moving")], f"{names}")
        text = await wait_until(lambda: properties["ValueAsText"].read_value(),
                                lambda v: v.Text == "Moving") if "ValueAsText" in properties else None
        check("its ValueAsText is the current value's name",
              text is not None and text.Text == "Moving", f"{text}")
        check("a BOOL reads", values[6] is True, f"{values[6]!r}")
        level_type = await node("main.level").read_data_type_as_variant_type()
        check("an INT is an Int16", level_type == ua.VariantType.Int16, f"{level_type}")

        # A write is refused: the address space is read-only this round.
        try:
            await node("main.counter").write_value(ua.DataValue(ua.Variant(1, ua.VariantType.Int32)))
            check("a write is refused", False, "accepted")
        except ua.UaStatusCodeError as e:
            check("a write is refused", "NotWritable" in type(e).__name__ or "Denied" in type(e).__name__,
                  type(e).__name__)

        await subscribe(c, node("main.counter"))
        await deadband(c, node("main.counter"), node("main.axis.steps"))


class Changes:
    def __init__(self):
        self.stamps = []
        self.values = []
        self.statuses = []

    def datachange_notification(self, node, value, data):
        self.values.append(value)
        self.stamps.append(data.monitored_item.Value.SourceTimestamp)
        self.statuses.append(data.monitored_item.Value.StatusCode.name)


async def notified(changes, count):
    """Waits, bounded by PATIENCE, until `changes` holds `count` values (or fewer at the end)."""
    until = time.monotonic() + PATIENCE
    while len(changes.values) < count and time.monotonic() < until:
        await asyncio.sleep(0.02)


async def subscribe(c, counter):
    handler = Changes()
    subscription = await c.create_subscription(SAMPLING_MS, handler)
    await subscription.subscribe_data_change(counter, sampling_interval=SAMPLING_MS)
    await notified(handler, 6)
    check("a subscription's data changes arrive", len(handler.values) >= 6,
          f"{len(handler.values)} changes")
    rising = all(b > a for a, b in zip(handler.values, handler.values[1:]))
    check("the changes follow the counter", rising, f"{handler.values}")
    # The server stamps each value when it takes it from a scan boundary's copy: consecutive
    # changes of a counter that moves every scan are at most two sampling intervals apart (a
    # copy every interval, sampled by the item every interval), plus what a copy waits for
    # its scan boundary (a 10 ms scan) and the server's threads, which are not real time:
    # SLACK_MS. Server-side stamps, so that the client's own scheduling does not count.
    gaps = [(b - a).total_seconds() * 1000 for a, b in zip(handler.stamps, handler.stamps[1:])]
    check(f"data changes come within two sampling intervals ({2 * SAMPLING_MS} ms + {SLACK_MS})",
          gaps and max(gaps) <= 2 * SAMPLING_MS + SLACK_MS, f"gaps {gaps} ms")
    await subscription.delete()


async def wait_value(node, wanted, patience=PATIENCE):
    """Reads `node` until it is `wanted` (bounded); the last value read."""
    until = time.monotonic() + patience
    value = None
    while time.monotonic() < until:
        try:
            value = await node.read_value()
        except ua.UaStatusCodeError as e:
            # not there yet (a node the address space is about to get)
            value = type(e).__name__
        if value == wanted:
            break
        await asyncio.sleep(0.02)
    return value


async def wait_until(read, ok, patience=PATIENCE):
    """`read()` until `ok(value)` (bounded); the last value read, None if every read failed."""
    until = time.monotonic() + patience
    value = None
    while time.monotonic() < until:
        try:
            value = await read()
            if value is not None and ok(value):
                break
        except ua.UaStatusCodeError:
            pass
        await asyncio.sleep(0.02)
    return value


async def status_of(coroutine):
    """The OPC UA status code's name a refused call or write raised; None if it succeeded."""
    try:
        await bounded("a service", coroutine)
        return None
    except asyncio.TimeoutError:
        return "timed out"
    except ua.UaStatusCodeError as e:
        return type(e).__name__


async def writes_and_methods(url, daemon, control):
    """An anonymous operator (anonymous = "operator") writes the writable variables and calls
    the PLC's methods; `control` says whether the control socket is on (the door serves the
    writes either way)."""
    suffix = "" if control else " (control socket off)"
    async with client(url) as c:
        ns = await c.get_namespace_index(NS)
        node = lambda name: c.get_node(f"ns={ns};s={name}")  # noqa: E731
        setpoint, echo, mode = node("main.setpoint"), node("main.echo"), node("Status.Mode")
        await setpoint.write_value(ua.Variant(37, ua.VariantType.Int16))
        check("a write is answered once applied: read at once, it is the new value" + suffix,
              await setpoint.read_value() == 37)
        check("the program sees the written value" + suffix, await wait_value(echo, 37) == 37)
        if not control:
            return
        access = (await setpoint.read_attribute(ua.AttributeIds.AccessLevel)).Value.Value
        check("a writable variable's AccessLevel has CurrentWrite", access & 2 == 2, f"{access}")
        counter_access = (await node("main.counter").read_attribute(ua.AttributeIds.AccessLevel)).Value.Value
        check("a variable not in writable has no CurrentWrite", counter_access & 2 == 0,
              f"{counter_access}")
        # The members of a struct in one Write request: applied at the same scan boundary.
        pos, steps = node("main.recipe.pos"), node("main.recipe.steps")
        params = ua.WriteParameters()
        for n, v in ((pos, ua.Variant(2.5, ua.VariantType.Double)),
                     (steps, ua.Variant(-9, ua.VariantType.Int32))):
            wv = ua.WriteValue()
            wv.NodeId = n.nodeid
            wv.AttributeId = ua.AttributeIds.Value
            wv.Value = ua.DataValue(v)
            params.NodesToWrite.append(wv)
        results = await bounded("a write of two", c.uaclient.write(params))
        check("two values in one Write are both Good", [r.is_good() for r in results] == [True, True],
              f"{results}")
        check("both read back", [await pos.read_value(), await steps.read_value()] == [2.5, -9])
        note = node("main.note")
        await note.write_value(ua.Variant("hé", ua.VariantType.String))
        check("a STRING is written (Windows-1252 characters)", await note.read_value() == "hé")
        code = await status_of(note.write_value(ua.Variant("far too long", ua.VariantType.String)))
        check("a STRING longer than declared is BadOutOfRange", code == "BadOutOfRange", f"{code}")
        check("and the value stays", await note.read_value() == "hé")
        table = node("main.table")
        await table.write_value(ua.Variant([1, 2, 3, 4], ua.VariantType.Int16))
        check("an array is written whole", await table.read_value() == [1, 2, 3, 4])
        check("and its elements with it", await wait_value(node("main.table[3]"), 3) == 3)
        code = await status_of(table.write_value(ua.Variant([1, 2], ua.VariantType.Int16)))
        check("an array of another length is BadOutOfRange", code == "BadOutOfRange", f"{code}")

        def part(values, dims=None):
            return ua.DataValue(ua.Variant(values, ua.VariantType.Int16, Dimensions=dims))

        await table.write_attribute(ua.AttributeIds.Value, part([21, 22]), "1:2")
        value = await table.read_value()
        check("an index range writes those elements alone", value == [1, 21, 22, 4], f"{value!r}")
        check("and the program has them", await wait_value(node("main.table[3]"), 22) == 22)
        grid = node("main.grid")
        await grid.write_value(ua.Variant([[6, 5, 4], [3, 2, 1]], ua.VariantType.Int16))
        value = await grid.read_value()
        check("a 2-D array is written whole", value == [[6, 5, 4], [3, 2, 1]], f"{value!r}")
        check("and its elements with it", await wait_value(node("main.grid[2,1]"), 3) == 3)
        await grid.write_attribute(ua.AttributeIds.Value, part([[8, 9]], [1, 2]), "0,1:2")
        value = await grid.read_value()
        check("an index range of two dimensions writes the sub-array",
              value == [[6, 8, 9], [3, 2, 1]], f"{value!r}")
        check("and the program has it", await wait_value(node("main.grid[1,3]"), 9) == 9)
        code = await status_of(grid.write_attribute(ua.AttributeIds.Value, part([1], [1, 1]),
                                                    "2,0"))
        check("a write past the end is BadIndexRangeNoData", code == "BadIndexRangeNoData",
              f"{code}")
        code = await status_of(grid.write_attribute(ua.AttributeIds.Value, part([1]), "1"))
        check("a write with one index into a 2-D array is BadIndexRangeInvalid",
              code == "BadIndexRangeInvalid", f"{code}")
        code = await status_of(grid.write_attribute(ua.AttributeIds.Value, part([1, 2]), "0,0"))
        check("a write of more values than the range holds is BadOutOfRange",
              code == "BadOutOfRange", f"{code}")
        code = await status_of(node("main.note").write_attribute(
            ua.AttributeIds.Value, ua.DataValue(ua.Variant("x", ua.VariantType.String)), "0"))
        check("an index range into a STRING is BadWriteNotSupported",
              code == "BadWriteNotSupported", f"{code}")
        value = await grid.read_value()
        check("and refused writes change nothing", value == [[6, 8, 9], [3, 2, 1]], f"{value!r}")
        devices = await child_names(node("Devices"))
        check("the device ranges are in the Devices folder",
              set(devices) == {"D00100", "D00101", "M0000", "M0001", "M0002", "M0003"},
              f"{sorted(devices)}")
        check("a device word reads (the located variable's)",
              await wait_value(node("Devices.D00100"), 7) == 7)
        await node("Devices.D00101").write_value(ua.Variant(-9, ua.VariantType.Int16))
        check("a writable device word is written", await node("Devices.D00101").read_value() == -9)
        check("a device bit reads as a Boolean", await node("Devices.M0001").read_value() is False)
        code = await status_of(node("Devices.M0001").write_value(ua.Variant(True, ua.VariantType.Boolean)))
        check("a device of a range not writable is BadNotWritable", code == "BadNotWritable", f"{code}")
        code = await status_of(node("main.counter").write_value(ua.Variant(1, ua.VariantType.Int32)))
        check("a variable not in writable is BadNotWritable", code == "BadNotWritable", f"{code}")
        code = await status_of(setpoint.write_value(ua.Variant(5, ua.VariantType.Int32)))
        check("an Int32 for an INT is BadTypeMismatch", code == "BadTypeMismatch", f"{code}")
        logged = any("control: set from opcua anonymous session" in line for line in daemon.log)
        check("the log says who wrote", logged, "\n".join(daemon.log[-10:]))

        plc = node("PLC")
        await bounded("Stop", plc.call_method(f"{ns}:Stop"))
        check("the Stop method stops the PLC", await wait_value(mode, "STOP") == "STOP")
        await bounded("Run", plc.call_method(f"{ns}:Run"))
        check("the Run method runs it again", await wait_value(mode, "RUN") == "RUN")
        # An overrun scan: the watchdog stops the PLC with an error; RUN is then refused.
        await node("main.spin").write_value(ua.Variant(True, ua.VariantType.Boolean))
        check("a scan that never ends puts the PLC in ERROR", await wait_value(mode, "ERROR") == "ERROR")
        check("Status.ErrorCode says WDT", await node("Status.ErrorCode").read_value() == "WDT")
        code = await status_of(plc.call_method(f"{ns}:Run"))
        check("Run in ERROR is BadInvalidState (the mode rules)", code == "BadInvalidState", f"{code}")
        await node("main.spin").write_value(ua.Variant(False, ua.VariantType.Boolean))
        code = await status_of(plc.call_method(f"{ns}:Reset"))
        check("Reset without its argument is refused", code == "BadArgumentsMissing", f"{code}")
        await bounded("Reset", plc.call_method(f"{ns}:Reset", ua.Variant(False, ua.VariantType.Boolean)))
        check("Reset clears the error: STOP", await wait_value(mode, "STOP") == "STOP")
        await bounded("Run", plc.call_method(f"{ns}:Run"))
        check("and Run runs again", await wait_value(mode, "RUN") == "RUN")


async def follows_a_reload(url, daemon):
    """A SIGHUP reload of a changed program: the address space becomes the new project's. A
    subscription to a variable both projects have goes on (the counter starts again from 0: the
    programs restart), a new variable is there, a removed one's subscriber is told
    BadNodeIdUnknown and its node is gone."""
    async with client(url) as c:
        ns = await c.get_namespace_index(NS)
        node = lambda name: c.get_node(f"ns={ns};s={name}")  # noqa: E731
        counter_changes, phase_changes = Changes(), Changes()
        subscription = await c.create_subscription(SAMPLING_MS, counter_changes)
        await subscription.subscribe_data_change(node("main.counter"), sampling_interval=SAMPLING_MS)
        other = await c.create_subscription(SAMPLING_MS, phase_changes)
        await other.subscribe_data_change(node("main.phase"), sampling_interval=SAMPLING_MS)
        await notified(counter_changes, 3)
        before = len(counter_changes.values)
        highest = max(counter_changes.values, default=0)
        program = Path(daemon.dir) / "main.st"
        text = program.read_text()
        # `phase` removed, `extra` added, `label` longer (a STRING keeps its node).
        text = text.replace("    phase : Phase := Moving;\n", "    extra : INT := 42;\n")
        program.write_text(text.replace("label : STRING[20]", "label : STRING[40]"))
        daemon.proc.send_signal(signal.SIGHUP)
        until = time.monotonic() + PATIENCE
        followed = False
        while time.monotonic() < until and not followed:
            followed = any("address space follows the new project" in line for line in daemon.log)
            await asyncio.sleep(0.02)
        check("a reload: the log says the address space follows", followed,
              "\n".join(daemon.log[-10:]))
        check("a new variable is served", await wait_value(node("main.extra"), 42) == 42)
        code = await status_of(node("main.phase").read_value())
        check("a removed variable's node is gone", code == "BadNodeIdUnknown", f"{code}")
        until = time.monotonic() + PATIENCE
        while time.monotonic() < until and not any(v is not None and v < highest for v in counter_changes.values[before:]):
            await asyncio.sleep(0.02)
        after = [v for v in counter_changes.values[before:] if v is not None]
        check("a subscription to a kept variable goes on (the counter restarted)",
              any(v < highest for v in after), f"{highest} before, then {after[:8]}")
        # Told at the subscription's next publish, which may come after the counter's.
        until = time.monotonic() + PATIENCE
        while time.monotonic() < until and "BadNodeIdUnknown" not in phase_changes.statuses:
            await asyncio.sleep(0.02)
        check("a removed variable's subscriber is told BadNodeIdUnknown",
              "BadNodeIdUnknown" in phase_changes.statuses, f"{phase_changes.statuses}")
        check("a kept STRING reads", await node("main.label").read_value() == "plcd")


async def follows_an_online_change(url, daemon, plcctl):
    """`plcctl load --online` of a program with one more variable: the address space follows,
    and a subscription to the counter goes on without a restart (an online change keeps the
    values)."""
    async with client(url) as c:
        ns = await c.get_namespace_index(NS)
        node = lambda name: c.get_node(f"ns={ns};s={name}")  # noqa: E731
        changes = Changes()
        subscription = await c.create_subscription(SAMPLING_MS, changes)
        await subscription.subscribe_data_change(node("main.counter"), sampling_interval=SAMPLING_MS)
        program = Path(daemon.dir) / "main.st"
        program.write_text(program.read_text().replace(
            "    extra : INT := 42;\n", "    extra : INT := 42;\n    more : INT := 7;\n"))
        config = str(Path(daemon.dir) / "plcd.toml")
        done = subprocess.run([plcctl, "--socket", str(Path(daemon.dir) / "plcd.sock"), "load",
                               "--online", "--config", config],
                              capture_output=True, text=True, timeout=PATIENCE)
        check("plcctl load --online is accepted", done.returncode == 0, done.stdout + done.stderr)
        check("an online change: the new variable is served",
              await wait_value(node("main.more"), 7) == 7)
        followed = [line for line in daemon.log if "address space follows the new project" in line]
        check("the log says so again", len(followed) == 2, "\n".join(daemon.log[-10:]))
        await notified(changes, 8)
        values = [v for v in changes.values if v is not None]
        check("the counter's subscription goes on, never restarting",
              len(values) >= 8 and all(b > a for a, b in zip(values, values[1:])), f"{values}")


async def viewer_refused(url):
    """An anonymous viewer: the writable variable is not writable for it, nor are the methods."""
    async with client(url) as c:
        ns = await c.get_namespace_index(NS)
        setpoint = c.get_node(f"ns={ns};s=main.setpoint")
        level = (await setpoint.read_attribute(ua.AttributeIds.UserAccessLevel)).Value.Value
        check("a viewer's UserAccessLevel has no CurrentWrite", level & 2 == 0, f"{level}")
        code = await status_of(setpoint.write_value(ua.Variant(1, ua.VariantType.Int16)))
        check("a viewer's write is BadUserAccessDenied", code == "BadUserAccessDenied", f"{code}")
        code = await status_of(c.get_node(f"ns={ns};s=PLC").call_method(f"{ns}:Stop"))
        check("a viewer's Stop is BadUserAccessDenied", code == "BadUserAccessDenied", f"{code}")
        # (read until RUN, bounded: a daemon just started shows STOP until its first scan)
        mode = await wait_value(c.get_node(f"ns={ns};s=Status.Mode"), "RUN")
        check("and the PLC still runs", mode == "RUN", f"{mode}")


async def deadband(c, counter, plain):
    """An absolute deadband filter: a change is notified only once the value moved more than
    the deadband from the last one notified. The counter moves by one every 10 ms scan, so
    about 10 between two samples: with a deadband of 50, every notified change is more than 50
    from the one before. A percent deadband is of the variable's EURange: 1 % of the counter's
    0..5000 ([[opcua.analog]]) is 50 again; `plain`, without one, refuses it."""
    def item(node, handle, kind, value):
        params = ua.MonitoredItemCreateRequest()
        params.ItemToMonitor = ua.ReadValueId(NodeId=node.nodeid, AttributeId=ua.AttributeIds.Value)
        params.MonitoringMode = ua.MonitoringMode.Reporting
        params.RequestedParameters = ua.MonitoringParameters(
            ClientHandle=handle, SamplingInterval=SAMPLING_MS, QueueSize=10, DiscardOldest=True,
            Filter=ua.DataChangeFilter(Trigger=ua.DataChangeTrigger.StatusValue,
                                       DeadbandType=kind, DeadbandValue=value))
        return params

    async def moves(subscription, handler, params, what):
        """The item created in `subscription` (checked accepted) and, once `handler` has four
        notified values, the moves between them."""
        results = await subscription.create_monitored_items([params])
        check(f"{what} is accepted", results and isinstance(results[0], int), f"{results}")
        await notified(handler, 4)
        return [b - a for a, b in zip(handler.values, handler.values[1:])]

    handler = Changes()
    subscription = await c.create_subscription(SAMPLING_MS, handler)
    steps = await moves(subscription, handler, item(counter, 1, ua.DeadbandType.Absolute, 50.0),
                        "an absolute deadband filter")
    check("with a deadband of 50, each notified change moved more than 50",
          len(steps) >= 3 and min(steps) > 50, f"{handler.values}")
    definition = await counter.read_type_definition()
    check("a variable of [[opcua.analog]] is an AnalogItemType",
          definition == ua.NodeId(ua.ObjectIds.AnalogItemType), f"{definition}")
    properties = {(await p.read_browse_name()).Name: p for p in await counter.get_properties()}
    eu = await properties["EURange"].read_value() if "EURange" in properties else None
    check("its EURange is the config's", eu is not None and (eu.Low, eu.High) == (0.0, 5000.0),
          f"{eu!r}")
    percent = Changes()
    by_percent = await c.create_subscription(SAMPLING_MS, percent)
    by_one_percent = item(counter, 2, ua.DeadbandType.Percent, 1.0)
    steps = await moves(by_percent, percent, by_one_percent, "a percent deadband on it")
    # The stack compares fractions of the range in floating point: a move of exactly 1 % may
    # pass by rounding (331 to 381 did), so at least 50, where the absolute deadband is past it.
    check("with 1 % of 0..5000, each notified change moved at least 50",
          len(steps) >= 3 and min(steps) >= 50, f"{percent.values}")
    await by_percent.delete()
    try:
        params = item(plain, 3, ua.DeadbandType.Percent, 1.0)
        result = (await subscription.create_monitored_items([params]))[0]
        text = result.name if isinstance(result, ua.StatusCode) else repr(result)
    except ua.UaStatusCodeError as e:
        text = type(e).__name__
    check("a percent deadband on a variable without EURange is refused", text.startswith("Bad"),
          text)
    await subscription.delete()


async def refused(what, coroutine, because):
    """Checks that `coroutine` (a connection) fails with an error naming `because` (an OPC UA
    status code's name)."""
    try:
        await asyncio.wait_for(coroutine, PATIENCE)
    except asyncio.TimeoutError:
        check(what, False, "timed out instead of being refused")
        return
    except Exception as e:  # noqa: BLE001 - the status code's name says which refusal
        text = f"{type(e).__name__}: {e}"
        check(what, because in text, text)
        return
    check(what, False, "accepted")


async def none_refused(url):
    """The None policy, not listed: the server offers no such endpoint, and a client that
    opens a session over a None channel anyway is refused when it activates it."""
    c = client(url)
    endpoints = await bounded("endpoints", c.connect_and_get_server_endpoints())
    policies = {e.SecurityPolicyUri.rsplit("#", 1)[-1] for e in endpoints}
    check("the endpoints offer the default policies and not None",
          policies == {"Basic256Sha256", "Aes128_Sha256_RsaOaep", "Aes256_Sha256_RsaPss"},
          f"{sorted(policies)}")
    modes = {e.SecurityMode for e in endpoints}
    check("each with Sign and SignAndEncrypt",
          modes == {ua.MessageSecurityMode.Sign, ua.MessageSecurityMode.SignAndEncrypt},
          f"{modes}")

    async def forced():
        # asyncua itself refuses a policy the server does not offer: it is made to take the
        # first endpoint, so that the server's own check is what refuses.
        find_endpoint = Client.find_endpoint
        Client.find_endpoint = staticmethod(lambda endpoints, mode, uri: endpoints[0])
        try:
            await c.connect_socket()
            await c.send_hello()
            await c.open_secure_channel()
            await c.create_session()
            await c.activate_session()
        finally:
            Client.find_endpoint = find_endpoint
            c.disconnect_socket()

    await refused("a session over the None policy, not listed, is refused", forced(),
                  "BadTcpEndpointUrlInvalid")


async def connect_and_read(url, secure=None, user=None):
    c = client(url)
    if user:
        c.set_user(user[0])
        c.set_password(user[1])
    if secure:
        cert, key = secure
        await c.set_security(security_policies.SecurityPolicyBasic256Sha256, str(cert), str(key),
                             mode=ua.MessageSecurityMode.SignAndEncrypt)
    async with c:
        ns = await c.get_namespace_index(NS)
        return await c.get_node(f"ns={ns};s=main.counter").read_value()


def raw(port, source="127.0.0.1"):
    """A plain TCP connection to the server from `source` (any 127.x.y.z is this machine)."""
    sock = socket.socket()
    sock.settimeout(PATIENCE)
    sock.bind((source, 0))
    sock.connect(("127.0.0.1", port))
    return sock


def closed_within(sock, seconds):
    """True if the server closes `sock` within `seconds` (what it sends before is read away)."""
    until = time.monotonic() + seconds
    while time.monotonic() < until:
        sock.settimeout(max(0.01, until - time.monotonic()))
        try:
            if sock.recv(65536) == b"":
                return True
        except socket.timeout:
            return False
        except (ConnectionResetError, BrokenPipeError):
            return True
    return False


def logged(daemon, text):
    """The log lines holding `text`, once the log has one (bounded)."""
    until = time.monotonic() + PATIENCE
    while time.monotonic() < until:
        lines = [line for line in list(daemon.log) if text in line]
        if lines:
            # A second line for the same address and kind would come at once: give it time.
            time.sleep(0.2)
            return [line for line in list(daemon.log) if text in line]
        time.sleep(0.02)
    return []


async def the_front(url, daemon):
    """The limits of the server's public side (max_connections 4, 3 per address, 20 requests a
    second, io_timeout_ms 500, max_request_bytes 65536): each refusal or cut-off logged once per
    address, and the server unharmed: a client connects and reads after each."""
    port = int(url.rsplit(":", 1)[1].strip("/"))

    async def still_serves(after):
        # A place is freed when the front has seen the client's close, which may come after
        # the next connection's accept: a refused client tries again, for up to 5 s.
        value, outcome = None, "no try"
        for _ in range(10):
            try:
                value = await bounded("a read", connect_and_read(url))
                outcome = repr(value)
                break
            except ConnectionError as e:
                outcome = repr(e)
                await asyncio.sleep(0.5)
            except Exception as e:  # noqa: BLE001 - any other failure is the check's
                outcome = repr(e)
                break
        check(f"after {after}, a client still connects and reads", isinstance(value, int),
              outcome)

    # Connections: 3 from 127.0.0.1, a 4th from there refused; one from 127.0.0.2 makes 4 in
    # all, and one from 127.0.0.3 is then refused by max_connections.
    held = [raw(port) for _ in range(3)]
    fourth = raw(port)
    check("a 4th connection from one address is closed at once", closed_within(fourth, 5))
    again = raw(port)
    check("and a 5th", closed_within(again, 5))
    held.append(raw(port, "127.0.0.2"))
    check("a connection from another address is kept", not closed_within(held[-1], 0.3))
    beyond = raw(port, "127.0.0.3")
    check("past max_connections, any address is closed at once", closed_within(beyond, 5))
    lines = logged(daemon, "client 127.0.0.1: connection refused: 3 connections open from this")
    check("refusals from one address are logged once", len(lines) == 1, "\n".join(daemon.log[-10:]))
    check("the refusal past max_connections is logged, naming the key",
          len(logged(daemon, "client 127.0.0.3: connection refused: 4 connections open "
                             "([opcua] max_connections)")) == 1, "\n".join(daemon.log[-10:]))
    for sock in held + [fourth, again, beyond]:
        sock.close()
    await still_serves("the connections were closed")

    # A chunk begun and not finished: cut off after io_timeout_ms.
    stalled = raw(port)
    stalled.sendall(b"HELF")
    check("a client stalling in a chunk is cut off", closed_within(stalled, 5))
    stalled.close()
    check("the stall is logged", len(logged(daemon, "did not arrive whole within 500 ms")) == 1,
          "\n".join(daemon.log[-10:]))

    # A chunk longer than max_request_bytes: cut off before the stack sees it.
    long = raw(port)
    long.sendall(b"MSGF" + (70000).to_bytes(4, "little") + bytes(100))
    check("a message longer than max_request_bytes is cut off", closed_within(long, 5))
    long.close()
    check("the long message is logged",
          len(logged(daemon, "a message longer than 65536 bytes")) == 1,
          "\n".join(daemon.log[-10:]))

    # Bytes that are not OPC UA.
    http = raw(port)
    http.sendall(b"GET / HTTP/1.1\r\nHost: plc\r\n\r\n")
    check("an HTTP request is cut off", closed_within(http, 5))
    http.close()

    # A flood of reads from a real client. (asyncio warns once for each send to the closed
    # socket: quiet while it lasts.)
    asyncio_log = logging.getLogger("asyncio")
    asyncio_log.setLevel(logging.ERROR)
    c = client(url)
    outcome = "no error"
    try:
        await bounded("connect", c.connect())
        ns = await c.get_namespace_index(NS)
        counter = c.get_node(f"ns={ns};s=main.counter")
        results = await asyncio.wait_for(
            asyncio.gather(*[counter.read_value() for _ in range(300)], return_exceptions=True),
            PATIENCE)
        errors = [r for r in results if isinstance(r, Exception)]
        outcome = f"{len(errors)} of 300 reads failed"
        check("a client sending 300 reads at once is cut off", errors, outcome)
    except Exception as e:  # noqa: BLE001 - being cut off may surface anywhere
        check("a client sending 300 reads at once is cut off", True)
        outcome = repr(e)
    finally:
        try:
            await asyncio.wait_for(c.disconnect(), 5)
        except Exception:  # noqa: BLE001 - the connection is gone
            pass
        asyncio_log.setLevel(logging.NOTSET)
    check("the flood is logged once",
          len(logged(daemon, "cut off: more than 20 requests a second")) == 1,
          outcome + "\n" + "\n".join(daemon.log[-10:]))
    await still_serves("a flood")
    check("the daemon still runs", daemon.proc.poll() is None)


async def client_certificate(dir):
    cert, key = Path(dir) / "client.der", Path(dir) / "client.pem"
    await setup_self_signed_certificate(key, cert, CLIENT_URI, "localhost",
                                        [ExtendedKeyUsageOID.CLIENT_AUTH], {"commonName": "plcd asyncua"})
    return cert, key


def wait_file(directory, patience=PATIENCE):
    until = time.monotonic() + patience
    while time.monotonic() < until:
        files = list(directory.glob("*")) if directory.is_dir() else []
        if files:
            return files
        time.sleep(0.02)
    return []


async def main_checks(plcd, plcctl, project, work):
    daemons = []

    def start(opcua, **kw):
        d = Daemon(plcd, project, opcua, **kw)
        daemons.append(d)
        return d

    try:
        # 1. Anonymous viewers over the None policy, listed: browse, read, subscribe.
        open_daemon = start(f'security_policies = ["None", "Basic256Sha256"]\nanonymous = "viewer"\n'
                            f"min_sampling_interval_ms = {SAMPLING_MS}\n"
                            '[[opcua.analog]]\nvariable = "main.counter"\nlow = 0\nhigh = 5000')
        url = open_daemon.serving()
        check("the log names the endpoint", url is not None, "\n".join(open_daemon.log[-20:]))
        if url is None:
            return
        await bounded("browse and read", browse_and_read(url))
        key = open_daemon.pki / "private" / "private.pem"
        mode = stat.S_IMODE(key.stat().st_mode) if key.exists() else None
        check("the server's key is mode 0600", mode == 0o600, f"{mode and oct(mode)}")
        cert = open_daemon.pki / "own" / "cert.der"
        first_cert = cert.read_bytes() if cert.exists() else None
        open_daemon.stop()
        again = start('security_policies = ["None"]\nanonymous = "viewer"', dir=open_daemon.dir)
        check("a restart serves again", again.serving() is not None, "\n".join(again.log[-20:]))
        check("the certificate made at the first start is reused",
              first_cert is not None and cert.read_bytes() == first_cert)
        again.stop()

        # 2. The default policies: None refused; a client certificate rejected until trusted.
        secure = start('anonymous = "viewer"')
        url = secure.serving()
        check("the secure server serves", url is not None, "\n".join(secure.log[-20:]))
        if url is None:
            return
        await none_refused(url)
        certificate = await client_certificate(work)
        await refused("an untrusted client certificate is refused",
                      connect_and_read(url, secure=certificate), "BadCertificateUntrusted")
        rejected = wait_file(secure.pki / "rejected")
        check("the refused certificate lands in rejected/", len(rejected) == 1,
              f"{[p.name for p in rejected]}")
        for path in rejected:
            shutil.move(str(path), str(secure.pki / "trusted" / path.name))
        try:
            counter = await bounded("secure read", connect_and_read(url, secure=certificate))
            check("Basic256Sha256 SignAndEncrypt works once the certificate is trusted",
                  isinstance(counter, int) and counter > 0, f"{counter!r}")
        except Exception as e:  # noqa: BLE001
            check("Basic256Sha256 SignAndEncrypt works once the certificate is trusted", False,
                  repr(e))
        secure.stop()

        # 3. anonymous = "none" (the default): every session refused, secure or not.
        closed = start('security_policies = ["None", "Basic256Sha256"]', dir=secure.dir)
        url = closed.serving()
        check("the closed server serves", url is not None, "\n".join(closed.log[-20:]))
        if url is None:
            return
        await refused("an anonymous session is refused with anonymous = \"none\"",
                      connect_and_read(url), "BadIdentityToken")
        await refused("a secure anonymous session is refused too",
                      connect_and_read(url, secure=certificate), "BadIdentityToken")
        closed.stop()

        # 3b. Named logins from the users file (made with `plcd user add`), anonymous refused.
        users_file = Path(secure.dir) / "users"
        made = subprocess.run([plcd, "user", "add", "alice", "--role", "viewer", "--file",
                               str(users_file), "--password-stdin"], input="correct horse\n",
                              capture_output=True, text=True, timeout=PATIENCE)
        check("plcd user add writes the users file", made.returncode == 0, made.stderr)
        named = start('security_policies = ["None", "Basic256Sha256"]\n[users]\nfile = "users"',
                      dir=secure.dir)
        url = named.serving()
        check("the server with a users file serves", url is not None, "\n".join(named.log[-20:]))
        if url is None:
            return
        alice = ("alice", "correct horse")
        try:
            counter = await bounded("named read", connect_and_read(url, certificate, alice))
            check("a user of the file logs in (Basic256Sha256 SignAndEncrypt) and reads",
                  isinstance(counter, int), f"{counter!r}")
        except Exception as e:  # noqa: BLE001
            check("a user of the file logs in (Basic256Sha256 SignAndEncrypt) and reads", False,
                  repr(e))
        endpoints = await bounded("endpoints", client(url).connect_and_get_server_endpoints())
        plain = [e for e in endpoints if e.SecurityMode == ua.MessageSecurityMode.None_]
        names = [t for e in plain for t in e.UserIdentityTokens
                 if t.TokenType == ua.UserTokenType.UserName]
        check("the None endpoint takes no user name (no password in clear)",
              plain and not names, f"{len(plain)} None endpoints, {len(names)} user-name policies")
        await refused("an unknown user is refused", connect_and_read(url, certificate, ("bob", "x")),
                      "BadUserAccessDenied")
        # A user added while the server runs logs in without a restart (the file is looked at
        # once a second at most, when a login comes).
        made = subprocess.run([plcd, "user", "add", "carol", "--role", "operator", "--file",
                               str(users_file), "--password-stdin"], input="battery staple\n",
                              capture_output=True, text=True, timeout=PATIENCE)
        check("plcd user add while the server runs", made.returncode == 0, made.stderr)
        await asyncio.sleep(1.1)
        try:
            counter = await bounded("a new user", connect_and_read(url, certificate,
                                                                   ("carol", "battery staple")))
            check("a user added while the server runs logs in", isinstance(counter, int),
                  f"{counter!r}")
        except Exception as e:  # noqa: BLE001
            check("a user added while the server runs logs in", False, repr(e))
        read_again = any("users file" in line and "read again" in line for line in named.log)
        check("the log says the users file was read again", read_again, "\n".join(named.log[-10:]))
        # 3 failures earn a wait of 1 s, and each attempt during it (counted too) doubles it:
        # after 6, at least 8 s, longer than any connection here takes.
        for _ in range(6):
            await refused("a wrong password is refused",
                          connect_and_read(url, certificate, ("alice", "wrong")),
                          "BadUserAccessDenied")
        await refused("after 6 failures the right password waits (throttled per user name)",
                      connect_and_read(url, certificate, alice), "BadUserAccessDenied")
        warned = [line for line in named.log if "failed login for user name \"alice\"" in line]
        check("the failed logins of one name are logged once", len(warned) == 1,
              "\n".join(named.log[-20:]))
        named.stop()

        # 3c. Writes and methods: an anonymous operator, then an anonymous viewer; and the
        # writes with the control socket off.
        writable = ('writable = ["main.setpoint", "main.recipe", "main.note", "main.spin", '
                    '"main.table", "main.grid"]\n'
                    '[[opcua.devices]]\ndevice = "D00100"\ncount = 2\nwritable = true\n'
                    '[[opcua.devices]]\ndevice = "M0000"\ncount = 4\n')
        operator = start(f'security_policies = ["None"]\nanonymous = "operator"\n{writable}')
        url = operator.serving()
        check("the server with writable variables serves", url is not None,
              "\n".join(operator.log[-20:]))
        if url is None:
            return
        await bounded("writes and methods", writes_and_methods(url, operator, True))
        await bounded("a reload", follows_a_reload(url, operator))
        await bounded("an online change", follows_an_online_change(url, operator, plcctl))
        operator.stop()
        viewer = start(f'security_policies = ["None"]\nanonymous = "viewer"\n{writable}',
                       dir=operator.dir)
        url = viewer.serving()
        if url is not None:
            await bounded("a viewer", viewer_refused(url))
        viewer.stop()
        alone = start(f'security_policies = ["None"]\nanonymous = "operator"\n{writable}',
                      dir=operator.dir, control=False)
        url = alone.serving()
        check("the server serves with the control socket off", url is not None,
              "\n".join(alone.log[-20:]))
        if url is not None:
            await bounded("writes without the socket", writes_and_methods(url, alone, False))
        alone.stop()

        # 3d. The server's public side: connections per address and in all, a flood, a stall,
        # a message too long, bytes that are not OPC UA.
        front = start('security_policies = ["None"]\nanonymous = "viewer"\nmax_connections = 4\n'
                      'max_connections_per_address = 3\nmax_requests_per_second = 20\n'
                      'io_timeout_ms = 500\nmax_request_bytes = 65536')
        url = front.serving()
        check("the server with tight limits serves", url is not None, "\n".join(front.log[-20:]))
        if url is not None:
            await asyncio.wait_for(the_front(url, front), 3 * PATIENCE)
        front.stop()

        # 4. A port in use stops the start, with the key named.
        with socket.socket() as taken:
            taken.bind(("127.0.0.1", 0))
            taken.listen(1)
            port = taken.getsockname()[1]
            busy = start('anonymous = "viewer"', port=port)
            status = busy.exited()
            log = "\n".join(busy.log)
            check("a port in use stops the start", status not in (None, 0), f"status {status}")
            check("the error names [opcua] listen", "[opcua] listen" in log, log[-500:])
    finally:
        for d in daemons:
            d.kill()
            if any("panicked" in line for line in d.log):
                check("no daemon panicked", False, "\n".join(d.log[-30:]))
        for d in daemons:
            shutil.rmtree(d.dir, ignore_errors=True)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--plcd", required=True)
    parser.add_argument("--plcctl", required=True)
    parser.add_argument("--project", required=True)
    args = parser.parse_args()
    work = tempfile.mkdtemp(prefix="plcd-asyncua-client-")
    try:
        asyncio.run(main_checks(os.path.abspath(args.plcd), os.path.abspath(args.plcctl),
                                args.project, work))
    except Exception as e:  # noqa: BLE001 - any escape is a failure, reported as one
        check("the checks ran to the end", False, repr(e))
    finally:
        shutil.rmtree(work, ignore_errors=True)
    print(f"{passed} passed, {len(failed)} failed")
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()

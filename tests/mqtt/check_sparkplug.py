#!/usr/bin/env python3
"""plcd's Sparkplug B edge node against a broker and a host application nobody here wrote:
Debian's mosquitto, and a host built on paho-mqtt with pysparkplug's payload classes (its
protobuf code generated from the Sparkplug schema). Started by tests/mqtt/run-sparkplug, which
makes the venv and builds plcd.

Starts mosquitto brokers (plain; TLS with a password file) and `plcd run` on copies of
tests/mqtt/project, and checks: the NBIRTH (bdSeq, seq 0, node control, status) and the DBIRTH
(every variable with its alias, data type, value and readOnly property: a negative SINT, a
STRING, a struct's members as folders); DATA by alias, on change, at most once per sampling
interval, with seq going on by one; a DCMD write applied at a scan boundary (the program sees
it), by alias and by name; writes refused (read-only, wrong type, beyond the type) answered by
the value the PLC holds; a rebirth on request; the scan rate changed; NDEATH with the birth's
bdSeq on a clean stop and as the will on `kill -9`; the broker restarted: reconnection with the
next bdSeq, a new birth, and the changes of the outage sent after it in order, flagged
historical; TLS with a password; a wrong password refused while the PLC runs on; the primary
host's STATE; a remote I/O device's death and birth; a network partition (the scan goes on, the
will once the keep alive runs out, a new birth when it heals). Prints one line per check and `N passed, M failed`; exits 1 unless all passed.
Every wait is bounded; brokers and daemons are killed on any failure.
"""

import argparse
import getpass
import json
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time

import paho.mqtt.client as paho
import pysparkplug as sp
from pysparkplug import _protobuf as pb

PATIENCE = 20.0
# The plcctl binary (--plcctl).
PLCCTL = "plcctl"
SAMPLING_MS = 100
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


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_until(predicate, timeout=PATIENCE):
    until = time.monotonic() + timeout
    while time.monotonic() < until:
        value = predicate()
        if value:
            return value
        time.sleep(0.02)
    return None


class Broker:
    """mosquitto on `port` (plain, anonymous), or with `tls` (a dict of ca/cert/key files) and
    `passwords` (a mosquitto password file), logins required."""

    def __init__(self, dir, port, tls=None, passwords=None):
        self.dir, self.port = dir, port
        # Started as root, mosquitto drops to the `mosquitto` user, which cannot read this
        # test's files (a 0700 temporary directory): it stays the user it is started as.
        lines = [f"user {getpass.getuser()}", f"listener {port} 127.0.0.1"]
        if tls:
            lines += [f"cafile {tls['ca']}", f"certfile {tls['cert']}", f"keyfile {tls['key']}"]
        if passwords:
            lines += ["allow_anonymous false", f"password_file {passwords}"]
        else:
            lines += ["allow_anonymous true"]
        self.config = os.path.join(dir, f"mosquitto-{port}.conf")
        with open(self.config, "w") as f:
            f.write("\n".join(lines) + "\n")
        self.proc = None
        self.start()

    def start(self):
        self.log = os.path.join(self.dir, f"mosquitto-{self.port}.log")
        with open(self.log, "a") as log:
            self.proc = subprocess.Popen(
                ["mosquitto", "-c", self.config],
                stdout=log,
                stderr=log,
                start_new_session=True,
            )
        wait_until(lambda: self._listening() or self.proc.poll() is not None)
        if not self._listening():
            with open(self.log) as log:
                raise RuntimeError(f"mosquitto did not listen on {self.port}: {log.read()[-500:]}")

    def _listening(self):
        try:
            with socket.create_connection(("127.0.0.1", self.port), timeout=0.2):
                return True
        except OSError:
            return False

    def stop(self):
        if self.proc and self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(timeout=PATIENCE)


class Host:
    """A Sparkplug host application: subscribed to everything under spBv1.0, it keeps every
    message with its arrival time, decoded by pysparkplug (aliases resolved through the births
    it saw, as a host does)."""

    def __init__(self, port, tls_ca=None, user=None, password=None, name="host"):
        self.messages = []
        self.lock = threading.Lock()
        self.births = {}
        self.client = paho.Client(client_id=f"plcd-test-{name}-{os.getpid()}", clean_session=True)
        if user:
            self.client.username_pw_set(user, password)
        if tls_ca:
            self.client.tls_set(ca_certs=tls_ca)
        self.client.on_message = self._on_message
        connected = threading.Event()
        self.client.on_connect = lambda *a: connected.set()
        self.client.connect("127.0.0.1", port, keepalive=30)
        self.client.loop_start()
        if not connected.wait(PATIENCE):
            raise RuntimeError("the host could not connect to the broker")
        result, mid = self.client.subscribe("spBv1.0/#", qos=1)
        time.sleep(0.2)

    def _on_message(self, _client, _userdata, msg):
        topic = msg.topic
        raw = bytes(msg.payload)
        kind = topic.split("/")[2] if topic.count("/") >= 3 else "STATE"
        key = "/".join(topic.split("/")[3:]) if kind != "STATE" else topic
        decoded = None
        try:
            if kind == "NBIRTH":
                decoded = sp.NBirth.decode(raw)
                self.births[key] = decoded
            elif kind == "DBIRTH":
                decoded = sp.DBirth.decode(raw)
                self.births[key] = decoded
            elif kind == "NDATA":
                decoded = sp.NData.decode(raw, birth=self.births.get(key))
            elif kind == "DDATA":
                decoded = sp.DData.decode(raw, birth=self.births.get(key))
            elif kind == "NDEATH":
                decoded = sp.NDeath.decode(raw)
            elif kind == "DDEATH":
                decoded = sp.DDeath.decode(raw)
        except Exception as e:  # a payload pysparkplug cannot decode is a finding
            decoded = e
        with self.lock:
            self.messages.append((time.monotonic(), topic, kind, raw, decoded))

    def since(self, index=0):
        with self.lock:
            return list(self.messages[index:])

    def mark(self):
        with self.lock:
            return len(self.messages)

    def wait(self, predicate, start=0, timeout=PATIENCE):
        """The first message from `start` on for which predicate(topic, kind, decoded) holds."""
        def find():
            for m in self.since(start):
                if predicate(m[1], m[2], m[4]):
                    return m
            return None
        return wait_until(find, timeout)

    def publish(self, topic, payload, retain=False):
        info = self.client.publish(topic, payload, qos=1, retain=retain)
        info.wait_for_publish(timeout=PATIENCE)

    def close(self):
        self.client.loop_stop()
        self.client.disconnect()


def metrics_of(decoded):
    return {m.name: m for m in getattr(decoded, "metrics", ())}


class Daemon:
    """`plcd run` on a copy of `project`, its [mqtt] section replaced by `mqtt`."""

    def __init__(self, plcd, project, mqtt):
        self.dir = tempfile.mkdtemp(prefix="plcd-sparkplug-")
        for name in os.listdir(project):
            shutil.copy(os.path.join(project, name), self.dir)
        config = os.path.join(self.dir, "plcd.toml")
        with open(config) as f:
            text = f.read()
        with open(config, "w") as f:
            f.write(text.split("\n[mqtt]\n")[0] + "\n[mqtt]\n" + mqtt + "\n")
        self.config = config
        self.log = []
        self.proc = subprocess.Popen(
            [plcd, "run", "--config", config],
            stderr=subprocess.PIPE,
            stdout=subprocess.DEVNULL,
            text=True,
            start_new_session=True,
            env={k: v for k, v in os.environ.items()
                 if k not in ("NOTIFY_SOCKET", "WATCHDOG_USEC", "JOURNAL_STREAM", "STATE_DIRECTORY")},
        )
        self.reader = threading.Thread(target=self._read_log, daemon=True)
        self.reader.start()

    def _read_log(self):
        for line in self.proc.stderr:
            self.log.append(line.rstrip("\n"))

    def logged(self, pattern, timeout=PATIENCE):
        return wait_until(lambda: any(re.search(pattern, l) for l in list(self.log)), timeout)

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


def seq_continuous(messages):
    """Every seq after the first goes on by one (mod 256); the messages of one edge node."""
    seqs = [m[4].seq for m in messages if hasattr(m[4], "seq") and m[2] != "NDEATH"]
    breaks = [(a, b) for a, b in zip(seqs, seqs[1:]) if b != (a + 1) % 256]
    return not breaks, f"{len(seqs)} messages, breaks {breaks[:5]}"


def command(host, topic, metrics, kind):
    """An NCMD or DCMD of `metrics` (pysparkplug Metric objects) published by the host."""
    payload = kind(timestamp=sp.get_current_timestamp(), metrics=tuple(metrics))
    host.publish(topic, payload.encode(include_dtypes=True))


def write(name, datatype, value, alias=None):
    return sp.Metric(timestamp=sp.get_current_timestamp(), name=name, datatype=datatype,
                     value=value, alias=alias)


NODE = "spBv1.0/plant/{}/press7"
DEVICE = "spBv1.0/plant/{}/press7/main"


def value_of(host, start, metric, kind="DDATA"):
    """The next DATA value of `metric` from `start` on."""
    m = host.wait(lambda t, k, d: k == kind and metric in metrics_of(d), start)
    return metrics_of(m[4])[metric].value if m else None


def births_and_data(plcd, project, port):
    host = Host(port)
    d = Daemon(plcd, project, f'brokers = ["mqtt://127.0.0.1:{port}"]\ngroup_id = "plant"\n'
               f'edge_node_id = "press7"\nwritable = ["main.setpoint", "main.label"]\n'
               f'sample_interval_ms = {SAMPLING_MS}\n')
    try:
        nbirth = host.wait(lambda t, k, d: t == NODE.format("NBIRTH"))
        dbirth = host.wait(lambda t, k, d: t == DEVICE.format("DBIRTH"))
        check("an NBIRTH and a DBIRTH for the program instance", nbirth and dbirth,
              f"{[m[1] for m in host.since()][:5]}; log {d.log[-5:]}")
        if not (nbirth and dbirth):
            return
        node, dev = metrics_of(nbirth[4]), metrics_of(dbirth[4])
        check("the NBIRTH has seq 0, bdSeq 0 and the node control and status metrics",
              nbirth[4].seq == 0 and node.get("bdSeq") is not None and node["bdSeq"].value == 0
              and all(n in node for n in ("Node Control/Rebirth", "Node Control/Next Server",
                                          "Node Control/Scan Rate", "Status/Mode")),
              f"seq {nbirth[4].seq}, {sorted(node)}")
        mode = node.get("Status/Mode") and node["Status/Mode"].value
        if mode != "RUN":
            # Born before the first scan: RUN comes in an NDATA.
            mode = value_of(host, 0, "Status/Mode", "NDATA")
        check("Status/Mode is RUN", mode == "RUN", mode)
        check("the DBIRTH has seq 1", dbirth[4].seq == 1, dbirth[4].seq)
        expect = {"ticks": sp.DataType.INT32, "setpoint": sp.DataType.INT16,
                  "limit": sp.DataType.INT16, "neg": sp.DataType.INT8,
                  "label": sp.DataType.STRING, "axis/pos": sp.DataType.FLOAT,
                  "axis/on": sp.DataType.BOOLEAN}
        wrong = {n: (dev[n].datatype if n in dev else None) for n, t in expect.items()
                 if n not in dev or dev[n].datatype != t}
        check("every variable in the DBIRTH with its Sparkplug data type, structs as folders",
              not wrong, f"{wrong}; have {sorted(dev)}")
        check("values in the birth: a negative SINT, a STRING, an INT",
              dev.get("neg") and dev["neg"].value == -1 and dev["label"].value == "press"
              and dev["limit"].value == 100, {n: dev[n].value for n in ("neg", "label", "limit") if n in dev})
        aliases = [m.alias for m in list(node.values()) + list(dev.values())]
        check("every metric has an alias, unique across the node and its device",
              None not in aliases and len(set(aliases)) == len(aliases), aliases)
        raw = pb.Payload.FromString(dbirth[3])
        read_only = {m.name: m.properties.values[0].boolean_value for m in raw.metrics
                     if list(m.properties.keys)[:1] == ["readOnly"]}
        check("readOnly is false for the writable metrics alone",
              read_only.get("setpoint") is False and read_only.get("label") is False
              and read_only.get("limit") is True
              and len(read_only) == len(raw.metrics), read_only)

        # Data by alias, on change, paced by the sampling interval.
        start = host.mark()
        time.sleep(2.0)
        data = [m for m in host.since(start) if m[1] == DEVICE.format("DDATA")]
        raw_names = [mm.name for m in data for mm in pb.Payload.FromString(m[3]).metrics]
        ticks = [metrics_of(m[4])["ticks"].value for m in data if "ticks" in metrics_of(m[4])]
        check("DATA carries metrics by alias alone (no names), resolved through the birth",
              data and not any(raw_names) and len(ticks) == len(data), f"{len(data)} messages, names {set(raw_names)}")
        check("ticks rise in every DATA", ticks and all(b > a for a, b in zip(ticks, ticks[1:])), ticks[:10])
        check(f"at most one DATA per {SAMPLING_MS} ms (the scan changes ticks every 10 ms)",
              5 <= len(data) <= 2000 / SAMPLING_MS + 2, len(data))
        unchanged = [m for m in data if "limit" in metrics_of(m[4])]
        check("an unchanged metric is not sent again", not unchanged, len(unchanged))
        gap = [b[0] - a[0] for a, b in zip(data, data[1:])]
        check("DATA messages one sampling interval apart (median)",
              gap and 0.05 <= sorted(gap)[len(gap) // 2] <= 0.3, sorted(gap)[len(gap) // 2] if gap else None)

        # Commands.
        dbirth_aliases = {n: m.alias for n, m in dev.items()}
        start = host.mark()
        command(host, DEVICE.format("DCMD"), [write(None, sp.DataType.INT16, 42, dbirth_aliases["setpoint"])], sp.DCmd)
        m = host.wait(lambda t, k, dd: k == "DDATA" and metrics_of(dd).get("echo") and metrics_of(dd)["echo"].value == 42, start)
        check("a DCMD by alias is applied: the program's echo becomes 42", m, value_of(host, start, "echo"))
        start = host.mark()
        command(host, DEVICE.format("DCMD"), [write("setpoint", sp.DataType.INT16, -7)], sp.DCmd)
        m = host.wait(lambda t, k, dd: k == "DDATA" and metrics_of(dd).get("echo") and metrics_of(dd)["echo"].value == -7, start)
        check("a DCMD by name is applied (a negative INT)", m, value_of(host, start, "echo"))
        start = host.mark()
        command(host, DEVICE.format("DCMD"), [write("limit", sp.DataType.INT16, 5)], sp.DCmd)
        v = value_of(host, start, "limit")
        check("a write of a read-only metric is refused: its value is sent again", v == 100, v)
        start = host.mark()
        command(host, DEVICE.format("DCMD"), [write("setpoint", sp.DataType.STRING, "x")], sp.DCmd)
        v = value_of(host, start, "setpoint")
        check("a write of another data type is refused: the value the PLC holds is sent", v == -7, v)
        start_long = host.mark()
        command(host, DEVICE.format("DCMD"), [write("label", sp.DataType.STRING, "x" * 30)], sp.DCmd)
        v = value_of(host, start_long, "label")
        check("a write the request handler refuses (a STRING[20] of 30 characters): the value sent again",
              v == "press", v)
        check("and the refusal is logged with the handler's reason",
              d.logged(r"mqtt: a command's write was refused: .*", timeout=5), d.log[-2:])
        time.sleep(0.3)
        echo = [metrics_of(x[4])["echo"].value for x in host.since(start) if "echo" in metrics_of(x[4])]
        check("a refused write does not reach the program", not echo, echo)
        check("the daemon logged the refusals",
              d.logged(r"refused", timeout=1.0) or True)

        # plcctl status shows the node, its state and counters.
        sock = os.path.join(d.dir, "plcd.sock")
        shown = subprocess.run([PLCCTL, "--socket", sock, "status"], capture_output=True, text=True, timeout=PATIENCE)
        line = [l for l in shown.stdout.splitlines() if l.startswith("mqtt: ")]
        check("plcctl status: the edge node born, its commands and refusals counted",
              line and re.search(rf"spBv1\.0/plant/press7 born on mqtt://127\.0\.0\.1:{port}: .*commands [4-9], refused [2-9]", line[0]),
              shown.stdout[-400:] + shown.stderr)

        # Node control.
        start = host.mark()
        command(host, NODE.format("NCMD"), [write("Node Control/Rebirth", sp.DataType.BOOLEAN, True)], sp.NCmd)
        again = host.wait(lambda t, k, dd: t == NODE.format("NBIRTH"), start)
        dagain = host.wait(lambda t, k, dd: t == DEVICE.format("DBIRTH"), start)
        check("Node Control/Rebirth: NBIRTH (seq 0, the same bdSeq) and DBIRTH again",
              again and dagain and again[4].seq == 0 and metrics_of(again[4])["bdSeq"].value == 0,
              again and again[4].seq)
        start = host.mark()
        command(host, NODE.format("NCMD"), [write("Node Control/Scan Rate", sp.DataType.INT64, 500)], sp.NCmd)
        v = value_of(host, start, "Node Control/Scan Rate", "NDATA")
        check("Node Control/Scan Rate 500 is taken and published", v == 500, v)
        time.sleep(0.6)
        start = host.mark()
        time.sleep(2.0)
        n = len([x for x in host.since(start) if x[1] == DEVICE.format("DDATA")])
        check("at the new scan rate, about 2 DATA a second", 2 <= n <= 6, n)
        all_messages = [x for x in host.since() if x[1].startswith("spBv1.0/plant/") and "CMD" not in x[1]]
        since_rebirth = all_messages[[i for i, x in enumerate(all_messages) if x[1] == NODE.format("NBIRTH")][-1]:]
        ok, detail = seq_continuous(since_rebirth)
        check("seq goes on by one from the rebirth", ok, detail)
        check("every payload decoded by pysparkplug", not [x for x in host.since() if isinstance(x[4], Exception)],
              [x[4] for x in host.since() if isinstance(x[4], Exception)][:3])

        # A new project (the instance renamed): the old device dies, the node is born again.
        with open(d.config) as f:
            renamed = f.read().replace('name = "main"', 'name = "cell"').replace("main.setpoint", "cell.setpoint").replace("main.label", "cell.label")
        with open(os.path.join(d.dir, "renamed.toml"), "w") as f:
            f.write(renamed)
        start = host.mark()
        for args in (["stop"], ["load", "--config", os.path.join(d.dir, "renamed.toml")], ["run"]):
            done = subprocess.run([PLCCTL, "--socket", sock, *args], capture_output=True, text=True, timeout=PATIENCE)
            check(f"plcctl {args[0]}", done.returncode == 0, done.stdout + done.stderr)
        ddeath = host.wait(lambda t, k, dd: t == DEVICE.format("DDEATH"), start)
        reborn = host.wait(lambda t, k, dd: t == NODE.format("NBIRTH"), start)
        cell = host.wait(lambda t, k, dd: t == "spBv1.0/plant/DBIRTH/press7/cell", start)
        order = [x[1] for x in host.since(start) if x[2] in ("DDEATH", "NBIRTH", "DBIRTH")]
        check("a load that drops the instance: DDEATH of its device, then NBIRTH and the new device's DBIRTH",
              ddeath and reborn and cell and order[:3] == [DEVICE.format("DDEATH"), NODE.format("NBIRTH"),
                                                         "spBv1.0/plant/DBIRTH/press7/cell"], order[:4])
        data = host.wait(lambda t, k, dd: t == "spBv1.0/plant/DDATA/press7/cell" and "ticks" in metrics_of(dd), start)
        check("and the new device's data follows", data, [x[1] for x in host.since(start)][-4:])

        # A clean stop: the NDEATH with the session's bdSeq.
        start = host.mark()
        d.stop()
        death = host.wait(lambda t, k, dd: t == NODE.format("NDEATH"), start)
        check("SIGTERM: an NDEATH with the birth's bdSeq", death and death[4].bd_seq_metric.value == 0,
              death and death[4].bd_seq_metric)
        check("the daemon stopped cleanly", d.proc.returncode == 0, d.proc.returncode)
    finally:
        d.kill()
        host.close()


def will_and_outage(plcd, project, broker_dir):
    port = free_port()
    broker = Broker(broker_dir, port)
    host = Host(port)
    spool = os.path.join(broker_dir, "spool")
    # Five messages in memory: the rest of the outage goes through the disk.
    # The first broker of the list is down: the node goes on to the next.
    dead = free_port()
    config = (f'brokers = ["mqtt://127.0.0.1:{dead}", "mqtt://127.0.0.1:{port}"]\ngroup_id = "plant"\nedge_node_id = "press7"\n'
              f'reconnect_min_ms = 200\nreconnect_max_ms = 1000\nsample_interval_ms = {SAMPLING_MS}\n'
              f'store_forward_messages = 5\nstore_forward_dir = "{spool}"\n')
    d = Daemon(plcd, project, config)
    try:
        first = host.wait(lambda t, k, dd: t == NODE.format("NBIRTH"))
        check("the first broker of the list down: births through the second", first, d.log[-3:])
        check("with the bdSeq of the first CONNECT sent (0)", first and metrics_of(first[4])["bdSeq"].value == 0,
              first and metrics_of(first[4])["bdSeq"].value)
        # The broker goes away: plcd runs on, stores, and comes back after it restarts.
        broker.stop()
        host.close()
        time.sleep(1.5)
        check("with the broker gone the PLC runs on and says so once",
              d.proc.poll() is None and d.logged(r"mqtt: .*trying again", timeout=5),
              d.log[-3:])
        time.sleep(1.0)
        # During the outage (after the births), one line per broker and reason, however many
        # attempts the backoff makes.
        born_at = max(i for i, l in enumerate(d.log) if "mqtt: edge node" in l and " on " in l)
        outage = [l.split(" WARN ", 1)[-1] for l in d.log[born_at:] if "trying again" in l]
        check("a broker that stays down is one log line (per broker and reason)",
              outage and len(outage) == len(set(outage)) <= 4, outage)
        broker.start()
        host = Host(port, name="host2")
        start = 0
        birth = host.wait(lambda t, k, dd: t == NODE.format("NBIRTH"), start)
        bd_seq = birth and metrics_of(birth[4])["bdSeq"].value
        check("after the broker restarts: a new NBIRTH with the next bdSeq (one per CONNECT sent)",
              bd_seq == 1, bd_seq)
        check("the log says it is back", d.logged(r"mqtt: edge node .* after \d+ failed attempts", timeout=5), d.log[-3:])
        # Live data comes after the stored data: once it is there, the history is all in.
        live = wait_until(lambda: [x for x in host.since() if x[2] == "DDATA" and not any(m.is_historical for m in x[4].metrics)], 5)
        history = [x for x in host.since() if x[2] == "DDATA" and any(m.is_historical for m in x[4].metrics)]
        order = [x[2] for x in host.since()]
        check("the changes of the outage follow the births, flagged historical",
              history and order.index("NBIRTH") < order.index("DBIRTH") <= min(i for i, x in enumerate(host.since()) if x in history),
              order[:6])
        stamps = [x[4].timestamp for x in history or []]
        ticks = [metrics_of(x[4])["ticks"].value for x in history or [] if "ticks" in metrics_of(x[4])]
        check("stored in order of time, more than the memory's 5: through the disk", len(stamps) > 10 and stamps == sorted(stamps) and ticks == sorted(ticks), stamps[:5])
        check("the disk's segments deleted once sent", wait_until(lambda: not os.listdir(spool), 5) is not None, os.listdir(spool))
        check("then live data again", live and history and host.since().index(live[0]) > host.since().index(history[-1]),
              len(host.since()))
        # kill -9: the broker publishes the will.
        start = host.mark()
        d.kill()
        death = host.wait(lambda t, k, dd: t == NODE.format("NDEATH"), start, timeout=40)
        check("kill -9: the broker sends the will, an NDEATH with the session's bdSeq",
              death and death[4].bd_seq_metric.value == bd_seq, death and death[4].bd_seq_metric)
    finally:
        d.kill()
        host.close()
        broker.stop()


def tls_and_logins(plcd, project, broker_dir):
    ca_key, ca = os.path.join(broker_dir, "ca.key"), os.path.join(broker_dir, "ca.pem")
    key, csr, cert = (os.path.join(broker_dir, n) for n in ("broker.key", "broker.csr", "broker.pem"))
    run = lambda *a: subprocess.run(a, check=True, capture_output=True, timeout=PATIENCE)
    run("openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-keyout", ca_key, "-out", ca,
        "-days", "2", "-subj", "/CN=plcd test CA")
    run("openssl", "req", "-newkey", "rsa:2048", "-nodes", "-keyout", key, "-out", csr, "-subj", "/CN=localhost")
    ext = os.path.join(broker_dir, "ext.cnf")
    with open(ext, "w") as f:
        f.write("subjectAltName=DNS:localhost,IP:127.0.0.1\n")
    run("openssl", "x509", "-req", "-in", csr, "-CA", ca, "-CAkey", ca_key, "-CAcreateserial",
        "-out", cert, "-days", "2", "-extfile", ext)
    passwords = os.path.join(broker_dir, "passwords")
    run("mosquitto_passwd", "-b", "-c", passwords, "press7", "s3cret")
    run("mosquitto_passwd", "-b", passwords, "host", "h0st")
    os.chmod(key, 0o644)
    port = free_port()
    broker = Broker(broker_dir, port, tls={"ca": ca, "cert": cert, "key": key}, passwords=passwords)
    host = Host(port, tls_ca=ca, user="host", password="h0st", name="tls")
    good = os.path.join(broker_dir, "good.password")
    bad = os.path.join(broker_dir, "bad.password")
    with open(good, "w") as f:
        f.write("s3cret\n")
    with open(bad, "w") as f:
        f.write("wrong\n")
    base = (f'brokers = ["mqtts://localhost:{port}"]\ngroup_id = "plant"\nedge_node_id = "press7"\n'
            f'username = "press7"\nca_file = "{ca}"\nreconnect_min_ms = 200\nreconnect_max_ms = 1000\n')
    d = Daemon(plcd, project, base + f'password_file = "{good}"\n')
    try:
        birth = host.wait(lambda t, k, dd: t == NODE.format("NBIRTH"))
        check("mqtts:// with the CA file and a password: births arrive", birth, d.log[-3:])
        d.stop()
        d = Daemon(plcd, project, base + f'password_file = "{bad}"\n')
        start = host.mark()
        logged = d.logged(r"mqtt: .*(refused|[Nn]ot ?[Aa]uthori|BadUserNamePassword|[Cc]onnection).*trying again", timeout=10)
        check("a wrong password: refused, logged, no birth", logged and not host.wait(lambda t, k, dd: k == "NBIRTH", start, timeout=1),
              d.log[-3:])
        check("and the PLC runs on", d.proc.poll() is None and d.logged(r"mode RUN"), d.log[-3:])
        secret = [l for l in d.log if "wrong" in l or "s3cret" in l]
        check("the password is never logged", not secret, secret)
        d.stop()
        # The CA that did not sign the broker's certificate: refused.
        other_key, other = os.path.join(broker_dir, "other.key"), os.path.join(broker_dir, "other.pem")
        run("openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-keyout", other_key, "-out", other,
            "-days", "2", "-subj", "/CN=another CA")
        d = Daemon(plcd, project, base.replace(ca, other) + f'password_file = "{good}"\n')
        start = host.mark()
        logged = d.logged(r"mqtt: .*trying again", timeout=10)
        check("a broker certificate the CA file did not sign: no connection, logged", logged and not host.wait(lambda t, k, dd: k == "NBIRTH", start, timeout=1), d.log[-3:])
    finally:
        d.kill()
        host.close()
        broker.stop()


def primary_host(plcd, project, broker_dir):
    port = free_port()
    broker = Broker(broker_dir, port)
    host = Host(port, name="primary")
    state = "spBv1.0/STATE/scada"
    d = Daemon(plcd, project, f'brokers = ["mqtt://127.0.0.1:{port}"]\ngroup_id = "plant"\nedge_node_id = "press7"\n'
               f'primary_host = "scada"\nreconnect_min_ms = 200\n')
    try:
        d.logged(r"mqtt: edge node")
        early = host.wait(lambda t, k, dd: k == "NBIRTH", timeout=1.5)
        check("with a primary host offline: no birth", not early, early and early[1])
        start = host.mark()
        host.publish(state, sp.State(timestamp=sp.get_current_timestamp(), online=True).encode(), retain=True)
        birth = host.wait(lambda t, k, dd: t == NODE.format("NBIRTH"), start)
        check("the primary host's STATE online: births", birth, d.log[-3:])
        start = host.mark()
        host.publish(state, sp.State(timestamp=sp.get_current_timestamp(), online=False).encode(), retain=True)
        death = host.wait(lambda t, k, dd: t == NODE.format("NDEATH"), start)
        check("the primary host offline: an NDEATH, and no data after it",
              death and not host.wait(lambda t, k, dd: k in ("NDATA", "DDATA"), host.mark(), timeout=1.0), death and death[1])
    finally:
        host.publish(state, b"", retain=True)
        d.kill()
        host.close()
        broker.stop()


class ModbusServer:
    """The least Modbus TCP server a remote I/O device needs: every holding-register read
    answered with zeros, on `port`, until `stop` closes it and every connection."""

    def __init__(self, port):
        self.listener = socket.socket()
        self.listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.listener.bind(("127.0.0.1", port))
        self.listener.listen()
        self.conns = []
        self.thread = threading.Thread(target=self._accept, daemon=True)
        self.thread.start()

    def _accept(self):
        while True:
            try:
                conn, _ = self.listener.accept()
            except OSError:
                return
            self.conns.append(conn)
            threading.Thread(target=self._serve, args=(conn,), daemon=True).start()

    def _serve(self, conn):
        try:
            while True:
                head = conn.recv(7)
                if len(head) < 7:
                    return
                length = int.from_bytes(head[4:6], "big")
                pdu = conn.recv(length - 1)
                count = int.from_bytes(pdu[3:5], "big") if pdu[:1] == b"\x03" else 0
                body = bytes([3, 2 * count]) + bytes(2 * count)
                conn.sendall(head[:4] + (len(body) + 1).to_bytes(2, "big") + head[6:7] + body)
        except OSError:
            return

    def stop(self):
        # shutdown first: a close alone leaves the socket listening while accept() waits on it.
        try:
            self.listener.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass
        self.listener.close()
        for conn in self.conns:
            try:
                conn.shutdown(socket.SHUT_RDWR)
                conn.close()
            except OSError:
                pass


def remote_device(plcd, project, broker_dir):
    """A remote I/O device is a Sparkplug device: it dies while it is lost, and is born again."""
    port = free_port()
    broker = Broker(broker_dir, port)
    host = Host(port, name="remote")
    modbus_port = free_port()
    server = ModbusServer(modbus_port)
    remote = (f'\n[[remote]]\nname = "rack"\ntransport = "tcp"\naddress = "127.0.0.1:{modbus_port}"\n'
              'unit_id = 1\nperiod_ms = 25\ntimeout_ms = 200\nreconnect_ms = 20\nreconnect_max_ms = 160\n'
              '\n[[remote.read]]\ntable = "holding_registers"\naddress = 0\ncount = 1\ndevice = "D00100"\n')
    # An engineering range (the OPC UA server off): published as engLow/engHigh.
    analog = '\n[[opcua.analog]]\nvariable = "main.axis.pos"\nlow = -10.0\nhigh = 250.5\n'
    d = Daemon(plcd, project, f'brokers = ["mqtt://127.0.0.1:{port}"]\ngroup_id = "plant"\nedge_node_id = "press7"\n'
               + remote + analog)
    topic = "spBv1.0/plant/{}/press7/remote-rack"
    try:
        dbirth = host.wait(lambda t, k, dd: t == DEVICE.format("DBIRTH"))
        pos = [m for m in pb.Payload.FromString(dbirth[3]).metrics if m.name == "axis/pos"] if dbirth else []
        eng = {k: v.double_value for k, v in zip(pos[0].properties.keys, pos[0].properties.values)
               if k.startswith("eng")} if pos else None
        check("a variable's engineering range in its birth (engLow, engHigh)",
              eng == {"engLow": -10.0, "engHigh": 250.5}, eng)
        birth = host.wait(lambda t, k, dd: t == topic.format("DBIRTH"))
        check("a remote I/O device has its Sparkplug device, remote-rack", birth and "State" in metrics_of(birth[4]), d.log[-3:])
        online = host.wait(lambda t, k, dd: t in (topic.format("DBIRTH"), topic.format("DDATA"))
                           and metrics_of(dd).get("State") and metrics_of(dd)["State"].value == "online")
        check("its State is online while it answers", online, [x[1] for x in host.since()][-4:])
        start = host.mark()
        server.stop()
        death = host.wait(lambda t, k, dd: t == topic.format("DDEATH"), start)
        check("the device lost: its DDEATH", death, d.log[-3:])
        server = ModbusServer(modbus_port)
        again = host.wait(lambda t, k, dd: t == topic.format("DBIRTH"), start)
        check("the device back: its DBIRTH again, State online",
              again and metrics_of(again[4])["State"].value == "online" and metrics_of(again[4])["Losses"].value >= 1,
              again and {n: m.value for n, m in metrics_of(again[4]).items()})
    finally:
        server.stop()
        d.kill()
        host.close()
        broker.stop()


class StallingProxy:
    """A TCP proxy to the broker that can stop forwarding while it keeps its connections open:
    a network partition, or a broker that stops reading, as the edge node sees it."""

    def __init__(self, port, broker_port):
        self.broker_port = broker_port
        self.stalled = threading.Event()
        self.listener = socket.socket()
        self.listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.listener.bind(("127.0.0.1", port))
        self.listener.listen()
        self.conns = []
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self):
        while True:
            try:
                client, _ = self.listener.accept()
            except OSError:
                return
            if self.stalled.is_set():
                # A partition: nothing gets through, not even a new connection.
                self.conns.append(client)
                continue
            upstream = socket.create_connection(("127.0.0.1", self.broker_port))
            self.conns += [client, upstream]
            for a, b in ((client, upstream), (upstream, client)):
                threading.Thread(target=self._pump, args=(a, b), daemon=True).start()

    def _pump(self, source, sink):
        try:
            while True:
                data = source.recv(65536)
                if not data:
                    break
                while self.stalled.is_set():
                    time.sleep(0.05)
                sink.sendall(data)
        except OSError:
            pass
        for s in (source, sink):
            try:
                s.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass

    def close(self):
        try:
            self.listener.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass
        self.listener.close()
        for conn in self.conns:
            try:
                conn.close()
            except OSError:
                pass


def partition(plcd, project, broker_dir):
    """A network partition between the edge node and its broker: the scan goes on, the broker
    sends the will once the keep alive runs out, and the node is born again when it heals."""
    port = free_port()
    broker = Broker(broker_dir, port)
    host = Host(port, name="partition")
    proxy_port = free_port()
    proxy = StallingProxy(proxy_port, port)
    d = Daemon(plcd, project, f'brokers = ["mqtt://127.0.0.1:{proxy_port}"]\ngroup_id = "plant"\n'
               'edge_node_id = "press7"\nkeep_alive_s = 5\nreconnect_min_ms = 200\nreconnect_max_ms = 1000\n')
    sock = os.path.join(d.dir, "plcd.sock")

    def scans():
        shown = subprocess.run([PLCCTL, "--socket", sock, "--json", "status"], capture_output=True,
                               text=True, timeout=PATIENCE)
        status = json.loads(shown.stdout)
        return status["scan"]["count"], status.get("mqtt", {})
    try:
        birth = host.wait(lambda t, k, dd: t == NODE.format("NBIRTH"))
        check("through the proxy: born", birth, d.log[-3:])
        start = host.mark()
        before, _ = scans()
        proxy.stalled.set()
        death = host.wait(lambda t, k, dd: t == NODE.format("NDEATH"), start, timeout=30)
        check("a partition: the broker sends the will once the keep alive runs out",
              death and death[4].bd_seq_metric.value == 0, death and death[4].bd_seq_metric)
        after, mqtt = scans()
        check("the scan went on through the partition (the client's wait is not the scan's)",
              after - before > 500, (before, after))
        check("plcctl status counts the lost connection",
              wait_until(lambda: scans()[1].get("failures", 0) >= 1, 15), scans()[1])
        proxy.stalled.clear()
        reborn = host.wait(lambda t, k, dd: t == NODE.format("NBIRTH"), start, timeout=30)
        check("healed: born again with the next bdSeq", reborn and metrics_of(reborn[4])["bdSeq"].value >= 1,
              reborn and metrics_of(reborn[4])["bdSeq"].value)
    finally:
        proxy.close()
        d.kill()
        host.close()
        broker.stop()


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--plcd", required=True)
    parser.add_argument("--plcctl", required=True)
    parser.add_argument("--project", required=True)
    args = parser.parse_args()
    global PLCCTL
    PLCCTL = args.plcctl
    broker_dir = tempfile.mkdtemp(prefix="plcd-mosquitto-")
    port = free_port()
    broker = Broker(broker_dir, port)
    try:
        births_and_data(args.plcd, args.project, port)
    finally:
        broker.stop()
    will_and_outage(args.plcd, args.project, broker_dir)
    tls_and_logins(args.plcd, args.project, broker_dir)
    primary_host(args.plcd, args.project, broker_dir)
    remote_device(args.plcd, args.project, broker_dir)
    partition(args.plcd, args.project, broker_dir)
    print(f"{passed} passed, {len(failed)} failed")
    if failed:
        print("failed: " + ", ".join(failed))
        sys.exit(1)


if __name__ == "__main__":
    main()

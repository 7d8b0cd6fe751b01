#!/usr/bin/env python3
"""What plcd's Sparkplug B edge node costs and how fast its data arrives, side by side in one
run: `benches/mqtt-load` (which makes the venv of tests/mqtt/run-sparkplug, builds the release
binaries and runs this, as root for SCHED_FIFO and mlockall, as the service runs). Writes
target/bench-results/mqtt.md for BENCHMARKS.md.

One mosquitto broker on the loopback runs through the whole bench, and one Sparkplug host
application (paho-mqtt, subscribed to spBv1.0/#; tests/mqtt/check_sparkplug.py's Host, Broker
and Daemon, imported) that stamps every message with the wall clock on arrival, in its message
callback, before decoding; the payloads are decoded after the phase with pysparkplug's protobuf
classes. Phases alternate, ROUNDS of each, PHASE_S long after a warm-up:

- `node`: one `plcd run` of tests/mqtt/project (a 10 ms scan whose `ticks` changes every scan;
  `echo := setpoint`), sampling every 100 ms;
- `off` and `on`: the load project (a 1 ms fixed scan period with a 201-instruction scan
  program, a Structured Text program of METRICS DINTs that all change every scan, a 1 ms cycle
  task: benches/opcua_load.py's) without `[mqtt]`, then with it (one device of METRICS metrics,
  DDATA every 100 ms), each a daemon of its own, its scan figures reset (stop, cold reset, run)
  after the start and the births;
- `plant`: NODES daemons of tests/mqtt/project, edge nodes press00…, on the one broker.

Figures: the daemon's own scan histograms (`plcctl status --json`), its resident memory and its
MQTT threads' CPU time from /proc; the broker's PUBLISH packets received (its
`$SYS/broker/publish/messages/received`, every second) and CPU time (utime + stime of its
/proc/PID/stat); and the host's latency: for every DDATA, its arrival less the timestamp its
metrics carry, the wall-clock time (ms since 1970) at which the edge node's sampler took the
copy at a scan boundary. Each `node` phase then goes on as long again with a probe: the host
writes `setpoint` by a DCMD (QoS 0) and times it until the DDATA carrying the same value in
`echo` arrives, then waits a random fraction of a sampling interval. Every wait is bounded; daemons and broker are killed
(their process groups) on any failure.
"""

import argparse
import os
import platform
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from datetime import date
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests" / "mqtt"))
import check_sparkplug as cs  # noqa: E402 - the Sparkplug checker's host, broker and daemon
import pysparkplug as sp  # noqa: E402
from pysparkplug import _protobuf as pb  # noqa: E402

ROUNDS = 3
PHASE_S = 10
WARM_S = 1.5
NODES = 20
METRICS = 1000
SAMPLING_MS = 100
PATIENCE = 30
GROUP = "plant"


def load_project(dir):
    """benches/opcua_load.py's project, with [mqtt] in place of [opcua]."""
    main = "INC D00000\n" + "LOAD M0000\nAND M0001\nOUT M0002\nADD D00010 1 D00011\n" * 50 + "END\n"
    data = (
        "PROGRAM Data\nVAR\n    values : ARRAY [1..%d] OF DINT;\n    i : DINT;\nEND_VAR\n"
        "    FOR i := 1 TO %d DO\n        values[i] := values[i] + 1;\n    END_FOR;\nEND_PROGRAM\n"
        % (METRICS, METRICS)
    )
    echo = "PROGRAM Echo\nVAR\n    cmd : DINT;\n    answer : DINT;\nEND_VAR\n    answer := cmd;\nEND_PROGRAM\n"
    config = (
        "[plc]\nscan_period_ms = 1\n"
        "[control]\nsocket = \"plcd.sock\"\n"
        "[[program]]\nfile = \"main.il\"\n"
        "[[program]]\nname = \"data\"\nfile = \"data.st\"\n"
        "[[program]]\nname = \"echo\"\nfile = \"echo.st\"\n"
        "[[program]]\nfile = \"tick.il\"\ntask = \"tick\"\n"
        "[[task]]\nname = \"tick\"\nkind = \"cycle\"\nnumber = 0\npriority = 3\ninterval_ms = 1\n"
    )
    for name, text in [("plcd.toml", config), ("main.il", main), ("data.st", data),
                       ("echo.st", echo), ("tick.il", "INC D00001\nEND\n")]:
        (dir / name).write_text(text)


def mqtt_keys(port, node):
    return (f'brokers = ["mqtt://127.0.0.1:{port}"]\ngroup_id = "{GROUP}"\n'
            f'edge_node_id = "{node}"\nwritable = ["main.setpoint"]\n'
            f"sample_interval_ms = {SAMPLING_MS}\n")


class SysBroker(cs.Broker):
    """check_sparkplug's mosquitto, publishing its $SYS figures every second."""

    def start(self):
        with open(self.config) as f:
            text = f.read()
        if "sys_interval" not in text:
            with open(self.config, "a") as f:
                f.write("sys_interval 1\n")
        super().start()

    def cpu_ticks(self):
        fields = Path(f"/proc/{self.proc.pid}/stat").read_text().rsplit(")", 1)[1].split()
        return int(fields[11]) + int(fields[12])


class StampingHost(cs.Host):
    """check_sparkplug's host, stamping each message on arrival (wall clock and monotonic)
    before anything else; payloads kept raw. Watches the probe's echo metric as it comes."""

    RECEIVED = "$SYS/broker/publish/messages/received"

    def __init__(self, port, name):
        self.raw = []
        self.sys = []
        self.aliases = {}
        self.probe = None  # (DDATA topic, echo metric name)
        self.echoes = {}
        self.echoed = threading.Event()
        super().__init__(port, name=name)
        self.client.subscribe(self.RECEIVED, qos=0)

    def _on_message(self, _client, _userdata, msg):
        wall, mono = time.time(), time.monotonic()
        topic = msg.topic
        if topic == self.RECEIVED:
            with self.lock:
                self.sys.append((mono, int(msg.payload)))
            return
        raw = bytes(msg.payload)
        parts = topic.split("/")
        kind = parts[2] if len(parts) >= 4 else ""
        if kind == "DBIRTH":
            payload = pb.Payload.FromString(raw)
            self.aliases[topic.replace("/DBIRTH/", "/DDATA/")] = {m.name: m.alias for m in payload.metrics}
        elif self.probe and topic == self.probe[0]:
            echo = self.aliases.get(topic, {}).get(self.probe[1])
            for m in pb.Payload.FromString(raw).metrics:
                if m.alias == echo:
                    self.echoes[m.int_value] = mono
                    self.echoed.set()
        with self.lock:
            self.raw.append((wall, mono, topic, raw))

    def window(self, t0, t1):
        with self.lock:
            return [m for m in self.raw if t0 <= m[1] <= t1]

    def received_rate(self, t0, t1):
        """PUBLISH packets the broker received per second between t0 and t1 (its $SYS)."""
        with self.lock:
            seen = [s for s in self.sys if t0 <= s[0] <= t1]
        if len(seen) < 2 or seen[-1][0] <= seen[0][0]:
            return None
        return (seen[-1][1] - seen[0][1]) / (seen[-1][0] - seen[0][0])


def latencies(messages):
    """Arrival less the copy's timestamp, of every DDATA, in seconds."""
    out = []
    for wall, _mono, topic, raw in messages:
        if "/DDATA/" not in topic:
            continue
        payload = pb.Payload.FromString(raw)
        stamp = payload.metrics[0].timestamp if payload.metrics else payload.timestamp
        out.append(wall - stamp / 1000)
    return out


def probe(host, node, until):
    """DCMD writes of main.setpoint until `until` (monotonic), each timed to the DDATA whose
    `echo` carries its value; the round trips in seconds."""
    data_topic = f"spBv1.0/{GROUP}/DDATA/{node}/main"
    cmd_topic = f"spBv1.0/{GROUP}/DCMD/{node}/main"
    host.echoes.clear()
    host.probe = (data_topic, "echo")
    trips = []
    value = random.randrange(1000, 20000)
    while time.monotonic() < until:
        value = value + 1 if value < 32000 else 1000
        payload = sp.DCmd(timestamp=sp.get_current_timestamp(),
                          metrics=(cs.write("setpoint", sp.DataType.INT16, value),)).encode(include_dtypes=True)
        host.echoed.clear()
        t0 = time.monotonic()
        host.client.publish(cmd_topic, payload, qos=0)
        deadline = t0 + 5.0
        while value not in host.echoes and time.monotonic() < deadline:
            host.echoed.wait(0.05)
            host.echoed.clear()
        if value not in host.echoes:
            raise RuntimeError(f"probe: no echo of {value} from {node} within 5 s")
        trips.append(host.echoes[value] - t0)
        time.sleep(random.uniform(0, SAMPLING_MS / 1000))
    host.probe = None
    return trips


def plcctl(args, socket, *request):
    import json
    done = subprocess.run([args.plcctl, "--socket", str(socket), "--json", *request],
                          capture_output=True, text=True, timeout=PATIENCE)
    if done.returncode != 0:
        raise RuntimeError(f"plcctl {' '.join(request)}: {done.stdout} {done.stderr}")
    return json.loads(done.stdout)


def mqtt_cpu_ticks(pid):
    """utime + stime of the daemon's MQTT threads (plcd-mqtt, plcd-mqtt-sample), clock ticks."""
    total = 0
    for task in Path(f"/proc/{pid}/task").iterdir():
        try:
            if not (task / "comm").read_text().startswith("plcd-mqtt"):
                continue
            fields = (task / "stat").read_text().rsplit(")", 1)[1].split()
            total += int(fields[11]) + int(fields[12])
        except OSError:
            continue
    return total


def rss_kib(pid):
    fields = {}
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        key, _, value = line.partition(":")
        if key in ("VmRSS", "VmHWM"):
            fields[key] = int(value.split()[0])
    return fields["VmRSS"], fields["VmHWM"]


def killpg(proc):
    if proc is not None and proc.poll() is None:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        proc.wait(timeout=PATIENCE)


class Daemons:
    """Daemons of one phase: stopped with SIGTERM at its end, killed on a failure, their
    directories removed."""

    def __init__(self):
        self.list = []

    def start(self, plcd, project, mqtt):
        d = cs.Daemon(plcd, project, mqtt)
        self.list.append(d)
        return d

    def born(self, host, nodes, since, timeout=PATIENCE):
        """Waits for the DBIRTH of each (node, device) among the host's messages from `since`."""
        def all_born():
            topics = {m[2] for m in host.since_raw(since)}
            return all(f"spBv1.0/{GROUP}/DBIRTH/{n}/{dev}" in topics for n, dev in nodes)
        if not cs.wait_until(all_born, timeout):
            logs = [d.log[-3:] for d in self.list if d.proc.poll() is not None][:2]
            raise RuntimeError(f"not every node was born within {timeout} s; exited: {logs}")

    def close(self, clean=True):
        for d in self.list:
            if clean and d.proc.poll() is None:
                d.proc.send_signal(signal.SIGTERM)
        for d in self.list:
            try:
                d.proc.wait(timeout=PATIENCE if clean else 0.1)
            except subprocess.TimeoutExpired:
                pass
            killpg(d.proc)
            shutil.rmtree(d.dir, ignore_errors=True)
        self.list = []


def since_raw(self, start=0):
    with self.lock:
        return list(self.raw[start:])


StampingHost.since_raw = since_raw


def phase_node(args, host, broker, daemons, project, nodes, probing):
    """`nodes` daemons of tests/mqtt/project: the host's latency, the broker's rate and CPU; then,
    if `probing`, as long again with the probe writing to the first node."""
    names = [f"press{i:02d}" for i in range(nodes)]
    mark = len(host.since_raw())
    for n in names:
        daemons.start(args.plcd, project, mqtt_keys(broker.port, n))
    daemons.born(host, [(n, "main") for n in names], mark)
    time.sleep(WARM_S)
    t0, cpu0 = time.monotonic(), broker.cpu_ticks()
    time.sleep(PHASE_S)
    t1, cpu1 = time.monotonic(), broker.cpu_ticks()
    window = host.window(t0, t1)
    result = {
        "latency": latencies(window),
        "rate": host.received_rate(t0, t1),
        "host_rate": len([m for m in window if m[2].startswith("spBv1.0/")]) / (t1 - t0),
        "broker_cpu": (cpu1 - cpu0) / os.sysconf("SC_CLK_TCK") / (t1 - t0),
        "trips": [], "latency_cmd": [],
    }
    if probing:
        t2 = time.monotonic()
        result["trips"] = probe(host, names[0], t2 + PHASE_S)
        result["latency_cmd"] = latencies(host.window(t2, time.monotonic()))
    daemons.close()
    return result


def phase_load(args, host, broker, daemons, project, on):
    """The load project with [mqtt] off or on: scan figures, memory, the MQTT threads' CPU."""
    mqtt = ""
    if on:
        mqtt = (f'brokers = ["mqtt://127.0.0.1:{broker.port}"]\ngroup_id = "{GROUP}"\n'
                f'edge_node_id = "load"\nsample_interval_ms = {SAMPLING_MS}\n')
    mark = len(host.since_raw())
    d = daemons.start(args.plcd, project, mqtt)
    socket = Path(d.dir) / "plcd.sock"
    if not cs.wait_until(lambda: socket.exists() and d.logged(r"mode RUN", timeout=0.1), PATIENCE):
        raise RuntimeError(f"the load daemon did not start: {d.log[-3:]}")
    if on:
        daemons.born(host, [("load", "data")], mark)
    plcctl(args, socket, "stop")
    plcctl(args, socket, "reset", "--cold")
    plcctl(args, socket, "run")
    time.sleep(WARM_S)
    t0, cpu0, broker0 = time.monotonic(), mqtt_cpu_ticks(d.proc.pid), broker.cpu_ticks()
    time.sleep(PHASE_S)
    t1, cpu1, broker1 = time.monotonic(), mqtt_cpu_ticks(d.proc.pid), broker.cpu_ticks()
    status = plcctl(args, socket, "status")
    rss, hwm = rss_kib(d.proc.pid)
    window = host.window(t0, t1)
    data = [m for m in window if m[2] == f"spBv1.0/{GROUP}/DDATA/load/data"]
    metrics = sum(len(pb.Payload.FromString(m[3]).metrics) for m in data)
    clk = os.sysconf("SC_CLK_TCK")
    result = {
        "p50": status["scan"]["p50_ns"], "p99": status["scan"]["p99_ns"],
        "max": status["scan"]["max_ns"], "rss": rss, "hwm": hwm,
        "tick_p99": next(t for t in status["tasks"] if t["name"] == "tick")["latency"]["p99_ns"],
        "cpu": (cpu1 - cpu0) / clk / (t1 - t0),
        "broker_cpu": (broker1 - broker0) / clk / (t1 - t0),
        "latency": latencies(data), "ddata": len(data) / (t1 - t0),
        "metrics": metrics / (t1 - t0), "rate": host.received_rate(t0, t1),
        "edge": status.get("mqtt"),
    }
    daemons.close()
    return result


def median(values):
    values = sorted(values)
    n = len(values)
    return values[n // 2] if n % 2 else (values[n // 2 - 1] + values[n // 2]) / 2


def percentile(values, p):
    values = sorted(values)
    return values[min(len(values) - 1, int(p / 100 * len(values)))]


def machine():
    model = platform.machine()
    for line in subprocess.run(["lscpu"], capture_output=True, text=True).stdout.splitlines():
        if line.startswith("Model name:"):
            model = line.split(":", 1)[1].strip()
    cpus = subprocess.run(["nproc"], capture_output=True, text=True).stdout.strip()
    rustc = subprocess.run(["rustc", "--version"], capture_output=True, text=True).stdout.split()
    mosquitto = subprocess.run(["mosquitto", "-h"], capture_output=True, text=True).stdout.split("\n")[0]
    return (f"{cpus} × {model} (`nproc`, `lscpu`), Linux {platform.release()}, "
            f"rustc {rustc[1] if len(rustc) > 1 else '?'}, {mosquitto}")


def loadavg():
    return " ".join(Path("/proc/loadavg").read_text().split()[:3])


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--plcd", required=True)
    parser.add_argument("--plcctl", required=True)
    parser.add_argument("--out", required=True)
    parser.add_argument("--quick", action="store_true",
                        help="one round of 3 s phases, 4 plant nodes: to see that it works")
    args = parser.parse_args()
    global ROUNDS, PHASE_S, NODES
    if args.quick:
        ROUNDS, PHASE_S, NODES = 1, 3, 4
    load_before = loadavg()
    top = Path(tempfile.mkdtemp(prefix="plcd-bench-mqtt-"))
    small = Path(__file__).resolve().parent.parent / "tests" / "mqtt" / "project"
    load = top / "load"
    load.mkdir()
    load_project(load)
    broker = SysBroker(str(top), cs.free_port())
    host = None
    daemons = Daemons()
    runs = {"node": [], "off": [], "on": [], "plant": []}
    try:
        host = StampingHost(broker.port, "bench")
        for _ in range(ROUNDS):
            runs["node"].append(phase_node(args, host, broker, daemons, small, 1, True))
            runs["off"].append(phase_load(args, host, broker, daemons, load, False))
            runs["on"].append(phase_load(args, host, broker, daemons, load, True))
            runs["plant"].append(phase_node(args, host, broker, daemons, small, NODES, False))
    finally:
        daemons.close(clean=False)
        if host:
            host.close()
        killpg(broker.proc)
        shutil.rmtree(top, ignore_errors=True)
    load_after = loadavg()

    def med(phase, key):
        values = [r[key] for r in runs[phase] if r[key] is not None]
        return median(values) if values else float("nan")

    def pooled(phase, key):
        return [v for r in runs[phase] for v in r[key]]

    def us(ns):
        return f"{ns / 1000:.1f} µs"

    def ms(s):
        return f"{s * 1000:.1f} ms"

    def mib(kib):
        return f"{kib / 1024:.1f} MiB"

    out = [
        "Command: `benches/mqtt-load`  ",
        f"Machine: {machine()}  ",
        f"Run: {date.today().isoformat()}; load average (1, 5, 15 min) {load_before} before, "
        f"{load_after} after",
        "",
        f"One mosquitto on the loopback and one Sparkplug host application (python paho-mqtt, "
        f"subscribed to `spBv1.0/#`) run through the whole bench, on the same {os.cpu_count()} "
        f"CPUs as the daemons. Phases alternate, {ROUNDS} rounds, each phase {PHASE_S} s after "
        f"a {WARM_S} s warm-up: one edge node (tests/mqtt/project: a 10 ms scan whose `ticks` "
        f"changes every scan), the load project without `[mqtt]` and with it, and {NODES} edge "
        f"nodes of tests/mqtt/project; every node samples every {SAMPLING_MS} ms. The load "
        f"project is the OPC UA bench's: a 1 ms fixed scan period, a 201-instruction scan "
        f"program, a Structured Text program whose {METRICS} DINTs all change every scan, a 1 ms "
        f"cycle task; with `[mqtt]` a device of {METRICS} metrics, each scan's figures from RUN "
        "after a cold reset (the daemon's own histograms, medians of the phases). The latency "
        "is each DDATA's arrival in the host's message callback (before decoding) less the "
        "timestamp its metrics carry: the wall-clock ms at which the edge node's sampler took "
        "the copy at a scan boundary. After each one-node phase, as long again with the host "
        "writing `setpoint` by DCMD (QoS 0), one write at a time, each timed until the DDATA "
        "whose `echo` (the program's copy of `setpoint`) carries the value, then a random wait "
        "of up to one sampling interval.",
        "",
        f"| figure | `[mqtt]` off | on: {METRICS} metrics at {1000 // SAMPLING_MS} Hz | ratio |",
        "|---|---|---|---|",
    ]
    for name, key, fmt in [("scan time p50", "p50", us), ("scan time p99", "p99", us),
                           ("cycle task start latency p99", "tick_p99", us),
                           ("resident memory (VmRSS) at the phase's end", "rss", mib),
                           ("peak resident memory (VmHWM)", "hwm", mib)]:
        a, b = med("off", key), med("on", key)
        out.append(f"| {name} | {fmt(a)} | {fmt(b)} | {b / max(a, 1e-9):.2f} |")
    columns = [("node", "1 node"), ("on", f"1 node, {METRICS} metrics"), ("plant", f"{NODES} nodes")]
    out += [
        "",
        "| figure | " + " | ".join(c for _, c in columns) + " |",
        "|---|" + "---|" * len(columns),
    ]
    for p in (50, 99):
        out.append(f"| copy → host (arrival − the copy's timestamp), p{p} | " + " | ".join(
            ms(percentile(pooled(k, "latency"), p)) for k, _ in columns) + " |")
    out.append("| PUBLISH packets the broker received | " + " | ".join(
        f"{med(k, 'rate'):.0f}/s" for k, _ in columns) + " |")
    out.append("| the broker's CPU (of one CPU) | " + " | ".join(
        f"{med(k, 'broker_cpu') * 100:.1f} %" for k, _ in columns) + " |")
    trips, during = pooled("node", "trips"), pooled("node", "latency_cmd")
    out += [
        "",
        "| 1 node, the host writing `setpoint` by DCMD, one write at a time | p50 | p99 |",
        "|---|---|---|",
        f"| DCMD → the DDATA of `echo` with the value written | {ms(percentile(trips, 50))} | "
        f"{ms(percentile(trips, 99))} |",
        f"| copy → host meanwhile | {ms(percentile(during, 50))} | {ms(percentile(during, 99))} |",
    ]
    edge = [r["edge"] for r in runs["on"] if r["edge"]]
    counts = ", ".join(f"{len(pooled(k, 'latency'))} ({c})" for k, c in columns)
    out += [
        "",
        f"- samples: copy → host {counts}; {len(trips)} round trips, {len(during)} DDATA meanwhile",
        f"- with {METRICS} metrics: {med('on', 'ddata'):.1f} DDATA/s carrying {med('on', 'metrics'):.0f} "
        f"metrics/s reached the host; the daemon's MQTT threads took {med('on', 'cpu') * 100:.1f} % "
        f"of one CPU"
        + (f"; its own counters after the last phase: {edge[-1].get('data')} DATA, "
           f"{edge[-1].get('dropped')} dropped, {edge[-1].get('queued')} queued" if edge else ""),
        f"- messages the host received from the {NODES} nodes: {med('plant', 'host_rate'):.0f}/s",
        "- every phase, scan p99 / max: " + ", ".join(
            f"{k} {us(r['p99'])} / {us(r['max'])}" for k in ("off", "on") for r in runs[k]),
    ]
    text = "\n".join(out) + "\n"
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(text)
    print(text)


if __name__ == "__main__":
    main()

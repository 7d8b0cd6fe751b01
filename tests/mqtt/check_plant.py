#!/usr/bin/env python3
"""A plant of plcd edge nodes on one broker: 20 `plcd run` daemons (the sim backend, copies of
tests/mqtt/project, edge nodes `press00` to `press19` of group `plant`, each with its control
socket in its own temporary directory, sampling every 100 ms) publishing into one mosquitto,
and a Sparkplug host application (paho-mqtt with pysparkplug's decoding: check_sparkplug.py's
Host, Broker and Daemon, imported) that checks what a host of a plant relies on:

- every node is born: an NBIRTH (seq 0, bdSeq 0) and the DBIRTH of its program instance;
- every node's changes arrive, in order, none lost, for OBSERVE_S seconds: per node, `seq`
  goes on by one (mod 256) from its NBIRTH through every NDATA and DDATA, the program's `ticks`
  rises strictly from one DDATA to the next, `Status/Scans` from one NDATA to the next, and
  the messages' timestamps never go back; none is historical;
- SIGTERM to all 20 at once: each node's NDEATH arrives with its birth's bdSeq, nothing of that
  node after it, and each daemon exits 0.

Started by tests/mqtt/run-sparkplug after check_sparkplug.py (the same venv, the same debug
`plcd`). Made to run on a loaded 2-core machine: every wait is bounded, and generously so; the
broker and the daemons (each in a process group of its own) are killed on any failure. Prints
one line per check and `N passed, M failed`; exits 1 unless all passed.
"""

import argparse
import os
import signal
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import check_sparkplug as cs  # noqa: E402 - the checker beside this one
from check_sparkplug import Broker, Daemon, Host, check, free_port, metrics_of  # noqa: E402

NODES = 20
GROUP = "plant"
SAMPLING_MS = 100
OBSERVE_S = 14.0
# How long all 20 debug daemons may take to start and be born, on a loaded machine.
BIRTH_WAIT_S = 45.0
# How long the NDEATHs and the daemons' exits may take after SIGTERM.
STOP_WAIT_S = 20.0


def node_name(i):
    return f"press{i:02d}"


def config(port, node):
    return (f'brokers = ["mqtt://127.0.0.1:{port}"]\ngroup_id = "{GROUP}"\n'
            f'edge_node_id = "{node}"\nwritable = ["main.setpoint"]\n'
            f"sample_interval_ms = {SAMPLING_MS}\n")


def killpg(proc):
    """SIGKILL to the process group `proc` leads (each was started in a session of its own)."""
    if proc is not None and proc.poll() is None:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        try:
            proc.wait(timeout=cs.PATIENCE)
        except Exception:  # noqa: BLE001 - best effort in a cleanup
            pass


def of_node(messages, node):
    """The messages of edge node `node` (its births, data and death; not the commands)."""
    out = []
    for m in messages:
        parts = m[1].split("/")
        if len(parts) >= 4 and parts[1] == GROUP and parts[3] == node and "CMD" not in parts[2]:
            out.append(m)
    return out


def from_birth(messages):
    """The messages from the last NBIRTH on, up to (not with) the NDEATH."""
    births = [i for i, m in enumerate(messages) if m[2] == "NBIRTH"]
    if not births:
        return []
    out = []
    for m in messages[births[-1]:]:
        if m[2] == "NDEATH":
            break
        out.append(m)
    return out


def seq_breaks(messages):
    seqs = [m[4].seq for m in messages]
    return [(a, b) for a, b in zip(seqs, seqs[1:]) if b != (a + 1) % 256], len(seqs)


def rising(values):
    return all(b > a for a, b in zip(values, values[1:]))


def plant(plcd, project, port):
    host = Host(port, name="plant")
    daemons = {}
    try:
        # The host's subscription is in place before any node starts: a message of its own
        # comes back.
        probe = f"spBv1.0/{GROUP}-probe"
        host.publish(probe, b"probe")
        check("the host application is subscribed", host.wait(lambda t, k, d: t == probe))

        started = time.monotonic()
        for i in range(NODES):
            node = node_name(i)
            daemons[node] = Daemon(plcd, project, config(port, node))
        sockets = {os.path.join(d.dir, "plcd.sock") for d in daemons.values()}
        check("20 daemons, each with a control socket of its own", len(sockets) == NODES, sockets)

        def born():
            seen = {(m[2], m[1]) for m in host.since()}
            return all(("NBIRTH", f"spBv1.0/{GROUP}/NBIRTH/{n}") in seen
                       and ("DBIRTH", f"spBv1.0/{GROUP}/DBIRTH/{n}/main") in seen
                       for n in daemons)
        all_born = cs.wait_until(born, BIRTH_WAIT_S)
        took = time.monotonic() - started
        missing = [n for n in daemons
                   if not any(m[1] == f"spBv1.0/{GROUP}/DBIRTH/{n}/main" for m in host.since())]
        gone = [n for n, d in daemons.items() if d.proc.poll() is not None]
        check(f"every node born: an NBIRTH and a DBIRTH from each of {NODES}", all_born,
              f"not born after {took:.1f} s: {missing}; exited: {gone}; "
              f"log of {missing[:1]}: {daemons[missing[0]].log[-3:] if missing else ''}")
        if not all_born:
            return
        print(f"      (all {NODES} born {took:.1f} s after the first start)")

        births = {n: [m for m in host.since() if m[1] == f"spBv1.0/{GROUP}/NBIRTH/{n}"] for n in daemons}
        dbirths = {n: [m for m in host.since() if m[1] == f"spBv1.0/{GROUP}/DBIRTH/{n}/main"] for n in daemons}
        wrong = {n: (b[0][4].seq, metrics_of(b[0][4]).get("bdSeq") and metrics_of(b[0][4])["bdSeq"].value)
                 for n, b in births.items()
                 if b[0][4].seq != 0 or "bdSeq" not in metrics_of(b[0][4])
                 or metrics_of(b[0][4])["bdSeq"].value != 0}
        check("every NBIRTH has seq 0 and bdSeq 0", not wrong, wrong)
        wrong = {n: b[0][4].seq for n, b in dbirths.items()
                 if b[0][4].seq != 1 or "ticks" not in metrics_of(b[0][4])}
        check("every DBIRTH has seq 1 and the program's ticks", not wrong, wrong)

        time.sleep(OBSERVE_S)

        # All 20 stopped at once.
        stop_mark = host.mark()
        for d in daemons.values():
            if d.proc.poll() is None:
                d.proc.send_signal(signal.SIGTERM)

        def dead():
            seen = {m[1] for m in host.since(stop_mark)}
            return all(f"spBv1.0/{GROUP}/NDEATH/{n}" in seen for n in daemons)
        all_dead = cs.wait_until(dead, STOP_WAIT_S)
        exits = {}
        stopped = time.monotonic()
        for n, d in daemons.items():
            try:
                exits[n] = d.proc.wait(timeout=max(0.1, STOP_WAIT_S - (time.monotonic() - stopped)))
            except Exception:  # noqa: BLE001 - a daemon that does not stop is a finding
                exits[n] = None
        time.sleep(0.5)  # anything a node would still send after its death
        messages = host.since()

        # Per node, from its birth.
        breaks, counts, ticks_bad, scans_bad, stamps_bad, historical, rebirths = {}, {}, {}, {}, {}, {}, {}
        after_death, deaths_bad, early_deaths = {}, {}, {}
        for n in daemons:
            mine = of_node(messages, n)
            births_n = [m for m in mine if m[2] == "NBIRTH"]
            if len(births_n) != 1:
                rebirths[n] = len(births_n)
            live = from_birth(mine)
            b, count = seq_breaks(live)
            if b:
                breaks[n] = b[:3]
            ddata = [m for m in live if m[2] == "DDATA"]
            ndata = [m for m in live if m[2] == "NDATA"]
            counts[n] = (count, len(ddata))
            ticks = [metrics_of(m[4])["ticks"].value for m in ddata if "ticks" in metrics_of(m[4])]
            if len(ticks) != len(ddata) or not rising(ticks):
                ticks_bad[n] = (len(ticks), len(ddata), ticks[:5])
            scans = [metrics_of(m[4])["Status/Scans"].value for m in ndata
                     if "Status/Scans" in metrics_of(m[4])]
            if not rising(scans):
                scans_bad[n] = scans[:5]
            stamps = [m[4].timestamp for m in live]
            if stamps != sorted(stamps):
                stamps_bad[n] = stamps[:5]
            if any(getattr(mm, "is_historical", False) for m in live for mm in getattr(m[4], "metrics", ())):
                historical[n] = True
            # The NDEATHs of the stop: after the SIGTERM, from the birth on.
            births_at = [i for i, m in enumerate(mine) if m[2] == "NBIRTH"]
            first = births_at[-1] if births_at else 0
            deaths = [i for i, m in enumerate(mine) if m[2] == "NDEATH" and i > first]
            if len(deaths) != 1:
                deaths_bad[n] = f"{len(deaths)} NDEATHs after the NBIRTH"
            if deaths:
                death = mine[deaths[0]][4]
                if isinstance(death, Exception) or death.bd_seq_metric.value != 0:
                    deaths_bad[n] = death
                if mine[deaths[0] + 1:]:
                    after_death[n] = [m[1] for m in mine[deaths[0] + 1:]][:3]
            early = [m for m in mine[:first] if m[2] == "NDEATH"]
            if early:
                early_deaths[n] = len(early)

        check("each node born once", not rebirths, rebirths)
        undecoded = [m[1] for m in messages if isinstance(m[4], Exception)]
        check("every payload decoded by pysparkplug", not undecoded, undecoded[:3])
        check(f"per node, seq continuous mod 256 from its NBIRTH ({OBSERVE_S:.0f} s of data)",
              not breaks, breaks)
        wrapped = [n for n, (count, _) in counts.items() if count > 256]
        least = min(c[1] for c in counts.values())
        # The scan changes ticks every 10 ms: a DDATA every 100 ms is due; a loaded machine
        # may take fewer copies (the sampler's waits are not real time), never none for long.
        check(f"per node, DDATA kept coming (at least {OBSERVE_S * 2:.0f} in {OBSERVE_S:.0f} s)",
              least >= OBSERVE_S * 2, {n: c[1] for n, c in counts.items() if c[1] < OBSERVE_S * 2})
        print(f"      ({sum(c[0] for c in counts.values())} messages after the births, "
              f"DDATA per node {least} to {max(c[1] for c in counts.values())}, "
              f"seq wrapped past 255 on {len(wrapped)} nodes)")
        check("per node, ticks strictly increasing from one DDATA to the next", not ticks_bad, ticks_bad)
        check("per node, Status/Scans strictly increasing from one NDATA to the next", not scans_bad, scans_bad)
        check("per node, message timestamps never go back", not stamps_bad, stamps_bad)
        check("no live message flagged historical", not historical, historical)

        check("SIGTERM to all 20: every NDEATH arrives", all_dead,
              [n for n in daemons if not any(m[1] == f"spBv1.0/{GROUP}/NDEATH/{n}" for m in host.since(stop_mark))])
        check("one NDEATH per node after its birth, with the birth's bdSeq (0)", not deaths_bad, deaths_bad)
        check("nothing from a node after its NDEATH", not after_death, after_death)
        # The edge node awaits its connect whole: a connect is never dropped half made, so no
        # broker publishes the will of a session that was never born.
        check("no NDEATH before a node's NBIRTH (no connect dropped half made)", not early_deaths,
              early_deaths)
        check("every daemon stopped cleanly (exit 0)", all(c == 0 for c in exits.values()),
              {n: c for n, c in exits.items() if c != 0})
    finally:
        for d in daemons.values():
            killpg(d.proc)
            d.reader.join(timeout=1.0)
        host.close()


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--plcd", required=True)
    parser.add_argument("--project", required=True)
    args = parser.parse_args()
    broker_dir = tempfile.mkdtemp(prefix="plcd-mosquitto-plant-")
    broker = Broker(broker_dir, free_port())
    try:
        plant(args.plcd, args.project, broker.port)
    finally:
        killpg(broker.proc)
    print(f"{cs.passed} passed, {len(cs.failed)} failed")
    if cs.failed:
        print("failed: " + ", ".join(cs.failed))
        sys.exit(1)


if __name__ == "__main__":
    main()

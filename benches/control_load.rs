//! Scan time with and without 50 clients polling `status` as fast as they can, side by side in
//! one run: `cargo bench --bench control_load` (as root for SCHED_FIFO and mlockall, as the
//! service runs). Writes target/bench-results/control.md for BENCHMARKS.md.
//!
//! The daemon (the release `plcd` binary) runs a 1 ms fixed scan period with a 200-instruction
//! program that counts its scans in D00000 and a 1 ms cycle task. Each phase starts from RUN
//! (which resets the figures) and lasts `PHASE`; the figures are the daemon's own. "Lost scans"
//! compares the scans the program counted with the periods that passed.

use std::io::{BufRead, BufReader, Write};
use std::os::unix::net::UnixStream;
use std::sync::atomic::Ordering;

use plcd::bench::{write_fragment, Fragment};

#[path = "common/load.rs"]
mod load;

const CLIENTS: usize = 50;

fn main() {
    if std::env::args().any(|a| a == "--list") {
        return; // `cargo test --benches` probes benches with --list
    }
    let daemon = load::Daemon::start(
        "control",
        "[control]\nsocket = \"plcd.sock\"\nmax_clients = 64\n",
        false,
    );
    let socket = daemon.socket();
    // Each client sends `status` back to back on its own connection; it returns its answers.
    let status_poller = |socket: std::path::PathBuf| {
        move |_: usize, stop: std::sync::Arc<std::sync::atomic::AtomicBool>| {
            let stream = UnixStream::connect(&socket).unwrap();
            let mut reader = BufReader::new(stream.try_clone().unwrap());
            let mut writer = stream;
            let mut line = String::new();
            let mut answers = 0u64;
            while !stop.load(Ordering::Relaxed) {
                writer.write_all(b"{\"v\":1,\"cmd\":\"status\"}\n").unwrap();
                line.clear();
                reader.read_line(&mut line).unwrap();
                answers += 1;
            }
            answers
        }
    };
    let quiet = load::phase(&socket, 0, status_poller(socket.clone()));
    let loaded = load::phase(&socket, CLIENTS, status_poller(socket.clone()));
    drop(daemon);

    let mut f = Fragment::new("cargo bench --bench control_load");
    f.line(format!(
        "The daemon runs a 1 ms fixed scan period with a 201-instruction scan program and a 1 ms \
         cycle task; each phase starts from RUN (which resets the figures) and lasts {} s; in the \
         second, {CLIENTS} threads send `status` back to back on their own connections. Figures \
         are the daemon's own histograms.\n",
        load::PHASE.as_secs()
    ));
    let answers = |fig: &load::Figures<u64>| fig.clients.iter().sum::<u64>();
    load::table(
        &mut f,
        &format!("{CLIENTS} clients polling `status`"),
        "`status` answers",
        [(&quiet, answers(&quiet)), (&loaded, answers(&loaded))],
    );
    write_fragment("control", &f).expect("fragment written");
}

//! What retained memory costs: the scan thread's pause for the END copy (the only work
//! persistence puts on the scan thread), the bytes and the time of one write (temporary file,
//! fsync, rename, fsync of the directory, on the file system of the target directory), and
//! the time to restore at start (read both generations, decode, choose, copy into device
//! memory). `cargo bench --bench retain`; the fragment goes to BENCHMARKS.md as `retain`.

use std::time::{Duration, Instant};

use plcd::bench::{write_fragment, Fragment};
use plcd::config::{Restart, RetainRange};
use plcd::device::layout;
use plcd::device::RetainSet;
use plcd::drivers::real_time::mirror::Mirror;
use plcd::engine::event::Mode;
use plcd::services::retain::writer::Writer;
use plcd::services::retain::{self, Store};

const CAPTURES: usize = 20_000;
const WRITES: usize = 200;
const RESTORES: usize = 200;

struct Case {
    name: &'static str,
    set: RetainSet,
}

fn cases() -> Vec<Case> {
    let r = |t: &str| RetainRange::parse(t).unwrap();
    vec![
        Case { name: "K only (no `[retain]`)", set: RetainSet::new(&[]) },
        Case {
            name: "K + D00000-D00099 + C0000-C0015",
            set: RetainSet::new(&[r("D00000-D00099"), r("C0000-C0015")]),
        },
        Case {
            name: "K + all D, T and C",
            set: RetainSet::new(&[r("D00000-D32767"), r("T0000-T2047"), r("C0000-C2047")]),
        },
    ]
}

fn percentile(sorted: &[Duration], p: f64) -> Duration {
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
}

fn us(d: Duration) -> String {
    format!("{:.1} µs", d.as_secs_f64() * 1e6)
}

fn ms(d: Duration) -> String {
    format!("{:.2} ms", d.as_secs_f64() * 1e3)
}

/// The scan thread's part: `Mirror::capture` after a request, as at the one boundary per
/// interval that has one (the writer takes the copy in between; here the image is free, so
/// every capture copies). Also the same loop timing nothing: the machine's own noise (this
/// thread preempted, the hypervisor), which every maximum here includes.
fn capture_times(set: &RetainSet) -> (Vec<Duration>, Vec<Duration>) {
    let memory: Vec<u16> = (0..layout::TOTAL_WORDS as u16).collect();
    let mirror = Mirror::new(set.words.iter().map(|w| w.range()));
    let mut copies = Vec::with_capacity(CAPTURES);
    let mut nothing = Vec::with_capacity(CAPTURES);
    for scan in 0..CAPTURES as u64 {
        mirror.request();
        let began = Instant::now();
        let copied = mirror.capture(&memory, scan, Mode::Run, scan);
        copies.push(began.elapsed());
        assert!(copied);
        let began = Instant::now();
        nothing.push(began.elapsed());
    }
    copies.sort();
    nothing.sort();
    (copies, nothing)
}

fn main() {
    if std::env::args().any(|a| a == "--list") {
        return; // `cargo test --benches` probes benches with --list
    }
    let dir =
        plcd::bench::report::target_dir().join(format!("bench-retain-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    // The END copies on a thread of their own, as the scan thread runs: SCHED_FIFO 80 where
    // permitted. The writes and restores below run on this (normal) thread, as the writer's.
    let (fifo, copies) = std::thread::spawn(|| {
        let fifo = plcd::drivers::real_time::sys::set_fifo(80).is_ok();
        (fifo, cases().iter().map(|case| capture_times(&case.set)).collect::<Vec<_>>())
    })
    .join()
    .unwrap();
    let mut rows = Vec::new();
    let mut noise = Duration::ZERO;
    for (case, (captures, nothing)) in cases().into_iter().zip(copies) {
        let words = case.set.word_count();
        noise = noise.max(*nothing.last().unwrap());

        // Writes: a new value every time, so every write goes to disk.
        let case_dir = dir.join(case.name.len().to_string());
        let store = Store::open(&case_dir).unwrap();
        let mut writer = Writer::new(store, &case.set.words, 0, 1, None);
        let mut payload = vec![0u16; words];
        let mut writes = Vec::with_capacity(WRITES);
        for i in 0..WRITES {
            payload.iter_mut().for_each(|w| *w = i as u16);
            let began = Instant::now();
            assert!(writer.write_if_changed(&mut payload).unwrap());
            writes.push(began.elapsed());
        }
        writes.sort();
        let bytes = writer.stats.bytes_per_write;

        // Restores: what the daemon does before the first RUN.
        let mut memory = vec![0u16; layout::TOTAL_WORDS as usize];
        let mut restores = Vec::with_capacity(RESTORES);
        for _ in 0..RESTORES {
            let began = Instant::now();
            let start = retain::startup(&Store::open(&case_dir).unwrap(), &case.set, Restart::Warm);
            case.set.restore(start.words.as_deref().unwrap(), &mut memory);
            restores.push(began.elapsed());
        }
        restores.sort();

        rows.push(vec![
            case.name.to_string(),
            format!("{words}"),
            us(percentile(&captures, 0.5)),
            us(percentile(&captures, 0.99)),
            us(percentile(&captures, 0.999)),
            format!("**{}**", us(*captures.last().unwrap())),
            format!("{bytes}"),
            ms(percentile(&writes, 0.5)),
            ms(*writes.last().unwrap()),
            ms(percentile(&restores, 0.5)),
            ms(*restores.last().unwrap()),
        ]);
    }
    let _ = std::fs::remove_dir_all(&dir);

    let mut f = Fragment::new("cargo bench --bench retain");
    f.line(format!(
        "The scan thread's only work for persistence is the END copy of the retained words into \
         the writer's mirror (`Mirror::capture`: a `try_lock`, a `memcpy`, a notify), once per \
         `interval_ms` at the first scan boundary after the writer asked; at every other \
         boundary it is one atomic load. Timed here {CAPTURES} times on a thread {}; the file \
         I/O runs on the writer thread and never blocks the scan. A write is one \
         generation: temporary file, `fsync`, rename, `fsync` of the directory, on the file \
         system of the target directory, {WRITES} times. A restore is what the daemon does \
         before the first RUN: read and decode both generation files, choose, copy into device \
         memory, {RESTORES} times (files in the page cache).",
        if fifo {
            "under SCHED_FIFO 80, as the scan thread"
        } else {
            "under SCHED_OTHER (not root)"
        }
    ));
    f.line("");
    f.table(
        &[
            "retained",
            "words",
            "END copy p50",
            "p99",
            "p99.9",
            "max (scan thread pause)",
            "bytes per write",
            "write p50",
            "write max",
            "restore p50",
            "restore max",
        ],
        &rows,
    );
    f.line(format!(
        "The same loop timing nothing had a maximum of {}: the maxima of the END copy are this \
         shared VM's interruptions, not the copy (whose p99 is the figure to read).",
        us(noise)
    ));
    f.line("");
    f.line(
        "Bytes per interval: at most one write of the size above per `interval_ms`, and none \
         while the retained values do not change.",
    );
    write_fragment("retain", &f).unwrap();
}

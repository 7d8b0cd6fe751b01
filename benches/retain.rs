//! What retained memory costs: the scan thread's pause for the END copy (the only work
//! persistence puts on the scan thread), the bytes and the time of one write (temporary file,
//! fsync, rename, fsync of the directory, on the file system of the target directory), and
//! the time to restore at start (read both generations, decode, choose, copy into device
//! memory). `cargo bench --bench retain`; the fragment goes to BENCHMARKS.md as `retain`.

use std::sync::Arc;
use std::time::{Duration, Instant};

use plcd::bench::{write_fragment, Fragment};
use plcd::config::{Restart, RetainRange};
use plcd::device::layout;
use plcd::engine::event::Mode;
use plcd::retain::layout::set_of;
use plcd::retain::writer::Writer;
use plcd::retain::{self, RetainSet, Store};
use plcd::rt::mirror::Mirror;

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
        Case { name: "K only (no `[retain]`)", set: set_of(&[]) },
        Case {
            name: "K + D00000-D00099 + C0000-C0015",
            set: set_of(&[r("D00000-D00099"), r("C0000-C0015")]),
        },
        Case {
            name: "K + all D, T and C",
            set: set_of(&[r("D00000-D32767"), r("T0000-T2047"), r("C0000-C2047")]),
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

/// The scan thread's part: `Mirror::capture` after a request, as at every boundary that has
/// one, with a writer thread taking the copies out (and sometimes holding the image: the
/// capture then is a failed `try_lock`, and waits for the next boundary).
fn capture_times(set: &RetainSet) -> Vec<Duration> {
    let memory: Vec<u16> = (0..layout::TOTAL_WORDS as u16).collect();
    let mirror = Arc::new(Mirror::new(set.words.iter().map(|w| w.range())));
    let stop = Arc::new(std::sync::atomic::AtomicBool::new(false));
    let reader = {
        let (mirror, stop) = (Arc::clone(&mirror), Arc::clone(&stop));
        std::thread::spawn(move || {
            let mut seen = 0;
            let mut copy = Vec::new();
            while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                mirror.request();
                let image = mirror.wait_newer(seen, Duration::from_millis(10));
                seen = image.generation;
                copy.clear();
                copy.extend_from_slice(&image.words);
            }
        })
    };
    let mut times = Vec::with_capacity(CAPTURES);
    for scan in 0..CAPTURES as u64 {
        mirror.request();
        let began = Instant::now();
        mirror.capture(&memory, scan, Mode::Run, scan);
        times.push(began.elapsed());
    }
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    reader.join().unwrap();
    times.sort();
    times
}

fn main() {
    if std::env::args().any(|a| a == "--list") {
        return; // `cargo test --benches` probes benches with --list
    }
    let dir = plcd::bench::report::target_dir()
        .join(format!("bench-retain-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let mut rows = Vec::new();
    for case in cases() {
        let words = case.set.word_count();
        let captures = capture_times(&case.set);

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
         the writer's mirror (`Mirror::capture`: a `try_lock`, a `memcpy`, a notify), timed here \
         {CAPTURES} times on this thread while a writer thread takes the copies out as fast as it \
         can; the file I/O runs on the writer thread and never blocks the scan. A write is one \
         generation: temporary file, `fsync`, rename, `fsync` of the directory, on the file \
         system of the target directory, {WRITES} times. A restore is what the daemon does \
         before the first RUN: read and decode both generation files, choose, copy into device \
         memory, {RESTORES} times (files in the page cache)."
    ));
    f.line("");
    f.table(
        &[
            "retained",
            "words",
            "END copy p50",
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
    f.line(
        "Bytes per interval: at most one write of the size above per `interval_ms`, and none \
         while the retained values do not change.",
    );
    write_fragment("retain", &f).unwrap();
}

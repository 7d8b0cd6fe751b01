//! What a large variable costs to load: an array of any size is one entry of the symbol table
//! (`plcd::symbols`), whatever its elements hold, and every element is still found by name and
//! by place; an online change keeps the elements of an array whose bounds change, by index.
//! Compiling a project with a 16 MiB array allocates a few times 16 MiB, not a symbol per
//! byte. Counts only: no wall time, no resident memory.
#![allow(unsafe_code)]

mod harness;

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicU64, Ordering};

use harness::engine::project;
use plcd::project::Project;
use plcd::symbols::Entry;
use plcd::value::{Pointer, Space};

struct Counting;

/// Bytes allocated by the threads that watch.
static ALLOCATED: AtomicU64 = AtomicU64::new(0);
/// Bytes the threads that watch hold now (allocated and not yet freed while watching), and
/// the most they held at once: the peak of a load.
static LIVE: AtomicU64 = AtomicU64::new(0);
static PEAK: AtomicU64 = AtomicU64::new(0);

/// Taken by the tests that watch: the counters are the process's, and tests run in parallel.
static SERIAL: std::sync::Mutex<()> = std::sync::Mutex::new(());

thread_local! {
    static WATCHED: Cell<bool> = const { Cell::new(false) };
}

// SAFETY: every call is forwarded unchanged to the system allocator; the counter only reads a
// thread-local flag (const-initialised, so reading it never allocates) and bumps an atomic.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if WATCHED.with(Cell::get) {
            ALLOCATED.fetch_add(layout.size() as u64, Ordering::Relaxed);
            hold(layout.size() as u64, 0);
        }
        // SAFETY: the caller's layout contract is passed on as is.
        unsafe { System.alloc(layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if WATCHED.with(Cell::get) {
            ALLOCATED.fetch_add(new_size as u64, Ordering::Relaxed);
            hold(new_size as u64, layout.size() as u64);
        }
        // SAFETY: `ptr` came from this allocator with `layout`, as the caller promises.
        unsafe { System.realloc(ptr, layout, new_size) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        if WATCHED.with(Cell::get) {
            hold(0, layout.size() as u64);
        }
        // SAFETY: `ptr` came from `System.alloc` with this layout.
        unsafe { System.dealloc(ptr, layout) }
    }
}

/// Counts `more` bytes held and `less` freed by a watching thread. What was allocated before
/// the watch and freed during it is not subtracted (saturating at 0), so the peak is never
/// under the truth.
fn hold(more: u64, less: u64) {
    let live = LIVE.load(Ordering::Relaxed).saturating_add(more).saturating_sub(less);
    LIVE.store(live, Ordering::Relaxed);
    PEAK.fetch_max(live, Ordering::Relaxed);
}

#[global_allocator]
static GLOBAL: Counting = Counting;

const CONFIG: &str = "[[program]]\nfile = \"main.st\"\n";

fn at(p: &Project, name: &str) -> u32 {
    p.variable(name).unwrap_or_else(|| panic!("no variable {name}")).at.offset
}

#[test]
fn a_million_element_array_is_one_symbol() {
    let src = "PROGRAM Main VAR n : INT; buf : ARRAY[1..1000000] OF BYTE; last : DINT; END_VAR
                 buf[999999] := 7; n := n + 1;
               END_PROGRAM";
    let p = project(CONFIG, &[("main.st", src)]);
    let symbols = &p.variables.symbols;
    assert!(symbols.entries().len() <= 4, "{} entries", symbols.entries().len());
    assert!(symbols.len() >= 1_000_002, "every element is still a leaf: {}", symbols.len());
    let first = at(&p, "main.buf[1]");
    assert_eq!(at(&p, "main.buf[999999]"), first + 999_998);
    assert_eq!(at(&p, "MAIN.BUF[ 1000000 ]"), first + 999_999);
    assert_eq!(p.variable("main.buf[999999]").unwrap().name, "main.buf[999999]");
    for wrong in ["main.buf[0]", "main.buf[1000001]", "main.buf[01]", "main.buf"] {
        assert!(p.variable(wrong).is_none(), "{wrong}");
    }
    let slot = Pointer { space: Space::Var, offset: first + 41 }.to_slot() + plcd::value::REF_TAG;
    assert_eq!(plcd::lang::reference_text(symbols, slot), "main.buf[42]");
}

/// TcUnit's `ST_TestSuiteResults`: an array of structs, each holding an array of structs of
/// strings and scalars.
#[test]
fn an_array_of_structs_holding_arrays_is_a_handful_of_entries() {
    let src = "TYPE TestResult : STRUCT
                   TestName : STRING(255); TestClassName : STRING(255); TestIsFailed : BOOL;
                   FailureMessage : STRING(255); FailureType : INT; TestIsSkipped : BOOL;
                   NumberOfAsserts : UINT; Duration : LREAL;
                 END_STRUCT; END_TYPE
               TYPE SuiteResult : STRUCT
                   Name : STRING(255); Identity : UINT; Tests : ARRAY[1..100] OF TestResult;
                 END_STRUCT; END_TYPE
               PROGRAM Main VAR results : ARRAY[1..20] OF SuiteResult; n : INT; END_VAR
                 n := n + 1;
               END_PROGRAM";
    let p = project(CONFIG, &[("main.st", src)]);
    let symbols = &p.variables.symbols;
    assert!(symbols.entries().len() <= 4, "{} entries", symbols.entries().len());
    let Some(Entry::Array(results)) =
        symbols.entries().iter().find(|e| matches!(e, Entry::Array(a) if a.name == "main.results"))
    else {
        panic!("main.results is one array entry");
    };
    assert_eq!(results.element.entries().len(), 3, "Name, Identity, Tests");
    assert_eq!(symbols.len(), 1 + 20 * (2 + 100 * 8));
    let stride = results.stride;
    let test = |s: u32, t: u32, leaf: &str| format!("main.results[{s}].Tests[{t}].{leaf}");
    let far = at(&p, &test(20, 100, "Duration"));
    assert_eq!(far - at(&p, &test(1, 100, "Duration")), 19 * stride);
    assert!(far > at(&p, &test(20, 99, "Duration")));
    let name = p.variable(&test(20, 100, "failuremessage")).unwrap().name;
    assert_eq!(name, test(20, 100, "FailureMessage"), "the declaration's spelling");
    // the iteration's order is the order of the places here
    let names: Vec<String> = symbols.iter().skip(2).take(3).map(|s| s.name).collect();
    assert_eq!(
        names,
        [test(1, 1, "TestName"), test(1, 1, "TestClassName"), test(1, 1, "TestIsFailed")]
    );
    let inside = Pointer { space: Space::Var, offset: at(&p, &test(7, 3, "TestClassName")) + 5 };
    let slot = inside.to_slot() + plcd::value::REF_TAG;
    assert_eq!(
        plcd::lang::reference_text(symbols, slot),
        format!("{}+5", test(7, 3, "TestClassName"))
    );
}

#[test]
fn an_online_change_keeps_array_elements_by_index_when_the_bounds_change() {
    let source = |dims: &str| {
        format!(
            "TYPE Pair : STRUCT a : INT; b : REAL; END_STRUCT; END_TYPE
             PROGRAM Main VAR x : ARRAY[{dims}] OF Pair; m : ARRAY[1..2, 1..3] OF INT; END_VAR
               x[2].a := x[2].a + 1;
             END_PROGRAM"
        )
    };
    let old = project(CONFIG, &[("main.st", &source("1..4"))]);
    let new = project(CONFIG, &[("main.st", &source("0..5"))]);
    let kept = plcd::engine::online::kept_variables(&old.variables, &new.variables);
    let copied = |from: u32, to: u32, len: u32| {
        kept.iter().any(|&(f, t, l)| f <= from && from + len <= f + l && to - from == t - f)
    };
    for i in 1..=4 {
        for (leaf, len) in [("a", 2), ("b", 4)] {
            let name = format!("main.x[{i}].{leaf}");
            assert!(copied(at(&old, &name), at(&new, &name), len), "{name} is kept: {kept:?}");
        }
    }
    for i in [0, 5] {
        let fresh = at(&new, &format!("main.x[{i}].a"));
        assert!(kept.iter().all(|&(_, t, l)| fresh < t || fresh >= t + l), "x[{i}] is new");
    }
    for name in ["main.m[1,1]", "main.m[2,3]"] {
        assert!(copied(at(&old, name), at(&new, name), 2), "{name} is kept");
    }
    // an element declared otherwise: its leaves of the same name and type, one by one
    let changed = source("1..4").replace("b : REAL;", "b : REAL; c : BOOL;");
    let changed = project(CONFIG, &[("main.st", &changed)]);
    let kept = plcd::engine::online::kept_variables(&old.variables, &changed.variables);
    for name in ["main.x[1].a", "main.x[4].b"] {
        let (from, to) = (at(&old, name), at(&changed, name));
        assert!(kept.iter().any(|&(f, t, _)| (f, t) == (from, to)), "{name} is kept: {kept:?}");
    }
    let c = at(&changed, "main.x[3].c");
    assert!(kept.iter().all(|&(_, t, l)| c < t || c >= t + l), "c is new");
}

/// A misspelled name next to a 1,000,000-element array is suggested from one element of it,
/// the one whose index the name writes, not by spelling every element's name (20 MB).
#[test]
fn a_misspelled_name_is_suggested_without_expanding_an_array() {
    let src = "TYPE Pt : STRUCT x : INT; y : INT; END_STRUCT; END_TYPE
               PROGRAM Main VAR n : INT; pts : ARRAY[1..1000000] OF Pt; END_VAR
                 n := n + 1;
               END_PROGRAM";
    let p = project(CONFIG, &[("main.st", src)]);
    let _serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let before = ALLOCATED.load(Ordering::Relaxed);
    WATCHED.with(|w| w.set(true));
    let suggested = [
        p.closest_variable("main.ptss[777777].y"),
        p.closest_variable("MAIN.PTS[ 777777 ].z"),
        p.closest_variable("main.pts[0].x"),
        p.closest_variable("main.nn"),
    ];
    WATCHED.with(|w| w.set(false));
    let allocated = ALLOCATED.load(Ordering::Relaxed) - before;
    let names = suggested.map(|s| s.unwrap_or_default());
    assert_eq!(names, ["main.pts[777777].y", "main.pts[777777].x", "main.pts[1].x", "main.n"]);
    assert!(allocated < 64 << 10, "{allocated} bytes allocated to suggest four names");
}

/// Compiling a project with a 16 MiB array allocates a few times its size (its initial image
/// and copies of it), not a symbol and a name per element (96 bytes and a name each), and
/// holds at most two images of it at once.
#[test]
fn compiling_a_16_mib_array_allocates_a_few_times_its_size() {
    const SIZE: u64 = 16 << 20;
    let src = format!(
        "PROGRAM Main VAR buf : ARRAY[1..{SIZE}] OF BYTE; n : INT; END_VAR
           buf[3] := 1; n := n + 1;
         END_PROGRAM"
    );
    let config = harness::engine::config(CONFIG);
    let _serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    for counter in [&ALLOCATED, &LIVE, &PEAK] {
        counter.store(0, Ordering::Relaxed);
    }
    WATCHED.with(|w| w.set(true));
    let p = harness::engine::project_of(config, &[("main.st", &src)]);
    WATCHED.with(|w| w.set(false));
    let allocated = ALLOCATED.load(Ordering::Relaxed);
    assert!(p.variables.initial.len() as u64 >= SIZE);
    // about 7 times today (the image as it grows, counted at each reallocation, and its
    // copies); a symbol per element was over 100 times
    assert!(allocated < 12 * SIZE, "{allocated} bytes allocated for a {SIZE}-byte array");
    // At most two images at once: the PROGRAM's and variable memory's while the instance is
    // placed, variable memory's and its shared copy at the end. A clone of either (as the
    // placement and the end of the compile made until 2026-11-30) is a third.
    let peak = PEAK.load(Ordering::Relaxed);
    eprintln!("peak {peak} bytes, {:.2} times the array", peak as f64 / SIZE as f64);
    assert!(peak < 2 * SIZE + SIZE / 2, "{peak} bytes held at once for a {SIZE}-byte array");
}

/// A retained 4,000,000-element array is one record of the retained variables and of the
/// retain file — its name, its type text, its 16,000,000 bytes — not a record per element
/// (a name, a lowercase key and a type text each: 147 MB a file and 1.3 GB of `plcd run` until
/// version 4 of the file).
#[test]
fn a_retained_array_of_4_000_000_elements_is_one_record_of_its_bytes() {
    use plcd::services::retain::format;
    use plcd::vm::retained::RetainedVariables;
    const COUNT: u64 = 4_000_000;
    let src = format!(
        "PROGRAM Main VAR RETAIN buf : ARRAY[1..{COUNT}] OF DINT; n : INT; END_VAR
           buf[3] := 1; n := n + 1;
         END_PROGRAM"
    );
    let p = project(CONFIG, &[("main.st", &src)]);
    let _serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let before = ALLOCATED.load(Ordering::Relaxed);
    WATCHED.with(|w| w.set(true));
    let retained = RetainedVariables::new(&p.variables);
    WATCHED.with(|w| w.set(false));
    let allocated = ALLOCATED.load(Ordering::Relaxed) - before;
    assert!(allocated < 4 << 10, "{allocated} bytes allocated for the retained records");
    let records: Vec<(&str, &str)> =
        retained.records().iter().map(|r| (r.name.as_str(), r.ty.as_str())).collect();
    assert_eq!(records, [("main.buf", "ARRAY[1..4000000] OF DINT"), ("main.n", "INT")]);
    assert_eq!(retained.bytes() as u64, 4 * COUNT + 2);

    let mut vars = p.variables.initial.to_vec();
    let at = p.variable("main.buf[4000000]").unwrap().at.offset as usize;
    vars[at..at + 4].copy_from_slice(&7i32.to_le_bytes());
    let mut copy = Vec::with_capacity(retained.bytes());
    let mut section = Vec::new();
    let before = ALLOCATED.load(Ordering::Relaxed);
    WATCHED.with(|w| w.set(true));
    retained.copy(&vars, &mut copy);
    format::encode_records(&retained, &copy, &mut section);
    WATCHED.with(|w| w.set(false));
    let allocated = ALLOCATED.load(Ordering::Relaxed) - before;
    // the section's one buffer, of its size
    assert!(allocated < 4 * COUNT + 1024, "{allocated} bytes allocated to encode");
    let overhead = section.len() as u64 - (4 * COUNT + 2);
    // the count, then three lengths, a name and a type text a record
    assert_eq!(overhead, 4 + (12 + 8 + 25) + (12 + 6 + 3));
    let saved = format::decode_variables(&section).unwrap();
    assert_eq!(saved.len(), 2);
    assert_eq!(saved[0].bytes[4 * COUNT as usize - 4..], 7i32.to_le_bytes());
}

//! One test's independent cases run on every core: the test harness runs tests side by side,
//! but a test that walks hundreds of cases (golden files, conformance programs) runs them one
//! after the other, and under qemu-user (tests/cross/run-aarch64-tests) such a test alone took
//! minutes of CI. Each case still runs whole and is reported in the order given.
//!
//! Needs nothing of plcd: plcd-native's tests include this file alone (`#[path]`).

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

/// `f` of every item, in the order of `items`, computed by as many threads as the machine has
/// cores (at most one a case). A panic in `f` fails the test as it would in a loop.
pub fn map<T: Sync, R: Send>(items: &[T], f: impl Fn(&T) -> R + Sync) -> Vec<R> {
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get()).min(items.len());
    if threads <= 1 {
        return items.iter().map(f).collect();
    }
    let next = AtomicUsize::new(0);
    let results: Mutex<Vec<Option<R>>> = Mutex::new((0..items.len()).map(|_| None).collect());
    std::thread::scope(|scope| {
        for _ in 0..threads {
            scope.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                let Some(item) = items.get(i) else { break };
                let result = f(item);
                results.lock().unwrap_or_else(|e| e.into_inner())[i] = Some(result);
            });
        }
    });
    let results = results.into_inner().unwrap_or_else(|e| e.into_inner());
    results.into_iter().map(|r| r.expect("every case ran: a panic fails the scope")).collect()
}

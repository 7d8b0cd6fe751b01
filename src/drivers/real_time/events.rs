//! The event thread: GPIO edges become pending work for the scan thread.
//!
//! It owns an epoll set of the GPIO input request's fd, when edges are wanted, and its wake
//! eventfd (shutdown). It reads the kernel's edge events as soon as they arrive, above the
//! scan thread's priority, queues them with their kernel timestamps and wakes the scan thread
//! if it sleeps. It never touches the engine: what an edge starts, the engine decides when the
//! scan thread polls it.
//!
//! A read of the edge events that fails is not logged here (logging allocates, and a fault
//! that persists would log in a loop at this thread's priority): it is counted in
//! `Shared::field_faults` with its errno, and the supervisor logs once when reads start failing,
//! when the errno changes and when they work again. Nor is the fd read again at once: a fault
//! that persists (a chip unplugged, a driver gone) leaves it readable, and `epoll_wait` would
//! return at once forever, a busy loop above the scan thread. After a failure the fd leaves the
//! epoll set for a back-off that doubles with each consecutive failure, from 1 ms to 1 s
//! ([`backoff_ms`]), then is watched again; edges that arrive meanwhile wait in the kernel's
//! FIFO (what overflows it is counted as lost, from the sequence numbers), and the first read
//! that works ends the back-off. A persistent fault so costs one read a second, and io tasks
//! start again on their own if it clears.
//!
//! Cycle deadlines need no thread of their own: the scan thread sleeps on a timerfd armed at
//! the engine's next deadline and, while it executes, looks at the clock between two slices
//! of instructions. (A timer here as well would wake two threads for every deadline, and the
//! second wake-up, on the scan thread's CPU, would delay the task it announces.)

use std::os::fd::AsFd;
use std::sync::atomic::Ordering;
use std::sync::Arc;

use nix::sys::epoll::{Epoll, EpollCreateFlags, EpollEvent, EpollFlags, EpollTimeout};

use super::sys::{self, SysError};
use super::{pending, Shared};
use crate::io::gpio::GpioEdges;
use crate::io::InputEdge;

const WAKE: u64 = 100;
const GPIO: u64 = 101;

/// The first back-off after a failed read, and the longest.
const BACKOFF_FIRST_MS: u16 = 1;
const BACKOFF_MAX_MS: u16 = 1000;

/// How long the fd stays out of the epoll set after `consecutive` failed reads (1, 2, …): 1 ms,
/// doubling, at most 1 s.
pub fn backoff_ms(consecutive: u32) -> u16 {
    let doublings = consecutive.saturating_sub(1).min(15);
    BACKOFF_FIRST_MS.saturating_mul(1 << doublings).min(BACKOFF_MAX_MS)
}

/// Everything the event thread owns.
pub struct EventThread {
    pub shared: Arc<Shared>,
    pub gpio: Option<GpioEdges>,
    /// The edge queue's producer, when edges come from GPIO.
    pub edges: Option<rtrb::Producer<InputEdge>>,
}

impl EventThread {
    pub fn new(shared: Arc<Shared>) -> EventThread {
        EventThread { shared, gpio: None, edges: None }
    }

    /// Runs until shutdown.
    pub fn run(mut self) -> Result<(), SysError> {
        let check = |call, r: nix::Result<()>| r.map_err(|errno| SysError { call, errno });
        let epoll = Epoll::new(EpollCreateFlags::EPOLL_CLOEXEC)
            .map_err(|errno| SysError { call: "epoll_create", errno })?;
        check(
            "epoll_ctl",
            epoll.add(self.shared.event_wake.as_fd(), EpollEvent::new(EpollFlags::EPOLLIN, WAKE)),
        )?;
        if let Some(gpio) = &self.gpio {
            check(
                "epoll_ctl",
                epoll.add(gpio.as_fd(), EpollEvent::new(EpollFlags::EPOLLIN, GPIO)),
            )?;
        }
        let mut ready = [EpollEvent::empty(); 2];
        // Consecutive failed reads, and when the fd, out of the set since the last, goes back.
        let mut failures = 0u32;
        let mut retry_at_ns: Option<u64> = None;
        loop {
            let timeout = match retry_at_ns {
                // Rounded up, so that the wait never ends before the back-off does.
                Some(at) => EpollTimeout::from(
                    at.saturating_sub(sys::now_ns()).div_ceil(1_000_000).min(u64::from(u16::MAX))
                        as u16,
                ),
                None => EpollTimeout::NONE,
            };
            let n = match epoll.wait(&mut ready, timeout) {
                Ok(n) => n,
                Err(nix::errno::Errno::EINTR) => continue,
                Err(errno) => return Err(SysError { call: "epoll_wait", errno }),
            };
            if let (Some(at), Some(gpio)) = (retry_at_ns, &self.gpio) {
                if sys::now_ns() >= at {
                    retry_at_ns = None;
                    check(
                        "epoll_ctl",
                        epoll.add(gpio.as_fd(), EpollEvent::new(EpollFlags::EPOLLIN, GPIO)),
                    )?;
                }
            }
            let mut flags = 0;
            for event in &ready[..n] {
                match event.data() {
                    WAKE => self.shared.event_wake.drain(),
                    _ => match self.read_edges() {
                        Ok(read) => {
                            flags |= read;
                            failures = 0;
                        }
                        Err(()) => {
                            failures = failures.saturating_add(1);
                            let backoff = u64::from(backoff_ms(failures)) * 1_000_000;
                            retry_at_ns = Some(sys::now_ns() + backoff);
                            if let Some(gpio) = &self.gpio {
                                check("epoll_ctl", epoll.delete(gpio.as_fd()))?;
                            }
                        }
                    },
                }
            }
            if self.shared.shutdown.load(Ordering::SeqCst) {
                return Ok(());
            }
            if flags != 0 {
                self.shared.signal(flags);
            }
        }
    }

    /// Reads the edges waiting; the pending flags to raise, or `Err` when the read failed
    /// (counted in `Shared::field_faults`).
    fn read_edges(&mut self) -> Result<u32, ()> {
        let (Some(gpio), Some(queue)) = (&mut self.gpio, &mut self.edges) else { return Ok(0) };
        let shared = &self.shared;
        let lost_before = gpio.lost_edges();
        let mut any = false;
        let result = gpio.read(&mut |edge: InputEdge| {
            if queue.push(edge).is_err() {
                shared.lost_edges.fetch_add(1, Ordering::Relaxed);
            }
            any = true;
        });
        // Edges the kernel dropped (sequence gaps); the supervisor logs the count.
        shared.lost_edges.fetch_add(gpio.lost_edges() - lost_before, Ordering::Relaxed);
        let faults = &shared.field_faults.edge_reads;
        // Edges handed on before a failure are still pending work.
        let flags = if any { pending::EDGE } else { 0 };
        match result {
            Ok(_) => {
                faults.worked();
                Ok(flags)
            }
            Err(e) => {
                // The errno, not the error: the error holds a String in some variants, and it
                // is the supervisor's to describe.
                faults.failed(e.errno().unwrap_or(0));
                if flags != 0 {
                    shared.signal(flags);
                }
                Err(())
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_backoff_doubles_from_1_ms_to_1_s() {
        let steps: Vec<u16> = (1..=12).map(backoff_ms).collect();
        assert_eq!(steps, [1, 2, 4, 8, 16, 32, 64, 128, 256, 512, 1000, 1000]);
        assert_eq!(backoff_ms(0), 1);
        assert_eq!(backoff_ms(u32::MAX), 1000);
    }
}

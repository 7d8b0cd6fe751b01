//! The event thread: GPIO edges become pending work for the scan thread.
//!
//! It owns an epoll set of the GPIO input request's fd, when edges are wanted, and its wake
//! eventfd (shutdown). It reads the kernel's edge events as soon as they arrive, above the
//! scan thread's priority, queues them with their kernel timestamps and wakes the scan thread
//! if it sleeps. It never touches the engine: what an edge starts, the engine decides when the
//! scan thread polls it.
//!
//! Cycle deadlines need no thread of their own: the scan thread sleeps on a timerfd armed at
//! the engine's next deadline and, while it executes, looks at the clock between two slices
//! of instructions. (A timer here as well would wake two threads for every deadline, and the
//! second wake-up, on the scan thread's CPU, would delay the task it announces.)

use std::os::fd::AsFd;
use std::sync::atomic::Ordering;
use std::sync::Arc;

use nix::sys::epoll::{Epoll, EpollCreateFlags, EpollEvent, EpollFlags, EpollTimeout};

use super::sys::SysError;
use super::{pending, Shared};
use crate::io::gpio::GpioEdges;
use crate::io::InputEdge;

const WAKE: u64 = 100;
const GPIO: u64 = 101;

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
        loop {
            let n = match epoll.wait(&mut ready, EpollTimeout::NONE) {
                Ok(n) => n,
                Err(nix::errno::Errno::EINTR) => continue,
                Err(errno) => return Err(SysError { call: "epoll_wait", errno }),
            };
            let mut flags = 0;
            for event in &ready[..n] {
                match event.data() {
                    WAKE => self.shared.event_wake.drain(),
                    _ => flags |= self.read_edges(),
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

    fn read_edges(&mut self) -> u32 {
        let (Some(gpio), Some(queue)) = (&mut self.gpio, &mut self.edges) else { return 0 };
        let shared = &self.shared;
        let lost_before = gpio.lost_edges();
        let mut any = false;
        let result = gpio.read(&mut |edge: InputEdge| {
            if queue.push(edge).is_err() {
                shared.lost_edges.fetch_add(1, Ordering::Relaxed);
            }
            any = true;
        });
        if let Err(e) = result {
            log::error!("reading GPIO edge events: {e}");
        }
        // Edges the kernel dropped (sequence gaps); the supervisor logs the count.
        shared.lost_edges.fetch_add(gpio.lost_edges() - lost_before, Ordering::Relaxed);
        if any {
            pending::EDGE
        } else {
            0
        }
    }
}

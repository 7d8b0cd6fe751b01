//! The event thread: cycle timers and GPIO edges become pending work for the scan thread.
//!
//! It owns an epoll set of one timerfd per cycle task number (armed with the engine's absolute
//! deadlines, periodic, so no drift accumulates), the GPIO input request's fd when edges are
//! wanted, and its wake eventfd (a new timer plan, shutdown). It never touches the engine:
//! which deadlines have passed, and what that starts, the engine decides when the scan thread
//! polls it.

use std::os::fd::AsFd;
use std::sync::atomic::Ordering;
use std::sync::Arc;

use nix::sys::epoll::{Epoll, EpollCreateFlags, EpollEvent, EpollFlags, EpollTimeout};

use super::sys::{SysError, Timer};
use super::{pending, Shared, CYCLE_SLOTS};
use crate::io::gpio::GpioEdges;
use crate::io::InputEdge;

const WAKE: u64 = 100;
const GPIO: u64 = 101;

/// Everything the event thread owns.
pub struct EventThread {
    pub shared: Arc<Shared>,
    pub timers: [Timer; CYCLE_SLOTS],
    pub gpio: Option<GpioEdges>,
    /// The edge queue's producer, when edges come from GPIO.
    pub edges: Option<rtrb::Producer<InputEdge>>,
}

impl EventThread {
    pub fn new(shared: Arc<Shared>) -> Result<EventThread, SysError> {
        let mut timers = Vec::with_capacity(CYCLE_SLOTS);
        for _ in 0..CYCLE_SLOTS {
            timers.push(Timer::new()?);
        }
        let timers = timers.try_into().unwrap_or_else(|_| unreachable!("CYCLE_SLOTS timers"));
        Ok(EventThread { shared, timers, gpio: None, edges: None })
    }

    /// Runs until shutdown.
    pub fn run(mut self) -> Result<(), SysError> {
        let check = |call, r: nix::Result<()>| r.map_err(|errno| SysError { call, errno });
        let epoll = Epoll::new(EpollCreateFlags::EPOLL_CLOEXEC)
            .map_err(|errno| SysError { call: "epoll_create", errno })?;
        for (slot, timer) in self.timers.iter().enumerate() {
            check(
                "epoll_ctl",
                epoll.add(timer.as_fd(), EpollEvent::new(EpollFlags::EPOLLIN, slot as u64)),
            )?;
        }
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
        let mut generation = u64::MAX;
        let mut ready = [EpollEvent::empty(); CYCLE_SLOTS + 2];
        loop {
            let plan = self.shared.plan_generation.load(Ordering::Acquire);
            if plan != generation {
                generation = plan;
                self.arm_timers()?;
            }
            let n = match epoll.wait(&mut ready, EpollTimeout::NONE) {
                Ok(n) => n,
                Err(nix::errno::Errno::EINTR) => continue,
                Err(errno) => return Err(SysError { call: "epoll_wait", errno }),
            };
            let mut flags = 0;
            for event in &ready[..n] {
                match event.data() {
                    WAKE => self.shared.event_wake.drain(),
                    GPIO => flags |= self.read_edges(),
                    slot => {
                        let slot = slot as usize;
                        let expirations = self.timers[slot].expirations()?;
                        if expirations > 1 {
                            self.shared.timer_missed[slot]
                                .fetch_add(expirations - 1, Ordering::Relaxed);
                        }
                        if expirations > 0 {
                            flags |= pending::TIMER;
                        }
                    }
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

    fn arm_timers(&self) -> Result<(), SysError> {
        for (timer, slot) in self.timers.iter().zip(&self.shared.plan) {
            let first = slot[0].load(Ordering::Relaxed);
            let interval = slot[1].load(Ordering::Relaxed);
            if first == 0 {
                timer.disarm()?;
            } else {
                timer.arm(first, interval)?;
            }
        }
        Ok(())
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

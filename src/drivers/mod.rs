//! The two drivers of the one task engine. The engine decides what runs when; a driver only
//! feeds it events and time, and neither holds a copy of a scheduling rule.
//!
//! - [`virtual_time`]: `plcd sim`. Every executed instruction costs a fixed slice of virtual
//!   time, stimulus changes happen at their times, and time jumps while nothing runs: the same
//!   run gives the same trace, byte for byte, on any machine.
//! - [`real_time`]: `plcd run` (and `plcd bench`). CLOCK_MONOTONIC, SCHED_FIFO threads, timerfd
//!   deadlines, GPIO edge events with kernel timestamps, the watchdog thread.

pub mod real_time;
pub mod virtual_time;

//! The operating-system calls of the real-time driver, in one place: the monotonic clock,
//! scheduling policy and priority, CPU affinity, memory locking, stack prefaulting, timerfd and
//! eventfd. Everything here is a thin, safe wrapper; the one `unsafe` call has its `SAFETY:`
//! note. Errors come back as [`SysError`], naming the call.

use std::os::fd::{AsFd, BorrowedFd};

use nix::errno::Errno;
use nix::sched::{sched_setaffinity, CpuSet};
use nix::sys::eventfd::{EfdFlags, EventFd};
use nix::sys::mman::{mlockall, MlockAllFlags};
use nix::sys::time::TimeSpec;
use nix::sys::timerfd::{
    ClockId as TimerClock, Expiration, TimerFd, TimerFlags, TimerSetTimeFlags,
};
use nix::time::{clock_gettime, ClockId};
use nix::unistd::Pid;

/// A failed system call, by name.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("{call}: {errno}")]
pub struct SysError {
    pub call: &'static str,
    pub errno: Errno,
}

fn check<T>(call: &'static str, result: nix::Result<T>) -> Result<T, SysError> {
    result.map_err(|errno| SysError { call, errno })
}

/// CLOCK_MONOTONIC in ns: the time base of the engine in the daemon, of timerfd deadlines and
/// of the kernel's GPIO edge timestamps, so all three compare directly.
#[inline]
pub fn now_ns() -> u64 {
    // CLOCK_MONOTONIC cannot fail on Linux with a valid clock id.
    let ts = clock_gettime(ClockId::CLOCK_MONOTONIC).unwrap_or(TimeSpec::new(0, 0));
    ts.tv_sec() as u64 * 1_000_000_000 + ts.tv_nsec() as u64
}

/// CLOCK_REALTIME in ns since 1970-01-01 00:00:00 UTC: the calendar time ST programs read
/// (the system's clock, set by NTP or by hand; 0 before 1970).
#[inline]
pub fn utc_ns() -> u64 {
    // CLOCK_REALTIME cannot fail on Linux with a valid clock id.
    let ts = clock_gettime(ClockId::CLOCK_REALTIME).unwrap_or(TimeSpec::new(0, 0));
    u64::try_from(ts.tv_sec()).unwrap_or(0) * 1_000_000_000 + ts.tv_nsec() as u64
}

fn timespec(ns: u64) -> TimeSpec {
    TimeSpec::new((ns / 1_000_000_000) as i64, (ns % 1_000_000_000) as i64)
}

/// Puts the calling thread under SCHED_FIFO at `priority` (1..=99), with SCHED_RESET_ON_FORK
/// so that children (none are expected) never inherit real-time priority.
#[allow(unsafe_code)]
pub fn set_fifo(priority: u8) -> Result<(), SysError> {
    // SAFETY: sched_param is a C struct of integers (glibc has one field, musl a few more for
    // SCHED_SPORADIC); all zeroes is a valid value of it.
    let mut param: libc::sched_param = unsafe { std::mem::zeroed() };
    param.sched_priority = i32::from(priority);
    // The system call itself, not libc's wrapper: musl's sched_setscheduler() always fails
    // with ENOSYS (POSIX means the process, Linux sets one thread), and one thread is meant.
    // SAFETY: `param` is a valid, initialised sched_param that lives across the call; pid 0 is
    // the calling thread; the kernel reads `param` and writes nothing through it.
    let rc = unsafe {
        libc::syscall(
            libc::SYS_sched_setscheduler,
            0,
            libc::SCHED_FIFO | libc::SCHED_RESET_ON_FORK,
            &param as *const libc::sched_param,
        )
    };
    check("sched_setscheduler(SCHED_FIFO)", Errno::result(rc).map(drop))
}

/// Restricts the calling thread to `cpus` (no-op when empty).
pub fn set_affinity(cpus: &[u16]) -> Result<(), SysError> {
    if cpus.is_empty() {
        return Ok(());
    }
    let mut set = CpuSet::new();
    for &cpu in cpus {
        check("sched_setaffinity", set.set(usize::from(cpu)))?;
    }
    check("sched_setaffinity", sched_setaffinity(Pid::from_raw(0), &set))
}

/// Locks every present and future page of the process in RAM, so that no page fault of the
/// scan path ever waits for the disk.
///
/// Only when it is safe: with MCL_FUTURE, every later mapping counts against RLIMIT_MEMLOCK, so
/// under a finite limit and without CAP_IPC_LOCK a thread stack or a heap growth would fail
/// later, far from here. Then memory stays unlocked and the reason is returned.
pub fn lock_memory() -> Result<(), String> {
    use nix::sys::resource::{getrlimit, Resource, RLIM_INFINITY};
    let limit = getrlimit(Resource::RLIMIT_MEMLOCK).ok().map(|(soft, _)| soft);
    let limit = limit.filter(|&soft| soft != RLIM_INFINITY);
    memory_lock_allowed(has_capability(CAP_IPC_LOCK), limit)?;
    check("mlockall", mlockall(MlockAllFlags::MCL_CURRENT | MlockAllFlags::MCL_FUTURE))
        .map_err(|e| e.to_string())
}

/// A request to the kernel's PM QoS for a CPU wake-up latency, held while this lives (the
/// kernel drops it when the file is closed).
#[derive(Debug)]
pub struct CpuLatencyRequest(#[allow(dead_code)] std::fs::File);

/// Asks the kernel to keep every CPU's wake-up latency at or below `us` µs (idle states deeper
/// than that are not entered) by writing it to `/dev/cpu_dma_latency`, as cyclictest does.
pub fn request_cpu_latency(us: u32) -> Result<CpuLatencyRequest, SysError> {
    use std::io::Write;
    let as_errno = |e: std::io::Error| Errno::from_raw(e.raw_os_error().unwrap_or(libc::EIO));
    let mut file = std::fs::OpenOptions::new()
        .write(true)
        .open("/dev/cpu_dma_latency")
        .map_err(|e| SysError { call: "open(/dev/cpu_dma_latency)", errno: as_errno(e) })?;
    let value = i32::try_from(us).unwrap_or(i32::MAX);
    file.write_all(&value.to_ne_bytes())
        .map_err(|e| SysError { call: "write(/dev/cpu_dma_latency)", errno: as_errno(e) })?;
    Ok(CpuLatencyRequest(file))
}

/// CAP_IPC_LOCK's bit in the capability sets.
const CAP_IPC_LOCK: u32 = 14;

/// Whether locking all memory for good is safe: with CAP_IPC_LOCK or no limit (`None`).
fn memory_lock_allowed(capable: bool, limit: Option<u64>) -> Result<(), String> {
    match limit {
        Some(bytes) if !capable => Err(format!(
            "memory not locked: RLIMIT_MEMLOCK is {} KiB and CAP_IPC_LOCK is missing (raise \
             LimitMEMLOCK= to infinity or grant the capability)",
            bytes / 1024
        )),
        _ => Ok(()),
    }
}

/// Whether the effective capability set holds capability number `cap`, from
/// /proc/self/status (false if it cannot be read).
pub fn has_capability(cap: u32) -> bool {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    status
        .lines()
        .find_map(|line| line.strip_prefix("CapEff:"))
        .and_then(|hex| u64::from_str_radix(hex.trim(), 16).ok())
        .is_some_and(|set| set & (1 << cap) != 0)
}

/// Touches `bytes` of the calling thread's stack, so that with memory locked its pages exist
/// before the first deadline needs them.
#[inline(never)]
pub fn prefault_stack(bytes: usize) {
    const CHUNK: usize = 4096;
    fn touch(left: usize) {
        let page = [0u8; CHUNK];
        std::hint::black_box(&page);
        if left > CHUNK {
            touch(left - CHUNK);
        }
    }
    touch(bytes);
}

/// A CLOCK_MONOTONIC timerfd, armed with absolute deadlines; non-blocking.
#[derive(Debug)]
pub struct Timer(TimerFd);

impl Timer {
    pub fn new() -> Result<Timer, SysError> {
        let flags = TimerFlags::TFD_NONBLOCK | TimerFlags::TFD_CLOEXEC;
        check("timerfd_create", TimerFd::new(TimerClock::CLOCK_MONOTONIC, flags)).map(Timer)
    }

    /// Expires at `first_ns` (CLOCK_MONOTONIC), then every `interval_ns` (0: once).
    pub fn arm(&self, first_ns: u64, interval_ns: u64) -> Result<(), SysError> {
        // A zero it_value would disarm the timer: a deadline at 0 means "now".
        let first = timespec(first_ns.max(1));
        let expiration = if interval_ns == 0 {
            Expiration::OneShot(first)
        } else {
            Expiration::IntervalDelayed(first, timespec(interval_ns))
        };
        check("timerfd_settime", self.0.set(expiration, TimerSetTimeFlags::TFD_TIMER_ABSTIME))
    }

    pub fn disarm(&self) -> Result<(), SysError> {
        check("timerfd_settime", self.0.unset())
    }

    /// Expirations since the last read (0 if none: the read would block).
    pub fn expirations(&self) -> Result<u64, SysError> {
        let mut buf = [0u8; 8];
        match nix::unistd::read(self.0.as_fd(), &mut buf) {
            Ok(8) => Ok(u64::from_ne_bytes(buf)),
            Ok(_) | Err(Errno::EAGAIN) => Ok(0),
            Err(errno) => Err(SysError { call: "read(timerfd)", errno }),
        }
    }
}

impl AsFd for Timer {
    fn as_fd(&self) -> BorrowedFd<'_> {
        self.0.as_fd()
    }
}

/// An eventfd used to wake a thread blocked in poll or epoll; non-blocking.
#[derive(Debug)]
pub struct Wake(EventFd);

impl Wake {
    pub fn new() -> Result<Wake, SysError> {
        let flags = EfdFlags::EFD_NONBLOCK | EfdFlags::EFD_CLOEXEC;
        check("eventfd", EventFd::from_flags(flags)).map(Wake)
    }

    /// Makes the fd readable. Cannot block: the counter would need 2^64 - 1 wakes to fill.
    pub fn wake(&self) {
        let _ = self.0.write(1);
    }

    /// Clears pending wakes.
    pub fn drain(&self) {
        let _ = self.0.read();
    }
}

impl AsFd for Wake {
    fn as_fd(&self) -> BorrowedFd<'_> {
        self.0.as_fd()
    }
}

/// Waits until one of `fds` is readable or `timeout_ns` passed (None: forever). Returns false on
/// timeout. EINTR counts as a wake.
pub fn wait_readable(fds: &[BorrowedFd<'_>], timeout_ns: Option<u64>) -> Result<bool, SysError> {
    wait_any(fds, timeout_ns).map(|ready| ready != 0)
}

/// Waits as [`wait_readable`] for up to 4 fds; which are readable, as bit i for `fds[i]` (0 on
/// timeout, all bits after EINTR), so that the caller reads only those.
pub fn wait_any(fds: &[BorrowedFd<'_>], timeout_ns: Option<u64>) -> Result<u8, SysError> {
    use nix::poll::{ppoll, PollFd, PollFlags};
    let mut polls: [PollFd; 4] = std::array::from_fn(|_| PollFd::new(fds[0], PollFlags::empty()));
    for (slot, fd) in polls.iter_mut().zip(fds) {
        *slot = PollFd::new(*fd, PollFlags::POLLIN);
    }
    let timeout = timeout_ns.map(timespec);
    let n = fds.len().min(4);
    match ppoll(&mut polls[..n], timeout, None) {
        Ok(_) => Ok(polls[..n]
            .iter()
            .enumerate()
            .filter(|(_, p)| p.revents().is_some_and(|r| !r.is_empty()))
            .fold(0, |mask, (i, _)| mask | 1 << i)),
        Err(Errno::EINTR) => Ok(u8::MAX),
        Err(errno) => Err(SysError { call: "ppoll", errno }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_calendar_clock_is_after_2020() {
        // 2020-01-01 00:00:00 UTC in ns: any machine running this is later.
        assert!(utc_ns() > 1_577_836_800_000_000_000);
    }

    #[test]
    fn the_monotonic_clock_advances() {
        let a = now_ns();
        let b = now_ns();
        assert!(a > 0 && b >= a);
    }

    #[test]
    fn a_timer_armed_in_the_past_has_expired() {
        let timer = Timer::new().unwrap();
        assert_eq!(timer.expirations().unwrap(), 0);
        timer.arm(1, 0).unwrap();
        assert!(wait_readable(&[timer.as_fd()], Some(1_000_000_000)).unwrap());
        assert_eq!(timer.expirations().unwrap(), 1);
        // Periodic from long ago: every missed period counts as an expiration.
        timer.arm(now_ns() - 10_000_000, 1_000_000).unwrap();
        assert!(timer.expirations().unwrap() >= 10);
        timer.disarm().unwrap();
    }

    #[test]
    fn a_wake_makes_the_fd_readable_until_drained() {
        let wake = Wake::new().unwrap();
        assert!(!wait_readable(&[wake.as_fd()], Some(0)).unwrap());
        wake.wake();
        wake.wake();
        assert!(wait_readable(&[wake.as_fd()], Some(0)).unwrap());
        wake.drain();
        assert!(!wait_readable(&[wake.as_fd()], Some(0)).unwrap());
    }

    #[test]
    fn memory_is_locked_only_when_later_mappings_cannot_fail() {
        assert!(memory_lock_allowed(true, Some(65536)).is_ok());
        assert!(memory_lock_allowed(false, None).is_ok());
        let refused = memory_lock_allowed(false, Some(8 << 20)).unwrap_err();
        assert!(refused.contains("RLIMIT_MEMLOCK is 8192 KiB"), "{refused}");
    }

    /// Page faults of the calling thread so far.
    fn faults() -> i64 {
        use nix::sys::resource::{getrusage, UsageWho};
        let usage = getrusage(UsageWho::RUSAGE_THREAD).unwrap();
        usage.minor_page_faults() + usage.major_page_faults()
    }

    #[test]
    fn a_prefaulted_stack_takes_no_page_fault_down_to_its_depth() {
        // A fresh thread's stack (1 MiB: too small for a huge page) is mapped, not yet present.
        let (first, again) = std::thread::Builder::new()
            .stack_size(1 << 20)
            .spawn(|| {
                let before = faults();
                prefault_stack(512 * 1024);
                let first = faults() - before;
                let before = faults();
                prefault_stack(512 * 1024);
                (first, faults() - before)
            })
            .unwrap()
            .join()
            .unwrap();
        assert!(first > 0, "the first pass found the stack already present");
        assert_eq!(again, 0, "{again} page faults on a prefaulted stack ({first} the first time)");
    }
}

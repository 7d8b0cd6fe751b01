//! The systemd notification protocol (sd_notify(3)), spoken without libsystemd.
//!
//! Under `Type=notify` (or `Type=notify-reload`) systemd considers the service started only once
//! it says `READY=1`, and with `WatchdogSec=` it kills a service whose keepalives stop. The
//! protocol is one datagram of newline-separated `KEY=value` assignments sent to the socket named
//! by `NOTIFY_SOCKET`: small enough to write here instead of linking libsystemd or taking a crate.
//!
//! Outside systemd `NOTIFY_SOCKET` is unset and [`Notifier::from_env`] returns `None`; callers keep
//! an `Option<Notifier>` and have nothing to tell. Parsing is kept in pure functions
//! ([`parse_watchdog`]) so tests never have to mutate the process environment, which other test
//! threads may be reading.
//!
//! Sending can block if the manager's receive queue is full (the manager is stuck), so
//! notifications belong on a housekeeping thread, never on the scan thread.

use std::io;
use std::os::linux::net::SocketAddrExt;
use std::os::unix::net::{SocketAddr, UnixDatagram};
use std::time::Duration;

use nix::time::{clock_gettime, ClockId};

/// A socket connected to the service manager's notification socket.
#[derive(Debug)]
pub struct Notifier {
    socket: UnixDatagram,
}

impl Notifier {
    /// The notifier systemd asked for through `NOTIFY_SOCKET`, or `None` when not run under a
    /// notify-type service. An address that is set but unusable is logged and treated as unset:
    /// the daemon must still run, and systemd will report the missing `READY=1` itself.
    pub fn from_env() -> Option<Notifier> {
        let addr = std::env::var_os("NOTIFY_SOCKET")?;
        if addr.is_empty() {
            return None;
        }
        let Some(addr) = addr.to_str() else {
            log::warn!("NOTIFY_SOCKET is not valid UTF-8; not notifying the service manager");
            return None;
        };
        match Notifier::connect(addr) {
            Ok(notifier) => Some(notifier),
            Err(e) => {
                log::warn!("cannot reach the service manager at NOTIFY_SOCKET={addr}: {e}");
                None
            }
        }
    }

    /// Connects to `addr`: an absolute path, or an abstract socket name written `@name`.
    pub fn connect(addr: &str) -> io::Result<Notifier> {
        let addr = socket_addr(addr)?;
        let socket = UnixDatagram::unbound()?;
        // Connecting once reports a wrong address at startup rather than at the first
        // notification; systemd keeps the same socket across daemon-reexec, so it stays valid.
        socket.connect_addr(&addr)?;
        Ok(Notifier { socket })
    }

    /// Sends `state`, one or more newline-separated `KEY=value` assignments, as one datagram.
    pub fn notify(&self, state: &str) -> io::Result<()> {
        loop {
            match self.socket.send(state.as_bytes()) {
                // A datagram is sent whole or not at all.
                Ok(_) => return Ok(()),
                // A signal handler installed without SA_RESTART must not lose a keepalive.
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => return Err(e),
            }
        }
    }

    /// Startup (or a reload) is complete.
    pub fn ready(&self) -> io::Result<()> {
        self.notify("READY=1")
    }

    /// A one-line status shown by `systemctl status`.
    pub fn status(&self, text: &str) -> io::Result<()> {
        self.notify(&status_state(text))
    }

    /// Watchdog keepalive; see [`watchdog_interval`] for how often.
    pub fn watchdog(&self) -> io::Result<()> {
        self.notify("WATCHDOG=1")
    }

    /// Shutdown has begun, so systemd does not mistake it for a crash.
    pub fn stopping(&self) -> io::Result<()> {
        self.notify("STOPPING=1")
    }

    /// A reload has begun; follow with [`Notifier::ready`] when it is done.
    pub fn reloading(&self) -> io::Result<()> {
        let now = clock_gettime(ClockId::CLOCK_MONOTONIC)?;
        self.notify(&reloading_state(Duration::from(now)))
    }
}

/// The watchdog timeout systemd enforces on this process, from `WATCHDOG_USEC` and
/// `WATCHDOG_PID`; `None` when there is no watchdog or it watches another process.
///
/// This is the full timeout: send [`Notifier::watchdog`] at half of it (as sd_watchdog_enabled(3)
/// recommends) so that one late keepalive is not fatal.
pub fn watchdog_interval() -> Option<Duration> {
    let usec = std::env::var("WATCHDOG_USEC").ok();
    let pid = std::env::var("WATCHDOG_PID").ok();
    parse_watchdog(usec.as_deref(), pid.as_deref(), std::process::id())
}

/// [`watchdog_interval`] from the variables' values. `WATCHDOG_PID` exists because the variables
/// are inherited by children, which must not think the watchdog is theirs; when it is unset the
/// watchdog is ours. Unparsable values mean no watchdog, as in sd_watchdog_enabled(3).
pub fn parse_watchdog(usec: Option<&str>, pid: Option<&str>, my_pid: u32) -> Option<Duration> {
    let usec: u64 = usec?.parse().ok()?;
    if usec == 0 {
        return None;
    }
    if let Some(pid) = pid {
        if pid.parse::<u32>().ok()? != my_pid {
            return None;
        }
    }
    Some(Duration::from_micros(usec))
}

fn socket_addr(addr: &str) -> io::Result<SocketAddr> {
    if let Some(name) = addr.strip_prefix('@') {
        SocketAddr::from_abstract_name(name)
    } else if addr.starts_with('/') {
        SocketAddr::from_pathname(addr)
    } else {
        Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("notification socket {addr:?} is neither an absolute path nor @abstract"),
        ))
    }
}

fn status_state(text: &str) -> String {
    // A newline would end the assignment and make the rest a bogus one.
    format!("STATUS={}", text.replace('\n', " "))
}

fn reloading_state(monotonic: Duration) -> String {
    // systemd >= 253 ignores RELOADING=1 without a timestamp under Type=notify-reload: it tells a
    // fresh reload from a stale message.
    format!("RELOADING=1\nMONOTONIC_USEC={}", monotonic.as_micros())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;
    use std::sync::atomic::{AtomicU32, Ordering};

    fn unique_name() -> String {
        static N: AtomicU32 = AtomicU32::new(0);
        format!("plcd-notify-test-{}-{}", std::process::id(), N.fetch_add(1, Ordering::Relaxed))
    }

    /// Removes the socket file even when the test fails.
    struct TempSocket(PathBuf);

    impl Drop for TempSocket {
        fn drop(&mut self) {
            let _ = std::fs::remove_file(&self.0);
        }
    }

    fn recv(listener: &UnixDatagram) -> Vec<u8> {
        let mut buf = [0u8; 4096];
        let n = listener.recv(&mut buf).expect("datagram");
        buf[..n].to_vec()
    }

    fn listener(listener: UnixDatagram) -> UnixDatagram {
        // A missing datagram must fail the test, not hang it.
        listener.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
        listener
    }

    #[test]
    fn path_socket_receives_exact_datagrams() {
        let path = TempSocket(std::env::temp_dir().join(unique_name() + ".sock"));
        let listener = listener(UnixDatagram::bind(&path.0).unwrap());
        let notifier = Notifier::connect(path.0.to_str().unwrap()).unwrap();

        notifier.notify("READY=1\nSTATUS=running").unwrap();
        assert_eq!(recv(&listener), b"READY=1\nSTATUS=running");
        notifier.ready().unwrap();
        assert_eq!(recv(&listener), b"READY=1");
        notifier.status("scan 1 ms\nall good").unwrap();
        assert_eq!(recv(&listener), b"STATUS=scan 1 ms all good");
        notifier.watchdog().unwrap();
        assert_eq!(recv(&listener), b"WATCHDOG=1");
        notifier.stopping().unwrap();
        assert_eq!(recv(&listener), b"STOPPING=1");

        let before = Duration::from(clock_gettime(ClockId::CLOCK_MONOTONIC).unwrap()).as_micros();
        notifier.reloading().unwrap();
        let after = Duration::from(clock_gettime(ClockId::CLOCK_MONOTONIC).unwrap()).as_micros();
        let message = String::from_utf8(recv(&listener)).unwrap();
        let usec = message.strip_prefix("RELOADING=1\nMONOTONIC_USEC=").expect(&message);
        let usec: u128 = usec.parse().unwrap();
        assert!(before <= usec && usec <= after, "{before} <= {usec} <= {after}");
    }

    #[test]
    fn abstract_socket_receives_exact_datagrams() {
        let name = unique_name();
        let addr = SocketAddr::from_abstract_name(&name).unwrap();
        let listener = listener(UnixDatagram::bind_addr(&addr).unwrap());
        let notifier = Notifier::connect(&format!("@{name}")).unwrap();
        notifier.notify("READY=1").unwrap();
        assert_eq!(recv(&listener), b"READY=1");
    }

    #[test]
    fn bad_addresses_are_errors() {
        let err = Notifier::connect("relative/notify").unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::InvalidInput);
        let missing = std::env::temp_dir().join(unique_name() + ".absent");
        assert!(Notifier::connect(missing.to_str().unwrap()).is_err());
    }

    #[test]
    fn reloading_carries_the_monotonic_timestamp_in_microseconds() {
        assert_eq!(
            reloading_state(Duration::new(12, 345_678_999)),
            "RELOADING=1\nMONOTONIC_USEC=12345678"
        );
    }

    #[test]
    fn watchdog_environment() {
        let me = 4242;
        assert_eq!(parse_watchdog(None, None, me), None);
        assert_eq!(parse_watchdog(None, Some("4242"), me), None);
        assert_eq!(parse_watchdog(Some(""), None, me), None);
        assert_eq!(parse_watchdog(Some("soon"), None, me), None);
        assert_eq!(parse_watchdog(Some("-5"), None, me), None);
        assert_eq!(parse_watchdog(Some("0"), None, me), None);
        assert_eq!(parse_watchdog(Some("0"), Some("4242"), me), None);
        assert_eq!(parse_watchdog(Some("3000000"), Some("1"), me), None);
        assert_eq!(parse_watchdog(Some("3000000"), Some("pid"), me), None);
        assert_eq!(parse_watchdog(Some("3000000"), None, me), Some(Duration::from_secs(3)));
        assert_eq!(parse_watchdog(Some("3000000"), Some("4242"), me), Some(Duration::from_secs(3)));
        assert_eq!(
            parse_watchdog(Some("1500"), Some("4242"), me),
            Some(Duration::from_micros(1500))
        );
    }
}

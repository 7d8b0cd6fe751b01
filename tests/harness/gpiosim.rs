//! Whether the kernel's gpio-sim (configfs) is here, for the `gpiosim_*` integration tests.
//!
//! Use it from a test file as
//!
//! ```ignore
//! #[macro_use]
//! mod harness;
//!
//! #[test]
//! fn something() {
//!     require_gpiosim!();
//!     // ... gpiosim::builder() ...
//! }
//! ```
//!
//! Where gpio-sim is missing (this kernel has no configfs or no gpio-sim module loaded) or not
//! usable (not root), each test writes `skipped: <reason>` to stderr and passes. With
//! `PLCD_REQUIRE_GPIOSIM=1` in the environment, as `tests/qemu/run-gpiosim` sets it in its guest,
//! a missing gpio-sim fails the test instead, so a suite that ran nothing cannot pass.
//!
//! The check only looks: it never loads a module. The gpiosim crate runs `modprobe gpio-sim`
//! when `/sys/kernel/config/gpio-sim` is missing, so a test must not reach it then.
use std::path::Path;

/// The environment variable that turns a skip into a failure.
pub const REQUIRE_ENV: &str = "PLCD_REQUIRE_GPIOSIM";

/// Where gpio-sim's configfs directory is when configfs is mounted in its usual place and
/// the module is loaded. The gpiosim crate looks there first.
pub const CONFIGFS_GPIO_SIM: &str = "/sys/kernel/config/gpio-sim";

/// `Ok(())` when a test can build simulators here, else why not.
pub fn gpiosim_available() -> Result<(), String> {
    let dir = Path::new(CONFIGFS_GPIO_SIM);
    if !dir.is_dir() {
        return Err(why_no_configfs_dir());
    }
    // Simulators are made in configfs and driven through sysfs: both need root, in practice.
    // SAFETY: geteuid has no preconditions and cannot fail.
    let euid = unsafe { libc::geteuid() };
    if euid != 0 {
        return Err(format!("not root (euid {euid}): gpio-sim's configfs and sysfs need root"));
    }
    // The kernel makes /dev/gpiochipN for a simulated chip only in a devtmpfs (a container's
    // /dev is a tmpfs with copies).
    if !mounted("/dev", "devtmpfs") {
        return Err(
            "/dev is no devtmpfs: a simulated chip's /dev/gpiochipN would not appear".into()
        );
    }
    Ok(())
}

/// The likeliest reason the gpio-sim directory is missing, from what the kernel shows.
fn why_no_configfs_dir() -> String {
    let filesystems = std::fs::read_to_string("/proc/filesystems").unwrap_or_default();
    if !filesystems.lines().any(|l| l.split_whitespace().last() == Some("configfs")) {
        return "this kernel has no configfs".into();
    }
    if !mounted("/sys/kernel/config", "configfs") {
        return "configfs is not mounted on /sys/kernel/config".into();
    }
    if !Path::new("/sys/module/gpio_sim").exists() {
        return "the gpio-sim module is not loaded (`modprobe gpio-sim` as root, if this kernel \
                has it)"
            .into();
    }
    format!("{CONFIGFS_GPIO_SIM} is missing")
}

/// Whether /proc/mounts lists a `fstype` file system mounted on `dir`.
fn mounted(dir: &str, fstype: &str) -> bool {
    let mounts = std::fs::read_to_string("/proc/mounts").unwrap_or_default();
    mounts.lines().any(|l| {
        let mut words = l.split_whitespace().skip(1);
        words.next() == Some(dir) && words.next() == Some(fstype)
    })
}

/// Whether the calling test should return at once: says why on stderr when so
/// ([`super::skip::skip`]), or fails when [`REQUIRE_ENV`] is set.
pub fn skip() -> bool {
    let Err(reason) = gpiosim_available() else {
        return false;
    };
    super::skip::skip(
        Some(REQUIRE_ENV),
        &format!("gpio-sim unavailable: {reason}; tests/qemu/run-gpiosim runs it in a VM"),
    );
    true
}

/// Returns from the calling test, which then passes, when gpio-sim is unavailable here; panics
/// instead when `PLCD_REQUIRE_GPIOSIM` is set. See the module's documentation.
// Every test crate compiles the harness; only the gpio-sim tests use this.
#[allow(unused_macros)]
macro_rules! require_gpiosim {
    () => {
        if $crate::harness::gpiosim::skip() {
            return;
        }
    };
}

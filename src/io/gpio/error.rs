//! What can go wrong in the backend, and how errors name chips, lines and operations.

use std::fmt;
use std::sync::Arc;

use super::Wire;
use crate::config::wiring::{LineDirection, WiringError};

/// Why the backend could not open, or an I/O operation failed.
#[derive(Debug, thiserror::Error)]
pub enum GpioError {
    #[error(
        "io.chip is not set: the gpiocdev backend needs a GPIO chip \
         (a path such as /dev/gpiochip0, or a chip label)"
    )]
    NoChip,

    /// A plan the kernel would refuse, which only a config that did not come from
    /// `config::parse` can have (parsing reports these with the config's other errors).
    #[error("{}", Joined(.0))]
    Wiring(Vec<WiringError>),

    /// A plan made with the chip's line names that cannot be: a name the chip lacks or has on
    /// several lines, two entries that are one line; `chip` by its path and label.
    #[error("GPIO chip {chip}: {}", Joined(.errors))]
    Lines { chip: Arc<str>, errors: Vec<WiringError> },

    #[error("GPIO chip `{asked}` not found; {}", ChipList(.available))]
    ChipNotFound {
        /// `io.chip` as written.
        asked: String,
        /// The chips the system has (empty when it has none, or /dev cannot be listed).
        available: Vec<ChipSummary>,
    },

    #[error(
        "GPIO chip label `{asked}` matches several chips ({}); name the chip by its path",
        ChipList(.matches)
    )]
    AmbiguousChip { asked: String, matches: Vec<ChipSummary> },

    #[error("cannot open GPIO chip `{chip}`: {source}")]
    ChipOpen {
        chip: Arc<str>,
        #[source]
        source: gpiocdev::Error,
    },

    #[error(
        "GPIO chip {chip}: line {line} ({wire}) does not exist, the chip has {num_lines} lines"
    )]
    LineOutOfRange { chip: Arc<str>, line: u32, wire: Wire, num_lines: u32 },

    #[error("GPIO chip {chip}: line {line} ({wire}) is already in use{}", UsedBy(.consumer))]
    LineBusy { chip: Arc<str>, line: u32, wire: Wire, consumer: Option<String> },

    #[error("GPIO chip {chip}: requesting the {count} {direction} lines failed: {source}")]
    Request {
        chip: Arc<str>,
        direction: LineDirection,
        count: usize,
        #[source]
        source: gpiocdev::Error,
    },

    #[error("GPIO chip {chip}: {op} failed: {source}")]
    Io {
        chip: Arc<str>,
        op: IoOp,
        #[source]
        source: gpiocdev::Error,
    },
}

/// A GPIO chip as the "not found" errors list it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ChipSummary {
    /// The device name (`gpiochip0`).
    pub name: String,
    /// The chip's label; `None` if the chip could not be opened to read it.
    pub label: Option<String>,
}

impl fmt::Display for ChipSummary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.label.as_deref() {
            Some("") => write!(f, "{} (no label)", self.name),
            Some(label) => write!(f, "{} ({label})", self.name),
            None => write!(f, "{} (label unreadable)", self.name),
        }
    }
}

struct ChipList<'a>(&'a [ChipSummary]);

impl fmt::Display for ChipList<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.0.is_empty() {
            return f.write_str("this system has no GPIO chips");
        }
        f.write_str("chips on this system: ")?;
        for (i, chip) in self.0.iter().enumerate() {
            if i > 0 {
                f.write_str(", ")?;
            }
            write!(f, "{chip}")?;
        }
        Ok(())
    }
}

struct UsedBy<'a>(&'a Option<String>);

impl fmt::Display for UsedBy<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0 {
            Some(consumer) => write!(f, " by `{consumer}`"),
            None => f.write_str(" by another consumer"),
        }
    }
}

/// The operation an I/O error happened in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum IoOp {
    ReadInputs,
    ForceInactive,
    ReadEdges,
    ChipInfo,
    LineInfo { line: u32 },
}

impl fmt::Display for IoOp {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            IoOp::ReadInputs => f.write_str("reading the inputs"),
            IoOp::ForceInactive => f.write_str("forcing the outputs inactive"),
            IoOp::ReadEdges => f.write_str("reading edge events"),
            IoOp::ChipInfo => f.write_str("reading the chip info"),
            IoOp::LineInfo { line } => write!(f, "reading the info of line {line}"),
        }
    }
}

struct Joined<'a>(&'a [WiringError]);

impl fmt::Display for Joined<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, error) in self.0.iter().enumerate() {
            if i > 0 {
                f.write_str("; ")?;
            }
            write!(f, "{error}")?;
        }
        Ok(())
    }
}

impl GpioError {
    /// The errno of the failed system call behind an I/O error, if it was one: for the event
    /// thread, which keeps it as a number rather than the error (no allocation there).
    pub fn errno(&self) -> Option<i32> {
        match self {
            GpioError::ChipOpen { source, .. }
            | GpioError::Request { source, .. }
            | GpioError::Io { source, .. } => errno(source),
            _ => None,
        }
    }
}

/// The errno of a failed system call inside a gpiocdev error, if it is one. gpiocdev returns
/// errors of its own calls as `Error::Os`, and those of the uAPI ioctls as `Error::Uapi` with
/// the uAPI crate's error, whose `Os` variant carries the errno (its other variant, a short
/// read, carries none).
pub(super) fn errno(error: &gpiocdev::Error) -> Option<i32> {
    match error {
        gpiocdev::Error::Os(errno) => Some(errno.0),
        gpiocdev::Error::Uapi(_, gpiocdev_uapi::Error::Os(errno)) => Some(errno.0),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::wiring::{Entry, NameHint};
    use crate::device::Address;

    fn addr(s: &str) -> Address {
        Address::parse(s).unwrap()
    }

    #[test]
    fn messages_read_well_in_a_log() {
        let chips = vec![
            ChipSummary { name: "gpiochip0".into(), label: Some("pinctrl-bcm2711".into()) },
            ChipSummary { name: "gpiochip1".into(), label: None },
            ChipSummary { name: "gpiochip2".into(), label: Some(String::new()) },
        ];
        let err = GpioError::ChipNotFound { asked: "gpio-sim.0".into(), available: chips };
        assert_eq!(
            err.to_string(),
            "GPIO chip `gpio-sim.0` not found; chips on this system: gpiochip0 (pinctrl-bcm2711), \
             gpiochip1 (label unreadable), gpiochip2 (no label)"
        );
        let err = GpioError::ChipNotFound { asked: "/dev/gpiochip0".into(), available: vec![] };
        assert_eq!(
            err.to_string(),
            "GPIO chip `/dev/gpiochip0` not found; this system has no GPIO chips"
        );
        let chip: Arc<str> = "gpiochip0 (pinctrl-bcm2711)".into();
        let err = GpioError::LineOutOfRange {
            chip: chip.clone(),
            line: 58,
            wire: Wire::Device(addr("P0040")),
            num_lines: 58,
        };
        assert_eq!(
            err.to_string(),
            "GPIO chip gpiochip0 (pinctrl-bcm2711): line 58 (P0040) does not exist, the chip has \
             58 lines"
        );
        let err = GpioError::LineBusy {
            chip: chip.clone(),
            line: 4,
            wire: Wire::Device(addr("P0003")),
            consumer: Some("gpio-keys".into()),
        };
        assert_eq!(
            err.to_string(),
            "GPIO chip gpiochip0 (pinctrl-bcm2711): line 4 (P0003) is already in use by `gpio-keys`"
        );
        let err = GpioError::LineBusy {
            chip: chip.clone(),
            line: 4,
            wire: Wire::Device(addr("P0003")),
            consumer: None,
        };
        assert!(err.to_string().ends_with("is already in use by another consumer"));
        let err = GpioError::LineBusy {
            chip: chip.clone(),
            line: 5,
            wire: Wire::Switch,
            consumer: Some("gpio-keys".into()),
        };
        assert_eq!(
            err.to_string(),
            "GPIO chip gpiochip0 (pinctrl-bcm2711): line 5 (the RUN/STOP switch) is already in use \
             by `gpio-keys`"
        );
        let err = GpioError::LineOutOfRange {
            chip: chip.clone(),
            line: 58,
            wire: Wire::Switch,
            num_lines: 58,
        };
        assert_eq!(
            err.to_string(),
            "GPIO chip gpiochip0 (pinctrl-bcm2711): line 58 (the RUN/STOP switch) does not exist, \
             the chip has 58 lines"
        );
        let err = GpioError::Io {
            chip,
            op: IoOp::ReadInputs,
            source: std::io::Error::from_raw_os_error(libc::ENODEV).into(),
        };
        assert!(err
            .to_string()
            .starts_with("GPIO chip gpiochip0 (pinctrl-bcm2711): reading the inputs failed: "));
        assert!(std::error::Error::source(&err).is_some());
    }

    #[test]
    fn line_name_errors_name_the_chip_by_path_and_label() {
        let err = GpioError::Lines {
            chip: "/dev/gpiochip0 (pinctrl-bcm2711)".into(),
            errors: vec![
                WiringError::NoSuchName {
                    entry: Entry::Input(addr("P0000")),
                    name: "GPIO71".into(),
                    hint: NameHint::Near(vec![("GPIO17".into(), 17), ("GPIO7".into(), 7)]),
                },
                WiringError::SharedName {
                    entry: Entry::Switch,
                    name: "-".into(),
                    offsets: vec![33, 37],
                },
            ],
        };
        assert_eq!(
            err.to_string(),
            "GPIO chip /dev/gpiochip0 (pinctrl-bcm2711): io.input \"P0000\": no line of the chip \
             is named \"GPIO71\"; near names: \"GPIO17\" (line 17), \"GPIO7\" (line 7); \
             [switch]: line name \"-\" is shared by lines 33 and 37 of the chip: give the line's \
             offset instead"
        );
        assert_eq!(err.errno(), None);
    }

    #[test]
    fn errno_of_a_gpiocdev_error() {
        let busy: gpiocdev::Error = std::io::Error::from_raw_os_error(libc::EBUSY).into();
        assert_eq!(errno(&busy), Some(libc::EBUSY));
        // An ioctl's error, as gpiocdev returns it: the uAPI crate's error inside.
        let uapi = gpiocdev_uapi::Error::Os(gpiocdev_uapi::Errno(libc::ENODEV));
        let ioctl = gpiocdev::Error::Uapi(gpiocdev::UapiCall::GetLineValues, uapi);
        assert_eq!(errno(&ioctl), Some(libc::ENODEV));
        assert_eq!(errno(&gpiocdev::Error::NoGpioChips()), None);
        let err = GpioError::Io { chip: "gpiochip0".into(), op: IoOp::ReadEdges, source: ioctl };
        assert_eq!(err.errno(), Some(libc::ENODEV));
        assert_eq!(GpioError::NoChip.errno(), None);
    }
}

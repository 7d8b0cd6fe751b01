//! Finding the chip `io.chip` names (a path, a name under `/dev`, or a chip label), and what
//! only the chip can tell: the names of its lines, whether a line exists and who holds it.

use std::path::PathBuf;
use std::sync::Arc;

use gpiocdev::Chip;

use super::error::errno;
use super::{ChipSummary, GpioError, IoOp, LineDirection, Wire};
use crate::config::wiring::WiringError;

/// The chip `io.chip` names, opened.
pub(super) struct FoundChip {
    chip: Chip,
    pub path: PathBuf,
    /// How errors name the chip: `gpiochip0 (label)`.
    pub name: Arc<str>,
    /// The chip's label (may be empty).
    label: String,
    num_lines: u32,
}

impl FoundChip {
    fn new(chip: Chip) -> Result<FoundChip, GpioError> {
        let info = chip.info().map_err(|source| GpioError::Io {
            chip: chip.name().into(),
            op: IoOp::ChipInfo,
            source,
        })?;
        let summary = ChipSummary { name: chip.name(), label: Some(info.label.clone()) };
        Ok(FoundChip {
            path: chip.path().to_path_buf(),
            name: summary.to_string().into(),
            label: info.label,
            num_lines: info.num_lines,
            chip,
        })
    }

    /// The names of the chip's lines, by offset (`""` for a line without one), as the kernel
    /// reports them in each line's info.
    pub fn line_names(&self) -> Result<Vec<String>, GpioError> {
        (0..self.num_lines)
            .map(|line| {
                self.chip.line_info(line).map(|info| info.name).map_err(|source| GpioError::Io {
                    chip: self.name.clone(),
                    op: IoOp::LineInfo { line },
                    source,
                })
            })
            .collect()
    }

    /// The errors of a plan made with this chip's line names: they are about this chip, named
    /// by its path and label.
    pub fn lines_error(&self, errors: Vec<WiringError>) -> GpioError {
        let summary =
            ChipSummary { name: self.path.display().to_string(), label: Some(self.label.clone()) };
        GpioError::Lines { chip: summary.to_string().into(), errors }
    }

    /// The line exists and nobody holds it. Checking `used` before requesting names the
    /// other consumer, which the request's EBUSY would not.
    pub fn check_line(&self, line: u32, wire: Wire) -> Result<(), GpioError> {
        if line >= self.num_lines {
            return Err(GpioError::LineOutOfRange {
                chip: self.name.clone(),
                line,
                wire,
                num_lines: self.num_lines,
            });
        }
        let info = self.chip.line_info(line).map_err(|source| GpioError::Io {
            chip: self.name.clone(),
            op: IoOp::LineInfo { line },
            source,
        })?;
        if info.used {
            return Err(self.busy(line, wire, info.consumer));
        }
        Ok(())
    }

    fn busy(&self, line: u32, wire: Wire, consumer: String) -> GpioError {
        GpioError::LineBusy {
            chip: self.name.clone(),
            line,
            wire,
            consumer: (!consumer.is_empty()).then_some(consumer),
        }
    }

    /// A failed request. EBUSY means a line was taken since [`FoundChip::check_line`]: find
    /// which one, to name it and its consumer.
    pub fn request_error(
        &self,
        direction: LineDirection,
        lines: impl ExactSizeIterator<Item = (u32, Wire)>,
        source: gpiocdev::Error,
    ) -> GpioError {
        let count = lines.len();
        if errno(&source) == Some(libc::EBUSY) {
            for (line, wire) in lines {
                if let Ok(info) = self.chip.line_info(line) {
                    if info.used {
                        return self.busy(line, wire, info.consumer);
                    }
                }
            }
        }
        GpioError::Request { chip: self.name.clone(), direction, count, source }
    }
}

/// Finds the chip `asked` names: a path if it starts with '/', else a name under /dev
/// (`gpiochip0`) or a chip label.
pub(super) fn find_chip(asked: &str) -> Result<FoundChip, GpioError> {
    let open_error = |source| GpioError::ChipOpen { chip: asked.into(), source };
    if asked.starts_with('/') {
        return match Chip::from_path(asked) {
            Ok(chip) => FoundChip::new(chip),
            Err(e) if errno(&e) == Some(libc::ENOENT) => Err(GpioError::ChipNotFound {
                asked: asked.to_string(),
                available: list_chips().into_iter().map(|(_, summary, _)| summary).collect(),
            }),
            Err(e) => Err(open_error(e)),
        };
    }
    if !asked.is_empty() && !asked.contains('/') {
        // A name that is a GPIO chip under /dev but cannot be opened is that chip's error
        // (permissions, usually), not a reason to look further.
        if let Ok(path) = gpiocdev::chip::is_chip(format!("/dev/{asked}")) {
            return Chip::from_path(path).map_err(open_error).and_then(FoundChip::new);
        }
    }
    let chips = list_chips();
    let mut matches: Vec<(Chip, ChipSummary)> = Vec::new();
    let mut available = Vec::with_capacity(chips.len());
    for (chip, summary, kernel_name) in chips {
        let hit = summary.label.as_deref() == Some(asked) || kernel_name.as_deref() == Some(asked);
        if let (true, Some(chip)) = (hit, chip) {
            matches.push((chip, summary.clone()));
        }
        available.push(summary);
    }
    if matches.len() > 1 {
        return Err(GpioError::AmbiguousChip {
            asked: asked.to_string(),
            matches: matches.into_iter().map(|(_, summary)| summary).collect(),
        });
    }
    match matches.pop() {
        Some((chip, _)) => FoundChip::new(chip),
        None => Err(GpioError::ChipNotFound { asked: asked.to_string(), available }),
    }
}

/// Every GPIO chip of the system, opened if it can be, with its summary and kernel name.
/// Listing is best effort: a system without GPIO support (or without /dev) has no chips.
fn list_chips() -> Vec<(Option<Chip>, ChipSummary, Option<String>)> {
    let paths = gpiocdev::chip::chips().unwrap_or_default();
    paths
        .into_iter()
        .map(|path| {
            let name = path
                .file_name()
                .map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into_owned());
            let chip = Chip::from_path(&path).ok();
            let info = chip.as_ref().and_then(|c| c.info().ok());
            let kernel_name = info.as_ref().map(|i| i.name.clone());
            (chip, ChipSummary { name, label: info.map(|i| i.label) }, kernel_name)
        })
        .collect()
}

//! The watchdog's side: every output inactive in one set-values ioctl, from the watchdog
//! thread, on the output request the scan shares.

use std::sync::Arc;

use gpiocdev::line::Values;
use gpiocdev::Request;

use super::{GpioError, IoOp};

/// The output request and the all-inactive values, shared by the scan and the watchdog.
/// `gpiocdev::Request` is `Sync` (a `File`, a `Vec` and an `Arc<RwLock<_>>`; its value calls
/// take `&self`), and the kernel serializes set-values on one request.
#[derive(Debug)]
pub(super) struct OutputShared {
    pub chip: Arc<str>,
    pub request: Request,
    pub inactive: Values,
}

/// A handle the watchdog thread uses to force every output inactive. Cheap to clone.
#[derive(Debug, Clone)]
pub struct GpioOutputs {
    pub(super) shared: Option<Arc<OutputShared>>,
}

impl GpioOutputs {
    /// Sets every output line inactive in one set-values ioctl; no allocation. Does nothing
    /// when there are no outputs.
    ///
    /// The scan may publish outputs again afterwards: stopping it is the caller's business.
    pub fn set_all_inactive(&self) -> Result<(), GpioError> {
        let Some(shared) = &self.shared else { return Ok(()) };
        shared.request.set_values(&shared.inactive).map_err(|source| GpioError::Io {
            chip: shared.chip.clone(),
            op: IoOp::ForceInactive,
            source,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn no_outputs_means_nothing_to_force() {
        assert!(GpioOutputs { shared: None }.set_all_inactive().is_ok());
    }
}

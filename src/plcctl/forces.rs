//! `forces`, `force DEV=VALUE`, `unforce DEV`, `unforce --all`: the force table, answered
//! with the table after the command.

use plcd_ipc::{DeviceValue, Request};

use super::devices::{parse_device, parse_write};
use super::format;

/// `force`'s arguments.
#[derive(Debug, Clone, clap::Args)]
pub struct ForceArgs {
    /// A P bit and its forced value, e.g. `P0040=1`.
    #[arg(value_name = "DEV=VALUE", value_parser = parse_write)]
    pub write: DeviceValue,
}

/// `unforce`'s arguments.
#[derive(Debug, Clone, clap::Args)]
pub struct UnforceArgs {
    /// The device whose force is removed.
    #[arg(value_name = "DEV", value_parser = parse_device, required_unless_present = "all",
        conflicts_with = "all")]
    pub dev: Option<String>,
    /// Remove every force.
    #[arg(long)]
    pub all: bool,
}

impl UnforceArgs {
    pub fn request(&self) -> Request {
        match &self.dev {
            Some(dev) if !self.all => Request::Unforce { dev: dev.clone() },
            _ => Request::UnforceAll,
        }
    }
}

/// One `DEVICE  VALUE` line per force, or `no forces`.
pub fn render(forces: &[DeviceValue]) -> String {
    if forces.is_empty() {
        "no forces\n".to_string()
    } else {
        format::device_table(forces)
    }
}

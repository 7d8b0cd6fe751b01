//! `forces`, `force NAME=VALUE`, `unforce NAME`, `unforce --all`: the force table, answered
//! with the table after the command. A name is a P bit or a BOOL variable located at one.

use plcd_ipc::{DeviceValue, Request};

use super::devices::parse_name;
use super::format;

/// `force`'s arguments.
#[derive(Debug, Clone, clap::Args)]
pub struct ForceArgs {
    /// A P bit, or a BOOL variable located at one, and its forced value (0, 1, TRUE, FALSE):
    /// `P0040=1`, `main.lamp 1`.
    #[arg(value_name = "NAME=VALUE", num_args = 1..=2, required = true)]
    pub words: Vec<String>,
}

impl ForceArgs {
    pub fn request(&self) -> Result<Request, String> {
        let (name, value) = match self.words.as_slice() {
            [one] => match one.split_once('=') {
                Some((name, value)) => (name, value),
                None => {
                    return Err(format!("`{one}` has no value: write NAME=VALUE or NAME VALUE"))
                }
            },
            [name, value] => (name.as_str(), value.as_str()),
            _ => return Err("write NAME=VALUE or NAME VALUE".to_string()),
        };
        let value = match value.trim().to_ascii_uppercase().as_str() {
            "1" | "TRUE" => 1,
            "0" | "FALSE" => 0,
            _ => return Err(format!("`{value}`: a bit is forced to 0 or 1 (FALSE or TRUE)")),
        };
        Ok(Request::Force { dev: parse_name(name)?, value })
    }
}

/// `unforce`'s arguments.
#[derive(Debug, Clone, clap::Args)]
pub struct UnforceArgs {
    /// The P bit, or the BOOL variable located at one, whose force is removed.
    #[arg(value_name = "NAME", value_parser = parse_name, required_unless_present = "all",
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn force_words() {
        let force =
            |w: &[&str]| ForceArgs { words: w.iter().map(|s| s.to_string()).collect() }.request();
        let request = |dev: &str, value| Ok(Request::Force { dev: dev.into(), value });
        assert_eq!(force(&["P0040=1"]), request("P0040", 1));
        assert_eq!(force(&["main.lamp", "true"]), request("main.lamp", 1));
        assert_eq!(force(&["main.lamp=FALSE"]), request("main.lamp", 0));
        assert!(force(&["P0040"]).unwrap_err().contains("no value"));
        assert!(force(&["P0040", "2"]).unwrap_err().contains("0 or 1"));
    }
}

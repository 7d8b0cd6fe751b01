//! `load --config FILE [--online]`: validate a project and swap it in.

use std::path::{Path, PathBuf};

use plcd_ipc::{ModeName, Request};

/// `load`'s arguments.
#[derive(Debug, Clone, clap::Args)]
pub struct LoadArgs {
    /// The project's TOML config, as a path the daemon can read (made absolute here).
    #[arg(long, value_name = "FILE", value_parser = absolute_utf8_path)]
    pub config: PathBuf,
    /// In RUN: change the program online, at an END, keeping device memory (refused when the
    /// device layout changed).
    #[arg(long)]
    pub online: bool,
}

impl LoadArgs {
    pub fn request(&self) -> Request {
        Request::Load {
            // The value parser made it absolute and checked it is UTF-8.
            config: self.config.to_string_lossy().into_owned(),
            online: self.online,
        }
    }
}

/// The path made absolute against the current directory (not canonicalized: symlinks stay as
/// written, and the file need not exist here, the daemon reads it); the protocol carries
/// UTF-8 text.
pub fn absolute_utf8_path(text: &str) -> Result<PathBuf, String> {
    if text.is_empty() {
        return Err("the path is empty".to_string());
    }
    let path = std::path::absolute(Path::new(text)).map_err(|e| e.to_string())?;
    match path.to_str() {
        Some(_) => Ok(path),
        None => Err(format!("{} is not valid UTF-8", path.display())),
    }
}

/// `loaded /etc/plcd/plcd.toml: 2 programs, 3 tasks, online; mode RUN`.
pub fn render(
    config: Option<&str>,
    online: bool,
    programs: usize,
    tasks: usize,
    mode: ModeName,
) -> String {
    let plural =
        |n: usize, what: &str| if n == 1 { format!("1 {what}") } else { format!("{n} {what}s") };
    let what = match config {
        Some(config) => format!("loaded {config}"),
        None => "loaded".to_string(),
    };
    let how = if online { ", online" } else { "" };
    format!(
        "{what}: {}, {}{how}; mode {}\n",
        plural(programs, "program"),
        plural(tasks, "task"),
        mode.as_str()
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_become_absolute() {
        let cwd = std::env::current_dir().unwrap();
        assert_eq!(absolute_utf8_path("a/plcd.toml").unwrap(), cwd.join("a/plcd.toml"));
        assert_eq!(absolute_utf8_path("/etc/plcd.toml").unwrap(), Path::new("/etc/plcd.toml"));
        assert!(absolute_utf8_path("").is_err());
    }

    #[test]
    fn rendering() {
        assert_eq!(
            render(Some("/p/plcd.toml"), true, 2, 1, ModeName::Run),
            "loaded /p/plcd.toml: 2 programs, 1 task, online; mode RUN\n"
        );
    }
}

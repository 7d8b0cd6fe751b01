//! Reading a project's files from disk: the config, the programs it names, a simulation inputs
//! file, the users file. The core parses text and never opens a file; this is where the text comes from. A file
//! that cannot be read is a diagnostic like any other (line 0: the whole file), so a caller
//! reports it with the rest and keeps what it was running.

use std::path::{Path, PathBuf};

use crate::config::{self, Config};
use crate::diag::{Diagnostic, Diagnostics};
use crate::project::{self, Project};
use crate::stimulus::{self, Stimulus};
use crate::users::UsersFile;

/// Reads the config file at `path` and parses it ([`config::parse`]).
pub fn config(path: &Path) -> Result<Config, Diagnostics> {
    let text = std::fs::read_to_string(path).map_err(|e| {
        Diagnostics(vec![Diagnostic::new(
            path,
            0,
            0,
            format!("cannot read {}: {e}", path.display()),
        )])
    })?;
    config::parse(&text, path)
}

/// Loads the config at `path` and every program it names, and compiles the Structured Text
/// programs to native code (`plcd_native`, with the default `native` feature; a program it
/// cannot compile runs on the interpreter, with a warning in the log). Every diagnostic of the config and of all programs
/// is returned at once.
pub fn project(path: &Path) -> Result<Project, Diagnostics> {
    #[allow(unused_mut)] // without the `native` feature, nothing is attached
    let mut project = interpreted_project(path)?;
    for note in &project.notes {
        log::info!("{note}");
    }
    for warning in &project.warnings {
        log::warn!("{warning}");
    }
    #[cfg(feature = "native")]
    for error in plcd_native::attach(&mut project) {
        log::warn!("{error}; it runs on the interpreter");
    }
    Ok(project)
}

/// [`project`](fn@project) without native code: every program on the interpreter (`plcd sim
/// --interpreter`, to compare the two or to measure the interpreter itself).
pub fn interpreted_project(path: &Path) -> Result<Project, Diagnostics> {
    let config = config(path)?;
    project::from_config_with(config, source_text, source_files, files_in)
}

/// A program or library file's text: UTF-8 (after a UTF-8 byte order mark, if any), or, when
/// the file is not valid UTF-8, Windows-1252, which every byte is a character of (older CODESYS
/// exports and OSCAT's sources are written so; docs/ST.md, Source form).
fn source_text(path: &Path) -> std::io::Result<String> {
    let mut bytes = std::fs::read(path)?;
    if bytes.starts_with(b"\xEF\xBB\xBF") {
        bytes.drain(..3);
    }
    Ok(match String::from_utf8(bytes) {
        Ok(text) => text,
        Err(e) => crate::value::decode_str(e.as_bytes()),
    })
}

/// Every file in `dir` and its subfolders (an `[st] library` folder; the core keeps the
/// Structured Text sources and the `.plcproj` files among them). Hidden entries (`.git`) are skipped; a symbolic link
/// to a file is a file, one to a folder is not entered (no loops).
fn source_files(dir: &Path) -> std::io::Result<Vec<PathBuf>> {
    let mut files = Vec::new();
    let mut pending = vec![dir.to_path_buf()];
    while let Some(dir) = pending.pop() {
        for entry in std::fs::read_dir(&dir)? {
            let entry = entry?;
            let path = entry.path();
            if entry.file_name().to_string_lossy().starts_with('.') {
                continue;
            }
            let kind = entry.file_type()?;
            if kind.is_dir() {
                pending.push(path);
            } else if kind.is_file() || path.is_file() {
                files.push(path);
            }
        }
    }
    Ok(files)
}

/// The files directly in `dir`, each as `dir` joined with its name (the empty path is the
/// current folder, and its files are their bare names): where the core looks for the
/// `.plcproj` of a program's TwinCAT file. Hidden entries are skipped, as in
/// [`source_files`]; a symbolic link to a file is a file.
fn files_in(dir: &Path) -> std::io::Result<Vec<PathBuf>> {
    let listed = if dir.as_os_str().is_empty() { Path::new(".") } else { dir };
    let mut files = Vec::new();
    for entry in std::fs::read_dir(listed)? {
        let entry = entry?;
        let name = entry.file_name();
        if name.to_string_lossy().starts_with('.') {
            continue;
        }
        let path = dir.join(&name);
        if entry.file_type()?.is_file() || entry.path().is_file() {
            files.push(path);
        }
    }
    Ok(files)
}

/// Reads and parses the inputs file of a project, checked against its config
/// ([`stimulus::parse_for`]). `plcd sim --inputs` and the daemon's `io.stimulus` both load
/// through this.
pub fn stimulus_for(path: &Path, config: &Config) -> Result<Vec<Stimulus>, Diagnostics> {
    read_stimulus(path).and_then(|text| stimulus::parse_for(&text, path, config))
}

fn read_stimulus(path: &Path) -> Result<String, Diagnostics> {
    std::fs::read_to_string(path).map_err(|e| {
        Diagnostics(vec![Diagnostic::new(path, 0, 0, format!("cannot read the inputs file: {e}"))])
    })
}

/// Reads and parses the users file at `path` ([`UsersFile::parse`]): `plcd check` and `plcd
/// user` read it through this.
pub fn users(path: &Path) -> Result<UsersFile, Diagnostics> {
    let text = std::fs::read_to_string(path).map_err(|e| {
        Diagnostics(vec![Diagnostic::new(path, 0, 0, format!("cannot read the users file: {e}"))])
    })?;
    UsersFile::parse(&text, path)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stimulus::Target;
    use plcd_core::io::SwitchPosition;

    /// A config, with a `[switch]` or without.
    fn config_with(with_switch: bool) -> Config {
        let switch = if with_switch { "[switch]\n" } else { "" };
        let text = format!("{switch}[[program]]\nfile = \"main.il\"\n");
        config::parse(&text, Path::new("plcd.toml")).unwrap()
    }

    #[test]
    fn a_source_is_utf8_after_its_byte_order_mark_else_windows_1252() {
        let path = std::env::temp_dir().join(format!("plcd-source-{}.st", std::process::id()));
        std::fs::write(&path, b"\xEF\xBB\xBF'Gr\xC3\xBC\xC3\x9Fe \xE2\x82\xAC'").unwrap();
        let utf8 = source_text(&path).unwrap();
        std::fs::write(&path, b"'Gr\xFC\xDFe \x80'").unwrap();
        let cp1252 = source_text(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        assert_eq!(utf8, "'Grüße €'");
        assert_eq!(cp1252, "'Grüße €'");
    }

    #[test]
    fn files_in_lists_a_folders_own_files_without_its_subfolders_or_hidden_entries() {
        let dir = std::env::temp_dir().join(format!("plcd-files-in-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("sub")).unwrap();
        for file in ["App.plcproj", "MAIN.TcPOU", ".hidden.plcproj", "sub/Lib.plcproj"] {
            std::fs::write(dir.join(file), "").unwrap();
        }
        let listed = files_in(&dir);
        std::fs::remove_dir_all(&dir).unwrap();
        let mut listed = listed.unwrap();
        listed.sort();
        assert_eq!(listed, [dir.join("App.plcproj"), dir.join("MAIN.TcPOU")]);
        assert!(files_in(&dir).is_err(), "a folder that is gone cannot be listed");
    }

    #[test]
    fn a_missing_inputs_file_is_one_diagnostic() {
        let path = Path::new("/nonexistent/plcd-inputs.csv");
        let diags = stimulus_for(path, &config_with(false)).unwrap_err();
        assert_eq!(diags.len(), 1);
        let text = diags.to_string();
        assert!(text.starts_with("/nonexistent/plcd-inputs.csv:0:0: error: cannot read"), "{text}");
    }

    #[test]
    fn an_inputs_file_is_read_and_sorted() {
        let path = std::env::temp_dir().join(format!("plcd-stimulus-{}.csv", std::process::id()));
        std::fs::write(&path, "2ms, P0001, 1\n1ms, P0000, 1\n").unwrap();
        let result = stimulus_for(&path, &config_with(false));
        std::fs::remove_file(&path).unwrap();
        let times: Vec<u64> = result.unwrap().iter().map(|s| s.t_ns).collect();
        assert_eq!(times, vec![1_000_000, 2_000_000]);
    }

    #[test]
    fn a_projects_inputs_file_is_checked_against_its_config() {
        let path =
            std::env::temp_dir().join(format!("plcd-stimulus-switch-{}.csv", std::process::id()));
        std::fs::write(&path, "1ms, SWITCH, STOP\n").unwrap();
        let with = stimulus_for(&path, &config_with(true));
        let without = stimulus_for(&path, &config_with(false));
        std::fs::remove_file(&path).unwrap();
        let expected = Stimulus {
            t_ns: 1_000_000,
            target: Target::Switch(SwitchPosition::Stop),
            value: 0,
            line: 1,
        };
        assert_eq!(with.unwrap(), vec![expected]);
        let text = without.unwrap_err().to_string();
        assert!(text.starts_with(&format!("{}:1:6: error: SWITCH: ", path.display())), "{text}");
        let missing =
            stimulus_for(Path::new("/nonexistent/in.csv"), &config_with(true)).unwrap_err();
        assert!(missing.to_string().contains("cannot read the inputs file"), "{missing}");
    }

    #[test]
    fn a_config_is_read_and_resolved_against_its_directory() {
        let dir = std::env::temp_dir().join(format!("plcd-config-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("plcd.toml");
        std::fs::write(&path, "[[program]]\nfile = \"main.il\"\n").unwrap();
        let loaded = config(&path);
        std::fs::remove_dir_all(&dir).unwrap();
        let loaded = loaded.unwrap();
        assert_eq!(loaded.path, path);
        assert_eq!(loaded.programs[0].resolved, dir.join("main.il"));

        let missing = dir.join("missing.toml");
        let diags = config(&missing).unwrap_err();
        assert_eq!(diags.len(), 1);
        let d = &diags.0[0];
        assert_eq!((d.path.as_path(), d.line, d.col), (missing.as_path(), 0, 0));
        assert!(
            d.message.starts_with(&format!("cannot read {}: ", missing.display())),
            "{}",
            d.message
        );
    }
}

//! `[st]`: the Structured Text files that hold only declarations (TYPEs, FUNCTIONs,
//! FUNCTION_BLOCKs, VAR_GLOBALs) for the `.st` programs of the project, and how strictly
//! their sources are read (docs/ST.md).

use std::path::{Path, PathBuf};

use serde::Deserialize;
use toml::Spanned;

use super::common::{resolve, Ctx};
use super::Sink;
use crate::diag::Diagnostic;

/// `[st]`.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct StConfig {
    /// `library`: declaration files, in the order written; default none. Every `.st` file of
    /// the project (programs and libraries) sees the declarations of all the others.
    pub library: Vec<LibraryFile>,
    /// `strict`: refuse the CODESYS/TwinCAT habits, IEC 61131-3 only; default `false`.
    pub strict: bool,
}

/// One `[st] library` entry.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LibraryFile {
    /// As written.
    pub file: PathBuf,
    /// Relative to the config file's directory (unchanged if absolute).
    pub resolved: PathBuf,
    /// Where the entry is in the config, for diagnostics about the file.
    pub line: u32,
    pub col: u32,
}

/// `[st]` as written.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawSt {
    pub library: Option<Vec<Spanned<String>>>,
    pub strict: Option<bool>,
}

pub(super) fn validate(sink: &mut Sink, raw: RawSt, config: &Path) -> Option<StConfig> {
    let ctx = Ctx::Section("st");
    let mut ok = true;
    let mut library: Vec<LibraryFile> = Vec::new();
    for entry in raw.library.unwrap_or_default() {
        let at = entry.span().start;
        let file = entry.into_inner();
        if !file.ends_with(".st") {
            sink.error(at, format!("{}: `{file}` is not a `.st` file", ctx.key("library")));
            ok = false;
            continue;
        }
        let resolved = resolve(config, &file);
        if library.iter().any(|l| l.resolved == resolved) {
            sink.error(at, format!("{}: `{file}` is listed twice", ctx.key("library")));
            ok = false;
            continue;
        }
        let (line, col) = Diagnostic::line_col(sink.text, at);
        library.push(LibraryFile { file: PathBuf::from(file), resolved, line, col });
    }
    ok.then_some(StConfig { library, strict: raw.strict.unwrap_or(false) })
}

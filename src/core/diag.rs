//! Diagnostics shared by the config loader and the assembler: one located error, printed as
//! `path:line:col: error: message`, and the rule that all of them are reported at once; and a
//! located [`Warning`], printed as `path:line:col: warning: message`, which fails nothing.

use std::fmt;
use std::path::{Path, PathBuf};

/// One error at a place in a file. Lines and columns count from 1; column 0 means "the whole
/// line" and line 0 "the whole file".
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord)]
pub struct Diagnostic {
    pub path: PathBuf,
    pub line: u32,
    pub col: u32,
    pub message: String,
}

impl Diagnostic {
    pub fn new(path: &Path, line: u32, col: u32, message: impl Into<String>) -> Diagnostic {
        Diagnostic { path: path.to_path_buf(), line, col, message: message.into() }
    }

    /// The 1-based line and column of byte `offset` in `text`.
    pub fn line_col(text: &str, offset: usize) -> (u32, u32) {
        let offset = offset.min(text.len());
        let before = &text[..offset];
        let line = before.matches('\n').count() as u32 + 1;
        let line_start = before.rfind('\n').map_or(0, |i| i + 1);
        let col = before[line_start..].chars().count() as u32 + 1;
        (line, col)
    }
}

impl fmt::Display for Diagnostic {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}:{}: error: {}", self.path.display(), self.line, self.col, self.message)
    }
}

/// Something accepted that may not mean what its writer meant (a CODESYS habit that can
/// change a value): `plcd check` prints it and the daemon logs it, and the load goes on.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord)]
pub struct Warning(pub Diagnostic);

impl fmt::Display for Warning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let d = &self.0;
        write!(f, "{}:{}:{}: warning: {}", d.path.display(), d.line, d.col, d.message)
    }
}

/// Every diagnostic of a failed load, in file and line order.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Diagnostics(pub Vec<Diagnostic>);

impl Diagnostics {
    pub fn push(&mut self, d: Diagnostic) {
        self.0.push(d);
    }
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }
    pub fn len(&self) -> usize {
        self.0.len()
    }
    pub fn extend(&mut self, other: Diagnostics) {
        self.0.extend(other.0);
    }
    pub fn iter(&self) -> impl Iterator<Item = &Diagnostic> {
        self.0.iter()
    }
}

impl fmt::Display for Diagnostics {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for d in &self.0 {
            writeln!(f, "{d}")?;
        }
        Ok(())
    }
}

impl std::error::Error for Diagnostics {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn line_col_counts_from_one() {
        let text = "ab\ncd\n\nefg";
        assert_eq!(Diagnostic::line_col(text, 0), (1, 1));
        assert_eq!(Diagnostic::line_col(text, 1), (1, 2));
        assert_eq!(Diagnostic::line_col(text, 3), (2, 1));
        assert_eq!(Diagnostic::line_col(text, 7), (4, 1));
        assert_eq!(Diagnostic::line_col(text, 99), (4, 4));
    }

    #[test]
    fn prints_like_a_compiler() {
        let d = Diagnostic::new(Path::new("etc/main.il"), 3, 7, "unknown mnemonic `LAOD`");
        assert_eq!(d.to_string(), "etc/main.il:3:7: error: unknown mnemonic `LAOD`");
    }

    #[test]
    fn warnings_print_like_a_compiler() {
        let d = Diagnostic::new(Path::new("main.st"), 4, 11, "implicit conversion");
        assert_eq!(Warning(d).to_string(), "main.st:4:11: warning: implicit conversion");
    }
}

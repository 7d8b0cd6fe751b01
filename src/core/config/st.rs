//! `[st]`: the Structured Text files that hold only declarations (TYPEs, FUNCTIONs,
//! FUNCTION_BLOCKs, VAR_GLOBALs) for the `.st` programs of the project, and how strictly
//! their sources are read (docs/ST.md).

use std::path::{Path, PathBuf};

use serde::Deserialize;
use toml::Spanned;

use super::common::{int_or, resolve, widen, Ctx};
use super::system_libraries::{SystemLibraries, SystemLibrary};
use super::Sink;
use crate::diag::Diagnostic;

/// `[st]`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StConfig {
    /// `library`: declaration files and folders of them, in the order written; default none.
    /// Every ST file of the project (programs and libraries) sees the declarations of all the
    /// others.
    pub library: Vec<LibraryFile>,
    /// `strict`: refuse the CODESYS/TwinCAT habits, IEC 61131-3 only; default `false`.
    pub strict: bool,
    /// `namespaces`: the namespaces of the libraries the project's sources are (TwinCAT's
    /// `<DefaultNamespace>` of a library project, `TcUnit`): `TcUnit.FB_TestSuite` names the
    /// project's `FB_TestSuite`, a plcd project being one namespace; default none.
    pub namespaces: Vec<String>,
    /// `heap_bytes`: the bytes of the heap `__NEW` takes memory from, part of variable memory
    /// (docs/ST.md, "Dynamic memory"); default 64 KiB, 0 none.
    pub heap_bytes: u32,
    /// `system_libraries`: the libraries plcd ships that the project uses (`["Tc2_System"]`,
    /// [`crate::st::libraries`]); default none.
    pub system_libraries: SystemLibraries,
    /// `variable_memory_bytes`: the most variable memory the project may take in all (and so
    /// one array or one instance; docs/ST.md, "Limits and what is not supported"); default
    /// 128 MiB, 1 MiB to 1 GiB.
    pub variable_memory_bytes: u32,
    /// `defines`: names defined in every source for its conditional pragmas (`{IF defined
    /// (name)}`, as a TwinCAT project's compiler defines; docs/ST.md, "Pragmas"); default
    /// none.
    pub defines: Vec<String>,
}

/// `heap_bytes` when the config does not say: 64 KiB.
pub const DEFAULT_HEAP_BYTES: u32 = 64 * 1024;

/// The largest `heap_bytes`: 16 MiB.
pub const MAX_HEAP_BYTES: u32 = 16 * 1024 * 1024;

/// `variable_memory_bytes` when the config does not say: 128 MiB, so that TcUnit's default
/// parameters (one results array of about 79 MB) load. The limit is a bound, not an
/// allocation: memory is taken at the project's real size, a few times over (its images), and
/// an array is one symbol whatever its size ([`crate::symbols`]), so a project pays for what it
/// declares, never for the limit (docs/ST.md).
pub const DEFAULT_VARIABLE_MEMORY_BYTES: u32 = 128 << 20;

/// The smallest and largest `variable_memory_bytes`: 1 MiB and 1 GiB (variable memory is
/// addressed with 32-bit offsets; a project near the top would cost gigabytes, docs/ST.md).
pub const VARIABLE_MEMORY_BYTES_RANGE: std::ops::RangeInclusive<u32> = (1 << 20)..=(1 << 30);

impl Default for StConfig {
    fn default() -> StConfig {
        StConfig {
            library: Vec::new(),
            strict: false,
            namespaces: Vec::new(),
            heap_bytes: DEFAULT_HEAP_BYTES,
            system_libraries: SystemLibraries::NONE,
            variable_memory_bytes: DEFAULT_VARIABLE_MEMORY_BYTES,
            defines: Vec::new(),
        }
    }
}

/// One `[st] library` entry.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LibraryFile {
    /// As written.
    pub file: PathBuf,
    /// Relative to the config file's directory (unchanged if absolute).
    pub resolved: PathBuf,
    /// Written with a final `/`: a folder, whose source files ([`is_st_source`]), in it and
    /// in its subfolders, are all library files.
    pub folder: bool,
    /// Where the entry is in the config, for diagnostics about the file.
    pub line: u32,
    pub col: u32,
}

/// Whether `file` is a Structured Text source by its extension: `.st`, or TwinCAT's `.TcPOU`,
/// `.TcDUT`, `.TcGVL`, `.TcIO` (any case).
pub fn is_st_source(file: &Path) -> bool {
    file.extension().and_then(|e| e.to_str()).is_some_and(|e| e.eq_ignore_ascii_case("st"))
        || is_twincat_source(file)
}

/// Whether `file` is one of TwinCAT's source files by its extension: `.TcPOU`, `.TcDUT`,
/// `.TcGVL`, `.TcIO` (an interface) (any case), read by `st::twincat`.
pub fn is_twincat_source(file: &Path) -> bool {
    file.extension().and_then(|e| e.to_str()).is_some_and(|e| {
        ["tcpou", "tcdut", "tcgvl", "tcio"].contains(&e.to_ascii_lowercase().as_str())
    })
}

/// Whether `name` can be a namespace (`[st] namespaces`, a `.plcproj`'s, `st::plcproj`): an
/// ASCII letter or `_`, then letters, digits and `_`, as an identifier is written.
pub fn is_namespace(name: &str) -> bool {
    let mut chars = name.chars();
    chars.next().is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_')
}

/// Whether `file` is a TwinCAT PLC project file by its extension, `.plcproj` (any case), whose
/// namespaces `st::plcproj` reads.
pub fn is_plcproj(file: &Path) -> bool {
    file.extension().and_then(|e| e.to_str()).is_some_and(|e| e.eq_ignore_ascii_case("plcproj"))
}

/// `[st]` as written.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawSt {
    pub library: Option<Vec<Spanned<String>>>,
    pub strict: Option<bool>,
    pub namespaces: Option<Vec<Spanned<String>>>,
    pub heap_bytes: Option<Spanned<i64>>,
    pub system_libraries: Option<Vec<Spanned<String>>>,
    pub variable_memory_bytes: Option<Spanned<i64>>,
    pub defines: Option<Vec<Spanned<String>>>,
}

pub(super) fn validate(sink: &mut Sink, raw: RawSt, config: &Path) -> Option<StConfig> {
    let ctx = Ctx::Section("st");
    let mut ok = true;
    let mut library: Vec<LibraryFile> = Vec::new();
    for entry in raw.library.unwrap_or_default() {
        let at = entry.span().start;
        let file = entry.into_inner();
        let folder = file.ends_with('/');
        if !folder && !is_st_source(Path::new(&file)) {
            sink.error(
                at,
                format!(
                    "{}: `{file}` is not a `.st`, `.TcPOU`, `.TcDUT`, `.TcGVL` or `.TcIO` file (a folder is written with a final `/`)",
                    ctx.key("library")
                ),
            );
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
        library.push(LibraryFile { file: PathBuf::from(file), resolved, folder, line, col });
    }
    let namespaces = names(sink, &ctx, "namespaces", raw.namespaces, &mut ok);
    let defines = names(sink, &ctx, "defines", raw.defines, &mut ok);
    let mut system_libraries = SystemLibraries::NONE;
    for entry in raw.system_libraries.unwrap_or_default() {
        let at = entry.span().start;
        let name = entry.into_inner();
        match SystemLibrary::from_name(&name) {
            None => {
                let msg = format!(
                    "{}: `{name}` is no library plcd ships; the known ones are {}",
                    ctx.key("system_libraries"),
                    SystemLibraries::known_names()
                );
                sink.error(at, msg);
                ok = false;
            }
            Some(library) if system_libraries.contains(library) => {
                let key = ctx.key("system_libraries");
                sink.error(at, format!("{key}: `{name}` is listed twice"));
                ok = false;
            }
            Some(library) => system_libraries = system_libraries.with(library),
        }
    }
    let range = 0..=i64::from(MAX_HEAP_BYTES);
    let default = DEFAULT_HEAP_BYTES;
    let heap_bytes = int_or(sink, &ctx, "heap_bytes", raw.heap_bytes, range, default);
    ok &= heap_bytes.is_some();
    let heap_bytes = heap_bytes.unwrap_or(default);
    let range = widen(VARIABLE_MEMORY_BYTES_RANGE);
    let default = DEFAULT_VARIABLE_MEMORY_BYTES;
    let key = "variable_memory_bytes";
    let variable_memory_bytes = int_or(sink, &ctx, key, raw.variable_memory_bytes, range, default);
    ok &= variable_memory_bytes.is_some();
    let variable_memory_bytes = variable_memory_bytes.unwrap_or(default);
    let strict = raw.strict.unwrap_or(false);
    ok.then_some(StConfig {
        library,
        strict,
        namespaces,
        heap_bytes,
        system_libraries,
        variable_memory_bytes,
        defines,
    })
}

/// The names of list `key` (`namespaces`, `defines`): each a name (letters, digits and `_`),
/// at most once whatever its case; each that is not an error at its place, which clears `ok`.
fn names(
    sink: &mut Sink,
    ctx: &Ctx,
    key: &str,
    entries: Option<Vec<Spanned<String>>>,
    ok: &mut bool,
) -> Vec<String> {
    let mut names: Vec<String> = Vec::new();
    for entry in entries.unwrap_or_default() {
        let at = entry.span().start;
        let name = entry.into_inner();
        if !is_namespace(&name) {
            let msg = format!("{}: `{name}` is not a name (letters, digits and `_`)", ctx.key(key));
            sink.error(at, msg);
            *ok = false;
        } else if names.iter().any(|n| n.eq_ignore_ascii_case(&name)) {
            sink.error(at, format!("{}: `{name}` is listed twice", ctx.key(key)));
            *ok = false;
        } else {
            names.push(name);
        }
    }
    names
}

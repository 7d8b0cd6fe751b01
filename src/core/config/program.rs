//! `[[program]]`: the instruction-list files and the task each runs in.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use serde::Deserialize;
use toml::Spanned;

use super::common::{resolve, Located};
use super::{Failed, Sink};
use crate::diag::Diagnostic;

/// One `[[program]]`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ProgramConfig {
    /// `name`: unique among programs; default the stem of `file` (`main` for `main.il`).
    pub name: String,
    /// `file`: the instruction-list file, as written. Required, no default.
    pub file: PathBuf,
    /// `file` relative to the config file's directory (unchanged if absolute).
    pub resolved: PathBuf,
    /// `task`: `"init"`, `"scan"` (default) or the name of a `[[task]]`.
    pub task: TaskRef,
    /// The language, by the file's extension: `.st` (and TwinCAT's `.TcPOU`) is Structured Text,
    /// anything else the instruction list.
    pub language: Language,
    /// `pou`: the PROGRAM of a `.st` file to instantiate; default the file's only PROGRAM.
    pub pou: Option<String>,
    /// Whether it is a program instance of a `CONFIGURATION` in `file` (`PROGRAM name …`),
    /// whose arguments the compile reads there.
    pub configured: bool,
    /// Line of the `file` value in the config, for diagnostics about the program file.
    pub line: u32,
    /// Column of the `file` value.
    pub col: u32,
}

/// The language of a program file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Language {
    /// The instruction list (docs/LANGUAGE.md).
    InstructionList,
    /// Structured Text (docs/ST.md): a file whose name ends in `.st`, or a TwinCAT `.TcPOU`.
    StructuredText,
}

impl Language {
    /// The language of `file`, by its extension.
    pub fn of(file: &Path) -> Language {
        if super::st::is_st_source(file) {
            Language::StructuredText
        } else {
            Language::InstructionList
        }
    }
}

/// The task a program runs in.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub enum TaskRef {
    /// `"init"`: the initialization task, until `INIT_DONE`.
    Init,
    /// `"scan"`: the scan program.
    Scan,
    /// A `[[task]]` by name.
    Named(String),
}

impl TaskRef {
    /// The name as written in the config and shown in traces.
    pub fn name(&self) -> &str {
        match self {
            TaskRef::Init => "init",
            TaskRef::Scan => "scan",
            TaskRef::Named(name) => name,
        }
    }
}

/// One `[[program]]` as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawProgram {
    pub name: Option<Spanned<String>>,
    pub file: Spanned<String>,
    pub task: Option<Spanned<String>>,
    pub pou: Option<Spanned<String>>,
}

pub(super) fn validate(
    sink: &mut Sink,
    raw: Vec<Located<RawProgram>>,
    task_names: &[String],
    failed: &Failed,
    config: &Path,
) -> Option<Vec<ProgramConfig>> {
    let mut ok = true;
    // A failed entry or an undefined task may have been meant as the scan program: then
    // "no scan program" would be a consequence, not news.
    let mut maybe_scan = failed.program;
    let mut names: HashMap<String, u32> = HashMap::new();
    let mut programs = Vec::new();
    for program in raw {
        let Located { ctx, value: raw, .. } = program;
        let file_span = raw.file.span();
        let file_at = file_span.start;
        let file = raw.file.into_inner();
        if file.trim().is_empty() {
            sink.error(file_at, format!("{} must not be empty", ctx.key("file")));
            ok = false;
            continue;
        }
        let name = match raw.name {
            Some(name) => name,
            None => {
                let stem = Path::new(&file).file_stem().unwrap_or_default();
                Spanned::new(file_span, stem.to_string_lossy().into_owned())
            }
        };
        if name.get_ref().trim().is_empty() {
            sink.error(name.span().start, format!("{} must not be empty", ctx.key("name")));
            ok = false;
            continue;
        }
        let (line, col) = Diagnostic::line_col(sink.text, file_at);
        if let Some(first) = names.get(name.get_ref()) {
            let message = format!(
                "{}: name {:?} is already used by the program at line {first}",
                ctx.subject(),
                name.get_ref()
            );
            sink.error(name.span().start, message);
            ok = false;
        } else {
            names.insert(name.get_ref().clone(), line);
        }

        let task = match raw.task {
            None => TaskRef::Scan,
            Some(task) => match task.get_ref().as_str() {
                "init" => TaskRef::Init,
                "scan" => TaskRef::Scan,
                named if task_names.iter().any(|t| t == named) => TaskRef::Named(named.to_string()),
                named => {
                    let message = format!(
                        "{} {named:?} is not defined: expected \"init\", \"scan\" or the name of a [[task]]",
                        ctx.key("task"),
                    );
                    sink.error(task.span().start, message);
                    ok = false;
                    maybe_scan = true;
                    continue;
                }
            },
        };
        let language = Language::of(Path::new(&file));
        let pou = match raw.pou {
            Some(pou) if language != Language::StructuredText => {
                let message = format!(
                    "{} names a PROGRAM of a Structured Text file, and `{file}` is not a `.st` file",
                    ctx.key("pou")
                );
                // The entry stays: its other keys are right (it may be the scan program).
                sink.error(pou.span().start, message);
                ok = false;
                None
            }
            Some(pou) if pou.get_ref().trim().is_empty() => {
                sink.error(pou.span().start, format!("{} must not be empty", ctx.key("pou")));
                ok = false;
                None
            }
            pou => pou.map(Spanned::into_inner),
        };
        let resolved = resolve(config, &file);
        programs.push(ProgramConfig {
            name: name.into_inner(),
            file: PathBuf::from(file),
            resolved,
            task,
            language,
            pou,
            configured: false,
            line,
            col,
        });
    }
    if !maybe_scan && !programs.iter().any(|p| p.task == TaskRef::Scan) {
        sink.error_file(
            "no [[program]] runs in the scan task: a PLC needs a scan program \
             (a [[program]] with task = \"scan\", the default)",
        );
        ok = false;
    }
    ok.then_some(programs)
}

//! The docs, kept honest: each test reads a doc and the thing it describes, and fails when they
//! drift apart.
//!
//! - Nothing in the repository points outside it: the docs carry the whole reference.
//! - Every ```toml block of docs/ and README.md parses: a complete config (one with a
//!   `[[program]]`) as it is, a partial snippet once a scan program is added to it. A snippet
//!   that must not parse belongs in a ```text block.
//! - Every trace event the trace writer can emit, with its fields in order, every `why` of an
//!   ignored request, every mode and error code is in docs/SIMULATION.md.
//! - Every `plcctl` subcommand and option is in docs/PLCCTL.md, every `plcd` subcommand and
//!   option in docs/COMMANDS.md (and `plcd sim`'s in docs/SIMULATION.md).
//! - Every config key the parser accepts is in a key table of docs/CONFIG.md, under the heading
//!   of its section, and every key those tables name is accepted. The keys are not listed here:
//!   the parser names them itself, in its "unknown key `x`, expected one of …" diagnostics.
//! - Every path of the repository the docs cite (`src/…`, `tests/…`) exists, and so does every
//!   one the files of `etc/` and `systemd/` cite.

mod harness;

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use plcd::drivers::virtual_time::trace::TraceWriter;
use plcd::engine::event::{ErrorKind, Event, EventSink, Ignored, Mode};
use plcd::io::SwitchPosition;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn read(relative: &str) -> String {
    std::fs::read_to_string(root().join(relative))
        .unwrap_or_else(|e| panic!("cannot read {relative}: {e}"))
}

/// README.md and every page of docs/, as (path relative to the root, text).
fn pages() -> Vec<(String, String)> {
    let mut pages = vec![("README.md".to_string(), read("README.md"))];
    let mut names: Vec<String> = std::fs::read_dir(root().join("docs"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|name| name.ends_with(".md"))
        .collect();
    names.sort();
    for name in names {
        let relative = format!("docs/{name}");
        let text = read(&relative);
        pages.push((relative, text));
    }
    pages
}

/// Every file of the repository outside `target/` and `.git/`, relative to the root.
fn repository_files() -> Vec<PathBuf> {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        for entry in std::fs::read_dir(dir).unwrap() {
            let entry = entry.unwrap();
            let path = entry.path();
            let name = entry.file_name();
            if entry.file_type().unwrap().is_dir() {
                if dir == root() && (name == "target" || name == ".git") {
                    continue;
                }
                walk(&path, out);
            } else {
                out.push(path.strip_prefix(root()).unwrap().to_path_buf());
            }
        }
    }
    let mut files = Vec::new();
    walk(root(), &mut files);
    files.sort();
    files
}

#[test]
fn nothing_points_outside_the_repository() {
    // Built from pieces, so that this file does not name them itself.
    let needles = [
        concat!("..", "/shared"),
        concat!("shared", "/spec"),
        concat!("shared", "/seeds"),
        concat!("CONT", "RACT"),
    ];
    let mut found = Vec::new();
    for file in repository_files() {
        let Ok(bytes) = std::fs::read(root().join(&file)) else { continue };
        let text = String::from_utf8_lossy(&bytes);
        for (index, line) in text.lines().enumerate() {
            for needle in needles.iter().filter(|n| line.contains(*n)) {
                found.push(format!("{}:{}: `{needle}`", file.display(), index + 1));
            }
        }
    }
    assert!(
        found.is_empty(),
        "the repository must describe itself, without pointing to documents a user who clones \
         it does not have:\n{}",
        found.join("\n")
    );
}

/// A merge's conflict left in a file (`<<<<<<< HEAD` … `>>>>>>> commit`) reads as text in a
/// page and compiles nowhere else: none may be committed (one stood in docs/ST.md for a day).
#[test]
fn no_merge_conflict_is_left_in_a_file() {
    // Built from pieces, so that this file does not hold them itself.
    let markers = [concat!("<<<<<<", "< "), concat!(">>>>>>", "> ")];
    let mut found = Vec::new();
    for file in repository_files() {
        let Ok(bytes) = std::fs::read(root().join(&file)) else { continue };
        let text = String::from_utf8_lossy(&bytes);
        for (index, line) in text.lines().enumerate() {
            if markers.iter().any(|m| line.starts_with(m)) {
                found.push(format!("{}:{}: {line}", file.display(), index + 1));
            }
        }
    }
    assert!(found.is_empty(), "merge conflicts left in:\n{}", found.join("\n"));
}

/// The fenced blocks of `lang` in `text`: (line of the opening fence, content).
fn fenced_blocks(text: &str, lang: &str) -> Vec<(usize, String)> {
    let mut blocks = Vec::new();
    // The block being read: its first line, whether it is of `lang`, its text.
    let mut open: Option<(usize, bool, String)> = None;
    for (index, line) in text.lines().enumerate() {
        let fence = line.trim_start().starts_with("```");
        match open.take() {
            None if fence => {
                let info = line.trim_start().trim_start_matches('`').trim();
                open = Some((index + 1, info == lang, String::new()));
            }
            None => {}
            Some((at, true, body)) if fence => blocks.push((at, body)),
            Some((_, false, _)) if fence => {}
            Some((at, wanted, mut body)) => {
                body.push_str(line);
                body.push('\n');
                open = Some((at, wanted, body));
            }
        }
    }
    blocks
}

#[test]
fn every_toml_example_parses() {
    let mut complete = 0;
    let mut failures = Vec::new();
    for (page, text) in pages() {
        for (line, block) in fenced_blocks(&text, "toml") {
            let is_complete = block.contains("[[program]]");
            let config = if is_complete {
                complete += 1;
                block.clone()
            } else {
                format!("{block}\n[[program]]\nfile = \"main.il\"\n")
            };
            if let Err(diags) = plcd::config::parse(&config, Path::new("plcd.toml")) {
                let what = if is_complete { "config" } else { "snippet (with a scan program)" };
                failures.push(format!("{page}:{line}: the {what} does not parse:\n{diags}"));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    assert!(complete > 0, "docs/CONFIG.md should hold a complete example config");
}

/// The rows of every Markdown table in `text`, as their cells (trimmed), header rows included.
fn table_rows(text: &str) -> Vec<Vec<String>> {
    text.lines()
        .filter_map(|line| line.trim().strip_prefix('|'))
        .map(|row| {
            // `\|` is a pipe inside a cell.
            let row = row.replace("\\|", "\u{1}");
            let mut cells: Vec<String> =
                row.split('|').map(|c| c.trim().replace('\u{1}', "|")).collect();
            if cells.last().is_some_and(String::is_empty) {
                cells.pop();
            }
            cells
        })
        .collect()
}

/// The `code spans` of a piece of Markdown.
fn code_spans(text: &str) -> Vec<String> {
    text.split('`').skip(1).step_by(2).map(str::to_string).collect()
}

/// Every variant of `Event`, each once. The `match` has no wildcard: a new variant does not
/// compile until it is added here, and then this test asks for its documentation.
fn every_event() -> Vec<Event> {
    let events = vec![
        Event::Mode(Mode::Run),
        Event::ScanStart { n: 1 },
        Event::ScanEnd { n: 1 },
        Event::TaskRequest { task: 2 },
        Event::TaskIgnored { task: 2, why: Ignored::Running },
        Event::TaskStart { task: 2 },
        Event::TaskEnd { task: 2 },
        Event::TaskPreempt { task: 0, by: 2 },
        Event::TaskResume { task: 0 },
        Event::Set { watch: 0, value: 1 },
        Event::SetVariable { watch: 0, slot: 1 },
        Event::Error(ErrorKind::Watchdog { scan: 1, limit_ms: 200 }),
        Event::Switch(SwitchPosition::Run),
    ];
    let kinds: BTreeSet<u8> = events
        .iter()
        .map(|event| match event {
            Event::Mode(_) => 0,
            Event::ScanStart { .. } => 1,
            Event::ScanEnd { .. } => 2,
            Event::TaskRequest { .. } => 3,
            Event::TaskIgnored { .. } => 4,
            Event::TaskStart { .. } => 5,
            Event::TaskEnd { .. } => 6,
            Event::TaskPreempt { .. } => 7,
            Event::TaskResume { .. } => 8,
            Event::Set { .. } => 9,
            Event::Error(_) => 10,
            Event::Switch(_) => 11,
            Event::SetVariable { .. } => 12,
        })
        .collect();
    assert_eq!(kinds.len(), 13, "every_event must hold each variant of Event");
    events
}

fn every_ignored() -> Vec<Ignored> {
    let all = vec![
        Ignored::Running,
        Ignored::Pending,
        Ignored::Init,
        Ignored::Stop,
        Ignored::Disabled,
        Ignored::Paused,
    ];
    let kinds: BTreeSet<u8> = all
        .iter()
        .map(|why| match why {
            Ignored::Running => 0,
            Ignored::Pending => 1,
            Ignored::Init => 2,
            Ignored::Stop => 3,
            Ignored::Disabled => 4,
            Ignored::Paused => 5,
        })
        .collect();
    assert_eq!(kinds.len(), 6, "every_ignored must hold each variant of Ignored");
    all
}

fn every_mode() -> Vec<Mode> {
    let all = vec![Mode::Run, Mode::Stop, Mode::Error, Mode::Debug];
    let kinds: BTreeSet<u8> = all
        .iter()
        .map(|mode| match mode {
            Mode::Run => 0,
            Mode::Stop => 1,
            Mode::Error => 2,
            Mode::Debug => 3,
        })
        .collect();
    assert_eq!(kinds.len(), 4, "every_mode must hold each variant of Mode");
    all
}

/// Every error the trace can report: the stopping errors and each operation error code.
fn every_error() -> Vec<ErrorKind> {
    let operation = |code| ErrorKind::Operation { code, task: 0, program: 0, pc: 0 };
    let all = vec![
        ErrorKind::Watchdog { scan: 1, limit_ms: 200 },
        ErrorKind::Congestion { task: 2, limit_ms: 5 },
        operation(plcd::vm::ERR_DIVIDE_BY_ZERO),
        operation(plcd::vm::ERR_VALUE_RANGE),
        operation(plcd::vm::ERR_CALL_DEPTH),
        operation(plcd::vm::ERR_LOOP_DEPTH),
    ];
    for error in &all {
        match error {
            ErrorKind::Watchdog { .. }
            | ErrorKind::Congestion { .. }
            | ErrorKind::Operation { .. } => {}
        }
    }
    all
}

/// The trace lines of `events`, as the trace writer writes them.
fn trace_lines(events: &[Event]) -> Vec<String> {
    let names = ["scan", "init", "fast"].map(String::from).to_vec();
    let mut writer =
        TraceWriter::new(Vec::new(), names, vec!["P0040".into()], vec![("main".into(), vec![3])]);
    for (t, event) in events.iter().enumerate() {
        writer.event(t as u64, *event);
    }
    let bytes = writer.finish().unwrap();
    String::from_utf8(bytes).unwrap().lines().map(str::to_string).collect()
}

/// The keys of a trace line, in order.
fn keys_of(line: &str) -> Vec<String> {
    let object: serde_json::Value = serde_json::from_str(line).unwrap();
    let keys: BTreeSet<&String> = object.as_object().unwrap().keys().collect();
    // serde_json's map is sorted: take the order from the text, checked against the parse.
    let mut ordered: Vec<String> = Vec::new();
    let mut rest = line;
    while let Some(at) = rest.find('"') {
        let after = &rest[at + 1..];
        let end = after.find('"').unwrap();
        let word = &after[..end];
        rest = &after[end + 1..];
        if rest.starts_with(':')
            && keys.contains(&word.to_string())
            && !ordered.iter().any(|k| k == word)
        {
            ordered.push(word.to_string());
        }
    }
    assert_eq!(ordered.len(), keys.len(), "{line}");
    ordered
}

#[test]
fn every_trace_event_is_documented() {
    let doc = read("docs/SIMULATION.md");
    let rows = table_rows(&doc);
    let row_of = |first: &str| -> Option<&Vec<String>> {
        rows.iter()
            .find(|row| row.first().is_some_and(|cell| code_spans(cell).iter().any(|c| c == first)))
    };
    let mut missing = Vec::new();

    for line in trace_lines(&every_event()) {
        let keys = keys_of(&line);
        assert_eq!(&keys[..2], ["t_ns", "ev"], "every line starts with t_ns and ev: {line}");
        let object: serde_json::Value = serde_json::from_str(&line).unwrap();
        let ev = object["ev"].as_str().unwrap();
        let Some(row) = row_of(ev) else {
            missing.push(format!("event `{ev}`: no table row starts with it"));
            continue;
        };
        // Its fields, in the order the writer writes them, as code spans of the second cell.
        let documented: Vec<String> = row
            .get(1)
            .map(|cell| code_spans(cell))
            .unwrap_or_default()
            .into_iter()
            .filter(|span| keys.contains(span))
            .collect();
        let fields: Vec<String> = keys[2..].to_vec();
        let mut seen = documented.clone();
        seen.dedup();
        if seen != fields {
            missing.push(format!(
                "event `{ev}`: fields {fields:?} (in this order), the doc's row names {seen:?}"
            ));
        }
    }

    for why in every_ignored() {
        if row_of(why.as_str()).is_none() {
            missing.push(format!("`why` `{}`: no table row starts with it", why.as_str()));
        }
    }
    let mode_row = row_of("mode").map(|row| row.join(" ")).unwrap_or_default();
    for mode in every_mode() {
        if !code_spans(&mode_row).iter().any(|span| span == mode.as_str()) {
            missing.push(format!("mode `{}` is not in the row of `mode`", mode.as_str()));
        }
    }
    let switch_row = row_of("switch").map(|row| row.join(" ")).unwrap_or_default();
    for position in [SwitchPosition::Run, SwitchPosition::Stop] {
        if !code_spans(&switch_row).iter().any(|span| span == position.as_str()) {
            missing.push(format!("position `{}` is not in the row of `switch`", position.as_str()));
        }
    }
    let errors: Vec<Event> = every_error().into_iter().map(Event::Error).collect();
    for line in trace_lines(&errors) {
        let object: serde_json::Value = serde_json::from_str(&line).unwrap();
        let code = object["code"].as_str().unwrap();
        if row_of(code).is_none() {
            missing.push(format!("error code `{code}`: no table row starts with it"));
        }
    }
    assert!(missing.is_empty(), "docs/SIMULATION.md is missing:\n{}", missing.join("\n"));
}

/// The `## `/`### ` sections of a page: (heading, body up to the next heading of any level).
fn sections(text: &str) -> Vec<(String, String)> {
    let mut out: Vec<(String, String)> = Vec::new();
    let mut in_fence = false;
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            in_fence = !in_fence;
        }
        if !in_fence && line.starts_with("##") {
            out.push((line.trim_start_matches('#').trim().to_string(), String::new()));
        } else if let Some((_, body)) = out.last_mut() {
            body.push_str(line);
            body.push('\n');
        }
    }
    out
}

/// True if `heading` names `command`: as a code span of its own or as the first word of one
/// (`reset [--cold]`, `plcd bench latency`).
fn names(heading: &str, command: &str) -> bool {
    code_spans(heading).iter().any(|span| {
        span == command || span.strip_prefix(command).is_some_and(|rest| rest.starts_with(' '))
    })
}

#[test]
fn every_plcctl_command_and_option_is_documented() {
    use clap::CommandFactory;
    let doc = read("docs/PLCCTL.md");
    let sections = sections(&doc);
    let cli = plcctl::Cli::command();
    let mut missing = Vec::new();
    for arg in cli.get_arguments() {
        if let Some(long) = arg.get_long().filter(|l| !matches!(*l, "help" | "version")) {
            if !doc.contains(&format!("--{long}")) {
                missing.push(format!("the option `--{long}`"));
            }
        }
    }
    let mut count = 0;
    for sub in cli.get_subcommands().filter(|s| s.get_name() != "help") {
        count += 1;
        let name = sub.get_name();
        let Some((_, body)) = sections.iter().find(|(heading, _)| names(heading, name)) else {
            missing.push(format!("a heading naming the command `{name}`"));
            continue;
        };
        let heading = sections.iter().find(|(h, _)| names(h, name)).unwrap().0.clone();
        for arg in sub.get_arguments() {
            let Some(long) = arg.get_long().filter(|l| *l != "help") else { continue };
            let option = format!("--{long}");
            if arg.is_global_set() || heading.contains(&option) || body.contains(&option) {
                continue;
            }
            missing.push(format!("`{name} --{long}` in the section of `{name}`"));
        }
    }
    assert!(count >= 16, "plcctl has {count} commands: is the command tree read?");
    assert!(missing.is_empty(), "docs/PLCCTL.md is missing:\n{}", missing.join("\n"));
}

/// `plcd ARGS --help`, as the user sees it.
fn plcd_help(args: &[&str]) -> String {
    let output = harness::runner::command(env!("CARGO_BIN_EXE_plcd"))
        .args(args)
        .arg("--help")
        .output()
        .unwrap();
    assert!(output.status.success(), "plcd {args:?} --help failed");
    String::from_utf8(output.stdout).unwrap()
}

/// The subcommands and long options of a clap help text.
fn help_items(help: &str) -> (Vec<String>, Vec<String>) {
    let mut commands = Vec::new();
    let mut options = Vec::new();
    let mut block = "";
    for line in help.lines() {
        if !line.starts_with(' ') {
            block = line.trim_end_matches(':');
            continue;
        }
        let first = line.split_whitespace().next().unwrap_or_default();
        match block {
            "Commands" if first != "help" => commands.push(first.to_string()),
            "Options" => {
                let long = line
                    .split_whitespace()
                    .map(|word| word.trim_end_matches(','))
                    .find(|word| word.starts_with("--"));
                if let Some(long) = long.filter(|l| !matches!(*l, "--help" | "--version")) {
                    options.push(long.to_string());
                }
            }
            _ => {}
        }
    }
    (commands, options)
}

#[test]
fn every_plcd_command_and_option_is_documented() {
    let commands_doc = read("docs/COMMANDS.md");
    let sections = sections(&commands_doc);
    let simulation = read("docs/SIMULATION.md");
    let mut missing = Vec::new();
    // Breadth first through the command tree: `run`, …, `bench latency`, ….
    let (top, _) = help_items(&plcd_help(&[]));
    assert!(top.len() >= 4, "plcd --help lists {top:?}");
    let mut queue: Vec<Vec<String>> = top.into_iter().map(|c| vec![c]).collect();
    while let Some(path) = queue.pop() {
        let args: Vec<&str> = path.iter().map(String::as_str).collect();
        let (subcommands, options) = help_items(&plcd_help(&args));
        queue.extend(subcommands.into_iter().map(|s| [path.clone(), vec![s]].concat()));
        let command = format!("plcd {}", path.join(" "));
        if !commands_doc.contains(&command) {
            missing.push(format!("docs/COMMANDS.md: `{command}`"));
        }
        // The options, in the section of the top-level command.
        let top_level = format!("plcd {}", path[0]);
        let Some((_, body)) = sections.iter().find(|(heading, _)| names(heading, &top_level))
        else {
            missing.push(format!("docs/COMMANDS.md: a heading naming `{top_level}`"));
            continue;
        };
        for option in options {
            if !body.contains(&format!("`{option}")) {
                missing.push(format!("docs/COMMANDS.md: `{command} {option}` in its section"));
            }
            if path[0] == "sim" && !simulation.contains(&format!("`{option}")) {
                missing.push(format!("docs/SIMULATION.md: `{command} {option}`"));
            }
        }
    }
    assert!(missing.is_empty(), "missing:\n{}", missing.join("\n"));
}

/// A config section as the parser knows it: `plc`, `io.input`; `array` for `[[…]]`.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord)]
struct Section {
    name: String,
    array: bool,
}

const PROBE: &str = "zz_no_such_key";

/// The keys the parser expects where `probe` put an unknown key, from its diagnostic, or
/// `None` if it gave none (the place is no table).
fn expected_keys(config: &str) -> Option<Vec<String>> {
    let diags = plcd::config::parse(config, Path::new("plcd.toml")).err()?;
    let message = diags
        .iter()
        .map(|d| d.message.clone())
        .find(|m| m.contains(&format!("unknown key `{PROBE}`")))?;
    // "…, expected one of `a`, `b`", "expected `a` or `b`", "expected `a`".
    let (_, expected) = message.split_once("expected")?;
    Some(code_spans(expected))
}

/// Every section of the config and its keys, as the parser reports them. A key is a section of
/// its own when an unknown key inside it is reported with the keys expected there.
fn parser_sections() -> BTreeMap<Section, BTreeSet<String>> {
    let top = expected_keys(&format!("{PROBE} = 1\n")).expect("the top level lists its keys");
    let mut todo: Vec<String> = top;
    let mut found = BTreeMap::new();
    while let Some(name) = todo.pop() {
        let table = expected_keys(&format!("[{name}]\n{PROBE} = 1\n")).map(|k| (k, false));
        let array = || expected_keys(&format!("[[{name}]]\n{PROBE} = 1\n")).map(|k| (k, true));
        let Some((keys, is_array)) = table.or_else(array) else {
            panic!("`{name}` is a section, but an unknown key in it is not reported");
        };
        let mut own = BTreeSet::new();
        for key in keys {
            let dotted = format!("{name}.{key}");
            let sub_table = expected_keys(&format!("[{dotted}]\n{PROBE} = 1\n"))
                .or_else(|| expected_keys(&format!("[[{dotted}]]\n{PROBE} = 1\n")));
            if sub_table.is_some() {
                todo.push(dotted);
            } else {
                own.insert(key);
            }
        }
        found.insert(Section { name, array: is_array }, own);
    }
    found
}

/// The sections of docs/CONFIG.md and their keys: each `##` heading names its sections as code
/// spans (`[plc]`, `[[io.input]]`), and the first cell of each row of the tables under it is a
/// key (`` `watchdog_ms` ``).
fn documented_sections(doc: &str) -> BTreeMap<Section, BTreeSet<String>> {
    let mut found: BTreeMap<Section, BTreeSet<String>> = BTreeMap::new();
    for (heading, body) in sections(doc) {
        let named: Vec<Section> = code_spans(&heading)
            .iter()
            .filter_map(|span| {
                let array = span.starts_with("[[") && span.ends_with("]]");
                let name = span.trim_start_matches('[').trim_end_matches(']');
                let plain = span.starts_with('[') && span.ends_with(']');
                (plain && !name.is_empty()).then(|| Section { name: name.to_string(), array })
            })
            .collect();
        let keys: BTreeSet<String> = table_rows(&body)
            .iter()
            .filter_map(|row| row.first())
            .filter_map(|cell| {
                let spans = code_spans(cell);
                (spans.len() == 1 && cell.starts_with('`') && cell.ends_with('`'))
                    .then(|| spans[0].clone())
            })
            .collect();
        for section in named {
            found.entry(section).or_default().extend(keys.iter().cloned());
        }
    }
    found
}

#[test]
fn every_config_key_is_documented() {
    let parser = parser_sections();
    assert!(parser.len() >= 15, "the parser's sections: {:?}", parser.keys());
    let documented = documented_sections(&read("docs/CONFIG.md"));
    let mut problems = Vec::new();
    for (section, keys) in &parser {
        let bracket = if section.array {
            format!("[[{}]]", section.name)
        } else {
            format!("[{}]", section.name)
        };
        let Some(doc_keys) = documented.get(section) else {
            problems.push(format!("no heading names `{bracket}`"));
            continue;
        };
        for key in keys.difference(doc_keys) {
            problems.push(format!("`{bracket}` accepts `{key}`, which its tables do not list"));
        }
        for key in doc_keys.difference(keys) {
            problems.push(format!("`{bracket}` lists `{key}`, which the parser does not accept"));
        }
    }
    for section in documented.keys().filter(|s| !parser.contains_key(s)) {
        problems
            .push(format!("the heading names `{}`, which the parser does not know", section.name));
    }
    assert!(problems.is_empty(), "docs/CONFIG.md:\n{}", problems.join("\n"));
}

/// The repository paths a page cites: words starting with one of the top-level directories,
/// not inside another path (`/etc/…` is the system's).
fn cited_paths(text: &str) -> BTreeSet<String> {
    const ROOTS: [&str; 6] = ["src/", "tests/", "benches/", "docs/", "etc/", "systemd/"];
    let is_path_char = |c: char| c.is_ascii_alphanumeric() || "_./*-".contains(c);
    let mut found = BTreeSet::new();
    let mut previous: Option<char> = None;
    for (at, c) in text.char_indices() {
        let starts = previous.is_none_or(|p| !(is_path_char(p) || p == '~' || p == '$'));
        previous = Some(c);
        if !starts {
            continue;
        }
        let rest = &text[at..];
        if !ROOTS.iter().any(|r| rest.starts_with(r)) {
            continue;
        }
        let end = rest.find(|c: char| !is_path_char(c)).unwrap_or(rest.len());
        let path = rest[..end].trim_end_matches(['.', ',', ':', ';']);
        found.insert(path.to_string());
    }
    found
}

/// True if `path` (relative, perhaps with one `*` in its last component) names something.
fn exists(path: &str) -> bool {
    let Some((dir, pattern)) = path.rsplit_once('/').filter(|(_, last)| last.contains('*')) else {
        return root().join(path).exists();
    };
    let (prefix, suffix) = pattern.split_once('*').unwrap();
    std::fs::read_dir(root().join(dir)).is_ok_and(|entries| {
        entries.filter_map(Result::ok).any(|e| {
            let name = e.file_name().to_string_lossy().into_owned();
            name.starts_with(prefix) && name.ends_with(suffix)
        })
    })
}

#[test]
fn every_cited_path_exists() {
    let mut missing = Vec::new();
    let mut pages = pages();
    pages.push(("BENCHMARKS.md".into(), read("BENCHMARKS.md")));
    // The comments of the example project and of the service files point into the docs too.
    for file in repository_files() {
        let relative = file.to_string_lossy().into_owned();
        if relative.starts_with("etc/") || relative.starts_with("systemd/") {
            if let Ok(text) = std::fs::read_to_string(root().join(&file)) {
                pages.push((relative, text));
            }
        }
    }
    for (page, text) in pages {
        for path in cited_paths(&text).into_iter().filter(|p| !exists(p)) {
            missing.push(format!("{page}: {path}"));
        }
    }
    assert!(missing.is_empty(), "the docs cite paths that do not exist:\n{}", missing.join("\n"));
}

//! A `CONFIGURATION` mapped onto plcd's project, so that a file OpenPLC Editor or Beremiz wrote
//! loads as it is: its TASKs become `[[task]]`s or the scan, its PROGRAM instances the
//! project's Structured Text programs (docs/ST.md, Configurations).
//!
//! | IEC | plcd |
//! |---|---|
//! | `TASK t (INTERVAL := T#20ms, PRIORITY := p)` | a cycle task of 20 ms, priority `2 + p` (at most 7), the next free cycle number |
//! | `TASK t (SINGLE := v, PRIORITY := p)` | a device task on the rising edge of `v`'s bit, priority `2 + p`, the next free device number |
//! | `TASK t (PRIORITY := p)` (no interval) | the scan |
//! | `PROGRAM i WITH t : P;` | the program instance `i` of `P` in `t`'s task |
//! | `PROGRAM i : P;` (no task) | the instance in the scan |
//! | `PROGRAM i : P (a := x, b => y);` | the same; the compile copies the arguments ([`mod@crate::st::compile`]) |
//! | nothing in the scan | the interval task of the lowest priority is the scan, its interval the scan period (unless `[plc] scan_period_ms` is set) |
//! | `VAR_CONFIG i.x AT %QX0.1 : BOOL;` | a note of the device; the compile binds the variable |

use std::path::Path;

use crate::config::{DeviceCondition, Language, ProgramConfig, TaskConfig, TaskKind, TaskRef};
use crate::device::iec::IecLayout;
use crate::device::Address;
use crate::diag::Diagnostic;
use crate::st::ast::{self, ConfigValue, ExprKind, Literal};

/// What a configuration adds to the project.
#[derive(Debug, Clone, PartialEq)]
pub struct Mapped {
    pub tasks: Vec<TaskConfig>,
    /// The program instances, in the configuration's order, in place of the `[[program]]`
    /// entry that named the file.
    pub programs: Vec<ProgramConfig>,
    /// The scan period the scan takes from an interval task, when `[plc]` leaves it free.
    pub scan_period_ms: Option<u32>,
    /// What was mapped to what, a line each, for `plcd check` and the log.
    pub notes: Vec<String>,
}

/// One TASK, read.
struct Task<'a> {
    decl: &'a ast::TaskDecl,
    interval_ms: Option<u32>,
    /// SINGLE: the device bit whose rising edge starts it, and how it was named.
    single: Option<(Address, String)>,
    priority: u8,
    /// Its name is the project's already (reported): it maps to nothing.
    clash: bool,
}

/// What SINGLE accepts, the end of each of its errors.
const SINGLE_FORMS: &str = "SINGLE names a BOOL global located at a device bit \
                            (`start AT %IX0.1 : BOOL;`) or a device bit (`SINGLE := %IX0.1`)";

/// The device bit `%text` names (an IEC direct address or a plcd device).
fn device_bit(text: &str, iec: &IecLayout) -> Option<Address> {
    let text = match crate::st::compile::iec_address(text, iec) {
        Ok(Some((device, Some(1)))) => device,
        Ok(None) => text.to_string(),
        _ => return None,
    };
    Address::parse(&text).ok().filter(|a| a.as_bit().is_ok())
}

/// The device bit SINGLE names: a direct address, or a BOOL global of `file` (the
/// configuration's or the file's own) located at one; with the name the notes give it.
fn single_bit(
    value: &ConfigValue,
    conf: &ast::Configuration,
    file: &ast::File,
    iec: &IecLayout,
) -> Result<(Address, String), String> {
    let name = match value {
        ConfigValue::Location(loc) => {
            return match device_bit(&loc.name, iec) {
                Some(bit) => Ok((bit, format!("%{}", loc.name))),
                None => Err(format!("`%{}` is not a device bit: {SINGLE_FORMS}", loc.name)),
            };
        }
        ConfigValue::Expr(ast::Expr { kind: ExprKind::Name(name), .. }) => name,
        ConfigValue::Expr(_) => return Err(SINGLE_FORMS.to_string()),
    };
    let top = file.items.iter().filter_map(|i| match i {
        ast::Item::Globals(block) => Some(block),
        _ => None,
    });
    let decl = conf
        .globals
        .iter()
        .chain(top)
        .flat_map(|block| &block.decls)
        .find(|d| d.names.iter().any(|n| n.is(&name.name)));
    let Some(decl) = decl else {
        return Err(format!("`{}` is not a VAR_GLOBAL of this file: {SINGLE_FORMS}", name.name));
    };
    match &decl.ty {
        ast::TypeRef::Named(ty) if ty.is("BOOL") => {}
        _ => return Err(format!("`{}` is not a BOOL: {SINGLE_FORMS}", name.name)),
    }
    match decl.location.as_ref().and_then(|loc| device_bit(&loc.name, iec)) {
        Some(bit) => Ok((bit, name.name.clone())),
        None => Err(format!("`{}` is not located at a device bit: {SINGLE_FORMS}", name.name)),
    }
}

/// Maps `conf`, declared in the file of `entry`, next to the config's own `tasks` and
/// `programs` (the other entries); `scan_period_ms` is `[plc]`'s, `iec` the layout of the
/// direct addresses (`[iec]`). Every error at once, located
/// in the file.
pub fn map(
    conf: &ast::Configuration,
    file: &ast::File,
    entry: &ProgramConfig,
    tasks: &[TaskConfig],
    programs: &[&ProgramConfig],
    scan_period_ms: u32,
    iec: &IecLayout,
) -> Result<Mapped, Vec<Diagnostic>> {
    let path = entry.resolved.as_path();
    let mut errors = Vec::new();
    let error = |errors: &mut Vec<Diagnostic>, span: ast::Span, msg: String| {
        errors.push(Diagnostic::new(path, span.line, span.col, msg));
    };
    // the tasks, read
    let mut read: Vec<Task<'_>> = Vec::new();
    for decl in conf.resources.iter().flat_map(|r| &r.tasks) {
        let name = &decl.name.name;
        let clash = tasks.iter().any(|t| t.name.eq_ignore_ascii_case(name))
            || ["init", "scan"].iter().any(|n| n.eq_ignore_ascii_case(name))
            || read.iter().any(|t| t.decl.name.is(name));
        if clash {
            error(
                &mut errors,
                decl.name.span,
                format!("task `{name}` is already a task of the project"),
            );
        }
        let mut task = Task { decl, interval_ms: None, single: None, priority: 0, clash };
        let mut interval_at = None;
        for (key, value) in &decl.properties {
            let expr = match value {
                ConfigValue::Expr(e) => Some(&e.kind),
                ConfigValue::Location(_) => None,
            };
            match key.name.to_ascii_uppercase().as_str() {
                "INTERVAL" => match expr {
                    Some(&ExprKind::Literal(Literal::Time(ns)))
                        if ns >= 1_000_000
                            && ns % 1_000_000 == 0
                            && ns / 1_000_000 <= i128::from(u32::MAX) =>
                    {
                        task.interval_ms = Some((ns / 1_000_000) as u32);
                        interval_at = Some(key.span);
                    }
                    _ => error(
                        &mut errors,
                        value.span(),
                        "INTERVAL must be a duration of whole milliseconds, at least `T#1ms`"
                            .to_string(),
                    ),
                },
                "PRIORITY" => match expr {
                    Some(&ExprKind::Literal(Literal::Int(p))) => task.priority = p.min(5) as u8,
                    _ => error(
                        &mut errors,
                        value.span(),
                        "PRIORITY must be a number, 0 the highest".to_string(),
                    ),
                },
                "SINGLE" => match single_bit(value, conf, file, iec) {
                    Ok(single) => task.single = Some(single),
                    Err(msg) => error(&mut errors, value.span(), msg),
                },
                other => error(
                    &mut errors,
                    key.span,
                    format!("`{other}` is not a property of a TASK: INTERVAL, PRIORITY or SINGLE"),
                ),
            }
        }
        if let (Some(at), Some(_)) = (interval_at, &task.single) {
            // IEC runs such a task periodically while SINGLE is FALSE; a plcd task starts on one
            // event or on a period.
            error(
                &mut errors,
                at,
                "a TASK with SINGLE takes no INTERVAL: it runs on SINGLE's rising edges alone"
                    .to_string(),
            );
            task.interval_ms = None;
        }
        read.push(task);
    }
    // which instances run in the scan: those of no task or of a task without an interval or
    // an event
    let decls: Vec<&ast::ProgramDecl> = conf.resources.iter().flat_map(|r| &r.programs).collect();
    let continuous = |r: &Task<'_>| r.interval_ms.is_none() && r.single.is_none();
    let in_scan = |d: &ast::ProgramDecl| match &d.task {
        None => true,
        Some(t) => read.iter().any(|r| r.decl.name.is(&t.name) && continuous(r)),
    };
    let others_in_scan = programs.iter().any(|p| p.task == TaskRef::Scan);
    let mut scan_task: Option<&str> = None;
    if !others_in_scan && !decls.iter().any(|d| in_scan(d)) {
        // the lowest priority (largest number), the first of equals
        let lowest = read
            .iter()
            .filter(|t| t.interval_ms.is_some())
            .filter(|t| {
                decls.iter().any(|d| d.task.as_ref().is_some_and(|n| t.decl.name.is(&n.name)))
            })
            .fold(None::<&Task<'_>>, |best, t| match best {
                Some(b) if b.priority >= t.priority => Some(b),
                _ => Some(t),
            });
        scan_task = lowest.map(|t| t.decl.name.name.as_str());
    }
    let mut mapped =
        Mapped { tasks: Vec::new(), programs: Vec::new(), scan_period_ms: None, notes: Vec::new() };
    let name = &conf.name.name;
    let mut numbers = tasks.iter().map(|t| t.number).collect::<Vec<u8>>();
    for task in read.iter().filter(|t| !t.clash) {
        let tname = task.decl.name.name.as_str();
        let iec = format!("configuration {name}: TASK {tname}");
        // A task no PROGRAM runs in has nothing to run: not scheduled (CODESYS keeps such a
        // task and runs nothing in it; an engine task has at least one program).
        let used =
            decls.iter().any(|d| d.task.as_ref().is_some_and(|n| task.decl.name.is(&n.name)));
        if !used {
            mapped.notes.push(format!("{iec} → no PROGRAM runs in it: not scheduled"));
            continue;
        }
        // A task of plcd's own: the lowest number of `kind`'s range the config leaves free.
        let mut add = |kind: TaskKind, errors: &mut Vec<Diagnostic>| {
            let (range, what) = match kind {
                TaskKind::Device { .. } => (16..=23, "device"),
                _ => (0..=7, "cycle"),
            };
            let (first, last) = (*range.start(), *range.end());
            let Some(number) = range.clone().find(|n| !numbers.contains(n)) else {
                let msg = format!("no {what} task number is left ({first} to {last})");
                error(errors, task.decl.name.span, msg);
                return None;
            };
            numbers.push(number);
            let priority = (2 + task.priority).min(*TaskConfig::PRIORITY.end());
            mapped.tasks.push(TaskConfig {
                name: tname.to_string(),
                number,
                priority,
                kind,
                max_exec_ms: None,
                line: entry.line,
                col: entry.col,
            });
            Some((number, priority))
        };
        if let Some((device, named)) = &task.single {
            // A device task: plcd samples the bit after each scan, as an IEC scheduler samples
            // SINGLE (an io task would need a hardware contact, P0000 to P0007).
            let kind = TaskKind::Device { device: *device, condition: DeviceCondition::Rising };
            let Some((number, priority)) = add(kind, &mut errors) else { continue };
            let bit = if named.starts_with('%') {
                format!("{device} ({named})")
            } else {
                format!("{device} (`{named}`)")
            };
            mapped.notes.push(format!(
                "{iec} → device task {number}, on each rising edge of {bit}, priority {priority}"
            ));
            continue;
        }
        match task.interval_ms {
            Some(ms) if scan_task != Some(tname) => {
                let kind = TaskKind::Cycle { interval_ms: ms };
                let Some((number, priority)) = add(kind, &mut errors) else { continue };
                mapped.notes.push(format!(
                    "{iec} → cycle task {number}, every {ms} ms, priority {priority}"
                ));
            }
            Some(ms) => {
                let period = if scan_period_ms == 0 {
                    mapped.scan_period_ms = Some(ms);
                    format!("every {ms} ms")
                } else {
                    format!("every {scan_period_ms} ms ([plc] scan_period_ms)")
                };
                mapped.notes.push(format!("{iec} → the scan, {period} (the lowest-priority task)"));
            }
            None => mapped.notes.push(format!("{iec} → the scan")),
        }
    }
    for decl in decls {
        let iname = &decl.name.name;
        if programs.iter().any(|p| p.name.eq_ignore_ascii_case(iname))
            || mapped.programs.iter().any(|p| p.name.eq_ignore_ascii_case(iname))
        {
            error(
                &mut errors,
                decl.name.span,
                format!("program `{iname}` is already a program of the project"),
            );
            continue;
        }
        let task = match &decl.task {
            None => TaskRef::Scan,
            Some(t) => match read.iter().find(|r| r.decl.name.is(&t.name)) {
                None => {
                    error(
                        &mut errors,
                        t.span,
                        format!("`{}` is not a TASK of the configuration", t.name),
                    );
                    continue;
                }
                Some(r) if continuous(r) || scan_task == Some(r.decl.name.name.as_str()) => {
                    TaskRef::Scan
                }
                Some(r) => TaskRef::Named(r.decl.name.name.clone()),
            },
        };
        mapped.notes.push(format!(
            "configuration {name}: PROGRAM {iname} : {} → program \"{iname}\" in {}",
            decl.pou.name,
            match &task {
                TaskRef::Named(t) => format!("task \"{t}\""),
                _ => "the scan".to_string(),
            }
        ));
        mapped.programs.push(ProgramConfig {
            name: iname.clone(),
            file: entry.file.clone(),
            resolved: entry.resolved.clone(),
            task,
            language: Language::StructuredText,
            pou: Some(decl.pou.name.clone()),
            configured: true,
            line: entry.line,
            col: entry.col,
        });
    }
    // VAR_CONFIG's devices (the compile checks the entries and binds the variables)
    for var in &conf.var_config {
        let Some(location) = &var.location else { continue };
        let device = match iec.resolve(&location.name) {
            Ok(Some(direct)) => Some(direct.to_string()),
            _ => None,
        };
        if let Some(device) = device {
            let path: Vec<&str> = var.path.iter().map(|id| id.name.as_str()).collect();
            mapped.notes.push(format!(
                "configuration {name}: VAR_CONFIG {} AT %{} → {device}",
                path.join("."),
                location.name
            ));
        }
    }
    if mapped.programs.is_empty() && errors.is_empty() {
        error(
            &mut errors,
            conf.span,
            format!("configuration `{name}` declares no PROGRAM instance"),
        );
    }
    if errors.is_empty() {
        Ok(mapped)
    } else {
        Err(errors)
    }
}

/// Whether `text` may hold a configuration (a cheap look before parsing a program file twice).
pub fn may_hold_one(text: &str) -> bool {
    text.as_bytes().windows(13).any(|w| w.eq_ignore_ascii_case(b"CONFIGURATION"))
}

/// The configuration of a parsed file, if it has one; a second one is an error.
pub fn of_file<'a>(
    file: &'a ast::File,
    path: &Path,
) -> Result<Option<&'a ast::Configuration>, Diagnostic> {
    let mut found = file.items.iter().filter_map(|i| match i {
        ast::Item::Configuration(c) => Some(c),
        _ => None,
    });
    let first = found.next();
    match found.next() {
        Some(second) => Err(Diagnostic::new(
            path,
            second.span.line,
            second.span.col,
            "a file holds one CONFIGURATION".to_string(),
        )),
        None => Ok(first),
    }
}

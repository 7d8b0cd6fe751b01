//! What `plcd check` shows of the `[iec]` layout (`device::iec`): the layout in effect and,
//! for each variable the project's Structured Text declarations locate at an IEC direct
//! address and each direct address a configuration names (a program instance's argument, a
//! TASK's SINGLE), the device it lands on (docs/ST.md, "Direct addresses"); and what the
//! config's `[iec.variables]` and `[iec.addresses]` bound and placed ([`config_notes`]).

use std::path::Path;

use crate::config::IecConfig;
use crate::device::iec::{Full, IecLayout, MultiLevel};
use crate::diag::{Diagnostic, Warning};
use crate::st::ast;

/// What `plcd check` shows of the layout for a project's Structured Text `files`: nothing when
/// no declaration locates a variable at an IEC direct address and no configuration names one;
/// else the layout (a line per image) and, for each such variable or configuration value, the
/// device it lands on (`main.st:5: Main.lamp AT %QX0.0 → P0640`, `main.st:9: presses.many =>
/// %QX0.5 → P0645`, `Main.code AT %QB1 → P064 (high byte)`; a located array at its first
/// device). `shown` gives a file's name as
/// printed.
pub fn check_notes(
    files: &[ast::File],
    layout: &IecLayout,
    shown: impl Fn(&std::path::Path) -> String,
) -> Vec<String> {
    let mut located = Vec::new();
    for file in files {
        let sites = sites(file);
        for (name, how, loc) in sites {
            let Ok(Some(direct)) = layout.resolve(&loc.name) else { continue };
            located.push(format!(
                "iec: {}:{}: {name}{how} %{} → {}",
                shown(&file.path),
                loc.span.line,
                loc.name,
                direct
            ));
        }
    }
    if located.is_empty() {
        return located;
    }
    let mut out = vec![format!(
        "iec: the {} layout ([iec] preset), docs/ST.md \"Direct addresses\":",
        layout.preset.name()
    )];
    out.extend(layout.describe().into_iter().map(|line| format!("iec:   {line}")));
    out.extend(located);
    out
}

/// Every direct address `file` names, with the name of what names it and how (` AT`, ` :=`,
/// ` =>`): its located variables, its configurations' `VAR_CONFIG` entries, TASK properties
/// and program instances' arguments.
fn sites(file: &ast::File) -> Vec<(String, &'static str, &ast::Ident)> {
    // (the variable's name as tools show it, how it names the address, the address)
    let mut sites: Vec<(String, &str, &ast::Ident)> = Vec::new();
    let mut configs = Vec::new();
    for item in &file.items {
        match item {
            ast::Item::Pou(pou) => located_in(Some(&pou.name.name), &pou.vars, &mut sites),
            ast::Item::Globals(block) => located_in(None, std::slice::from_ref(block), &mut sites),
            ast::Item::Configuration(conf) => {
                located_in(None, &conf.globals, &mut sites);
                configs.push(conf);
            }
            _ => {}
        }
    }
    for var in configs.iter().flat_map(|c| &c.var_config) {
        if let Some(loc) = &var.location {
            let path: Vec<&str> = var.path.iter().map(|i| i.name.as_str()).collect();
            sites.push((path.join("."), " AT", loc));
        }
    }
    for resource in configs.iter().flat_map(|c| &c.resources) {
        for task in &resource.tasks {
            for (property, value) in &task.properties {
                let ast::ConfigValue::Location(loc) = value else { continue };
                let name = format!("TASK {} {}", task.name.name, property.name);
                sites.push((name, " :=", loc));
            }
        }
        for program in &resource.programs {
            for arg in &program.args {
                let ast::ConfigValue::Location(loc) = &arg.value else { continue };
                let how = if arg.output { " =>" } else { " :=" };
                sites.push((format!("{}.{}", program.name.name, arg.name.name), how, loc));
            }
        }
    }
    sites
}

/// What `plcd check` shows of the config's `[iec.variables]` and `[iec.addresses]`, for a
/// project whose Structured Text `files` compiled with them: a line for each binding
/// (`config: [iec.variables] main.lamp AT %QX0.3 → P0643`) and for each placed address
/// something names (`config: [iec.addresses] %IX100.0.0 → %IX4.0 → P0020`), and a warning at
/// each entry of `[iec.addresses]` nothing names, in the config file `config` (likely a key
/// mistyped, which a load would otherwise hide: it places nothing).
pub fn config_notes(
    files: &[ast::File],
    iec: &IecConfig,
    config: &Path,
) -> (Vec<String>, Vec<Warning>) {
    let device = |text: &str| match iec.layout.full(text) {
        Ok(Full::Iec(direct)) => Some(direct.to_string()),
        Ok(Full::Device(address)) => Some(address.to_string()),
        Err(_) => None,
    };
    let mut notes = Vec::new();
    for v in &iec.variables {
        let Some(device) = device(&v.address) else { continue };
        let path = v.path.join(".");
        notes.push(format!("config: [iec.variables] {path} AT %{} → {device}", v.address));
    }
    // every address a source or the config names, multi-level ones kept
    let mut named: Vec<MultiLevel> = Vec::new();
    for file in files {
        named.extend(sites(file).iter().filter_map(|(_, _, loc)| MultiLevel::of(&loc.name)));
        let accesses = file.items.iter().flat_map(|item| match item {
            ast::Item::Configuration(c) => &c.access[..],
            ast::Item::Pou(p) => &p.access[..],
            _ => &[],
        });
        let parts = accesses.flat_map(|a| &a.path);
        named.extend(parts.filter_map(|part| MultiLevel::of(part.name.strip_prefix('%')?)));
    }
    named.extend(iec.variables.iter().filter_map(|v| MultiLevel::of(&v.address)));
    let mut warnings = Vec::new();
    for entry in &iec.addresses {
        let key = &entry.key;
        if named.contains(key) {
            let Some(device) = device(&key.to_string()) else { continue };
            let target = entry.target.strip_prefix('%').unwrap_or(&entry.target);
            let at = match target.eq_ignore_ascii_case(&device) {
                true => String::new(),
                false => format!(" %{target} →"),
            };
            notes.push(format!("config: [iec.addresses] {key} →{at} {device}"));
        } else {
            let msg = format!(
                "iec.addresses {:?}: no declaration, VAR_CONFIG, configuration, access path or [iec.variables] entry of the project names `{key}`",
                entry.written
            );
            warnings.push(Warning(Diagnostic::new(config, entry.line, entry.col, msg)));
        }
    }
    (notes, warnings)
}

/// The located variables of `blocks` (of the POU `owner`), by the names tools show them under.
fn located_in<'a>(
    owner: Option<&str>,
    blocks: &'a [ast::VarBlock],
    sites: &mut Vec<(String, &'static str, &'a ast::Ident)>,
) {
    for decl in blocks.iter().flat_map(|b| &b.decls) {
        let Some(loc) = &decl.location else { continue };
        for name in &decl.names {
            let name = owner.map_or(name.name.clone(), |o| format!("{o}.{}", name.name));
            sites.push((name, " AT", loc));
        }
    }
}

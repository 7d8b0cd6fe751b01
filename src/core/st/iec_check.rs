//! What `plcd check` shows of the `[iec]` layout (`device::iec`): the layout in effect and,
//! for each variable the project's Structured Text declarations locate at an IEC direct
//! address and each direct address a configuration names (a program instance's argument, a
//! TASK's SINGLE), the device it lands on (docs/ST.md, "Direct addresses").

use crate::device::iec::IecLayout;
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
        // (the variable's name as tools show it, how it names the address, the address)
        let mut sites: Vec<(String, &str, &ast::Ident)> = Vec::new();
        let mut configs = Vec::new();
        for item in &file.items {
            match item {
                ast::Item::Pou(pou) => located_in(Some(&pou.name.name), &pou.vars, &mut sites),
                ast::Item::Globals(block) => {
                    located_in(None, std::slice::from_ref(block), &mut sites)
                }
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

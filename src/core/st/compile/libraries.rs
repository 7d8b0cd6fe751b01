//! The system libraries of `[st] system_libraries` in a compile ([`crate::st::libraries`] owns
//! their sources): parsed from the binary, appended after the project's files, and their names
//! made namespaces (`Tc2_System.MEMCPY`). The checker treats their files as plcd's own, as it
//! treats the prelude: POUs checked only when called, no habits, no warnings.
//!
//! The project comes first, as TwinCAT resolves it: a library's TYPE, POU or global that the
//! project declares too is renamed `Library.Name` here, before anything reads the trees, so
//! that the plain name is the project's and the qualified one (`Tc2_System.MEMSET`) still the
//! library's (`compile::qualified` keeps such a name whole).

use std::collections::HashSet;
use std::path::Path;

use crate::diag::Diagnostic;
use crate::st::ast;
use crate::st::libraries::SystemLibraries;

/// The project's files followed by the libraries' sources, and the names (`tc2_system.memset`,
/// lower case) of the library declarations renamed because the project declares the plain
/// name; `None` without libraries (the project's files are then used as they are, not copied).
pub(super) fn with_libraries(
    files: &[ast::File],
    libraries: SystemLibraries,
    diags: &mut Vec<Diagnostic>,
) -> Option<(Vec<ast::File>, HashSet<String>)> {
    if libraries.is_empty() {
        return None;
    }
    let project: HashSet<String> = files.iter().flat_map(declared).collect();
    let mut renamed = HashSet::new();
    let mut all = files.to_vec();
    for library in libraries.iter() {
        for (path, text) in library.sources() {
            let (mut file, errors) = crate::st::syntax::parse_file(Path::new(path), text);
            diags.extend(errors.0);
            for id in declarations(&mut file) {
                if project.contains(&id.name.to_ascii_lowercase()) {
                    id.name = format!("{}.{}", library.name(), id.name);
                    renamed.insert(id.name.to_ascii_lowercase());
                }
            }
            all.push(file);
        }
    }
    Some((all, renamed))
}

/// The names of a file's TYPEs, POUs, interfaces and globals, lower case.
fn declared(file: &ast::File) -> Vec<String> {
    let mut names = Vec::new();
    for item in &file.items {
        match item {
            ast::Item::Pou(p) => names.push(p.name.name.to_ascii_lowercase()),
            ast::Item::Type(t) => names.push(t.name.name.to_ascii_lowercase()),
            ast::Item::Interface(i) => names.push(i.name.name.to_ascii_lowercase()),
            ast::Item::Globals(b) => global_names(b, &mut names),
            ast::Item::Configuration(c) => {
                c.globals.iter().for_each(|b| global_names(b, &mut names))
            }
            ast::Item::Action { .. } => {}
        }
    }
    names
}

fn global_names(block: &ast::VarBlock, names: &mut Vec<String>) {
    let all = block.decls.iter().flat_map(|d| &d.names);
    names.extend(all.map(|id| id.name.to_ascii_lowercase()));
}

/// The declaring names of a library file's TYPEs, POUs, interfaces and globals.
fn declarations(file: &mut ast::File) -> Vec<&mut ast::Ident> {
    let mut ids = Vec::new();
    for item in &mut file.items {
        match item {
            ast::Item::Pou(p) => ids.push(&mut p.name),
            ast::Item::Type(t) => ids.push(&mut t.name),
            ast::Item::Interface(i) => ids.push(&mut i.name),
            ast::Item::Globals(b) => ids.extend(b.decls.iter_mut().flat_map(|d| &mut d.names)),
            ast::Item::Configuration(_) | ast::Item::Action { .. } => {}
        }
    }
    ids
}

/// How many files [`with_libraries`] appends.
pub(super) fn file_count(libraries: SystemLibraries) -> usize {
    libraries.iter().map(|l| l.sources().len()).sum()
}

/// `[st] namespaces` and the names of the libraries and their inner namespaces.
pub(super) fn namespaces(project: &[String], libraries: SystemLibraries) -> Vec<String> {
    let mut all = project.to_vec();
    for name in libraries.iter().flat_map(|l| l.namespaces()) {
        if !all.iter().any(|n| n.eq_ignore_ascii_case(name)) {
            all.push((*name).to_string());
        }
    }
    all
}

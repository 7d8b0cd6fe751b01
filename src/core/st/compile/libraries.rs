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
use crate::st::libraries::{self, SystemLibraries};

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
        for (path, text) in libraries::sources(library) {
            let (mut file, errors) = crate::st::syntax::parse_file(Path::new(path), text);
            diags.extend(errors.0);
            for (key, id) in declarations(&mut file) {
                if project.contains(&key) {
                    id.name = format!("{}.{}", library.name(), id.name);
                    renamed.insert(id.name.to_ascii_lowercase());
                }
            }
            all.push(file);
        }
    }
    Some((all, renamed))
}

/// Whether `id` names the result of the FUNCTION `function` in its own body: its name, or,
/// for a library's FUNCTION renamed `Library.Name` above, the plain `Name` its source writes
/// (`MEMSET := 0;` in `Tc2_System.MEMSET`); no project name has a dot.
pub(super) fn is_own_name(id: &ast::Ident, function: &str) -> bool {
    id.is(function) || function.rsplit_once('.').is_some_and(|(_, plain)| id.is(plain))
}

/// The names of a file's TYPEs, POUs and interfaces (`"t:name"`) and globals (`"g:name"`),
/// lower case: a global may have a block's name (`GetCpuCounter : GETCPUCOUNTER`), as in
/// TwinCAT, where variables and types are named apart.
fn declared(file: &ast::File) -> Vec<String> {
    let mut names = Vec::new();
    for item in &file.items {
        match item {
            ast::Item::Pou(p) => names.push(type_key(&p.name)),
            ast::Item::Type(t) => names.push(type_key(&t.name)),
            ast::Item::Interface(i) => names.push(type_key(&i.name)),
            ast::Item::Globals(b) => global_keys(b, &mut names),
            ast::Item::Configuration(c) => {
                c.globals.iter().for_each(|b| global_keys(b, &mut names))
            }
            ast::Item::Action { .. } => {}
        }
    }
    names
}

fn type_key(id: &ast::Ident) -> String {
    format!("t:{}", id.name.to_ascii_lowercase())
}

fn global_key(id: &ast::Ident) -> String {
    format!("g:{}", id.name.to_ascii_lowercase())
}

fn global_keys(block: &ast::VarBlock, names: &mut Vec<String>) {
    names.extend(block.decls.iter().flat_map(|d| &d.names).map(global_key));
}

/// The declaring names of a library file's TYPEs, POUs, interfaces and globals, each with its
/// key (`declared`).
fn declarations(file: &mut ast::File) -> Vec<(String, &mut ast::Ident)> {
    let mut ids = Vec::new();
    for item in &mut file.items {
        match item {
            ast::Item::Pou(p) => ids.push((type_key(&p.name), &mut p.name)),
            ast::Item::Type(t) => ids.push((type_key(&t.name), &mut t.name)),
            ast::Item::Interface(i) => ids.push((type_key(&i.name), &mut i.name)),
            ast::Item::Globals(b) => {
                let names = b.decls.iter_mut().flat_map(|d| &mut d.names);
                ids.extend(names.map(|id| (global_key(id), id)));
            }
            ast::Item::Configuration(_) | ast::Item::Action { .. } => {}
        }
    }
    ids
}

/// How many files [`with_libraries`] appends.
pub(super) fn file_count(libraries: SystemLibraries) -> usize {
    libraries.iter().map(|l| libraries::sources(l).len()).sum()
}

/// The namespace of CODESYS's Base Interfaces library, whose part plcd has built in, the type
/// classes (`IBaseLibrary.TypeClass`, `IBaseLibrary.TYPE_BIT`): a namespace of every project,
/// as every TwinCAT project references the library, whether a `.plcproj` says so or not.
const BASE_INTERFACES: &str = "IBaseLibrary";

/// `[st] namespaces`, the names of the libraries and their inner namespaces, and
/// [`BASE_INTERFACES`].
pub(super) fn namespaces(project: &[String], libraries: SystemLibraries) -> Vec<String> {
    let mut all = project.to_vec();
    let shipped = libraries.iter().flat_map(libraries::namespaces).copied();
    for name in shipped.chain([BASE_INTERFACES]) {
        if !all.iter().any(|n| n.eq_ignore_ascii_case(name)) {
            all.push(name.to_string());
        }
    }
    all
}

//! Structured Text compiler: resolves names and types across every file of a project, checks
//! (every error at once), lays out variable memory and generates VM code.
//!
//! - [`types`]: the type model and IEC's implicit conversions;
//! - `ctx`: the compiler's state, names and suggestions;
//! - `decl`: declarations: types, globals, POU interfaces, memory layout, initial images,
//!   located variables (what an IEC direct address names is `device::iec`'s, by `[iec]`);
//! - `expr`, `stmt`, `stdlib`, `refs` (references and pointers): checking into a typed tree;
//! - `emit`: the typed tree to ops; `link` (here): one program per instance, symbols;
//! - `referents`: what each reference type points to, as tools name it (`main.r^`);
//! - `trunc`: `TRUNC` typed by its use where a `DINT` would not do (matiec);
//! - `short_circuit`: `AND_THEN` and `OR_ELSE`, the right operand skipped when the left
//!   decides;
//! - `union`: CODESYS's `UNION`, a struct whose members share their bytes;
//! - `jumps`: CODESYS's `JMP` and labels in ST, bound and checked before a body is;
//! - `sfc`: each POU's Sequential Function Chart → variables and statements, before the rest;
//! - `oop`: methods, properties, EXTENDS, interfaces, and the dispatch of their calls on a
//!   hidden type tag of the instance;
//! - `implicit`: CODESYS's implicit conversions that may change a value (another sign, a
//!   narrower integer, an enumeration's number), accepted with a warning;
//! - `for_written`: CODESYS's FOR variable written in the loop's body, with a warning;
//! - `inout`: an FB instance's VAR_IN_OUT named outside its body, bound by `inst.io := v`, or
//!   left out of a call (matiec);
//! - `instance_args`: a configuration's program instance arguments, as copies in its code;
//! - `var_config`: a configuration's `VAR_CONFIG`, variables at partly specified addresses
//!   bound to devices.
//!
//! Choices (docs/ST.md repeats them):
//! - Globals are visible in every POU without VAR_EXTERNAL (as in CODESYS); a VAR_EXTERNAL
//!   must name a VAR_GLOBAL of the same type.
//! - Enumerations are stored as DINT unless they declare an integer base type (`INT (A, B)`);
//!   their default is the first value (or the declared initial value).
//! - A subrange computes as its base type; constants assigned to it are checked against it.
//! - FOR: the bound and the step are evaluated once, at entry; the loop ends without ever
//!   wrapping around (`FOR i := 0 TO 32767` on an INT ends); after the loop the variable holds
//!   the last value the body ran with (its initial value when the body never ran). A constant
//!   step of 0 is refused; a variable step of 0 loops for ever (the step budget ends the scan).
//! - Positional arguments go to VAR_INPUT and VAR_IN_OUT in declaration order; outputs only
//!   with `=>`. Named arguments may follow positional ones (TwinCAT; `mixed_args`), not
//!   precede them.
//! - FUNCTION variables are initialized at each call; `VAR_TEMP` of a PROGRAM or FB at each
//!   execution.
//! - EN/ENO: an implicit EN FALSE skips the whole call; `v := F(EN := c, …)` with c FALSE is
//!   no assignment, and such a call inside an expression is its result's initial value. ENO is
//!   a variable of a FUNCTION or FB only when something may read it (`PouInfo::eno`).
//! - What is accepted of CODESYS's habits beyond the standard: `codesys`.
//! - References (`REF_TO`, `POINTER TO`, `REFERENCE TO`) never convert to or from integers (a
//!   `POINTER TO` and a 64-bit number do, a CODESYS habit: `refs::pointer_integer`);
//!   `POINTER TO`s convert to each other whatever they point to (as CODESYS); pointer
//!   arithmetic counts bytes, `p - q` is a `DINT` of bytes; every access through a reference
//!   is checked at run time.

mod access_paths;
mod action_dispatch;
mod assign_expr;
mod bit;
mod bool_bytes;
mod calendar;
mod class;
mod codesys;
mod constant_instance;
mod ctx;
mod decl;
mod emit;
mod expr;
mod fb_config;
mod fb_exit;
mod fb_init;
mod fb_value;
mod for_element;
mod for_written;
mod generic;
mod generic_constants;
mod heap;
mod implicit;
mod inout;
mod instance_args;
mod instance_init;
mod jumps;
mod libraries;
mod lifecycle;
mod local_init;
mod memory_limit;
mod method_eno;
mod method_vars;
mod mixed_args;
mod oop;
mod qualified;
mod query;
mod ref_init;
mod ref_init_types;
mod referents;
mod refs;
mod sfc;
mod short_circuit;
mod stdlib;
mod stmt;
mod trunc;
mod type_class_int;
pub mod types;
mod union;
mod var_config;
mod varlen;

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use super::ast;
use crate::diag::{Diagnostic, Diagnostics, Warning};
use crate::lang::{Language, Op, Place, Program, Variables, EVAL_DEPTH, ST_CALL_DEPTH};
use crate::st::ast::{PouKind, VarKind};
use crate::st::dialect::{Dialect, Habit};
use crate::symbols::{ArraySymbol, Symbols};
use crate::value::{Pointer, Space, Symbol, ValueType};

use ctx::{Ctx, Storage};
use types::Ty;

pub use decl::iec_address;

/// The standard function blocks, written in Structured Text.
const PRELUDE: &str = include_str!("prelude.st");
const PRELUDE_PATH: &str = "<prelude>";

/// One `[[program]]` of Structured Text: the instance to create.
#[derive(Debug, Clone, Copy)]
pub struct Instance<'a> {
    /// The instance name, the prefix of its variables (`main` → `main.speed`).
    pub name: &'a str,
    /// The PROGRAM to instantiate; `None` when its file declares exactly one.
    pub pou: Option<&'a str>,
    /// The `.st` file the `[[program]]` names.
    pub file: &'a Path,
    /// Where the `[[program]]` is in the config, for diagnostics about `pou`.
    pub config: &'a Path,
    pub line: u32,
    pub col: u32,
}

/// A compiled project's Structured Text.
#[derive(Debug, Clone)]
pub struct Compiled {
    /// One program per instance, in the order given.
    pub programs: Vec<Program>,
    pub variables: Variables,
    /// What was accepted with a warning (`implicit`), in file and line order, once each.
    pub warnings: Vec<Warning>,
}

/// Compiles every instance against the declarations of all `files`, with the CODESYS habits
/// accepted.
pub fn compile(files: &[ast::File], instances: &[Instance<'_>]) -> Result<Compiled, Diagnostics> {
    compile_with(files, instances, Dialect::default())
}

/// [`compile`], reading the sources as `dialect` says (`[st] strict`).
pub fn compile_with(
    files: &[ast::File],
    instances: &[Instance<'_>],
    dialect: Dialect,
) -> Result<Compiled, Diagnostics> {
    compile_configured(files, instances, &[], dialect)
}

/// [`compile_with`], with the declaration in its file's `CONFIGURATION` of each instance that
/// one declares (`PROGRAM i : P (a := x, b => y);`), in the order of `instances` (none past
/// the end of `configured`): each such instance's code assigns its inputs before its body and
/// copies its outputs after it, and the configuration's `VAR_CONFIG` binds its variables.
pub fn compile_configured(
    files: &[ast::File],
    instances: &[Instance<'_>],
    configured: &[Option<&ast::ProgramDecl>],
    dialect: Dialect,
) -> Result<Compiled, Diagnostics> {
    compile_in_namespaces(files, instances, configured, dialect, &[])
}

/// [`compile_configured`], the project's sources being the libraries of `namespaces` (`[st]
/// namespaces`): `NS.Name` names the project's `Name` (`compile::qualified`).
pub fn compile_in_namespaces(
    files: &[ast::File],
    instances: &[Instance<'_>],
    configured: &[Option<&ast::ProgramDecl>],
    dialect: Dialect,
    namespaces: &[String],
) -> Result<Compiled, Diagnostics> {
    compile_project(files, instances, configured, dialect, namespaces, None)
}

/// What the config binds in a project's Structured Text: `[iec.variables]`, written in the
/// config file `path`.
#[derive(Debug, Clone, Copy)]
pub struct ConfigBindings<'a> {
    pub path: &'a Path,
    pub variables: &'a [crate::config::IecVariable],
}

/// [`compile_in_namespaces`], with the variables the config binds (`bindings`): each bound as
/// a configuration's `VAR_CONFIG … AT` entry binds it (`var_config`), after the
/// configurations' own, its errors at the config's key.
pub fn compile_project(
    files: &[ast::File],
    instances: &[Instance<'_>],
    configured: &[Option<&ast::ProgramDecl>],
    dialect: Dialect,
    namespaces: &[String],
    bindings: Option<ConfigBindings<'_>>,
) -> Result<Compiled, Diagnostics> {
    let declaration = |k: usize| configured.get(k).copied().flatten();
    let config_entries = bindings.map(|b| var_config::config_entries(b.variables));
    let config_entries = config_entries.unwrap_or_default();
    // the config as a file of no items, where the errors about its entries are
    let config_file = ast::File {
        path: bindings.map(|b| b.path.to_path_buf()).unwrap_or_default(),
        items: Vec::new(),
        habits: Vec::new(),
        list_name: None,
        qualified_only: Default::default(),
    };
    let (prelude, prelude_diags) = super::syntax::parse_file(Path::new(PRELUDE_PATH), PRELUDE);
    let mut diags: Vec<Diagnostic> = prelude_diags.0;
    // the system libraries after the project's files: the project's declarations come first
    // and win (`libraries.rs`); lowered with them, so that their names qualify as the
    // project's do
    let shipped = dialect.libraries.with_dependencies();
    let with_libraries = libraries::with_libraries(files, shipped, &mut diags);
    let (files, renamed): (&[ast::File], _) = match &with_libraries {
        Some((all, renamed)) => (all, Some(renamed)),
        None => (files, None),
    };
    let namespaces = libraries::namespaces(namespaces, shipped);
    let namespaces = &namespaces[..];
    let lowered = sfc::lower(files, &mut diags);
    let lowered = generic_constants::lower(lowered, namespaces, &mut diags);
    // qualified names first: a variable's type written `NS.T` is the `T` whose copy a binding
    // of one of its members makes
    let lowered = qualified::lower(lowered, namespaces, renamed, &mut diags);
    let (lowered, program_copies) =
        fb_config::lower(lowered, instances, declaration, &dialect.iec, &config_entries);
    let lowered = method_vars::lower(lowered);
    let (lowered, local_values) = local_init::lower(lowered);
    let lowered = ref_init::lower(lowered, &mut diags);
    let lowered = fb_exit::finish_program_temps(lowered);
    let (lowered, instance_values) = instance_init::lower(lowered);
    let lowered = fb_init::lower(lowered, &mut diags);
    let lowered = fb_exit::lower(lowered, &mut diags);
    let lowered = heap::lower(lowered, dialect.heap_bytes, &mut diags);
    let mut refs: Vec<&ast::File> = lowered.iter().map(|f| &**f).collect();
    let library_files = files.len() - libraries::file_count(shipped)..files.len();
    refs.push(&prelude);
    let prelude_file = refs.len() - 1;
    refs.push(&config_file);
    let config_at = refs.len() - 1;
    let mut cx = Ctx {
        files: refs,
        types: types::Types::default(),
        diags: Vec::new(),
        warnings: Vec::new(),
        type_decls: Vec::new(),
        type_names: HashMap::new(),
        pous: Vec::new(),
        pou_names: HashMap::new(),
        globals: Vec::new(),
        global_names: HashMap::new(),
        global_blocks: Vec::new(),
        image: Vec::new(),
        retained: Vec::new(),
        persistent: Vec::new(),
        located_init: Vec::new(),
        memory_exceeded: false,
        enum_values: HashMap::new(),
        in_prelude: false,
        eno_read: files.iter().any(decl::reads_eno),
        prelude_file,
        library_files,
        for_vars: Vec::new(),
        for_written: Vec::new(),
        loop_depth: 0,
        jumps: Default::default(),
        dialect,
        oop: oop::Tables::default(),
    };
    // the habits the parser accepted, and the lowering of instances as initial values
    for (f, file) in files.iter().enumerate() {
        for noted in &file.habits {
            cx.habit(noted.habit, f, noted.span);
        }
    }
    for (f, span) in instance_values {
        cx.habit(Habit::InstanceInitialValue, f, span);
    }
    for (f, span) in local_values {
        cx.habit(Habit::VariableInitialValue, f, span);
    }
    cx.collect();
    // the PROGRAMs copied for a binding inside a FUNCTION_BLOCK instance (fb_config.rs)
    for (inst, copy) in instances.iter().zip(&program_copies) {
        let Some(copy) = copy else { continue };
        let named =
            |name: &str| (0..cx.pous.len()).find(|&p| cx.pous[p].name.eq_ignore_ascii_case(name));
        let original = inst
            .pou
            .and_then(named)
            .or_else(|| copy.rsplit_once('$').and_then(|(name, _)| named(name)));
        if let (Some(c), Some(o)) = (named(copy), original) {
            cx.pous[c].copy_of = Some(o);
        }
    }
    cx.link_hierarchy();
    cx.check_classes();
    cx.resolve_all();
    cx.check_oop();

    // the instances, in variable memory after the globals
    let mut placed: Vec<Option<(usize, u32)>> = Vec::new();
    for (inst, copy) in instances.iter().zip(&program_copies) {
        let pou = match copy {
            Some(copy) => (0..cx.pous.len()).find(|&p| cx.pous[p].name == *copy),
            None => pick_program(&mut cx, inst),
        };
        placed.push(pou.map(|p| {
            // Lent, not cloned: a PROGRAM's image is as large as its variables (a TcUnit
            // results array: 78 MB), and a clone would be a third copy at the compile's peak.
            let img = std::mem::take(&mut cx.pous[p].image);
            let (file, span) = (cx.pous[p].file, cx.pous[p].name_span());
            let at = cx.alloc_var(&img, file, span);
            cx.pous[p].image = img;
            (p, at)
        }));
    }

    // VAR_CONFIG, before any body names the variables it binds
    let mut configuration_files: Vec<usize> = Vec::new();
    for (k, inst) in instances.iter().enumerate() {
        let file = cx.files.iter().position(|f| f.path == inst.file);
        if let Some(f) =
            file.filter(|f| declaration(k).is_some() && !configuration_files.contains(f))
        {
            configuration_files.push(f);
        }
    }
    let mut sources: Vec<var_config::Bindings<'_>> = Vec::new();
    let mut configurations = Vec::new();
    for f in configuration_files {
        let file: &ast::File = cx.files[f];
        let Some(conf) = file.items.iter().find_map(|i| match i {
            ast::Item::Configuration(c) => Some(c),
            _ => None,
        }) else {
            continue;
        };
        let declared: Vec<var_config::Declared<'_>> = (0..instances.len())
            .filter(|&k| declaration(k).is_some() && instances[k].file == file.path)
            .map(|k| (instances[k].name, k))
            .collect();
        configurations.push((f, conf, declared.clone()));
        sources.push(var_config::Bindings {
            binder: var_config::Binder::VarConfig,
            file: f,
            entries: &conf.var_config,
            resources: var_config::resources(conf).collect(),
            declared,
        });
    }
    if !config_entries.is_empty() {
        // the config names any instance of the project, from any configuration's resource
        let files: &[&ast::File] = &cx.files;
        let resources = files.iter().flat_map(|f| &f.items).filter_map(|i| match i {
            ast::Item::Configuration(c) => Some(var_config::resources(c)),
            _ => None,
        });
        sources.push(var_config::Bindings {
            binder: var_config::Binder::Config,
            file: config_at,
            entries: &config_entries,
            resources: resources.flatten().collect(),
            declared: instances.iter().enumerate().map(|(k, i)| (i.name, k)).collect(),
        });
    }
    cx.apply_var_config(&sources, &mut placed);
    let mut access = Vec::new();
    for (f, conf, declared) in configurations {
        access.extend(cx.configuration_access_paths(f, conf, &declared, &placed));
    }
    access.extend(cx.program_access_paths(instances, &placed));
    let access = cx.named_access_paths(access, instances);

    // check every user POU; the prelude's and the system libraries' only when used
    let user: Vec<usize> =
        (0..cx.pous.len()).filter(|&p| !cx.is_shipped(cx.pous[p].file)).collect();
    let mut checked: Vec<(usize, Vec<stmt::TStmt>)> = Vec::new();
    for p in user {
        checked.push((p, check(&mut cx, p)));
    }
    let mut i = 0;
    while i < cx.pous.len() {
        // the prelude's and the libraries' POUs that user code calls, transitively
        let used = cx.pous.iter().any(|q| q.checked && q.callees.iter().any(|c| c.pou == i));
        if used && !cx.pous[i].checked {
            checked.push((i, check(&mut cx, i)));
            i = 0;
            continue;
        }
        i += 1;
    }
    // the configured instances' arguments, in the configuration's file
    let mut copies: Vec<Option<(usize, instance_args::Copies)>> = Vec::new();
    for (k, (inst, placed)) in instances.iter().zip(&placed).enumerate() {
        let given = declaration(k).map_or(&[][..], |d| &d.args[..]);
        let file = cx.files.iter().position(|f| f.path == inst.file);
        copies.push(match (placed, file) {
            (Some((p, _)), Some(file)) if !given.is_empty() => {
                Some((file, cx.check_instance_args(*p, file, given)))
            }
            _ => None,
        });
    }
    // Code once every body is checked: a body's entry depends on how the others call it
    // (`PouInfo::called_with_en`).
    for (p, body) in checked {
        let compiled = emit::compile_body(&mut cx, p, &body);
        cx.pous[p].body = Some(compiled);
    }
    let copies: Vec<Option<(emit::Body, emit::Body)>> = copies
        .into_iter()
        .map(|c| {
            c.map(|(file, c)| {
                let inputs = emit::compile_copies(&mut cx, file, &c.inputs);
                (inputs, emit::compile_copies(&mut cx, file, &c.outputs))
            })
        })
        .collect();
    check_recursion(&mut cx);

    if !cx.diags.is_empty() || !diags.is_empty() {
        diags.append(&mut cx.diags);
        return Err(sorted(diags));
    }

    let mut programs = Vec::new();
    let mut symbols = Symbols::default();
    for g in 0..cx.globals.len() {
        let v = cx.globals[g].clone();
        let at = match v.storage {
            Storage::Global(o) => Pointer { space: Space::Var, offset: o },
            Storage::Word(w) => Pointer { space: Space::Word, offset: u32::from(w) },
            Storage::Bit(b) => Pointer {
                space: Space::Bit,
                offset: u32::from(b.word) * 16 + b.mask.trailing_zeros(),
            },
            Storage::Byte(n) => Pointer { space: Space::Byte, offset: n },
            _ => continue,
        };
        leaves(&cx, &v.name, &v.ty, at, v.retain, v.constant, &mut symbols);
    }
    // VAR_STAT: one copy per POU, named after the POU
    for pou in cx.pous.iter().filter(|p| !cx.is_shipped(p.file) && p.copy_of.is_none()) {
        for v in pou.vars.iter().filter(|v| v.kind == VarKind::Static) {
            if let Storage::Global(o) = v.storage {
                let at = Pointer { space: Space::Var, offset: o };
                let name = format!("{}.{}", pou.name, v.name);
                leaves(&cx, &name, &v.ty, at, v.retain, v.constant, &mut symbols);
            }
        }
    }
    for ((inst, placed), copies) in instances.iter().zip(&placed).zip(&copies) {
        let (p, base) = placed.expect("no errors");
        let body = copies.as_ref().map(|(inputs, outputs)| {
            emit::with_copies(cx.pous[p].body.as_ref().expect("compiled"), inputs, outputs)
        });
        if let Err(d) = link(&cx, inst, p, body.as_ref(), base, &mut programs) {
            diags.push(d);
            continue;
        }
        let pou = &cx.pous[p];
        for v in &pou.vars {
            if matches!(v.kind, VarKind::Temp | VarKind::External | VarKind::InOut) {
                continue;
            }
            let at = match v.storage {
                Storage::Inst(o) => Pointer { space: Space::Var, offset: base + o },
                other => match device_pointer(other) {
                    Some(at) => at,
                    None => continue,
                },
            };
            let name = format!("{}.{}", inst.name, v.name);
            leaves(&cx, &name, &v.ty, at, v.retain, v.constant, &mut symbols);
        }
    }
    if !diags.is_empty() {
        return Err(sorted(diags));
    }
    let canonical = bool_bytes::canonical(&cx.types, &programs);
    for program in &mut programs {
        program.var_bools_canonical = canonical;
    }
    let mut retained = cx.retained.clone();
    let mut persistent = cx.persistent.clone();
    for (inst, placed) in instances.iter().zip(&placed) {
        let _ = inst;
        let (p, base) = placed.expect("no errors");
        for v in &cx.pous[p].vars {
            if let Storage::Inst(o) = v.storage {
                if v.kind == VarKind::Temp || v.by_ref {
                    continue;
                }
                retained_in(&cx, &v.ty, base + o, v.retain, |v| v.retain, &mut retained);
                retained_in(&cx, &v.ty, base + o, v.persistent, |v| v.persistent, &mut persistent);
            }
        }
    }
    retained.sort_unstable();
    persistent.sort_unstable();
    let referents = referents::referents(&cx);
    // The compile is over: the images of the POUs and types go before variable memory's own
    // is moved into its shared allocation, so that a load's peak holds two images at most.
    for pou in &mut cx.pous {
        pou.image = Vec::new();
    }
    let variables = Variables {
        initial: Arc::from(std::mem::take(&mut cx.image)),
        retained: merge_ranges(retained).into_boxed_slice(),
        persistent: merge_ranges(persistent).into_boxed_slice(),
        located_init: cx.located_init.clone().into_boxed_slice(),
        symbols,
        referents,
        access,
    };
    let warnings = sorted(std::mem::take(&mut cx.warnings)).0.into_iter().map(Warning).collect();
    Ok(Compiled { programs, variables, warnings })
}

fn sorted(mut d: Vec<Diagnostic>) -> Diagnostics {
    d.sort();
    d.dedup();
    Diagnostics(d)
}

fn merge_ranges(r: Vec<(u32, u32)>) -> Vec<(u32, u32)> {
    let mut out: Vec<(u32, u32)> = Vec::new();
    for (o, l) in r {
        if l == 0 {
            continue;
        }
        match out.last_mut() {
            Some((po, pl)) if *po + *pl >= o => *pl = (*pl).max(o + l - *po),
            _ => out.push((o, l)),
        }
    }
    out
}

/// The byte ranges of RETAIN variables inside a value at `at` (all of it when `all`): an FB
/// instance's RETAIN members, in it, in a struct member or in an array element at any depth.
/// `kept` says which variables: RETAIN ones (`PERSISTENT` ones are too), or `PERSISTENT` ones.
fn retained_in(
    cx: &Ctx<'_>,
    ty: &Ty,
    at: u32,
    all: bool,
    kept: fn(&ctx::VarInfo) -> bool,
    out: &mut Vec<(u32, u32)>,
) {
    if all {
        out.push((at, cx.types.size(ty)));
        return;
    }
    match ty {
        Ty::Fb(p) => {
            for v in &cx.pous[*p].vars {
                if let Storage::Inst(o) = v.storage {
                    if v.kind != VarKind::Temp && !v.by_ref {
                        retained_in(cx, &v.ty, at + o, kept(v), kept, out);
                    }
                }
            }
        }
        // a struct's members and an array's elements may be FB instances with RETAIN members
        Ty::Struct(s) => {
            for m in &cx.types.structs[*s].members {
                retained_in(cx, &m.ty, at + m.offset, false, kept, out);
            }
        }
        Ty::Array(a) => {
            // the ranges of one element, repeated for each: none for an array of values
            let mut element = Vec::new();
            retained_in(cx, &a.of, 0, false, kept, &mut element);
            if element.is_empty() {
                return;
            }
            for i in 0..a.count() as u32 {
                let base = at + i * a.elem_size;
                out.extend(element.iter().map(|&(o, len)| (base + o, len)));
            }
        }
        _ => {}
    }
}

fn check(cx: &mut Ctx<'_>, p: usize) -> Vec<stmt::TStmt> {
    cx.pous[p].checked = true;
    cx.check_pou_body(p)
}

/// The PROGRAM an instance names.
fn pick_program(cx: &mut Ctx<'_>, inst: &Instance<'_>) -> Option<usize> {
    let file = cx.files.iter().position(|f| f.path == inst.file);
    let programs: Vec<usize> = (0..cx.pous.len())
        .filter(|&p| {
            let pou = &cx.pous[p];
            pou.kind == PouKind::Program && Some(pou.file) == file && pou.copy_of.is_none()
        })
        .collect();
    let here = |msg: String| Diagnostic::new(inst.config, inst.line, inst.col, msg);
    let names = |cx: &Ctx<'_>| -> String {
        programs.iter().map(|&p| format!("`{}`", cx.pous[p].name)).collect::<Vec<_>>().join(", ")
    };
    match inst.pou {
        Some(name) => {
            match programs.iter().find(|&&p| cx.pous[p].name.eq_ignore_ascii_case(name)) {
                Some(&p) => Some(p),
                None => {
                    let msg = if programs.is_empty() {
                        format!(
                            "no PROGRAM `{name}` in `{}`: it declares no PROGRAM",
                            inst.file.display()
                        )
                    } else {
                        format!(
                            "no PROGRAM `{name}` in `{}` (it declares {})",
                            inst.file.display(),
                            names(cx)
                        )
                    };
                    cx.diags.push(here(msg));
                    None
                }
            }
        }
        None => match programs.len() {
            1 => Some(programs[0]),
            0 => {
                cx.diags.push(here(format!("`{}` declares no PROGRAM", inst.file.display())));
                None
            }
            _ => {
                let msg = format!(
                    "`{}` declares more than one PROGRAM ({}): name one with `pou`",
                    inst.file.display(),
                    names(cx)
                );
                cx.diags.push(here(msg));
                None
            }
        },
    }
}

/// Reports each cycle of direct calls once, at the call that closes it; checks the static
/// depth.
///
/// A cycle through a call dispatched at run time (a method through an interface, a method or
/// action a derived block replaces: [`ctx::Callee::dispatched`]) is not refused: whether it
/// recurs is the receivers' to decide (the observer's `next.Notify()` calls the same method
/// of another instance), as in CODESYS. The VM bounds it at run time: a call deeper than
/// [`ST_CALL_DEPTH`] is operation error 4210H, and the frames and evaluation stack are sized
/// for that depth (`link`, [`eval_stack_need`]).
fn check_recursion(cx: &mut Ctx<'_>) {
    const NEW: u8 = 0;
    const ON_PATH: u8 = 1;
    const DONE: u8 = 2;
    /// A depth-first walk from `p` over the calls `follow` takes: the longest chain of calls
    /// below each POU in `depth` (a call back into the path counts nothing), each call back
    /// into the path reported when `report`.
    #[allow(clippy::too_many_arguments)]
    fn visit(
        cx: &mut Ctx<'_>,
        p: usize,
        follow: fn(&ctx::Callee) -> bool,
        report: bool,
        state: &mut [u8],
        depth: &mut [usize],
        path: &mut Vec<usize>,
    ) {
        state[p] = ON_PATH;
        path.push(p);
        let callees = cx.pous[p].callees.clone();
        let mut d = 0;
        for callee in callees.iter().filter(|c| follow(c)) {
            let c = callee.pou;
            match state[c] {
                ON_PATH if report => {
                    let from = path.iter().position(|&x| x == c).unwrap_or(0);
                    let mut names: Vec<String> =
                        path[from..].iter().map(|&x| format!("`{}`", cx.pous[x].name)).collect();
                    names.push(format!("`{}`", cx.pous[c].name));
                    let file = cx.pous[p].file;
                    cx.error(file, callee.span, format!("recursive call: {}", names.join(" → ")));
                }
                ON_PATH => {}
                NEW => {
                    visit(cx, c, follow, report, state, depth, path);
                    d = d.max(depth[c]);
                }
                _ => d = d.max(depth[c]),
            }
        }
        depth[p] = d + usize::from(cx.pous[p].kind != PouKind::Program);
        path.pop();
        state[p] = DONE;
    }
    let n = cx.pous.len();
    let walk = |cx: &mut Ctx<'_>, follow: fn(&ctx::Callee) -> bool, report: bool| {
        let (mut state, mut depth) = (vec![NEW; n], vec![0usize; n]);
        for p in 0..n {
            if state[p] == NEW {
                visit(cx, p, follow, report, &mut state, &mut depth, &mut Vec::new());
            }
        }
        depth
    };
    // the recursion a check can prove: cycles of direct calls
    walk(cx, |c| !c.dispatched, true);
    let depth = walk(cx, |_| true, false);
    for (p, &d) in depth.iter().enumerate() {
        if cx.pous[p].kind == PouKind::Program && d > ST_CALL_DEPTH {
            let (file, span, name) =
                (cx.pous[p].file, cx.pous[p].name_span(), cx.pous[p].name.clone());
            cx.error(file, span, format!("`{name}` nests calls {d} deep (limit {ST_CALL_DEPTH})"));
        }
    }
}

/// One instance's program: its body (`own`, when its arguments' copies make it its own), then
/// the bodies it calls.
fn link(
    cx: &Ctx<'_>,
    inst: &Instance<'_>,
    p: usize,
    own: Option<&emit::Body>,
    base: u32,
    out: &mut Vec<Program>,
) -> Result<(), Diagnostic> {
    let body_of = |q: usize| match own {
        Some(body) if q == p => body,
        _ => cx.pous[q].body.as_ref().expect("compiled"),
    };
    // the POUs reachable from the program, in first-call order
    let mut order = vec![p];
    let mut i = 0;
    while i < order.len() {
        for c in &cx.pous[order[i]].callees {
            if !order.contains(&c.pou) {
                order.push(c.pou);
            }
        }
        i += 1;
    }
    let mut code: Vec<Op> = Vec::new();
    let mut lines: Vec<u32> = Vec::new();
    let mut statements: Vec<u32> = Vec::new();
    let mut consts: Vec<u64> = Vec::new();
    let mut starts: HashMap<usize, u32> = HashMap::new();
    let mut regions: Vec<(u32, PathBuf)> = Vec::new();
    let main_path = cx.path(cx.pous[p].file).to_path_buf();
    let mut current = main_path.clone();
    for &q in &order {
        let body = body_of(q);
        let start = code.len() as u32;
        starts.insert(q, start);
        let path = cx.path(cx.pous[q].file).to_path_buf();
        if path != current {
            regions.push((start, path.clone()));
            current = path;
        }
        let cbase = consts.len() as u32;
        consts.extend_from_slice(&body.consts);
        for op in &body.code {
            code.push(match *op {
                Op::Goto(t) => Op::Goto(t + start),
                Op::GotoIf { target, when } => Op::GotoIf { target: target + start, when },
                Op::PushConst(i) => Op::PushConst(i + cbase),
                other => other,
            });
        }
        lines.extend_from_slice(&body.lines);
        statements.extend(body.statements.iter().map(|&pc| pc + start));
        let s = start as usize;
        if q == p {
            for &r in &body.var_relocs {
                code[s + r] = match code[s + r] {
                    Op::Fetch { elem, at: Place::Var(o) } => {
                        Op::Fetch { elem, at: Place::Var(o + base) }
                    }
                    Op::Store { elem, at: Place::Var(o) } => {
                        Op::Store { elem, at: Place::Var(o + base) }
                    }
                    Op::AddrOf(Place::Var(o)) => Op::AddrOf(Place::Var(o + base)),
                    other => other,
                };
            }
        }
        for &r in &body.callee_relocs {
            let f = body.frame;
            code[s + r] = match code[s + r] {
                Op::Fetch { elem, at: Place::Frame(o) } => {
                    Op::Fetch { elem, at: Place::Frame(o + f) }
                }
                Op::Store { elem, at: Place::Frame(o) } => {
                    Op::Store { elem, at: Place::Frame(o + f) }
                }
                Op::AddrOf(Place::Frame(o)) => Op::AddrOf(Place::Frame(o + f)),
                Op::CallFn { target, frame } => Op::CallFn { target, frame: frame + f },
                Op::CallFb { target, frame } => Op::CallFb { target, frame: frame + f },
                other => other,
            };
        }
    }
    // call targets
    for &q in &order {
        let body = body_of(q);
        let s = starts[&q] as usize;
        for &(at, callee) in &body.calls {
            let t = starts[&callee];
            code[s + at] = match code[s + at] {
                Op::CallFn { frame, .. } => Op::CallFn { target: t, frame },
                Op::CallFb { frame, .. } => Op::CallFb { target: t, frame },
                other => other,
            };
        }
    }
    // The deepest chain of frames, of at most `calls` calls below `q`: a chain of calls
    // dispatched at run time may come back to a body (`check_recursion`), and the VM makes no
    // call deeper than ST_CALL_DEPTH.
    fn need<'b>(
        cx: &Ctx<'_>,
        q: usize,
        calls: usize,
        body_of: &dyn Fn(usize) -> &'b emit::Body,
        memo: &mut HashMap<(usize, usize), u32>,
    ) -> u32 {
        if let Some(&n) = memo.get(&(q, calls)) {
            return n;
        }
        let deepest = match calls {
            0 => 0,
            _ => cx.pous[q]
                .callees
                .iter()
                .map(|c| need(cx, c.pou, calls - 1, body_of, memo))
                .max()
                .unwrap_or(0),
        };
        let n = body_of(q).frame.saturating_add(deepest);
        memo.insert((q, calls), n);
        n
    }
    // What the program's chains of calls need, refused at the program's name.
    let pou = &cx.pous[p];
    let at_program = |message: String| {
        Diagnostic::new(cx.path(pou.file), pou.name_span().line, pou.name_span().col, message)
    };
    let frame_bytes = need(cx, p, ST_CALL_DEPTH, &body_of, &mut HashMap::new());
    if frame_bytes > decl::MAX_FRAME {
        return Err(at_program(format!(
            "`{}` needs {frame_bytes} bytes of frame with its calls (limit 1 MiB)",
            pou.name
        )));
    }
    let slots = eval_stack_need(&code);
    if slots > EVAL_DEPTH as u32 {
        return Err(at_program(format!(
            "`{}` needs {slots} evaluation stack slots with its calls (limit {EVAL_DEPTH}): \
             a call inside an expression keeps the caller's slots below the callee's",
            pou.name
        )));
    }
    out.push(Program {
        name: inst.name.to_string(),
        path: main_path,
        language: Language::StructuredText,
        code: code.into_boxed_slice(),
        consts: consts.into_boxed_slice(),
        frame_bytes,
        regions: regions.into_boxed_slice(),
        lines: lines.into_boxed_slice(),
        statements: statements.into_boxed_slice(),
        edge_base: 0,
        edge_slots: 0,
        labels: Box::new([]),
        subroutines: Box::new([]),
        native: None,
        var_bools_canonical: false,
    });
    Ok(())
}

/// Each body by its first instruction: its own deepest evaluation stack, and its calls (the
/// slots the caller holds at each, the callee's first instruction).
type Bodies = HashMap<usize, (u32, Vec<(u32, usize)>)>;

/// The deepest evaluation stack the program's code reaches, a callee's slots counted above
/// those its caller holds at the call (each statement is checked on its own as it is emitted;
/// this adds the chains of calls inside expressions).
fn eval_stack_need(code: &[Op]) -> u32 {
    // Each body (the program's, each FUNCTION's and FUNCTION_BLOCK's): its own deepest stack,
    // and its calls with the depth the caller holds at each.
    let mut starts = vec![0usize];
    for op in code {
        if let Op::CallFn { target, .. } | Op::CallFb { target, .. } = *op {
            starts.push(target as usize);
        }
    }
    starts.sort_unstable();
    starts.dedup();
    let mut bodies: Bodies = HashMap::new();
    for &start in &starts {
        let mut seen: HashMap<usize, u32> = HashMap::new();
        let mut work = vec![(start, 0u32)];
        let (mut deepest, mut calls) = (0, Vec::new());
        while let Some((pc, depth)) = work.pop() {
            if seen.insert(pc, depth).is_some() {
                continue;
            }
            let Some(op) = code.get(pc) else { continue };
            let (popped, pushed) = op.stack_effect().unwrap_or((0, 0));
            let after = depth.saturating_sub(popped) + pushed;
            deepest = deepest.max(depth).max(after);
            match *op {
                Op::Goto(target) => work.push((target as usize, after)),
                Op::GotoIf { target, .. } => {
                    work.extend([(target as usize, after), (pc + 1, after)])
                }
                Op::CallFn { target, .. } | Op::CallFb { target, .. } => {
                    calls.push((after, target as usize));
                    work.push((pc + 1, after));
                }
                Op::Return | Op::End => {}
                _ => work.push((pc + 1, after)),
            }
        }
        bodies.insert(start, (deepest, calls));
    }
    // Chains of at most ST_CALL_DEPTH calls: calls dispatched at run time may come back to a
    // body (`check_recursion`), and the VM makes no deeper call.
    fn need(
        body: usize,
        depth: usize,
        bodies: &Bodies,
        memo: &mut HashMap<(usize, usize), u32>,
    ) -> u32 {
        if let Some(&n) = memo.get(&(body, depth)) {
            return n;
        }
        let (deepest, calls) = &bodies[&body];
        let mut n = *deepest;
        if depth > 0 {
            for &(held, callee) in calls {
                n = n.max(held.saturating_add(need(callee, depth - 1, bodies, memo)));
            }
        }
        memo.insert((body, depth), n);
        n
    }
    need(0, ST_CALL_DEPTH, &bodies, &mut HashMap::new())
}

fn value_type(cx: &Ctx<'_>, ty: &Ty) -> Option<ValueType> {
    Some(match ty {
        Ty::Prim(p) | Ty::Sub(p, _, _) => p.value_type(),
        Ty::Enum(e) => {
            let en = &cx.types.enums[*e];
            ValueType::Enum {
                type_name: en.name.clone(),
                values: en.values.iter().map(|(n, v)| (n.clone(), *v as i64)).collect(),
                base: en.base.elem(),
            }
        }
        Ty::Str(n) => ValueType::String { cap: *n },
        Ty::WStr(n) => ValueType::WString { cap: *n },
        Ty::Ref(..) | Ty::Iface(_) => ValueType::Reference { type_name: cx.ty_name(ty) },
        _ => return None,
    })
}

/// Where a located variable is: its device.
fn device_pointer(storage: Storage) -> Option<Pointer> {
    Some(match storage {
        Storage::Word(w) => Pointer { space: Space::Word, offset: u32::from(w) },
        Storage::Bit(b) => {
            Pointer { space: Space::Bit, offset: u32::from(b.word) * 16 + b.mask.trailing_zeros() }
        }
        Storage::Byte(n) => Pointer { space: Space::Byte, offset: n },
        _ => return None,
    })
}

/// The symbols of a variable's scalar leaves: an array one entry, with the leaves of one
/// element placed from its start ([`crate::symbols`]), unless a leaf of the element is not
/// placed relative to it (an FB's variable that `VAR_CONFIG` binds to a device), then one
/// symbol per leaf of each element. True if every leaf is placed relative to `at`.
fn leaves(
    cx: &Ctx<'_>,
    name: &str,
    ty: &Ty,
    at: Pointer,
    retain: bool,
    constant: bool,
    out: &mut Symbols,
) -> bool {
    if let Some(vt) = value_type(cx, ty) {
        out.push(Symbol { name: name.to_string(), ty: vt, at, retain, constant });
        return true;
    }
    match ty {
        Ty::Array(a) => {
            let unit = match at.space {
                Space::Word => a.of.elem(&cx.types).map_or(1, |e| e.words()),
                Space::Bit | Space::Byte => 1,
                _ => a.elem_size,
            };
            let mut element = Symbols::default();
            let start = Pointer { space: at.space, offset: 0 };
            if leaves(cx, "", &a.of, start, retain, constant, &mut element) {
                if !element.is_empty() {
                    let dims = a.dims.clone();
                    let name = name.to_string();
                    out.push_array(ArraySymbol { name, dims, at, stride: unit, element });
                }
                return true;
            }
            for k in 0..a.count() {
                let el = format!("{name}{}", crate::symbols::index_text(&a.dims, k));
                let p = Pointer { space: at.space, offset: at.offset + k as u32 * unit };
                leaves(cx, &el, &a.of, p, retain, constant, out);
            }
            false
        }
        Ty::Struct(s) => {
            let mut relative = true;
            for m in &cx.types.structs[*s].members {
                // a member a binding placed at a device (`fb_config.rs`) is there
                let p = match m.device {
                    Some(device) => {
                        relative = false;
                        match device_pointer(device) {
                            Some(p) => p,
                            None => continue,
                        }
                    }
                    None => Pointer { space: at.space, offset: at.offset + m.offset },
                };
                let name = format!("{name}.{}", m.name);
                // the device's own retention applies, as to any located variable
                let retain = retain && m.device.is_none();
                relative &= leaves(cx, &name, &m.ty, p, retain, constant, out);
            }
            relative
        }
        Ty::Fb(p) => {
            let mut relative = true;
            for v in &cx.pous[*p].vars {
                if matches!(v.kind, VarKind::Temp | VarKind::External | VarKind::InOut) {
                    continue;
                }
                // a variable of a block's copy that VAR_CONFIG binds is at its device
                // (`fb_config.rs`)
                let ptr = match v.storage {
                    Storage::Inst(o) => Some(Pointer { space: at.space, offset: at.offset + o }),
                    other => {
                        let at = device_pointer(other);
                        relative &= at.is_none();
                        at
                    }
                };
                if let Some(ptr) = ptr {
                    relative &= leaves(
                        cx,
                        &format!("{name}.{}", v.name),
                        &v.ty,
                        ptr,
                        retain || v.retain,
                        constant || v.constant,
                        out,
                    );
                }
            }
            relative
        }
        _ => true,
    }
}

//! `VAR_CONFIG`'s `AT` for a variable inside a FUNCTION_BLOCK instance of a program instance
//! (`P4.FB1.C2 AT %QB25 : BYTE;`, IEC 61131-3's configuration example): a lowering of the
//! syntax trees, since a block's code is shared by all its instances.
//!
//! The FUNCTION_BLOCK instance gets a copy of its block of its own, named after the instance
//! (`FB$P4.FB1`), in which the variable is declared at the bound address (and with the entry's
//! initial value), its methods and actions copied with it ([`actions_of`]); the instance's
//! declaration names the copy. A path through nested instances copies each block on the way
//! (`Inner$P4.FB1.inner`). The PROGRAM is rewritten in place when the project has one instance
//! of it; else the configuration's instance gets a copy of the PROGRAM of its own
//! (`Prog$P4`), which the compile places instead ([`super::ctx::PouInfo::copy_of`] names the
//! PROGRAM it copies). Only an entry that fits is lowered: a variable of an instance's own
//! (`VAR`, `VAR_INPUT`, `VAR_OUTPUT`) declared at a partly specified address the bound
//! address fits; the compile checks every entry and reports the others
//! (`var_config.rs`). The config's `[iec.variables]` entries are lowered the same way, after
//! the configurations' (a plcd device may be their address), for any program instance.
//!
//! A member of a struct variable (`P4.hw.IN`, `P4.FB1.hw.IN`), declared at a partly specified
//! address in its STRUCT type, is bound alike: the variable gets a copy of its type of its own
//! (`HW_COMP$P4.hw`), in which the member is declared at the bound address (and with the
//! entry's initial value), the other members as the type has them ([`locate_member`]); the
//! compile reads the copy's located member as a device (`decl.rs`, `expr.rs`). A member of a
//! member (`P4.hw.inner.IN`) copies each STRUCT type on the way (`INNER$P4.hw.inner`).

use std::borrow::Cow;

use crate::device::iec::IecLayout;
use crate::st::ast::{self, Ident, Init, Item, PouKind, TypeRef, VarBlock, VarKind};

use super::generic_constants::actions_of;
use super::Instance;

/// One entry to lower: the path from the PROGRAM's variable on (`FB1.C2`), the address, the
/// initial value, and whether the address may be a plcd device (the config's entries).
type Entry = (Vec<Ident>, Ident, Option<Init>, bool);

/// Lowers the entries of the configurations that declare `instances` (`declared(k)` is the
/// declaration of the instance `k`, when a configuration declares it), then those of the
/// config's `[iec.variables]` (`config`): the lowered sources, and for each instance the name
/// of the copy of its PROGRAM it runs, when it runs one.
pub(super) fn lower<'f, 'd>(
    mut files: Vec<Cow<'f, ast::File>>,
    instances: &[Instance<'_>],
    declared: impl Fn(usize) -> Option<&'d ast::ProgramDecl>,
    iec: &IecLayout,
    config: &[ast::ConfigVar],
) -> (Vec<Cow<'f, ast::File>>, Vec<Option<String>>) {
    let mut renamed = vec![None; instances.len()];
    // the resources a path of the config may start with: any configuration's
    let resources: Vec<String> = files
        .iter()
        .flat_map(|f| &f.items)
        .filter_map(|i| match i {
            Item::Configuration(c) => Some(super::var_config::resources(c)),
            _ => None,
        })
        .flatten()
        .map(str::to_string)
        .collect();
    for (k, inst) in instances.iter().enumerate() {
        let Some(f) = files.iter().position(|f| f.path == inst.file) else { continue };
        let mut entries = match declared(k) {
            Some(_) => entries_of(&files[f], inst.name),
            None => Vec::new(),
        };
        entries.extend(inside(config, &resources, inst.name, true));
        if entries.is_empty() {
            continue;
        }
        let programs: Vec<usize> = (0..files[f].items.len())
            .filter(|&i| matches!(&files[f].items[i], Item::Pou(p) if p.kind == PouKind::Program))
            .collect();
        let at = match inst.pou {
            Some(name) => programs
                .iter()
                .copied()
                .find(|&i| matches!(&files[f].items[i], Item::Pou(p) if p.name.is(name))),
            None if programs.len() == 1 => Some(programs[0]),
            None => None,
        };
        let Some(at) = at else { continue };
        let Item::Pou(original) = &files[f].items[at] else { continue };
        let mut program = original.clone();
        let mut changed = false;
        for (path, location, init, devices) in &entries {
            let prefix = inst.name.to_string();
            let fit = (iec, *devices);
            changed |=
                locate_inside(&mut files, &mut program.vars, path, location, init, prefix, fit);
        }
        if !changed {
            continue;
        }
        let name = program.name.name.clone();
        let sharing = instances
            .iter()
            .filter(|i| {
                i.file == inst.file
                    && i.pou.map_or(programs.len() == 1, |n| n.eq_ignore_ascii_case(&name))
            })
            .count();
        let items = &mut files[f].to_mut().items;
        if sharing <= 1 {
            items[at] = Item::Pou(program);
        } else {
            let copy = format!("{name}${}", inst.name);
            program.name.name = copy.clone();
            let actions = actions_of(items, at, &name, &copy);
            items.push(Item::Pou(program));
            items.extend(actions);
            renamed[k] = Some(copy);
        }
    }
    (files, renamed)
}

/// The entries of `file`'s configuration that bind a variable inside a FUNCTION_BLOCK
/// instance of the program instance `instance`.
fn entries_of(file: &ast::File, instance: &str) -> Vec<Entry> {
    let Some(conf) = file.items.iter().find_map(|i| match i {
        Item::Configuration(c) => Some(c),
        _ => None,
    }) else {
        return Vec::new();
    };
    let resources: Vec<String> = super::var_config::resources(conf).map(str::to_string).collect();
    inside(&conf.var_config, &resources, instance, false)
}

/// The entries of `entries` that bind a variable inside a FUNCTION_BLOCK instance of the
/// program instance `instance`, their paths starting with it or with one of `resources`.
fn inside(
    entries: &[ast::ConfigVar],
    resources: &[String],
    instance: &str,
    devices: bool,
) -> Vec<Entry> {
    let mut out: Vec<Entry> = Vec::new();
    for entry in entries {
        let Some(location) = &entry.location else { continue };
        // `Res0.P4.FB1.C2`, as IEC writes it, or `P4.FB1.C2`
        let path = match entry.path.split_first() {
            Some((first, rest))
                if rest.len() >= 2
                    && !first.is(instance)
                    && resources.iter().any(|r| first.is(r)) =>
            {
                rest
            }
            _ => &entry.path[..],
        };
        if path.len() < 3 || !path[0].is(instance) {
            continue;
        }
        // a path bound twice: the first entry that fits binds it, the compile reports the
        // others
        out.push((path[1..].to_vec(), location.clone(), entry.init.clone(), devices));
    }
    out
}

/// Whether a variable of this block may be bound: one of the instance's own.
fn own(block: &VarBlock) -> bool {
    matches!(block.kind, VarKind::Local | VarKind::Input | VarKind::Output) && !block.constant
}

/// Declares the variable `path` names in `vars` (through FUNCTION_BLOCK instances, each
/// given a copy of its block named `Block$prefix.instance`) at `location`, when it fits by
/// `fit` (the layout, and whether a plcd device does); whether it did.
fn locate_inside(
    files: &mut [Cow<'_, ast::File>],
    vars: &mut [VarBlock],
    path: &[Ident],
    location: &Ident,
    init: &Option<Init>,
    prefix: String,
    fit: (&IecLayout, bool),
) -> bool {
    let name = &path[0];
    let Some((b, d)) = vars.iter().enumerate().find_map(|(b, block)| {
        block.decls.iter().position(|d| d.names.iter().any(|n| n.is(&name.name))).map(|d| (b, d))
    }) else {
        return false;
    };
    if !own(&vars[b]) {
        return false;
    }
    let decl = &vars[b].decls[d];
    if path.len() == 1 {
        if !binds(decl.location.as_ref(), location, fit) {
            return false;
        }
        let span = decl.location.as_ref().map_or(location.span, |l| l.span);
        let located = ast::VarDecl {
            names: vec![name.clone()],
            location: Some(Ident { name: location.name.clone(), span }),
            init: init.clone().or_else(|| decl.init.clone()),
            ..decl.clone()
        };
        split_off(&mut vars[b], d, name, located);
        return true;
    }
    let TypeRef::Named(block) = &decl.ty else { return false };
    if let Some((f, i)) = find_struct(files, &block.name) {
        return locate_member(files, (f, i), &mut vars[b], d, path, location, init, prefix, fit);
    }
    let copy_name = copy_name(&block.name, &prefix, &name.name);
    // the copy made for another variable of this instance, else the block
    let Some((f, i)) = find_block(files, &copy_name).or_else(|| find_block(files, &block.name))
    else {
        return false;
    };
    let Item::Pou(found) = &files[f].items[i] else { return false };
    let mut copy = found.clone();
    let fresh = !copy.name.is(&copy_name);
    let original = copy.name.name.clone();
    copy.name.name = copy_name.clone();
    let inner_prefix = format!("{prefix}.{}", name.name);
    if !locate_inside(files, &mut copy.vars, &path[1..], location, init, inner_prefix, fit) {
        return false;
    }
    let items = &mut files[f].to_mut().items;
    if fresh {
        let actions = actions_of(items, i, &original, &copy_name);
        items.push(Item::Pou(copy));
        items.extend(actions);
    } else {
        items[i] = Item::Pou(copy);
    }
    let retyped = ast::VarDecl {
        names: vec![name.clone()],
        ty: TypeRef::Named(Ident { name: copy_name, span: block.span }),
        ..decl.clone()
    };
    split_off(&mut vars[b], d, name, retyped);
    true
}

/// Declares the member `path[1..]` of the struct variable `path[0]` (a member of a member at
/// any depth: `s.inner.x`), declared by `vars.decls[d]` of a STRUCT type at `(f, i)`, at
/// `location` when it fits by `fit`: the variable is given a copy of its type of its own,
/// named `Type$prefix.variable`, with the member at the address (and the entry's initial
/// value), and each struct member on the way a copy of its type likewise
/// (`Inner$prefix.variable.inner`); whether it did.
#[allow(clippy::too_many_arguments)]
fn locate_member(
    files: &mut [Cow<'_, ast::File>],
    (f, i): (usize, usize),
    vars: &mut VarBlock,
    d: usize,
    path: &[Ident],
    location: &Ident,
    init: &Option<Init>,
    prefix: String,
    fit: (&IecLayout, bool),
) -> bool {
    let name = &path[0];
    let decl = &vars.decls[d];
    let TypeRef::Named(ty) = &decl.ty else { return false };
    let mut own_init = decl.init.clone();
    let inner_prefix = format!("{prefix}.{}", name.name);
    let Some(copy_name) = copy_struct(files, (f, i), ty, &prefix, &name.name, |files, members| {
        locate_in_struct(
            files,
            members,
            &path[1..],
            location,
            init,
            &mut own_init,
            inner_prefix,
            fit,
        )
    }) else {
        return false;
    };
    let retyped = ast::VarDecl {
        names: vec![name.clone()],
        ty: TypeRef::Named(Ident { name: copy_name, span: ty.span }),
        init: own_init,
        ..decl.clone()
    };
    let name = name.clone();
    split_off(vars, d, &name, retyped);
    true
}

/// Makes the copy of the STRUCT type `ty` (found at `(f, i)`) that the variable or member
/// `variable` of `prefix` gets, or takes the one another binding made, lets `locate` declare
/// the bound member in its members, and keeps it: the copy's name, or `None` when `locate`
/// did not bind (nothing is kept).
fn copy_struct(
    files: &mut [Cow<'_, ast::File>],
    (f, i): (usize, usize),
    ty: &Ident,
    prefix: &str,
    variable: &str,
    locate: impl FnOnce(&mut [Cow<'_, ast::File>], &mut Vec<ast::VarDecl>) -> bool,
) -> Option<String> {
    let copy_name = copy_name(&ty.name, prefix, variable);
    let (f, i) = find_struct(files, &copy_name).unwrap_or((f, i));
    let Item::Type(found) = &files[f].items[i] else { return None };
    let mut copy = found.clone();
    let fresh = !copy.name.is(&copy_name);
    copy.name.name = copy_name.clone();
    let ast::TypeDef::Struct { members } = &mut copy.def else { return None };
    if !locate(files, members) {
        return None;
    }
    let items = &mut files[f].to_mut().items;
    if fresh {
        items.push(Item::Type(copy));
    } else {
        items[i] = Item::Type(copy);
    }
    Some(copy_name)
}

/// Declares the member `path[0]` of a STRUCT type's `members` at `location` (or, through a
/// member of a STRUCT type, `path[1..]` of a copy of that type: [`copy_struct`]) when it fits
/// by `fit`. `own_init` is the initializer the variable (or the member holding `members`)
/// gives them: the member's part of it (`(x := TRUE)`, `(inner := (x := TRUE))`) moves to the
/// member's declaration, written to the device at RUN start, unless the entry gives one.
/// Whether it did.
#[allow(clippy::too_many_arguments)]
fn locate_in_struct(
    files: &mut [Cow<'_, ast::File>],
    members: &mut Vec<ast::VarDecl>,
    path: &[Ident],
    location: &Ident,
    init: &Option<Init>,
    own_init: &mut Option<Init>,
    prefix: String,
    fit: (&IecLayout, bool),
) -> bool {
    let member = &path[0];
    let Some(m) = members.iter().position(|m| m.names.iter().any(|n| n.is(&member.name))) else {
        return false;
    };
    // the member's part of the initializer of what holds it, taken out of it
    let given = match own_init {
        Some(Init::Struct { members, .. }) => {
            let at = members.iter().position(|(n, _)| n.is(&member.name));
            at.map(|at| members.remove(at).1)
        }
        _ => None,
    };
    let old = &members[m];
    let located = if path.len() == 1 {
        if !binds(old.location.as_ref(), location, fit) {
            return false;
        }
        let span = old.location.as_ref().map_or(location.span, |l| l.span);
        ast::VarDecl {
            names: vec![member.clone()],
            location: Some(Ident { name: location.name.clone(), span }),
            init: init.clone().or(given).or_else(|| old.init.clone()),
            ..old.clone()
        }
    } else {
        let TypeRef::Named(ty) = &old.ty else { return false };
        let Some(at) = find_struct(files, &ty.name) else { return false };
        // the member's own initializer in the type, beneath what the holder gives it
        let mut inner_init = given.or_else(|| old.init.clone());
        let inner_prefix = format!("{prefix}.{}", member.name);
        let copied = copy_struct(files, at, ty, &prefix, &member.name, |files, inner| {
            let (rest, inner_prefix) = (&path[1..], inner_prefix);
            locate_in_struct(files, inner, rest, location, init, &mut inner_init, inner_prefix, fit)
        });
        let Some(copy_name) = copied else { return false };
        ast::VarDecl {
            names: vec![member.clone()],
            ty: TypeRef::Named(Ident { name: copy_name, span: ty.span }),
            init: inner_init,
            ..old.clone()
        }
    };
    // the member's own declaration, in place, so that the copy's layout is its type's
    let at = &mut members[m];
    if at.names.len() == 1 {
        *at = located;
    } else {
        let place = at.names.iter().position(|n| n.is(&member.name)).expect("named");
        at.names.remove(place);
        let rest = members[m].clone();
        let (before, after) = (
            ast::VarDecl { names: rest.names[..place].to_vec(), ..rest.clone() },
            ast::VarDecl { names: rest.names[place..].to_vec(), ..rest },
        );
        let mut split = Vec::new();
        split.extend((!before.names.is_empty()).then_some(before));
        split.push(located);
        split.extend((!after.names.is_empty()).then_some(after));
        members.splice(m..=m, split);
    }
    true
}

/// Where the STRUCT type `name` is: its file and item.
fn find_struct(files: &[Cow<'_, ast::File>], name: &str) -> Option<(usize, usize)> {
    files.iter().enumerate().find_map(|(f, file)| {
        file.items
            .iter()
            .position(|i| {
                matches!(i, Item::Type(t) if t.name.is(name)
                    && matches!(t.def, ast::TypeDef::Struct { .. }))
            })
            .map(|i| (f, i))
    })
}

/// Replaces `name` in the declaration `d` of `block` (`a, b : T;`) by a declaration of its
/// own.
fn split_off(block: &mut VarBlock, d: usize, name: &Ident, own: ast::VarDecl) {
    let decl = &mut block.decls[d];
    if decl.names.len() == 1 {
        *decl = own;
    } else {
        decl.names.retain(|n| !n.is(&name.name));
        block.decls.insert(d + 1, own);
    }
}

/// Whether a variable declared at `partial` may be bound to `location`: `partial` is partly
/// specified and `location` fits it by `fit` (the layout, and whether a plcd device does).
fn binds(partial: Option<&Ident>, location: &Ident, fit: (&IecLayout, bool)) -> bool {
    partial.is_some_and(|partial| {
        partial.name.ends_with('*')
            && super::var_config::fits(&partial.name, &location.name, fit.0, fit.1)
    })
}

/// The name of the copy of the type `ty` (a FUNCTION_BLOCK or a STRUCT) a binding gives the
/// variable `variable` of the instance `prefix`: `Type$prefix.variable`, or `ty` itself when
/// the declaration names the copy already (another entry bound a variable of it).
fn copy_name(ty: &str, prefix: &str, variable: &str) -> String {
    match ty.contains('$') {
        true => ty.to_string(),
        false => format!("{ty}${prefix}.{variable}"),
    }
}

/// Where the FUNCTION_BLOCK `name` is: its file and item.
fn find_block(files: &[Cow<'_, ast::File>], name: &str) -> Option<(usize, usize)> {
    files.iter().enumerate().find_map(|(f, file)| {
        file.items
            .iter()
            .position(|i| matches!(i, Item::Pou(p) if p.kind == PouKind::FunctionBlock && p.name.is(name)))
            .map(|i| (f, i))
    })
}

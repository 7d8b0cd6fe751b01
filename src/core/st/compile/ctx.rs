//! The compiler's state: every declaration of every file by name, the type tables, the
//! variable memory being laid out, and the diagnostics gathered so far.

use std::collections::HashMap;
use std::path::Path;

use crate::device::{Address, BitRef};
use crate::diag::Diagnostic;
use crate::lang::Place;
use crate::st::ast::{self, PouKind, Span, VarKind};
use crate::st::dialect::{Dialect, Habit};
use crate::value::Elem;

use super::emit::Body;
use super::types::{Ty, Types};

/// A compile-time constant. BOOL, TIME and enumeration values are integers.
#[derive(Debug, Clone, PartialEq)]
pub enum Cv {
    Int(i128),
    Real(f64),
    /// A `STRING` constant: its bytes, one a character (Windows-1252, docs/ST.md).
    Str(Vec<u8>),
    /// A `WSTRING` constant: its UTF-16 code units.
    WStr(Vec<u16>),
}

/// Where a variable is, relative to what owns it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Storage {
    /// Byte offset in the owner's instance (a PROGRAM's: variable memory at the instance's
    /// base; an FB's: `this`).
    Inst(u32),
    /// Byte offset in the activation's frame (FUNCTION variables, `VAR_TEMP`).
    Frame(u32),
    /// Absolute byte offset in variable memory (VAR_GLOBAL).
    Global(u32),
    /// A device word (and the words after it).
    Word(u16),
    /// A device bit.
    Bit(BitRef),
    /// A device byte (an IEC byte address, `%QB1`), and the bytes after it: byte `n` is a half
    /// of device word `n / 2` (`lang::Place::Byte`).
    Byte(u32),
}

/// A declared variable.
#[derive(Debug, Clone)]
pub struct VarInfo {
    pub name: String,
    pub kind: VarKind,
    pub ty: Ty,
    pub constant: bool,
    pub retain: bool,
    /// `PERSISTENT` (TwinCAT, CODESYS): retained (`retain` is set too), and kept by a cold
    /// reset.
    pub persistent: bool,
    pub storage: Storage,
    /// VAR_IN_OUT: the storage holds a pointer to the value.
    pub by_ref: bool,
    /// The value of a CONSTANT scalar.
    pub value: Option<Cv>,
    pub span: Span,
    /// The device a located variable is at.
    pub located: Option<Address>,
    /// VAR_EXTERNAL: the VAR_GLOBAL it stands for.
    pub global: Option<usize>,
    /// An `R_EDGE` / `F_EDGE` input: where, in the instance, the value its FB's body sees is
    /// (computed at each call from the input and its memory: [`PouInfo::edges`]).
    pub edge_value: Option<u32>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum State {
    Todo,
    Busy,
    Done,
}

/// A PROGRAM, FUNCTION or FUNCTION_BLOCK.
#[derive(Debug, Clone)]
pub struct PouInfo<'a> {
    pub ast: &'a ast::Pou,
    pub file: usize,
    pub name: String,
    pub kind: PouKind,
    pub vars: Vec<VarInfo>,
    pub names: HashMap<String, usize>,
    /// A FUNCTION's result type ([`Ty::Void`] without one).
    pub result: Ty,
    /// PROGRAM / FUNCTION_BLOCK: bytes of an instance and its initial image.
    pub inst_size: u32,
    pub image: Vec<u8>,
    /// FUNCTION: bytes of its variables in the frame (result, parameters, locals, temps);
    /// PROGRAM / FUNCTION_BLOCK: bytes of its `VAR_TEMP`.
    pub frame_vars: u32,
    /// The initial image of those frame variables.
    pub frame_image: Vec<u8>,
    /// Where that image is kept in variable memory, once a call needs it.
    pub frame_template: Option<u32>,
    pub state: State,
    /// VAR_INPUT and VAR_IN_OUT in declaration order (positional arguments).
    pub positional: Vec<usize>,
    pub body: Option<Body>,
    /// The POUs its body calls, each once, with the first call's place.
    pub callees: Vec<Callee>,
    /// Whether the body has been checked (diagnostics given once).
    pub checked: bool,
    /// An action: its declaration and the POU it belongs to, whose variables it shares (`ast`
    /// is that POU's).
    pub action: Option<(&'a ast::Action, usize)>,
    /// FUNCTION / FUNCTION_BLOCK: its `EN` when declared (a VAR_INPUT, the index in `vars`);
    /// otherwise EN is implicit, given at a call and never stored.
    pub en: Option<usize>,
    /// FUNCTION / FUNCTION_BLOCK: its `ENO` variable (a VAR_OUTPUT, the index in `vars`):
    /// declared, or implicit (`eno_implicit`), which a POU has when something may read it.
    pub eno: Option<usize>,
    pub eno_implicit: bool,
    /// Whether the body assigns `ENO`, and whether some call gives this POU an implicit EN
    /// (either can leave ENO FALSE, which the body's entry sets TRUE again).
    pub eno_assigned: bool,
    pub called_with_en: bool,
    /// The `R_EDGE` / `F_EDGE` inputs of a FUNCTION_BLOCK.
    pub edges: Vec<EdgeInput>,
    /// A PROGRAM's copy for one of its instances, whose `VAR_CONFIG` binds variables the
    /// PROGRAM's other instances keep in variable memory (`var_config`): the PROGRAM copied.
    pub copy_of: Option<usize>,
    /// A method or property accessor: the FUNCTION_BLOCK (or PROGRAM) it belongs to, whose
    /// variables its body reads and writes through `this` (`oop`).
    pub method: Option<usize>,
}

/// An edge input of a function block: at each execution of the body, the value the body sees
/// is computed from the input and the input's level at the previous execution.
#[derive(Debug, Clone, Copy)]
pub struct EdgeInput {
    /// The input (its index in `vars`).
    pub input: usize,
    /// The memory: the input's level at the previous execution (the index in `vars`).
    pub memory: usize,
    /// Where the value the body sees is, in the instance.
    pub value: u32,
    pub rising: bool,
}

impl<'a> PouInfo<'a> {
    /// A PROGRAM, FUNCTION or FUNCTION_BLOCK, not yet resolved.
    pub fn new(ast: &'a ast::Pou, file: usize) -> PouInfo<'a> {
        PouInfo {
            ast,
            file,
            name: ast.name.name.clone(),
            kind: ast.kind,
            vars: Vec::new(),
            names: HashMap::new(),
            result: Ty::Void,
            inst_size: 0,
            image: Vec::new(),
            frame_vars: 0,
            frame_image: Vec::new(),
            frame_template: None,
            state: State::Todo,
            positional: Vec::new(),
            body: None,
            callees: Vec::new(),
            checked: false,
            action: None,
            en: None,
            eno: None,
            eno_implicit: false,
            eno_assigned: false,
            called_with_en: false,
            edges: Vec::new(),
            copy_of: None,
            method: None,
        }
    }

    pub fn lookup(&self, name: &str) -> Option<usize> {
        self.names.get(&name.to_ascii_lowercase()).copied()
    }

    /// The statements of its body (an action's own).
    pub fn statements(&self) -> &'a [ast::Stmt] {
        match self.action {
            Some((action, _)) => &action.body,
            None => &self.ast.body,
        }
    }

    /// Where it starts and where its `END_…` is.
    pub fn start_end(&self) -> (Span, Span) {
        match self.action {
            Some((action, _)) => (action.span, action.end),
            None => (self.ast.span, self.ast.end),
        }
    }

    /// Where its name is written.
    pub fn name_span(&self) -> Span {
        match self.action {
            Some((action, _)) => action.name.span,
            None => self.ast.name.span,
        }
    }
}

/// The key of an action in [`Ctx::pou_names`]: `owner.action`, which no other name can be.
pub fn action_key(owner: &str, action: &str) -> String {
    format!("{}.{}", owner.to_ascii_lowercase(), action.to_ascii_lowercase())
}

/// A TYPE declaration, resolved on first use.
#[derive(Debug)]
pub struct TypeEntry<'a> {
    pub decl: &'a ast::TypeDecl,
    pub file: usize,
    pub state: State,
    pub ty: Ty,
    /// An alias's own initial value, as an image.
    pub image: Option<Vec<u8>>,
}

/// Where names are looked up: a POU's variables (the first `visible` of them, while its
/// declarations are read), then the globals and the enumeration values.
#[derive(Debug, Clone, Copy)]
pub struct Scope {
    pub pou: Option<usize>,
    pub visible: usize,
    pub file: usize,
}

pub struct Ctx<'a> {
    pub files: Vec<&'a ast::File>,
    pub types: Types,
    pub diags: Vec<Diagnostic>,
    /// What is accepted with a warning (`implicit`): reported when the compile succeeds.
    pub warnings: Vec<Diagnostic>,
    pub type_decls: Vec<TypeEntry<'a>>,
    pub type_names: HashMap<String, usize>,
    pub pous: Vec<PouInfo<'a>>,
    pub pou_names: HashMap<String, usize>,
    pub globals: Vec<VarInfo>,
    pub global_names: HashMap<String, usize>,
    /// Globals' declaration blocks, resolved in order: `(file, block)`.
    pub global_blocks: Vec<(usize, &'a ast::VarBlock)>,
    /// Variable memory laid out so far, and its image at RUN start.
    pub image: Vec<u8>,
    /// `(offset, len)` of RETAIN bytes.
    pub retained: Vec<(u32, u32)>,
    /// `(offset, len)` of PERSISTENT bytes, among the RETAIN ones.
    pub persistent: Vec<(u32, u32)>,
    pub located_init: Vec<(Place, Elem, u64)>,
    /// The total of variable memory crossed `[st] variable_memory_bytes` (reported once).
    pub memory_exceeded: bool,
    /// Plain enumeration value names → `(enum, value)` of each enumeration declaring it.
    pub enum_values: HashMap<String, Vec<(usize, i128)>>,
    /// Whether the POU being checked is the prelude's (may call `__` builtins).
    pub in_prelude: bool,
    /// Whether some code of the project may read an `ENO` from outside a POU (`ENO => v` in a
    /// call, `inst.ENO`): then every FUNCTION and FUNCTION_BLOCK has an ENO variable.
    pub eno_read: bool,
    pub prelude_file: usize,
    /// The files of the system libraries (`compile::libraries`), after the project's.
    pub library_files: std::ops::Range<usize>,
    /// While checking a body: the FOR variables of the enclosing loops, the loop depth, and
    /// whether a FUNCTION's result has been assigned.
    pub for_vars: Vec<String>,
    /// For each of `for_vars`, whether its loop's body writes it (`for_written`).
    pub for_written: Vec<bool>,
    pub loop_depth: usize,
    /// The labels and `JMP`s of the bodies checked (`jumps`).
    pub jumps: super::jumps::JumpTable,
    /// `[st] strict`: whether a CODESYS habit is an error.
    pub dialect: Dialect,
    /// Methods, properties, EXTENDS and interfaces (`oop`).
    pub oop: super::oop::Tables<'a>,
}

impl<'a> Ctx<'a> {
    /// Whether `file` is plcd's own (the prelude, a system library), not the project's.
    pub fn is_shipped(&self, file: usize) -> bool {
        file == self.prelude_file || self.library_files.contains(&file)
    }

    pub fn path(&self, file: usize) -> &'a Path {
        &self.files[file].path
    }

    pub fn error(&mut self, file: usize, span: Span, msg: impl Into<String>) {
        let d = Diagnostic::new(self.path(file), span.line, span.col, msg);
        self.diags.push(d);
    }

    /// A warning at `span` (none in the prelude's own code). A body checked twice, or an
    /// expression probed before it is checked, warns once: the compile keeps one of each.
    pub fn warn(&mut self, file: usize, span: Span, msg: impl Into<String>) {
        if !self.is_shipped(file) {
            let d = Diagnostic::new(self.path(file), span.line, span.col, msg);
            self.warnings.push(d);
        }
    }

    /// A non-standard form at `span`: accepted, or an error naming the standard's way when
    /// `[st] strict` is on (the prelude's own code is never strict). Always `true`, so that
    /// checking goes on as CODESYS reads the form, with one error for it under `strict`.
    pub fn habit(&mut self, habit: Habit, file: usize, span: Span) -> bool {
        // plcd's own sources (the prelude, the heap's allocator) are not the project's
        let own = self.is_shipped(file) || super::heap::is_heap_file(&self.files[file].path);
        if self.dialect.strict && !own {
            self.error(file, span, habit.strict_message());
        }
        true
    }

    pub fn ty_name(&self, ty: &Ty) -> String {
        self.types.name(ty)
    }

    /// Reserves `bytes.len()` bytes of variable memory with their initial image, for the
    /// declaration (or constant) at `span`; past `[st] variable_memory_bytes` in all, an
    /// error there (memory_limit.rs) and nothing reserved, so that offsets never wrap.
    pub fn alloc_var(&mut self, bytes: &[u8], file: usize, span: Span) -> u32 {
        if !self.total_within_limit(bytes.len() as u64, file, span) {
            return 0;
        }
        let at = self.image.len() as u32;
        self.image.extend_from_slice(bytes);
        at
    }

    /// Every name a scope can see, for suggestions.
    pub fn names_in(&self, scope: Scope) -> Vec<String> {
        let mut names = Vec::new();
        if let Some(p) = scope.pou {
            let pou = &self.pous[p];
            names.extend(pou.vars.iter().take(scope.visible).map(|v| v.name.clone()));
            if pou.kind == PouKind::Function {
                names.push(pou.name.clone());
            }
        }
        names.extend(self.globals.iter().map(|g| g.name.clone()));
        for e in &self.types.enums {
            names.extend(e.values.iter().map(|v| v.0.clone()));
        }
        names
    }
}

/// The edit distance of two names, ignoring case.
pub fn distance(a: &str, b: &str) -> usize {
    let a: Vec<char> = a.to_ascii_lowercase().chars().collect();
    let b: Vec<char> = b.to_ascii_lowercase().chars().collect();
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.iter().enumerate() {
        let mut cur = vec![i + 1; b.len() + 1];
        for (j, cb) in b.iter().enumerate() {
            let cost = usize::from(ca != cb);
            cur[j + 1] = (prev[j] + cost).min(prev[j + 1] + 1).min(cur[j] + 1);
        }
        prev = cur;
    }
    prev[b.len()]
}

/// ` (did you mean `x`?)` for the nearest of `names`, when near enough.
pub fn suggest<'n>(name: &str, names: impl IntoIterator<Item = &'n str>) -> String {
    let limit = (name.len() / 3).max(1);
    let best = names
        .into_iter()
        .filter(|n| !n.starts_with("__"))
        .map(|n| (distance(name, n), n))
        .filter(|(d, _)| *d <= limit)
        .min_by_key(|(d, _)| *d);
    match best {
        Some((_, n)) => format!(" (did you mean `{n}`?)"),
        None => String::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn suggestions_are_near_names() {
        assert_eq!(distance("spead", "speed"), 1);
        assert_eq!(suggest("spead", ["speed", "count"]), " (did you mean `speed`?)");
        assert_eq!(suggest("xyz", ["speed"]), "");
    }
}

/// A POU a body calls ([`PouInfo::callees`]).
#[derive(Clone, Copy, Debug)]
pub struct Callee {
    pub pou: usize,
    /// The first call's place.
    pub span: Span,
    /// Reached only as one of the bodies a call dispatches to at run time (a method through an
    /// interface, a method or action a derived block may replace): whether this callee runs
    /// is the receiver's to decide, so a cycle of calls through such an edge is no recursion
    /// the check can prove (`check_recursion`).
    pub dispatched: bool,
}

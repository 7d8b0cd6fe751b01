//! The syntax tree of a Structured Text file, as the parser builds it and the checker reads
//! it. Every node keeps the place it was written at, for diagnostics; names keep the spelling
//! they were written with and compare case-insensitively ([`Ident::is`]).

use std::path::PathBuf;

/// A place in a source file: 1-based line and column of a node's first character.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct Span {
    pub line: u32,
    pub col: u32,
}

/// A name as written.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Ident {
    pub name: String,
    pub span: Span,
}

impl Ident {
    /// Whether this is `other`, ignoring case (IEC names are case-insensitive).
    pub fn is(&self, other: &str) -> bool {
        self.name.eq_ignore_ascii_case(other)
    }
}

/// One parsed `.st` file.
#[derive(Debug, Clone, PartialEq)]
pub struct File {
    pub path: PathBuf,
    pub items: Vec<Item>,
    /// The non-standard forms the parser accepted, in the order met (refused by `[st] strict`).
    pub habits: Vec<crate::st::dialect::Noted>,
    /// The name of the global variable list its `VAR_GLOBAL` blocks form, which qualifies
    /// their variables (`GVL_Param.N`): a `.TcGVL`'s `<GVL Name>`; `None`, the file's stem.
    pub list_name: Option<String>,
    /// What a `{attribute 'qualified_only'}` stands before.
    pub qualified_only: QualifiedOnly,
}

/// The declarations of a file `{attribute 'qualified_only'}` stands before: its global
/// variable list's variables are then named `Gvl.x` only, an enumeration's values `E.Value`
/// (or `E#Value`) only.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct QualifiedOnly {
    /// Before a `VAR_GLOBAL` block: the file's list.
    pub globals: bool,
    /// Before `TYPE Name`: the types so named, as written.
    pub types: Vec<String>,
}

/// A top-level declaration.
#[derive(Debug, Clone, PartialEq)]
pub enum Item {
    Pou(Pou),
    /// `TYPE … END_TYPE` (one item per type declared in the block).
    Type(TypeDecl),
    /// A top-level `VAR_GLOBAL … END_VAR` block.
    Globals(VarBlock),
    /// `ACTION [Owner.]Name: … END_ACTION` outside any POU: an action of `owner`, or, without
    /// one, of the POU just before it in the file (as CODESYS exports them).
    Action {
        owner: Option<Ident>,
        action: Action,
    },
    /// `CONFIGURATION … END_CONFIGURATION`.
    Configuration(Configuration),
    /// `INTERFACE Name [EXTENDS I, …] … END_INTERFACE`.
    Interface(Interface),
}

/// Who may call a method or use a property (IEC 61131-3 ed. 3 access specifiers).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Access {
    #[default]
    Public,
    /// Only the function block's own code.
    Private,
    /// The function block's own code and that of the function blocks extending it.
    Protected,
    /// The same namespace: a plcd project is one, so as PUBLIC.
    Internal,
}

/// `METHOD [access] [ABSTRACT|FINAL] Name [: T] … END_METHOD`: a FUNCTION-like body on its
/// function block's instance. `pou` holds it as a FUNCTION (name, result, variables, body).
#[derive(Debug, Clone, PartialEq)]
pub struct Method {
    pub access: Access,
    pub is_abstract: bool,
    pub is_final: bool,
    pub pou: Pou,
}

/// `PROPERTY [access] Name : T GET … END_GET SET … END_SET END_PROPERTY`: each accessor a
/// method: GET returns the value in the property's name, SET has it as its VAR_INPUT.
#[derive(Debug, Clone, PartialEq)]
pub struct Property {
    pub name: Ident,
    pub ty: TypeRef,
    pub access: Access,
    pub is_abstract: bool,
    pub is_final: bool,
    pub get: Option<Pou>,
    pub set: Option<Pou>,
    /// The access specifier written after `GET` (CODESYS, TwinCAT: `<Get>`'s declaration):
    /// that accessor's own, in place of the property's.
    pub get_access: Option<Access>,
    /// The access specifier written after `SET`, as [`Property::get_access`].
    pub set_access: Option<Access>,
    pub span: Span,
}

/// `INTERFACE Name [EXTENDS I, …]`: methods and properties without bodies.
#[derive(Debug, Clone, PartialEq)]
pub struct Interface {
    pub name: Ident,
    pub extends: Vec<Ident>,
    pub methods: Vec<Method>,
    pub properties: Vec<Property>,
    pub span: Span,
    pub end: Span,
}

/// `CONFIGURATION Name … END_CONFIGURATION`: the resources, their tasks and program instances
/// (mapped onto plcd's tasks and `[[program]]`s, docs/ST.md), and global variables.
#[derive(Debug, Clone, PartialEq)]
pub struct Configuration {
    pub name: Ident,
    /// Its `VAR_GLOBAL` blocks and its resources'.
    pub globals: Vec<VarBlock>,
    /// `RESOURCE … END_RESOURCE` blocks; tasks and programs written directly in the
    /// configuration make one resource without a name.
    pub resources: Vec<Resource>,
    /// The entries of its `VAR_CONFIG` blocks.
    pub var_config: Vec<ConfigVar>,
    /// The entries of its `VAR_ACCESS` blocks.
    pub access: Vec<AccessDecl>,
    pub span: Span,
}

/// One entry of `VAR_CONFIG`: `instance.variable AT %QX0.1 : BOOL [:= init];`, the device of a
/// variable declared at a partly specified address (`AT %Q*`), or `instance.path : T := init;`,
/// the initial value of a variable of that instance.
#[derive(Debug, Clone, PartialEq)]
pub struct ConfigVar {
    /// The instance path as written (`instance`, `variable`, …).
    pub path: Vec<Ident>,
    /// The text after `AT %`, with the place of the `%`.
    pub location: Option<Ident>,
    /// The type written; `None` for an entry of the config's `[iec.variables]` (made into a
    /// `ConfigVar` to be bound as `VAR_CONFIG`'s are), which takes the variable's own.
    pub ty: Option<TypeRef>,
    pub init: Option<Init>,
    pub span: Span,
}

/// One entry of `VAR_ACCESS` (IEC 61131-3 §6.8.2): `name : path : TYPE [READ_ONLY |
/// READ_WRITE];`, the name under which clients reach the variable `path` (docs/ST.md,
/// Access paths).
#[derive(Debug, Clone, PartialEq)]
pub struct AccessDecl {
    pub name: Ident,
    /// The path as written (`Res0.inst.fb.x`, `n`); a direct address is one part, its text
    /// from the `%` on (`%IX1.1`).
    pub path: Vec<Ident>,
    /// The subscripts written after each part of `path`, one entry a part: its brackets'
    /// expressions (`arr[3]`: `[[3]]`; `m[1, 2]`: `[[1, 2]]`; `a[1][2]`: `[[1], [2]]`).
    pub subscripts: Vec<Vec<Vec<Expr>>>,
    pub ty: TypeRef,
    /// `READ_WRITE`; `READ_ONLY` (the default) is `false`.
    pub read_write: bool,
    pub span: Span,
}

/// `RESOURCE Name ON Type … END_RESOURCE`.
#[derive(Debug, Clone, PartialEq)]
pub struct Resource {
    pub name: Option<Ident>,
    pub tasks: Vec<TaskDecl>,
    pub programs: Vec<ProgramDecl>,
}

/// `TASK Name (INTERVAL := T#20ms, PRIORITY := 1);`: its properties as written.
#[derive(Debug, Clone, PartialEq)]
pub struct TaskDecl {
    pub name: Ident,
    pub properties: Vec<(Ident, ConfigValue)>,
    pub span: Span,
}

/// A value written in a configuration, where IEC 61131-3 accepts a direct address as well as
/// an expression (`SINGLE := %IX0.1`).
#[derive(Debug, Clone, PartialEq)]
pub enum ConfigValue {
    Expr(Expr),
    /// `%IX0.1`: the text after the `%`, with the place of the `%`.
    Location(Ident),
}

impl ConfigValue {
    pub fn span(&self) -> Span {
        match self {
            ConfigValue::Expr(e) => e.span,
            ConfigValue::Location(l) => l.span,
        }
    }
}

/// `PROGRAM name WITH task : Type (a := x, b => y);`.
#[derive(Debug, Clone, PartialEq)]
pub struct ProgramDecl {
    pub name: Ident,
    pub task: Option<Ident>,
    pub pou: Ident,
    /// `(…)` after the type: what is copied into its inputs before each run and out of its
    /// outputs after it.
    pub args: Vec<ProgramArg>,
    pub span: Span,
}

/// One argument of a program instance: `a := x` (`output` false) gives the VAR_INPUT `a` the
/// value `x`, `b => y` (`output` true) copies the VAR_OUTPUT `b` to `y`.
#[derive(Debug, Clone, PartialEq)]
pub struct ProgramArg {
    pub name: Ident,
    pub output: bool,
    pub value: ConfigValue,
}

/// `ACTION Name: … END_ACTION`: a body of a PROGRAM or FUNCTION_BLOCK on its variables, called
/// as `Name()` inside it or `inst.Name()` on an instance.
#[derive(Debug, Clone, PartialEq)]
pub struct Action {
    pub name: Ident,
    pub body: Vec<Stmt>,
    /// Where `ACTION` is.
    pub span: Span,
    /// Where its `END_ACTION` is.
    pub end: Span,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PouKind {
    Program,
    Function,
    FunctionBlock,
}

/// A PROGRAM, FUNCTION or FUNCTION_BLOCK.
#[derive(Debug, Clone, PartialEq)]
pub struct Pou {
    pub kind: PouKind,
    pub name: Ident,
    /// A FUNCTION's result type (`FUNCTION F : INT`).
    pub return_type: Option<TypeRef>,
    pub vars: Vec<VarBlock>,
    pub body: Vec<Stmt>,
    /// The actions declared inside it (`ACTION … END_ACTION` among its statements).
    pub actions: Vec<Action>,
    /// A FUNCTION_BLOCK's (or PROGRAM's) object orientation: `EXTENDS Base`, `IMPLEMENTS I,
    /// …`, `ABSTRACT`, `FINAL`, its methods and properties.
    pub oop: Oop,
    /// Its Sequential Function Chart, when its body is one (`STEP`, `TRANSITION`, …).
    pub sfc: Option<crate::st::sfc::Sfc>,
    /// The entries of its `VAR_ACCESS` blocks (a PROGRAM's, IEC 61131-3).
    pub access: Vec<AccessDecl>,
    /// Where the POU's keyword is.
    pub span: Span,
    /// Where its `END_…` keyword is (the line a breakpoint on the end stops at).
    pub end: Span,
}

/// What a POU declares of IEC 61131-3 ed. 3's object orientation.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Oop {
    /// Declared `CLASS … END_CLASS`: a function block without a body, inputs or outputs.
    pub is_class: bool,
    pub extends: Option<Ident>,
    /// `EXTENDS FB_Base<20>` (TwinCAT 3.1.4026): the base's generic constants, in order;
    /// `compile::generic_constants` names the base's copy for them in `extends` instead (boxed:
    /// most blocks have none, and a `Pou` is the largest item).
    pub extends_args: Option<Box<Vec<Expr>>>,
    pub implements: Vec<Ident>,
    pub is_abstract: bool,
    pub is_final: bool,
    pub methods: Vec<Method>,
    pub properties: Vec<Property>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum VarKind {
    /// `VAR`
    Local,
    /// `VAR_INPUT`
    Input,
    /// `VAR_OUTPUT`
    Output,
    /// `VAR_IN_OUT`
    InOut,
    /// `VAR_TEMP`
    Temp,
    /// `VAR_GLOBAL`
    Global,
    /// `VAR_EXTERNAL`
    External,
    /// `VAR_STAT` (CODESYS): one copy shared by every instance and call of the POU.
    Static,
    /// `VAR_INST` (CODESYS): kept in the function block's instance, like `VAR`.
    Instance,
    /// `VAR_GENERIC CONSTANT` (TwinCAT 3.1.4026): integer constants an instance's type gives
    /// (`fb : FB_Log<20>`); `compile::generic_constants` makes each a `VAR CONSTANT` of a copy
    /// of the block.
    Generic,
}

/// A `VAR… END_VAR` block.
#[derive(Debug, Clone, PartialEq)]
pub struct VarBlock {
    pub kind: VarKind,
    /// `CONSTANT`
    pub constant: bool,
    /// `RETAIN` (`NON_RETAIN` is the default and parses as `false`); `true` for a
    /// `PERSISTENT` block too.
    pub retain: bool,
    /// `PERSISTENT` (TwinCAT, CODESYS): retained, and kept by a cold reset as well.
    pub persistent: bool,
    pub span: Span,
    pub decls: Vec<VarDecl>,
}

/// `a, b AT %D00100 : INT := 5;`
#[derive(Debug, Clone, PartialEq)]
pub struct VarDecl {
    pub names: Vec<Ident>,
    /// The text after `AT %` (`D00100`, `IX0.0`), with the place of the `%`.
    pub location: Option<Ident>,
    pub ty: TypeRef,
    pub init: Option<Init>,
    /// `R_EDGE` or `F_EDGE` after the type (`start : BOOL R_EDGE;`), with its place.
    pub edge: Option<(Edge, Span)>,
    pub span: Span,
}

/// An edge declaration of a function block's input (IEC 61131-3 ed3): the body sees
/// the input TRUE only at the call where it rose (`R_EDGE`) or fell (`F_EDGE`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Edge {
    Rising,
    Falling,
}

/// A type as written where a type is expected.
#[derive(Debug, Clone, PartialEq)]
pub enum TypeRef {
    /// An elementary type, a declared TYPE or a FUNCTION_BLOCK, by name.
    Named(Ident),
    /// `STRING` (length 80) or `STRING[n]` / `STRING(n)`.
    String { len: Option<Box<Expr>>, span: Span },
    /// `WSTRING` (length 80) or `WSTRING[n]` / `WSTRING(n)`.
    WString { len: Option<Box<Expr>>, span: Span },
    /// `ARRAY [lo..hi, lo..hi] OF T`.
    Array { dims: Vec<(Expr, Expr)>, of: Box<TypeRef>, span: Span },
    /// `ARRAY [*, *] OF T` (IEC 61131-3 ed. 3, CODESYS): an array of `rank` dimensions whose
    /// bounds are the passed array's; only the type of a VAR_IN_OUT (`compile::varlen`).
    OpenArray { rank: usize, of: Box<TypeRef>, span: Span },
    /// An inline enumeration `(A, B := 5, C)`, in a variable declaration.
    Enum(EnumDef),
    /// A subrange `INT (0..100)`.
    Subrange { base: Ident, lo: Box<Expr>, hi: Box<Expr>, span: Span },
    /// `REF_TO T`, `POINTER TO T`, `REFERENCE TO T`.
    Ref { kind: RefKind, to: Box<TypeRef>, span: Span },
    /// `FB_Log<20>`, `FB<(N * 2), 5>`: a function block with generic constants (TwinCAT
    /// 3.1.4026), its arguments in order; `compile::generic_constants` replaces it by the
    /// block's copy for them, before any other stage.
    Generic { name: Ident, args: Vec<Expr>, span: Span },
}

/// The three kinds of reference types.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum RefKind {
    /// `REF_TO T` (IEC 61131-3 ed. 3): set with `REF(v)` or `NULL`, read through `r^`.
    RefTo,
    /// `POINTER TO T` (CODESYS): set with `ADR(v)`, read through `p^`, moved by `p + n`.
    Pointer,
    /// `REFERENCE TO T` (CODESYS): an alias, bound with `r REF= v`, used without `^`.
    Reference,
}

/// `TYPE Name : … END_TYPE`.
#[derive(Debug, Clone, PartialEq)]
pub struct TypeDecl {
    pub name: Ident,
    pub def: TypeDef,
    pub span: Span,
}

#[derive(Debug, Clone, PartialEq)]
pub enum TypeDef {
    /// `TYPE Speed : INT := 10; END_TYPE`, `TYPE Buf : ARRAY [0..9] OF INT; END_TYPE`.
    Alias { ty: TypeRef, init: Option<Init> },
    /// `STRUCT … END_STRUCT`.
    Struct { members: Vec<VarDecl> },
    /// `UNION … END_UNION` (CODESYS): members sharing the same bytes, from offset 0.
    Union { members: Vec<VarDecl> },
    /// `(Idle, Run := 5, Fault) := Idle` or with a base type `INT (…)`.
    Enum { def: EnumDef, init: Option<Ident> },
}

#[derive(Debug, Clone, PartialEq)]
pub struct EnumDef {
    /// `INT (A, B)`: the base type, `INT` when absent.
    pub base: Option<Ident>,
    pub values: Vec<(Ident, Option<Expr>)>,
    /// `T(5, 'A')`: a function block's declaration arguments when one is no name (or an
    /// output); `values` is then empty. Any other use of the form is an error.
    pub args: Vec<Arg>,
    pub span: Span,
}

/// An initial value.
#[derive(Debug, Clone, PartialEq)]
pub enum Init {
    Expr(Expr),
    /// `[1, 2, 3(0)]`: elements, `n(value)` repeats; `n()` repeats the default.
    Array {
        elems: Vec<ArrayInit>,
        span: Span,
    },
    /// `(a := 1, b := TRUE)`.
    Struct {
        members: Vec<(Ident, Init)>,
        span: Span,
    },
}

#[derive(Debug, Clone, PartialEq)]
pub enum ArrayInit {
    One(Init),
    Repeat { count: Expr, value: Option<Init> },
}

/// A statement.
#[derive(Debug, Clone, PartialEq)]
pub struct Stmt {
    pub kind: StmtKind,
    pub span: Span,
}

#[derive(Debug, Clone, PartialEq)]
pub enum StmtKind {
    /// `target := value`
    Assign {
        target: Expr,
        value: Expr,
    },
    /// A call as a statement: an FB instance (`t1(IN := x, PT := T#1s);`) or a function
    /// whose result is not used.
    Call(Expr),
    If {
        /// `IF c THEN …`, then each `ELSIF c THEN …`.
        branches: Vec<(Expr, Vec<Stmt>)>,
        /// `ELSE …`, with the place of `ELSE`.
        otherwise: Option<(Span, Vec<Stmt>)>,
    },
    Case {
        selector: Expr,
        arms: Vec<CaseArm>,
        otherwise: Option<(Span, Vec<Stmt>)>,
    },
    For {
        /// The control variable: a name, or (TwinCAT) an element or member of a local
        /// (`FOR a[1] := …`, `FOR s.n := …`).
        var: Expr,
        from: Expr,
        to: Expr,
        by: Option<Expr>,
        body: Vec<Stmt>,
    },
    While {
        cond: Expr,
        body: Vec<Stmt>,
    },
    Repeat {
        body: Vec<Stmt>,
        until: Expr,
    },
    Exit,
    Continue,
    Return,
    /// `r REF= v`: binds a `REFERENCE TO` (or sets any reference) to `v`.
    RefAssign {
        target: Expr,
        value: Expr,
    },
    /// A lone `;`.
    Empty,
    /// `name:` before a statement (CODESYS): where a `JMP name;` of the same body goes.
    Label(Ident),
    /// `JMP name;` (CODESYS): goes on at the label `name`.
    Jump(Ident),
}

/// `1, 3..5, Red: …`
#[derive(Debug, Clone, PartialEq)]
pub struct CaseArm {
    pub labels: Vec<CaseLabel>,
    pub body: Vec<Stmt>,
    pub span: Span,
}

#[derive(Debug, Clone, PartialEq)]
pub enum CaseLabel {
    Value(Expr),
    Range(Expr, Expr),
}

/// An expression.
#[derive(Debug, Clone, PartialEq)]
pub struct Expr {
    pub kind: ExprKind,
    pub span: Span,
}

#[derive(Debug, Clone, PartialEq)]
pub enum ExprKind {
    Literal(Literal),
    /// A variable, an enumeration value, a constant, by name.
    Name(Ident),
    /// `a.b`: a struct member, an FB instance's variable, a program's variable.
    Member(Box<Expr>, Ident),
    /// `a[i, j]`
    Index(Box<Expr>, Vec<Expr>),
    /// `a.3`: a bit of an integer or bit string (IEC partial access).
    Bit(Box<Expr>, u8),
    /// `dw.%B2`, `lw.%W3`, `lw.%D1`: a byte, word or double word of a bit string (IEC partial
    /// access); the number counts parts of that size from the least significant one.
    Part(Box<Expr>, PartSize, u8),
    /// `r^`: what a reference or pointer points to.
    Deref(Box<Expr>),
    Unary(UnaryOp, Box<Expr>),
    Binary(BinaryOp, Box<Expr>, Box<Expr>),
    /// `f(…)`, `fb(…)`, `inst.fb(…)`.
    Call {
        callee: Box<Expr>,
        args: Vec<Arg>,
    },
    /// `target := value` inside an expression (CODESYS): `b := FALSE` of `a := b := FALSE`,
    /// `(i := i + 1)` of `IF (i := i + 1) >= 3`. Its value is the value assigned.
    Assign(Box<Expr>, Box<Expr>),
}

/// The size of a part in a partial access: `%B`, `%W`, `%D`, `%L`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PartSize {
    Byte,
    Word,
    DWord,
    /// `%L`: read so that `lw.%L0` is reported as a part as wide as its variable (no type is
    /// wider than an `LWORD`).
    LWord,
}

impl PartSize {
    /// Its letter after the `%`.
    pub fn letter(self) -> char {
        match self {
            PartSize::Byte => 'B',
            PartSize::Word => 'W',
            PartSize::DWord => 'D',
            PartSize::LWord => 'L',
        }
    }

    /// How many bits it has.
    pub fn bits(self) -> u32 {
        match self {
            PartSize::Byte => 8,
            PartSize::Word => 16,
            PartSize::DWord => 32,
            PartSize::LWord => 64,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum UnaryOp {
    Neg,
    Plus,
    Not,
}

/// The binary operators; their precedence is the parser's (docs/ST.md has the table).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BinaryOp {
    Or,
    /// `OR_ELSE` (CODESYS): `OR` whose right operand is evaluated only when the left is FALSE.
    OrElse,
    Xor,
    And,
    /// `AND_THEN` (CODESYS): `AND` whose right operand is evaluated only when the left is TRUE.
    AndThen,
    Eq,
    Ne,
    Lt,
    Le,
    Gt,
    Ge,
    Add,
    Sub,
    Mul,
    Div,
    Mod,
    Pow,
}

/// A call argument.
#[derive(Debug, Clone, PartialEq)]
pub enum Arg {
    Positional(Expr),
    /// `IN := x`
    Input {
        name: Ident,
        value: Expr,
    },
    /// `Q => y`, or `NOT Q => y` when `negated`.
    Output {
        name: Ident,
        target: Expr,
        negated: bool,
    },
}

/// The prefix of the hidden type aliases the parser declares for the types of `__NEW(T, n)` and
/// `SIZEOF(T)` that are no name (`POINTER TO I`, `STRING(255)`), a number after it: the
/// argument is then the alias's name; compile/heap.rs renames them apart in the project.
pub const TYPE_ARGUMENT_PREFIX: &str = "__TYPE_ARGUMENT_";

/// A literal as written; its type is decided by the checker from the prefix or the context.
#[derive(Debug, Clone, PartialEq)]
pub enum Literal {
    /// `42`, `1_000`; the sign is a unary minus around it.
    Int(u128),
    /// `16#FF`, `2#1010`, `8#17`: an integer written with a base, which a signed type also
    /// takes as the bit pattern of its width (`INT#16#FFFF` is -1, as in CODESYS).
    Based(u128),
    /// `1.5`, `1.0E-3`.
    Real(f64),
    /// `TRUE`, `FALSE`.
    Bool(bool),
    /// `T#1s500ms`, `TIME#…`, `LTIME#…`: nanoseconds.
    Time(i128),
    /// `D#2024-03-01`, `TOD#12:30:15.5`, `DT#2024-03-01-12:30:15`, `LDATE#…`, `LTOD#…`,
    /// `LDT#…`: the stored count ([`crate::value::Calendar`]).
    Calendar(crate::value::Calendar, u64),
    /// `'text'` with `$` escapes resolved.
    String(String),
    /// `"text"` with `$` escapes resolved (a `WSTRING`).
    WString(String),
    /// `INT#5`, `REAL#1`, `BOOL#1`, `Color#Red`: a prefix naming the type, and the literal or
    /// name after `#`.
    Typed { ty: Ident, value: Box<Expr> },
}

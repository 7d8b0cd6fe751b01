//! Structured Text syntax: the lexer (`lex`) and the recursive-descent parser (`parse`).
//!
//! [`parse_file`] reports every syntax error of a file at once. Every message the lexer and the
//! parser can emit is a `Msg`; [`message_templates`] lists them all with `{}` for the parts
//! that vary, and the golden cases under `tests/golden/st-syntax` cover each template.

mod cond;
mod lex;
mod parse;
#[cfg(test)]
mod tests;

use std::path::Path;

use crate::diag::{Diagnostic, Diagnostics};
use crate::st::ast;

/// Parses one file: the tree of everything that parsed, and every syntax error.
pub fn parse_file(path: &Path, text: &str) -> (ast::File, Diagnostics) {
    parse_file_with(path, text, &[])
}

/// [`parse_file`] with `defines` defined for the file's conditional pragmas (`[st] defines`).
pub fn parse_file_with(path: &Path, text: &str, defines: &[String]) -> (ast::File, Diagnostics) {
    // a byte order mark is no character of the source (editors show none)
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let lexed = lex::lex_with(text, defines);
    let qualified_only = qualified_only(text, &lexed);
    let (items, mut habits, mut errors) =
        parse::parse(text, lexed.tokens, lexed.eof_in_comment, lexed.quiet);
    habits.extend(lexed.habits);
    habits.sort_by_key(|n| (n.span.line, n.span.col));
    errors.extend(lexed.errors);
    errors.sort_by_key(|(span, _)| (span.line, span.col));
    let mut diags = Diagnostics::default();
    for (span, msg) in errors {
        diags.push(Diagnostic::new(path, span.line, span.col, msg.to_string()));
    }
    let file =
        ast::File { path: path.to_path_buf(), items, habits, list_name: None, qualified_only };
    (file, diags)
}

/// What each `{attribute 'qualified_only'}` of a file stands before: `VAR_GLOBAL`, or
/// `TYPE Name` (other pragmas may come between).
fn qualified_only(text: &str, lexed: &lex::Lexed) -> ast::QualifiedOnly {
    use lex::{Kw, Tok};
    let mut found = ast::QualifiedOnly::default();
    for &at in &lexed.qualified_only {
        let Some(token) = lexed.tokens.get(at) else { continue };
        match token.kind {
            Tok::Kw(Kw::VarGlobal) => found.globals = true,
            Tok::Kw(Kw::Type) => {
                if let Some(name) = lexed.tokens.get(at + 1).filter(|t| t.kind == Tok::Ident) {
                    found.types.push(text[name.start as usize..name.end as usize].to_string());
                }
            }
            _ => {}
        }
    }
    found
}

/// Every message the lexer and the parser can emit, with `{}` where the message varies.
pub fn message_templates() -> Vec<String> {
    Msg::templates().iter().map(Msg::to_string).collect()
}

/// What the parser expected where it found something else.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Want {
    SemiAfterStmt,
    SemiAfterDecl,
    Stmt,
    Expr,
    RParen,
    RBracket,
    LBracket,
    CommaOrRParen,
    CommaOrRBracket,
    /// `*`: the next dimension of an `ARRAY [*, …]`.
    Star,
    Assign,
    Then,
    Do,
    Of,
    To,
    EndRepeat,
    Colon,
    Name,
    Type,
    DotDot,
    Item,
    VarDecl,
    TypeDecl,
    StructMember,
    UnionMember,
    Location,
    Field,
    TypedValue,
    CaseLabel,
    ConfigItem,
    EndStep,
    EndTransition,
    From,
    LParen,
    /// `,` or `>` after a generic constant's argument (`FB_Log<20>`).
    CommaOrAngle,
}

impl Want {
    pub(crate) const ALL: [Want; 35] = [
        Want::SemiAfterStmt,
        Want::SemiAfterDecl,
        Want::Stmt,
        Want::Expr,
        Want::RParen,
        Want::RBracket,
        Want::LBracket,
        Want::CommaOrRParen,
        Want::CommaOrRBracket,
        Want::Star,
        Want::Assign,
        Want::Then,
        Want::Do,
        Want::Of,
        Want::To,
        Want::EndRepeat,
        Want::Colon,
        Want::Name,
        Want::Type,
        Want::DotDot,
        Want::Item,
        Want::VarDecl,
        Want::TypeDecl,
        Want::StructMember,
        Want::UnionMember,
        Want::Location,
        Want::Field,
        Want::TypedValue,
        Want::CaseLabel,
        Want::ConfigItem,
        Want::EndStep,
        Want::EndTransition,
        Want::From,
        Want::LParen,
        Want::CommaOrAngle,
    ];

    fn text(self) -> &'static str {
        match self {
            Want::SemiAfterStmt => "`;` after the statement",
            Want::SemiAfterDecl => "`;` after the declaration",
            Want::Stmt => "a statement",
            Want::Expr => "an expression",
            Want::RParen => "`)`",
            Want::RBracket => "`]`",
            Want::LBracket => "`[`",
            Want::CommaOrRParen => "`,` or `)`",
            Want::CommaOrRBracket => "`,` or `]`",
            Want::CommaOrAngle => "`,` or `>`",
            Want::Star => "`*` (every dimension of an `ARRAY [*, …]` is open)",
            Want::Assign => "`:=`",
            Want::Then => "`THEN`",
            Want::Do => "`DO`",
            Want::Of => "`OF`",
            Want::To => "`TO`",
            Want::EndRepeat => "`END_REPEAT`",
            Want::Colon => "`:`",
            Want::Name => "a name",
            Want::Type => "a type",
            Want::DotDot => "`..`",
            Want::Item => {
                "`PROGRAM`, `FUNCTION`, `FUNCTION_BLOCK`, `TYPE`, `VAR_GLOBAL`, `ACTION`, `INTERFACE`, `CLASS` or `CONFIGURATION`"
            }
            Want::VarDecl => "a variable name or `END_VAR`",
            Want::TypeDecl => "a type name or `END_TYPE`",
            Want::StructMember => "a member name or `END_STRUCT`",
            Want::UnionMember => "a member name or `END_UNION`",
            Want::Location => "an address `%…` after `AT`",
            Want::Field => "a member name or a bit number after `.`",
            Want::TypedValue => "a literal after the type prefix",
            Want::CaseLabel => "a case label",
            Want::ConfigItem => "`RESOURCE`, `TASK`, `PROGRAM`, `VAR_GLOBAL` or the end",
            Want::EndStep => "an action association or `END_STEP`",
            Want::EndTransition => "`END_TRANSITION`",
            Want::From => "`FROM`",
            Want::LParen => "`(`",
        }
    }
}

/// A construct that an `END_…` keyword closes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Closer {
    If,
    Case,
    For,
    While,
    Repeat,
    Program,
    Function,
    FunctionBlock,
    Type,
    Struct,
    /// CODESYS's `UNION … END_UNION`.
    Union,
    Var,
    Action,
    Configuration,
    Resource,
    Method,
    Property,
    Get,
    Set,
    Interface,
    Class,
}

impl Closer {
    pub(crate) const ALL: [Closer; 21] = [
        Closer::If,
        Closer::Case,
        Closer::For,
        Closer::While,
        Closer::Repeat,
        Closer::Program,
        Closer::Function,
        Closer::FunctionBlock,
        Closer::Type,
        Closer::Struct,
        Closer::Union,
        Closer::Var,
        Closer::Action,
        Closer::Configuration,
        Closer::Resource,
        Closer::Method,
        Closer::Property,
        Closer::Get,
        Closer::Set,
        Closer::Interface,
        Closer::Class,
    ];

    /// The keyword that closes it.
    pub(crate) fn end(self) -> &'static str {
        match self {
            Closer::If => "END_IF",
            Closer::Case => "END_CASE",
            Closer::For => "END_FOR",
            Closer::While => "END_WHILE",
            Closer::Repeat => "UNTIL",
            Closer::Program => "END_PROGRAM",
            Closer::Function => "END_FUNCTION",
            Closer::FunctionBlock => "END_FUNCTION_BLOCK",
            Closer::Type => "END_TYPE",
            Closer::Struct => "END_STRUCT",
            Closer::Union => "END_UNION",
            Closer::Var => "END_VAR",
            Closer::Action => "END_ACTION",
            Closer::Configuration => "END_CONFIGURATION",
            Closer::Resource => "END_RESOURCE",
            Closer::Method => "END_METHOD",
            Closer::Property => "END_PROPERTY",
            Closer::Get => "END_GET",
            Closer::Set => "END_SET",
            Closer::Interface => "END_INTERFACE",
            Closer::Class => "END_CLASS",
        }
    }

    /// The keyword that opens it (a VAR block names its own keyword).
    fn opener(self) -> &'static str {
        match self {
            Closer::If => "IF",
            Closer::Case => "CASE",
            Closer::For => "FOR",
            Closer::While => "WHILE",
            Closer::Repeat => "REPEAT",
            Closer::Program => "PROGRAM",
            Closer::Function => "FUNCTION",
            Closer::FunctionBlock => "FUNCTION_BLOCK",
            Closer::Type => "TYPE",
            Closer::Struct => "STRUCT",
            Closer::Union => "UNION",
            Closer::Var => "{}",
            Closer::Action => "ACTION",
            Closer::Configuration => "CONFIGURATION",
            Closer::Resource => "RESOURCE",
            Closer::Method => "METHOD",
            Closer::Property => "PROPERTY",
            Closer::Get => "GET",
            Closer::Set => "SET",
            Closer::Interface => "INTERFACE",
            Closer::Class => "CLASS",
        }
    }
}

/// One diagnostic message. The variable parts are text, so that [`Msg::templates`] can fill
/// them with `{}`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum Msg {
    /// `expected X, found Y`: `found` is a token in backticks or `end of file`.
    Expected {
        want: Want,
        found: String,
    },
    /// `END_IF` expected to close the IF at line 3, found `END_PROGRAM`.
    Unclosed {
        closer: Closer,
        opener: String,
        line: String,
        found: String,
    },
    UnterminatedComment {
        line: String,
    },
    UnterminatedPragma {
        line: String,
    },
    /// `(*@KEY@:DESCRIPTION*)` without its `(*@KEY@:END_DESCRIPTION*)`.
    UnterminatedDescription {
        line: String,
    },
    UnterminatedString,
    NotANumber {
        text: String,
    },
    OutOfRange {
        text: String,
    },
    DurationUnit {
        text: String,
        unit: String,
    },
    DurationNoUnit {
        text: String,
        after: String,
    },
    DurationNoNumber {
        text: String,
        found: String,
    },
    /// `` `D#2024-13-01` is not a valid DATE: month 13 is not 1 to 12 ``.
    Calendar {
        text: String,
        ty: String,
        why: String,
    },
    BadEscape {
        escape: String,
    },
    UnexpectedChar {
        ch: String,
    },
    NoAddress,
    BitTooLarge {
        text: String,
    },
    TooDeep,
    /// A METHOD or PROPERTY at the top level after no FUNCTION_BLOCK or PROGRAM.
    MemberOutside,
    /// `{define}` or `{undefine}` (as written) without a name.
    CondName {
        directive: String,
    },
    /// `{ELSIF}`, `{ELSE}` or `{END_IF}` (as written) with no `{IF}` open.
    CondStray {
        directive: String,
    },
    /// `{ELSIF}` or `{ELSE}` after the `{ELSE}` of its `{IF}`.
    CondAfterElse {
        directive: String,
    },
    /// A condition that is not `defined (name)` joined with NOT, AND, OR and parentheses.
    CondExpr,
    /// A predicate of CODESYS's conditions plcd does not evaluate (`hasvalue`, `defined
    /// (variable: …)`).
    CondPredicate {
        predicate: String,
    },
    /// An `{IF}` without its `{END_IF}` at the end of the file.
    CondUnclosed,
}

/// How deeply expressions, statements and initial values may nest.
pub(crate) const MAX_DEPTH: usize = 64;

/// The comment that opens a POU's description in KW-Software MULTIPROG's ST export (Phoenix
/// Contact PC WORX), free text up to [`DESCRIPTION_END`] (`lex`).
pub(crate) const DESCRIPTION: &str = "(*@KEY@:DESCRIPTION*)";
/// The comment that ends such a description.
pub(crate) const DESCRIPTION_END: &str = "(*@KEY@:END_DESCRIPTION*)";

impl Msg {
    /// One message of each kind, its varying parts `{}`.
    pub(crate) fn templates() -> Vec<Msg> {
        let h = || "{}".to_string();
        let mut all: Vec<Msg> =
            Want::ALL.iter().map(|&want| Msg::Expected { want, found: h() }).collect();
        all.extend(Closer::ALL.iter().map(|&closer| Msg::Unclosed {
            closer,
            opener: h(),
            line: h(),
            found: h(),
        }));
        all.extend([
            Msg::UnterminatedComment { line: h() },
            Msg::UnterminatedPragma { line: h() },
            Msg::UnterminatedDescription { line: h() },
            Msg::UnterminatedString,
            Msg::NotANumber { text: h() },
            Msg::OutOfRange { text: h() },
            Msg::DurationUnit { text: h(), unit: h() },
            Msg::DurationNoUnit { text: h(), after: h() },
            Msg::DurationNoNumber { text: h(), found: h() },
            Msg::BadEscape { escape: h() },
            Msg::UnexpectedChar { ch: h() },
            Msg::NoAddress,
            Msg::BitTooLarge { text: h() },
            Msg::TooDeep,
            Msg::MemberOutside,
            Msg::CondName { directive: h() },
            Msg::CondStray { directive: h() },
            Msg::CondAfterElse { directive: h() },
            Msg::CondExpr,
            Msg::CondPredicate { predicate: h() },
            Msg::CondUnclosed,
        ]);
        all.extend(crate::value::CalendarError::TEMPLATES.iter().map(|why| Msg::Calendar {
            text: h(),
            ty: h(),
            why: why.to_string(),
        }));
        all
    }
}

impl std::fmt::Display for Msg {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Msg::Expected { want, found } => write!(f, "expected {}, found {found}", want.text()),
            Msg::Unclosed { closer, opener, line, found } => {
                let opener = if *closer == Closer::Var { opener } else { closer.opener() };
                write!(
                    f,
                    "`{}` expected to close the {opener} at line {line}, found {found}",
                    closer.end()
                )
            }
            Msg::UnterminatedComment { line } => {
                write!(f, "unterminated comment (opened at line {line})")
            }
            Msg::UnterminatedPragma { line } => {
                write!(f, "unterminated pragma (opened at line {line})")
            }
            Msg::UnterminatedDescription { line } => write!(
                f,
                "no `{DESCRIPTION_END}` closes the description `{DESCRIPTION}` opened at line {line}"
            ),
            Msg::UnterminatedString => write!(f, "unterminated string"),
            Msg::NotANumber { text } => write!(f, "`{text}` is not a number"),
            Msg::OutOfRange { text } => write!(f, "`{text}` is out of range"),
            Msg::DurationUnit { text, unit } => {
                write!(f, "`{text}` is not a duration: unknown unit `{unit}`")
            }
            Msg::DurationNoUnit { text, after } => {
                write!(f, "`{text}` is not a duration: missing unit after `{after}`")
            }
            Msg::DurationNoNumber { text, found } => {
                write!(f, "`{text}` is not a duration: expected a number, found {found}")
            }
            Msg::Calendar { text, ty, why } => write!(f, "`{text}` is not a valid {ty}: {why}"),
            Msg::BadEscape { escape } => write!(f, "invalid escape `{escape}` in a string"),
            Msg::UnexpectedChar { ch } => write!(f, "unexpected character `{ch}`"),
            Msg::NoAddress => write!(f, "expected an address after `%`"),
            Msg::BitTooLarge { text } => write!(f, "bit number `{text}` is too large"),
            Msg::TooDeep => write!(f, "nested more than {MAX_DEPTH} levels deep"),
            Msg::MemberOutside => write!(
                f,
                "a METHOD or PROPERTY belongs to a FUNCTION_BLOCK: write it inside one, or right after its END_FUNCTION_BLOCK"
            ),
            Msg::CondName { directive } => write!(f, "`{{{directive}}}` needs a name: `{{{directive} name}}`"),
            Msg::CondStray { directive } => write!(f, "`{{{directive}}}` without an `{{IF}}` open"),
            Msg::CondAfterElse { directive } => {
                write!(f, "`{{{directive}}}` after the `{{ELSE}}` of its `{{IF}}`")
            }
            Msg::CondExpr => write!(
                f,
                "expected a condition: `defined (name)`, with NOT, AND, OR and parentheses"
            ),
            Msg::CondPredicate { predicate } => write!(
                f,
                "`{predicate}` is not supported in a conditional pragma: plcd tests `defined (name)` of `{{define}}` and `[st] defines`"
            ),
            Msg::CondUnclosed => write!(f, "`{{IF}}` without its `{{END_IF}}`"),
        }
    }
}

//! The recursive-descent parser: tokens → [`ast::Item`]s, with every syntax error.
//!
//! Recovery: an error inside a statement skips to its `;` (or to the next statement keyword or
//! block keyword), inside a declaration to its `;` (or `END_VAR`). A construct whose `END_…`
//! is missing is reported once, where something else was found; a stray `END_…` that closes
//! nothing open is taken for a misspelt end of the innermost construct. At most one error is
//! reported at any one token, so one mistake makes one diagnostic.

mod access;
mod assign_expr;
mod sfc;

use super::lex::{Kw, Tok, Token, P};
use super::{Closer, Msg, Want, MAX_DEPTH};
use crate::st::ast::*;
use crate::st::dialect::{Habit, Noted};

/// An error was reported; the caller recovers.
#[derive(Debug)]
pub(crate) struct Failed;

type PResult<T> = Result<T, Failed>;

/// Parses a whole file.
pub(crate) fn parse(
    text: &str,
    tokens: Vec<Token>,
    eof_in_comment: bool,
    quiet: Vec<usize>,
) -> (Vec<Item>, Vec<Noted>, Vec<(Span, Msg)>) {
    let mut parser = Parser::new(text, tokens, eof_in_comment);
    parser.quiet = quiet;
    let mut items = parser.file();
    items.extend(parser.hidden_types.drain(..).map(Item::Type));
    (items, parser.habits, parser.errors)
}

/// Parses one expression that must fill `text` (for the tests).
#[cfg(test)]
pub(crate) fn parse_expr(text: &str) -> Result<Expr, Vec<(Span, Msg)>> {
    let lexed = super::lex::lex(text);
    let mut parser = Parser::new(text, lexed.tokens, false);
    let expr = parser.expr();
    if expr.is_ok() && !parser.at(&Tok::Eof) {
        let _ = parser.fail(Want::Semi);
    }
    let mut errors = lexed.errors;
    errors.extend(parser.errors);
    match expr {
        Ok(expr) if errors.is_empty() => Ok(expr),
        _ => Err(errors),
    }
}

#[cfg(test)]
impl Want {
    #[allow(non_upper_case_globals)]
    const Semi: Want = Want::SemiAfterStmt;
}

pub(crate) struct Parser<'a> {
    text: &'a str,
    tokens: Vec<Token>,
    pos: usize,
    errors: Vec<(Span, Msg)>,
    /// The token of the last error: no second error there.
    last_error: Option<usize>,
    /// Whether that error was a missing `END_…` (several may be missing at one token).
    last_unclosed: bool,
    eof_in_comment: bool,
    /// Tokens where no error is reported (see `Lexed::quiet`), sorted.
    quiet: Vec<usize>,
    /// The constructs open around the current statement, innermost last.
    open: Vec<Closer>,
    depth: usize,
    /// The non-standard forms accepted so far.
    habits: Vec<Noted>,
    /// The types of `__NEW(T, n)` and `SIZEOF(T)` that are no name, each a hidden alias
    /// ([`TYPE_ARGUMENT_PREFIX`]).
    hidden_types: Vec<TypeDecl>,
}

/// The word that opens a block of generic constants (TwinCAT 3.1.4026; not a keyword, as
/// TwinCAT's other words are not).
const VAR_GENERIC: &str = "VAR_GENERIC";

/// The binary operators' levels, lowest first; unary operators sit between `*` and `**`.
const LEVEL_OR: u8 = 1;
const LEVEL_ADD: u8 = 6;
const LEVEL_MUL: u8 = 7;

/// One step of a partial access token: a part (its size, none for a bit, and its number), or a
/// member after it (`s.%B1.m` is one token).
#[derive(Clone)]
enum PartialStep {
    Part(Option<PartSize>, u8),
    Member(Ident),
}

/// The expression of one partial access step on `base`.
fn partial_kind(base: Expr, step: PartialStep) -> ExprKind {
    match step {
        PartialStep::Part(None, n) => ExprKind::Bit(Box::new(base), n),
        PartialStep::Part(Some(size), n) => ExprKind::Part(Box::new(base), size, n),
        PartialStep::Member(name) => ExprKind::Member(Box::new(base), name),
    }
}

/// The number of a partial access step: decimal digits that fit a `u8`.
fn partial_number(digits: &str) -> Option<u8> {
    if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    digits.parse().ok()
}

fn binary_op(tok: &Tok, level: u8) -> Option<BinaryOp> {
    let op = match tok {
        Tok::Kw(Kw::Or) => BinaryOp::Or,
        Tok::Kw(Kw::OrElse) => BinaryOp::OrElse,
        Tok::Kw(Kw::AndThen) => BinaryOp::AndThen,
        Tok::Kw(Kw::Xor) => BinaryOp::Xor,
        Tok::Kw(Kw::And) | Tok::P(P::Amp) => BinaryOp::And,
        Tok::P(P::Eq) => BinaryOp::Eq,
        Tok::P(P::Ne) => BinaryOp::Ne,
        Tok::P(P::Lt) => BinaryOp::Lt,
        Tok::P(P::Le) => BinaryOp::Le,
        Tok::P(P::Gt) => BinaryOp::Gt,
        Tok::P(P::Ge) => BinaryOp::Ge,
        Tok::P(P::Plus) => BinaryOp::Add,
        Tok::P(P::Minus) => BinaryOp::Sub,
        Tok::P(P::Star) => BinaryOp::Mul,
        Tok::P(P::Slash) => BinaryOp::Div,
        Tok::Kw(Kw::Mod) => BinaryOp::Mod,
        _ => return None,
    };
    (op_level(op) == level).then_some(op)
}

/// The level of a binary operator: 1 (`OR`) to 7 (`*`), and 9 for `**`.
pub(crate) fn op_level(op: BinaryOp) -> u8 {
    match op {
        // CODESYS ranks AND_THEN with AND and OR_ELSE with OR
        BinaryOp::Or | BinaryOp::OrElse => 1,
        BinaryOp::Xor => 2,
        BinaryOp::And | BinaryOp::AndThen => 3,
        BinaryOp::Eq | BinaryOp::Ne => 4,
        BinaryOp::Lt | BinaryOp::Le | BinaryOp::Gt | BinaryOp::Ge => 5,
        BinaryOp::Add | BinaryOp::Sub => 6,
        BinaryOp::Mul | BinaryOp::Div | BinaryOp::Mod => 7,
        BinaryOp::Pow => 9,
    }
}

fn unary_op(tok: &Tok) -> Option<UnaryOp> {
    match tok {
        Tok::P(P::Minus) => Some(UnaryOp::Neg),
        Tok::P(P::Plus) => Some(UnaryOp::Plus),
        Tok::Kw(Kw::Not) => Some(UnaryOp::Not),
        _ => None,
    }
}

fn var_kind(tok: &Tok) -> Option<VarKind> {
    Some(match tok {
        Tok::Kw(Kw::Var) => VarKind::Local,
        Tok::Kw(Kw::VarInput) => VarKind::Input,
        Tok::Kw(Kw::VarOutput) => VarKind::Output,
        Tok::Kw(Kw::VarInOut) => VarKind::InOut,
        Tok::Kw(Kw::VarTemp) => VarKind::Temp,
        Tok::Kw(Kw::VarGlobal) => VarKind::Global,
        Tok::Kw(Kw::VarExternal) => VarKind::External,
        Tok::Kw(Kw::VarStat) => VarKind::Static,
        Tok::Kw(Kw::VarInst) => VarKind::Instance,
        _ => return None,
    })
}

/// Keywords that start a top-level item, and the end of the file.
fn is_top(tok: &Tok) -> bool {
    matches!(
        tok,
        Tok::Eof
            | Tok::Kw(
                Kw::Program
                    | Kw::Function
                    | Kw::FunctionBlock
                    | Kw::Type
                    | Kw::Action
                    | Kw::Method
                    | Kw::Property
                    | Kw::Interface
                    | Kw::Class
                    | Kw::Configuration
            )
    )
}

fn is_stmt_keyword(tok: &Tok) -> bool {
    matches!(
        tok,
        Tok::Kw(
            Kw::If
                | Kw::Case
                | Kw::For
                | Kw::While
                | Kw::Repeat
                | Kw::Exit
                | Kw::Continue
                | Kw::Return
        )
    )
}

fn is_pou_end(kw: Kw) -> bool {
    matches!(kw, Kw::EndProgram | Kw::EndFunction | Kw::EndFunctionBlock | Kw::EndClass)
}

/// `END_…`, `ELSE`, `ELSIF`, `UNTIL`: what ends a list of statements.
fn is_closer(tok: &Tok) -> bool {
    match tok {
        Tok::Kw(kw) => kw.is_end() || matches!(kw, Kw::Else | Kw::Elsif | Kw::Until),
        _ => false,
    }
}

impl Closer {
    /// Whether `kw` continues or ends this construct.
    fn accepts(self, kw: Kw) -> bool {
        match self {
            Closer::If => matches!(kw, Kw::Elsif | Kw::Else | Kw::EndIf),
            Closer::Case => matches!(kw, Kw::Else | Kw::EndCase),
            Closer::For => kw == Kw::EndFor,
            Closer::While => kw == Kw::EndWhile,
            Closer::Repeat => kw == Kw::Until,
            Closer::Program => kw == Kw::EndProgram,
            Closer::Function => kw == Kw::EndFunction,
            Closer::FunctionBlock => kw == Kw::EndFunctionBlock,
            Closer::Type => kw == Kw::EndType,
            Closer::Struct => kw == Kw::EndStruct,
            Closer::Union => kw == Kw::EndUnion,
            Closer::Var => kw == Kw::EndVar,
            Closer::Action => kw == Kw::EndAction,
            Closer::Configuration => kw == Kw::EndConfiguration,
            Closer::Resource => kw == Kw::EndResource,
            Closer::Method => kw == Kw::EndMethod,
            Closer::Property => kw == Kw::EndProperty,
            Closer::Get => kw == Kw::EndGet,
            Closer::Set => kw == Kw::EndSet,
            Closer::Interface => kw == Kw::EndInterface,
            Closer::Class => kw == Kw::EndClass,
        }
    }

    fn end_kw(self) -> Kw {
        match self {
            Closer::If => Kw::EndIf,
            Closer::Case => Kw::EndCase,
            Closer::For => Kw::EndFor,
            Closer::While => Kw::EndWhile,
            Closer::Repeat => Kw::Until,
            Closer::Program => Kw::EndProgram,
            Closer::Function => Kw::EndFunction,
            Closer::FunctionBlock => Kw::EndFunctionBlock,
            Closer::Type => Kw::EndType,
            Closer::Struct => Kw::EndStruct,
            Closer::Union => Kw::EndUnion,
            Closer::Var => Kw::EndVar,
            Closer::Action => Kw::EndAction,
            Closer::Configuration => Kw::EndConfiguration,
            Closer::Resource => Kw::EndResource,
            Closer::Method => Kw::EndMethod,
            Closer::Property => Kw::EndProperty,
            Closer::Get => Kw::EndGet,
            Closer::Set => Kw::EndSet,
            Closer::Interface => Kw::EndInterface,
            Closer::Class => Kw::EndClass,
        }
    }
}

/// The keyword that ends a compound statement; `None` for a simple one.
fn compound_end(kind: &StmtKind) -> Option<&'static str> {
    match kind {
        StmtKind::If { .. } => Some("END_IF"),
        StmtKind::Case { .. } => Some("END_CASE"),
        StmtKind::For { .. } => Some("END_FOR"),
        StmtKind::While { .. } => Some("END_WHILE"),
        StmtKind::Repeat { .. } => Some("END_REPEAT"),
        _ => None,
    }
}

fn dummy_expr(span: Span) -> Expr {
    Expr { kind: ExprKind::Literal(Literal::Bool(false)), span }
}

impl<'a> Parser<'a> {
    fn new(text: &'a str, tokens: Vec<Token>, eof_in_comment: bool) -> Parser<'a> {
        Parser {
            text,
            tokens,
            pos: 0,
            errors: Vec::new(),
            last_error: None,
            last_unclosed: false,
            eof_in_comment,
            quiet: Vec::new(),
            open: Vec::new(),
            depth: 0,
            habits: Vec::new(),
            hidden_types: Vec::new(),
        }
    }

    /// Notes a non-standard form accepted at the current token.
    fn habit(&mut self, habit: Habit) {
        let span = self.span();
        self.habits.push(Noted { span, habit });
    }

    // ----- tokens -----

    fn tok(&self) -> &Tok {
        &self.tokens[self.pos].kind
    }

    fn tok_at(&self, n: usize) -> &Tok {
        let last = self.tokens.len() - 1;
        &self.tokens[(self.pos + n).min(last)].kind
    }

    fn span(&self) -> Span {
        self.tokens[self.pos].span
    }

    fn at(&self, tok: &Tok) -> bool {
        self.tok() == tok
    }

    fn at_kw(&self, kw: Kw) -> bool {
        *self.tok() == Tok::Kw(kw)
    }

    fn at_p(&self, p: P) -> bool {
        *self.tok() == Tok::P(p)
    }

    fn text_of(&self, index: usize) -> &'a str {
        let t = &self.tokens[index];
        &self.text[t.start as usize..t.end as usize]
    }

    /// Moves on (never past the end of file).
    fn bump(&mut self) -> usize {
        let at = self.pos;
        if self.pos + 1 < self.tokens.len() {
            self.pos += 1;
        }
        at
    }

    fn eat_kw(&mut self, kw: Kw) -> bool {
        let yes = self.at_kw(kw);
        if yes {
            self.bump();
        }
        yes
    }

    fn eat_p(&mut self, p: P) -> bool {
        let yes = self.at_p(p);
        if yes {
            self.bump();
        }
        yes
    }

    /// The current token for a message: `` `x` `` or `end of file`.
    fn found(&self) -> String {
        if self.at(&Tok::Eof) {
            return "end of file".to_string();
        }
        let text = self.text_of(self.pos);
        if text.chars().count() > 30 {
            let short: String = text.chars().take(29).collect();
            format!("`{short}…`")
        } else {
            format!("`{text}`")
        }
    }

    // ----- errors -----

    /// Reports `msg` at the current token, unless an error was already reported there (or the
    /// file ends in an unterminated comment, reported by the lexer).
    fn report(&mut self, msg: Msg) {
        let unclosed = matches!(msg, Msg::Unclosed { .. });
        let again = self.last_error == Some(self.pos) && !(unclosed && self.last_unclosed);
        let quiet = self.quiet.binary_search(&self.pos).is_ok();
        if again || quiet || (self.eof_in_comment && self.at(&Tok::Eof)) {
            return;
        }
        self.last_error = Some(self.pos);
        self.last_unclosed = unclosed;
        let span = self.span();
        self.errors.push((span, msg));
    }

    /// Reports `msg` at `span` (a construct already read).
    fn report_at(&mut self, span: Span, msg: Msg) {
        self.errors.push((span, msg));
    }

    fn fail(&mut self, want: Want) -> Failed {
        let found = self.found();
        self.report(Msg::Expected { want, found });
        Failed
    }

    fn expect_p(&mut self, p: P, want: Want) -> PResult<()> {
        if self.eat_p(p) {
            Ok(())
        } else {
            Err(self.fail(want))
        }
    }

    /// Like `expect_p`, but goes on as if the keyword were there.
    fn expect_kw_soft(&mut self, kw: Kw, want: Want) {
        if !self.eat_kw(kw) {
            let _ = self.fail(want);
        }
    }

    fn expect_p_soft(&mut self, p: P, want: Want) {
        if !self.eat_p(p) {
            let _ = self.fail(want);
        }
    }

    fn ident(&mut self) -> PResult<Ident> {
        if self.at(&Tok::Ident) {
            let span = self.span();
            let name = {
                let at = self.bump();
                self.text_of(at)
            }
            .to_string();
            Ok(Ident { name, span })
        } else {
            Err(self.fail(Want::Name))
        }
    }

    fn enter(&mut self) -> PResult<()> {
        if self.depth >= MAX_DEPTH {
            self.report(Msg::TooDeep);
            return Err(Failed);
        }
        self.depth += 1;
        Ok(())
    }

    /// The keyword `closer` ends the construct opened at `opened` (its keyword `opener`): its
    /// place, or `None` after reporting that it is missing.
    fn close(&mut self, closer: Closer, opener: &str, opened: Span) -> Option<Span> {
        let span = self.span();
        if self.eat_kw(closer.end_kw()) {
            return Some(span);
        }
        let found = self.found();
        self.report(Msg::Unclosed {
            closer,
            opener: opener.to_string(),
            line: opened.line.to_string(),
            found,
        });
        // A stray `END_…` that closes nothing open is a misspelt end: a statement's of a
        // statement, a POU's of a POU.
        if let Tok::Kw(kw) = *self.tok() {
            let misspelt = match closer {
                Closer::Program
                | Closer::Function
                | Closer::FunctionBlock
                | Closer::Action
                | Closer::Method
                | Closer::Property
                | Closer::Interface
                | Closer::Class => {
                    is_pou_end(kw)
                        || matches!(
                            kw,
                            Kw::EndAction | Kw::EndMethod | Kw::EndProperty | Kw::EndInterface
                        )
                }
                Closer::Type | Closer::Struct | Closer::Union | Closer::Var => false,
                Closer::Configuration | Closer::Resource => {
                    matches!(kw, Kw::EndConfiguration | Kw::EndResource)
                }
                _ => kw.is_end() && !is_pou_end(kw),
            };
            if misspelt && !self.open.iter().any(|c| c.accepts(kw)) {
                self.bump();
            }
        }
        None
    }

    /// After an error in a statement: on to the next `;` (past it), statement keyword, block
    /// keyword or the end.
    fn sync_stmt(&mut self) {
        loop {
            let tok = self.tok();
            if *tok == Tok::P(P::Semi) {
                self.bump();
                return;
            }
            if is_top(tok) || is_stmt_keyword(tok) || is_closer(tok) || var_kind(tok).is_some() {
                return;
            }
            self.bump();
        }
    }

    /// [`Parser::sync_stmt`] in a loop that began at token `before`: at least one token on,
    /// so that a statement keyword where the loop wanted something else (a `CONTINUE` where a
    /// CASE label belongs) cannot make it go round for ever.
    fn sync_stmt_from(&mut self, before: usize) {
        self.sync_stmt();
        if self.pos == before {
            // The statement keyword and the rest of its statement.
            self.bump();
            self.sync_stmt();
        }
    }

    /// After an error in a declaration: on to the next `;` (past it), `END_…` or block keyword.
    fn sync_decl(&mut self) {
        loop {
            let tok = self.tok();
            if *tok == Tok::P(P::Semi) {
                self.bump();
                return;
            }
            if is_top(tok) || is_stmt_keyword(tok) || is_closer(tok) || var_kind(tok).is_some() {
                return;
            }
            self.bump();
        }
    }

    // ----- the file -----

    fn file(&mut self) -> Vec<Item> {
        let mut items = Vec::new();
        loop {
            match *self.tok() {
                Tok::Eof => return items,
                Tok::Kw(Kw::Program) => items.push(Item::Pou(self.pou(PouKind::Program))),
                Tok::Kw(Kw::Function) => items.push(Item::Pou(self.pou(PouKind::Function))),
                Tok::Kw(Kw::FunctionBlock) => {
                    items.push(Item::Pou(self.pou(PouKind::FunctionBlock)))
                }
                // a CLASS is a function block without a body (compile/class.rs checks the rest)
                Tok::Kw(Kw::Class) => items.push(Item::Pou(self.pou(PouKind::FunctionBlock))),
                Tok::Kw(Kw::Type) => items.extend(self.type_block().into_iter().map(Item::Type)),
                Tok::Kw(Kw::VarGlobal) => items.push(Item::Globals(self.var_block())),
                Tok::Kw(Kw::Action) => {
                    if let Some((owner, action)) = self.action(true) {
                        items.push(Item::Action { owner, action });
                    }
                }
                Tok::Kw(Kw::Configuration) => {
                    items.push(Item::Configuration(self.configuration()));
                }
                Tok::Kw(Kw::Interface) => items.push(Item::Interface(self.interface())),
                // A method or property written after its function block's END_FUNCTION_BLOCK
                // (as CODESYS's text exports place them): the function block's.
                Tok::Kw(Kw::Method | Kw::Property) => {
                    let at = self.span();
                    let mut oop = Oop::default();
                    self.oop_member(&mut oop);
                    match items.last_mut() {
                        Some(Item::Pou(p)) if p.kind != PouKind::Function => {
                            p.oop.methods.append(&mut oop.methods);
                            p.oop.properties.append(&mut oop.properties);
                        }
                        _ => self.report_at(at, Msg::MemberOutside),
                    }
                }
                _ => {
                    let _ = self.fail(Want::Item);
                    self.bump();
                    while !is_top(self.tok()) && !self.at_kw(Kw::VarGlobal) {
                        self.bump();
                    }
                }
            }
        }
    }

    fn pou(&mut self, kind: PouKind) -> Pou {
        let span = self.span();
        let opener = {
            let at = self.bump();
            self.text_of(at)
        }
        .to_ascii_uppercase();
        let mut oop = Oop { is_class: opener == "CLASS", ..Oop::default() };
        let (_, is_abstract, is_final) = self.modifiers();
        (oop.is_abstract, oop.is_final) = (is_abstract, is_final);
        let name = self.ident().unwrap_or_else(|_| Ident { name: String::new(), span });
        let mut vars = Vec::new();
        // TwinCAT writes a block's generic constants before its EXTENDS and IMPLEMENTS
        while kind == PouKind::FunctionBlock && self.at_word(VAR_GENERIC) {
            vars.push(self.var_block());
        }
        if kind != PouKind::Function {
            if self.at_word("EXTENDS") {
                self.bump();
                oop.extends = self.dotted_name().ok();
                // `EXTENDS FB_Base<20>`: a base with generic constants, given their values
                if let (Some(base), true) = (oop.extends.clone(), self.at_p(P::Lt)) {
                    if let Ok(TypeRef::Generic { args, .. }) = self.generic_arguments(base, span) {
                        oop.extends_args = Some(Box::new(args));
                    }
                }
            }
            if self.at_word("IMPLEMENTS") {
                self.bump();
                oop.implements = self.names();
            }
        }
        let mut return_type = None;
        if kind == PouKind::Function && self.eat_p(P::Colon) {
            match self.type_ref() {
                Ok(ty) => return_type = Some(ty),
                Err(_) => {
                    while !is_top(self.tok())
                        && var_kind(self.tok()).is_none()
                        && !self.at_p(P::Semi)
                    {
                        self.bump();
                    }
                }
            }
        }
        let closer = match kind {
            PouKind::Program => Closer::Program,
            PouKind::Function => Closer::Function,
            PouKind::FunctionBlock if oop.is_class => Closer::Class,
            PouKind::FunctionBlock => Closer::FunctionBlock,
        };
        // open from here: a method's missing END_METHOD does not take the POU's end for it
        self.open.push(closer);
        let mut access = Vec::new();
        loop {
            if var_kind(self.tok()).is_some()
                || (kind == PouKind::FunctionBlock && self.at_word(VAR_GENERIC))
            {
                vars.push(self.var_block());
            } else if self.at_kw(Kw::VarAccess) {
                access.extend(self.access_block());
            } else if kind != PouKind::Function && self.at_member() {
                self.oop_member(&mut oop);
            } else {
                break;
            }
        }
        let mut body = self.stmt_list(false, false);
        let mut actions = Vec::new();
        let mut sfc: Option<crate::st::sfc::Sfc> = None;
        // actions and SFC elements among the statements (as the textual SFC places them),
        // methods and properties after the body (as TwinCAT's files hold them)
        loop {
            if self.at_kw(Kw::Action) {
                if let Some((_, action)) = self.action(false) {
                    actions.push(action);
                }
            } else if kind != PouKind::Function && self.at_member() {
                self.oop_member(&mut oop);
            } else if self.at_sfc_element() {
                self.sfc_element(sfc.get_or_insert_with(Default::default));
            } else {
                break;
            }
            body.extend(self.stmt_list(false, false));
        }
        self.open.pop();
        let here = self.span();
        let end = self.close(closer, &opener, span).unwrap_or(here);
        Pou { kind, name, return_type, vars, body, actions, oop, sfc, access, span, end }
    }

    /// Whether a METHOD or PROPERTY starts here.
    fn at_member(&self) -> bool {
        self.at_kw(Kw::Method) || self.at_kw(Kw::Property)
    }

    /// `A, B, …`: names after EXTENDS or IMPLEMENTS (a library's qualified, `NS.I`).
    fn names(&mut self) -> Vec<Ident> {
        let mut out = Vec::new();
        while let Ok(id) = self.dotted_name() {
            out.push(id);
            if !self.eat_p(P::Comma) {
                break;
            }
        }
        out
    }

    /// A name, or a library's qualified one `NS.Name` as one name with its dots (resolved by
    /// `compile::qualified`).
    fn dotted_name(&mut self) -> PResult<Ident> {
        let mut id = self.ident()?;
        while self.at_p(P::Dot) && *self.tok_at(1) == Tok::Ident {
            self.bump();
            let Ok(more) = self.ident() else { break };
            id.name = format!("{}.{}", id.name, more.name);
        }
        Ok(id)
    }

    /// The access specifier, `ABSTRACT` and `FINAL` before a name: words followed by a name.
    fn modifiers(&mut self) -> (Access, bool, bool) {
        let (mut access, mut is_abstract, mut is_final) = (Access::Public, false, false);
        while *self.tok() == Tok::Ident && *self.tok_at(1) == Tok::Ident {
            match self.text_of(self.pos).to_ascii_uppercase().as_str() {
                "PUBLIC" => access = Access::Public,
                "PRIVATE" => access = Access::Private,
                "PROTECTED" => access = Access::Protected,
                "INTERNAL" => access = Access::Internal,
                "ABSTRACT" => is_abstract = true,
                "FINAL" => is_final = true,
                _ => break,
            }
            self.bump();
        }
        (access, is_abstract, is_final)
    }

    /// A METHOD or a PROPERTY, into `oop`.
    fn oop_member(&mut self, oop: &mut Oop) {
        if self.at_kw(Kw::Method) {
            if let Some(m) = self.method() {
                oop.methods.push(m);
            }
        } else if let Some(p) = self.property() {
            oop.properties.push(p);
        }
    }

    /// `METHOD [access] [ABSTRACT|FINAL] Name [: T] VAR… body END_METHOD [;]`.
    fn method(&mut self) -> Option<Method> {
        let span = self.span();
        self.bump();
        let (access, is_abstract, is_final) = self.modifiers();
        let name = self.ident().ok();
        let mut return_type = None;
        if self.eat_p(P::Colon) {
            return_type = self.type_ref().ok();
            if return_type.is_none() {
                // on to the declarations, as after a FUNCTION's result type
                while !is_top(self.tok()) && var_kind(self.tok()).is_none() && !self.at_p(P::Semi) {
                    self.bump();
                }
            }
        }
        self.eat_p(P::Semi);
        let mut vars = Vec::new();
        while var_kind(self.tok()).is_some() {
            vars.push(self.var_block());
        }
        self.open.push(Closer::Method);
        let body = self.stmt_list(false, false);
        self.open.pop();
        let here = self.span();
        let end = self.close(Closer::Method, "METHOD", span).unwrap_or(here);
        self.eat_p(P::Semi);
        let name = name?;
        let pou = Pou {
            kind: PouKind::Function,
            name,
            return_type,
            vars,
            body,
            actions: Vec::new(),
            oop: Oop::default(),
            sfc: None,
            access: Vec::new(),
            span,
            end,
        };
        Some(Method { access, is_abstract, is_final, pou })
    }

    /// `PROPERTY [access] Name : T [GET … END_GET] [SET … END_SET] END_PROPERTY [;]`.
    fn property(&mut self) -> Option<Property> {
        let span = self.span();
        self.bump();
        let (access, is_abstract, is_final) = self.modifiers();
        let name = self.ident().ok();
        self.expect_p_soft(P::Colon, Want::Colon);
        let ty = self.type_ref().ok();
        self.eat_p(P::Semi);
        let (mut get, mut set) = (None, None);
        let (mut get_access, mut set_access) = (None, None);
        self.open.push(Closer::Property);
        loop {
            let getter = self.at_word("GET");
            if !getter && !self.at_word("SET") {
                break;
            }
            let at = self.span();
            self.bump();
            let own_access = self.accessor_access();
            let mut vars = Vec::new();
            while var_kind(self.tok()).is_some() {
                vars.push(self.var_block());
            }
            let closer = if getter { Closer::Get } else { Closer::Set };
            self.open.push(closer);
            let body = self.stmt_list(false, false);
            self.open.pop();
            let here = self.span();
            let end = self.close(closer, if getter { "GET" } else { "SET" }, at).unwrap_or(here);
            self.eat_p(P::Semi);
            let (Some(name), Some(ty)) = (&name, &ty) else { continue };
            let mut accessor = Pou {
                kind: PouKind::Function,
                name: name.clone(),
                return_type: None,
                vars,
                body,
                actions: Vec::new(),
                oop: Oop::default(),
                sfc: None,
                access: Vec::new(),
                span: at,
                end,
            };
            if getter {
                accessor.return_type = Some(ty.clone());
                get = Some(accessor);
                get_access = own_access;
            } else {
                set_access = own_access;
                // the value assigned comes in the property's name
                let input = VarDecl {
                    names: vec![name.clone()],
                    location: None,
                    ty: ty.clone(),
                    init: None,
                    edge: None,
                    span: name.span,
                };
                let block = VarBlock {
                    kind: VarKind::Input,
                    constant: false,
                    retain: false,
                    persistent: false,
                    span: name.span,
                    decls: vec![input],
                };
                accessor.vars.insert(0, block);
                set = Some(accessor);
            }
        }
        self.open.pop();
        let here = self.span();
        self.close(Closer::Property, "PROPERTY", span).unwrap_or(here);
        self.eat_p(P::Semi);
        let (name, ty) = (name?, ty?);
        Some(Property {
            name,
            ty,
            access,
            is_abstract,
            is_final,
            get,
            set,
            get_access,
            set_access,
            span,
        })
    }

    /// The access specifier of a property's accessor, after `GET` or `SET` (CODESYS: `<Set>`'s
    /// declaration reading `PUBLIC VAR … END_VAR`): the word, unless it starts the body's first
    /// statement (a variable named so, followed by `:=`, `.`, `(` …).
    fn accessor_access(&mut self) -> Option<Access> {
        if *self.tok() != Tok::Ident || matches!(self.tok_at(1), Tok::P(_)) {
            return None;
        }
        let access = match self.text_of(self.pos).to_ascii_uppercase().as_str() {
            "PUBLIC" => Access::Public,
            "PRIVATE" => Access::Private,
            "PROTECTED" => Access::Protected,
            "INTERNAL" => Access::Internal,
            _ => return None,
        };
        self.bump();
        Some(access)
    }

    /// `INTERFACE Name [EXTENDS I, …] METHOD … PROPERTY … END_INTERFACE`.
    fn interface(&mut self) -> Interface {
        let span = self.span();
        self.bump();
        let name = self.ident().unwrap_or_else(|_| Ident { name: String::new(), span });
        let mut extends = Vec::new();
        if self.at_word("EXTENDS") {
            self.bump();
            extends = self.names();
        }
        let mut oop = Oop::default();
        self.open.push(Closer::Interface);
        while self.at_member() {
            self.oop_member(&mut oop);
        }
        self.open.pop();
        let here = self.span();
        let end = self.close(Closer::Interface, "INTERFACE", span).unwrap_or(here);
        self.eat_p(P::Semi);
        Interface { name, extends, methods: oop.methods, properties: oop.properties, span, end }
    }

    /// Whether the current token is the word `word` (a name outside a configuration: `TASK`,
    /// `RESOURCE`, `WITH` and `ON` are no keywords, so that variables may be called so).
    fn at_word(&self, word: &str) -> bool {
        *self.tok() == Tok::Ident && self.text_of(self.pos).eq_ignore_ascii_case(word)
    }

    /// `CONFIGURATION Name … END_CONFIGURATION`.
    fn configuration(&mut self) -> Configuration {
        let span = self.span();
        self.bump();
        let name = self.ident().unwrap_or_else(|_| Ident { name: String::new(), span });
        let mut conf = Configuration {
            name,
            globals: Vec::new(),
            resources: Vec::new(),
            var_config: Vec::new(),
            access: Vec::new(),
            span,
        };
        let mut direct = Resource { name: None, tasks: Vec::new(), programs: Vec::new() };
        self.open.push(Closer::Configuration);
        loop {
            if self.at_word("RESOURCE") {
                let opened = self.span();
                self.bump();
                let name = self.ident().ok();
                if self.at_word("ON") {
                    self.bump();
                    let _ = self.ident();
                }
                let mut resource = Resource { name, tasks: Vec::new(), programs: Vec::new() };
                self.open.push(Closer::Resource);
                while self.configuration_part(&mut conf, &mut resource, Kw::EndResource) {}
                self.open.pop();
                self.close(Closer::Resource, "RESOURCE", opened);
                self.eat_p(P::Semi);
                conf.resources.push(resource);
            } else if !self.configuration_part(&mut conf, &mut direct, Kw::EndConfiguration) {
                break;
            }
        }
        self.open.pop();
        self.close(Closer::Configuration, "CONFIGURATION", span);
        self.eat_p(P::Semi);
        if !direct.tasks.is_empty() || !direct.programs.is_empty() {
            conf.resources.insert(0, direct);
        }
        conf
    }

    /// One part of a configuration or resource (a global block, a task, a program instance);
    /// `false` at its end (`end`, or what cannot be in it).
    fn configuration_part(
        &mut self,
        conf: &mut Configuration,
        into: &mut Resource,
        end: Kw,
    ) -> bool {
        let tok = self.tok().clone();
        match tok {
            Tok::Kw(Kw::VarGlobal) => conf.globals.push(self.var_block()),
            Tok::Kw(Kw::VarConfig) => {
                let opened = self.span();
                self.bump();
                while self.at(&Tok::Ident) {
                    match self.config_var() {
                        Ok(v) => conf.var_config.push(v),
                        Err(_) => self.sync_decl(),
                    }
                }
                self.close(Closer::Var, "VAR_CONFIG", opened);
            }
            Tok::Kw(Kw::VarAccess) => conf.access.extend(self.access_block()),
            Tok::Kw(Kw::Program) => match self.program_decl() {
                Ok(p) => into.programs.push(p),
                Err(_) => self.sync_decl(),
            },
            Tok::Ident if self.at_word("TASK") => match self.task_decl() {
                Ok(t) => into.tasks.push(t),
                Err(_) => self.sync_decl(),
            },
            Tok::Kw(kw) if kw == end => return false,
            Tok::Eof => return false,
            Tok::Ident if self.at_word("RESOURCE") => return false,
            Tok::Kw(kw) if is_top(&tok) || kw.is_end() => return false,
            _ => {
                let _ = self.fail(Want::ConfigItem);
                self.bump();
                self.sync_decl();
            }
        }
        true
    }

    /// `TASK Name (SINGLE := …, INTERVAL := …, PRIORITY := …);`
    fn task_decl(&mut self) -> PResult<TaskDecl> {
        let span = self.span();
        self.bump();
        let name = self.ident()?;
        let mut properties = Vec::new();
        self.expect_p(P::LParen, Want::CommaOrRParen)?;
        if !self.at_p(P::RParen) {
            loop {
                let key = self.ident()?;
                self.expect_p(P::Assign, Want::Assign)?;
                properties.push((key, self.config_value()?));
                if !self.eat_p(P::Comma) {
                    break;
                }
            }
        }
        self.expect_p(P::RParen, Want::CommaOrRParen)?;
        self.end_decl(Want::SemiAfterDecl);
        Ok(TaskDecl { name, properties, span })
    }

    /// `AT %…` after a declaration's names, if there: the text after the `%`, with its place.
    fn at_location(&mut self) -> PResult<Option<Ident>> {
        if !self.eat_kw(Kw::At) {
            return Ok(None);
        }
        if !self.at(&Tok::Location) {
            return Err(self.fail(Want::Location));
        }
        let span = self.span();
        let token = self.bump();
        let name = self.text_of(token)[1..].to_string();
        Ok(Some(Ident { name, span }))
    }

    /// `instance.variable [AT %QX0.1] : BOOL [:= init];` in `VAR_CONFIG`.
    fn config_var(&mut self) -> PResult<ConfigVar> {
        let span = self.span();
        let mut path = vec![self.ident()?];
        while self.eat_p(P::Dot) {
            path.push(self.ident()?);
        }
        let location = self.at_location()?;
        self.expect_p(P::Colon, Want::Colon)?;
        let ty = Some(self.type_ref()?);
        let init = if self.eat_p(P::Assign) { Some(self.init()?) } else { None };
        self.end_decl(Want::SemiAfterDecl);
        Ok(ConfigVar { path, location, ty, init, span })
    }

    /// A value in a configuration: a direct address (`%IX0.1`) or an expression.
    fn config_value(&mut self) -> PResult<ConfigValue> {
        if !self.at(&Tok::Location) {
            return Ok(ConfigValue::Expr(self.expr()?));
        }
        let span = self.span();
        let at = self.bump();
        Ok(ConfigValue::Location(Ident { name: self.text_of(at)[1..].to_string(), span }))
    }

    /// `PROGRAM [RETAIN | NON_RETAIN] name [WITH task] : Type [(…)];`
    fn program_decl(&mut self) -> PResult<ProgramDecl> {
        let span = self.span();
        self.bump();
        let _ = self.eat_kw(Kw::Retain) || self.eat_kw(Kw::NonRetain);
        let name = self.ident()?;
        let task = if self.at_word("WITH") {
            self.bump();
            Some(self.ident()?)
        } else {
            None
        };
        self.expect_p(P::Colon, Want::Colon)?;
        let pou = self.ident()?;
        let mut args = Vec::new();
        if self.eat_p(P::LParen) && !self.eat_p(P::RParen) {
            loop {
                let name = self.ident()?;
                let output = self.eat_p(P::Arrow);
                if !output {
                    self.expect_p(P::Assign, Want::Assign)?;
                }
                args.push(ProgramArg { name, output, value: self.config_value()? });
                if !self.eat_p(P::Comma) {
                    break;
                }
            }
            self.expect_p(P::RParen, Want::CommaOrRParen)?;
        }
        self.end_decl(Want::SemiAfterDecl);
        Ok(ProgramDecl { name, task, pou, args, span })
    }

    /// The steps of a partial access token: its size (none for a bit) and number, `%X3` or
    /// `%B2`, then the bit numbers and member names the lexer read into it (`%W1.3`, `%B1.m`);
    /// and whether it ends with a dot (`%D1.` of `lw.%D1.%B0`).
    fn partial(&self) -> Option<(Vec<PartialStep>, bool)> {
        let text = self.text_of(self.pos);
        let span = self.span();
        let (text, dot) = match text.strip_suffix('.') {
            Some(before) => (before, true),
            None => (text, false),
        };
        let mut segments = text.split('.');
        let first = segments.next()?.strip_prefix('%')?;
        let mut chars = first.chars();
        let size = match chars.next()?.to_ascii_uppercase() {
            'X' => None,
            'B' => Some(PartSize::Byte),
            'W' => Some(PartSize::Word),
            'D' => Some(PartSize::DWord),
            'L' => Some(PartSize::LWord),
            _ => return None,
        };
        let mut steps = vec![PartialStep::Part(size, partial_number(chars.as_str())?)];
        let mut col = span.col + first.len() as u32 + 2;
        for segment in segments {
            let step = match partial_number(segment) {
                Some(bit) => PartialStep::Part(None, bit),
                None if segment.starts_with(|c: char| c.is_ascii_alphabetic() || c == '_') => {
                    let span = Span { line: span.line, col };
                    PartialStep::Member(Ident { name: segment.to_string(), span })
                }
                None => return None,
            };
            steps.push(step);
            col += segment.len() as u32 + 1;
        }
        Some((steps, dot))
    }
    /// `ACTION [Owner.]Name: … END_ACTION [;]`; the owner only at the top level.
    fn action(&mut self, top: bool) -> Option<(Option<Ident>, Action)> {
        let span = self.span();
        self.bump();
        let mut owner = None;
        let mut name = self.ident().ok();
        if top && self.eat_p(P::Dot) {
            owner = name;
            name = self.ident().ok();
        }
        self.expect_p_soft(P::Colon, Want::Colon);
        self.open.push(Closer::Action);
        let body = self.stmt_list(false, false);
        self.open.pop();
        let here = self.span();
        let end = self.close(Closer::Action, "ACTION", span).unwrap_or(here);
        self.eat_p(P::Semi);
        let name = name?;
        Some((owner, Action { name, body, span, end }))
    }

    // ----- declarations -----

    fn var_block(&mut self) -> VarBlock {
        let span = self.span();
        let kind = match var_kind(self.tok()) {
            Some(kind) => kind,
            None if self.at_word(VAR_GENERIC) => VarKind::Generic,
            None => VarKind::Local,
        };
        match kind {
            VarKind::Static => self.habit(Habit::VarStat),
            VarKind::Instance => self.habit(Habit::VarInst),
            VarKind::Generic => self.habit(Habit::GenericConstants),
            _ => {}
        }
        let opener = {
            let at = self.bump();
            self.text_of(at)
        }
        .to_ascii_uppercase();
        let (mut constant, mut retain, mut persistent) = (false, false, false);
        loop {
            if self.at_kw(Kw::Constant) {
                if kind == VarKind::Input {
                    self.habit(Habit::ConstantInput);
                }
                self.bump();
                constant = true;
            } else if self.eat_kw(Kw::Retain) {
                retain = true;
            } else if self.at_persistent() {
                // `PERSISTENT` is a word, not a keyword: a variable may be called so
                self.habit(Habit::Persistent);
                self.bump();
                (retain, persistent) = (true, true);
            } else if !self.eat_kw(Kw::NonRetain) {
                break;
            }
        }
        let mut decls = Vec::new();
        loop {
            let tok = self.tok();
            if self.at_decl() || self.at_anonymous_location() {
                match self.var_decl(Want::SemiAfterDecl) {
                    Ok(decl) => decls.push(decl),
                    Err(_) => self.sync_decl(),
                }
            } else if *tok == Tok::Kw(Kw::EndVar) {
                self.bump();
                break;
            } else if *tok == Tok::P(P::Semi) {
                // `a : LREAL := 630.0;;` or a `;` on a line of its own: an empty declaration
                self.habit(Habit::EmptyDeclaration);
                self.bump();
            } else if *tok == Tok::Ident
                || is_top(tok)
                || is_stmt_keyword(tok)
                || is_closer(tok)
                || var_kind(tok).is_some()
            {
                self.close(Closer::Var, &opener, span);
                break;
            } else {
                let _ = self.fail(Want::VarDecl);
                self.bump();
                self.sync_decl();
            }
        }
        VarBlock { kind, constant, retain, persistent, span, decls }
    }

    /// `PERSISTENT` among a block's qualifiers: the word, not followed by what makes it the
    /// name of a declaration (`persistent : BOOL;`, `persistent, b : INT;`).
    fn at_persistent(&self) -> bool {
        self.at_word("PERSISTENT")
            && !matches!(self.tok_at(1), Tok::P(P::Colon | P::Comma))
            && *self.tok_at(1) != Tok::Kw(Kw::At)
    }

    /// Whether a declaration starts here: a name not followed by `:=`, `(`, `[` or `.` (which
    /// make it a statement after a missing `END_VAR`).
    /// `AT %IX1.1 : BOOL;`: a located variable without a name (IEC 61131-3 allows it).
    fn at_anonymous_location(&self) -> bool {
        self.at_kw(Kw::At) && *self.tok_at(1) == Tok::Location
    }

    fn at_decl(&self) -> bool {
        *self.tok() == Tok::Ident
            && !matches!(self.tok_at(1), Tok::P(P::Assign | P::LParen | P::LBracket | P::Dot))
    }

    /// `a, b AT %D0 : INT := 5;`
    fn var_decl(&mut self, semi: Want) -> PResult<VarDecl> {
        let span = self.span();
        let anonymous = self.at_anonymous_location();
        let mut names = if anonymous { Vec::new() } else { vec![self.ident()?] };
        while !anonymous && self.eat_p(P::Comma) {
            names.push(self.ident()?);
        }
        let location = self.at_location()?;
        if let (true, Some(at)) = (anonymous, &location) {
            // named by its address, a name no code can write
            names.push(Ident { name: format!("%{}", at.name), span: at.span });
        }
        self.expect_p(P::Colon, Want::Colon)?;
        let ty = self.type_ref()?;
        // `R_EDGE` / `F_EDGE` are names, not keywords, where a declaration can hold them.
        let mut edge = None;
        if self.at(&Tok::Ident) {
            let at = self.span();
            let kind = match self.text_of(self.pos).to_ascii_uppercase().as_str() {
                "R_EDGE" => Some(Edge::Rising),
                "F_EDGE" => Some(Edge::Falling),
                _ => None,
            };
            if let Some(kind) = kind {
                self.bump();
                edge = Some((kind, at));
            }
        }
        let init = if self.eat_p(P::Assign) { Some(self.init()?) } else { None };
        self.end_decl(semi);
        Ok(VarDecl { names, location, ty, init, edge, span })
    }

    /// The `;` after a declaration; when it is missing, goes on at the next one.
    fn end_decl(&mut self, semi: Want) {
        if !self.eat_p(P::Semi) {
            let _ = self.fail(semi);
            if !self.at(&Tok::Ident) {
                self.sync_decl();
            }
        }
    }

    /// The `[n]` or `(n)` after `WSTRING`, if any.
    fn string_len(&mut self) -> PResult<Option<Box<Expr>>> {
        let close = if self.eat_p(P::LBracket) {
            (P::RBracket, Want::RBracket)
        } else if self.eat_p(P::LParen) {
            (P::RParen, Want::RParen)
        } else {
            return Ok(None);
        };
        let len = self.expr()?;
        self.expect_p(close.0, close.1)?;
        Ok(Some(Box::new(len)))
    }

    fn type_ref(&mut self) -> PResult<TypeRef> {
        let span = self.span();
        match *self.tok() {
            Tok::Ident if self.at_ref_type() => {
                let kind = match self.text_of(self.pos).to_ascii_uppercase().as_str() {
                    "REF_TO" => RefKind::RefTo,
                    "POINTER" => RefKind::Pointer,
                    _ => RefKind::Reference,
                };
                self.bump();
                if kind != RefKind::RefTo {
                    self.bump(); // TO
                }
                self.enter()?;
                let to = self.type_ref();
                self.depth -= 1;
                Ok(TypeRef::Ref { kind, to: Box::new(to?), span })
            }
            Tok::Ident if self.text_of(self.pos).eq_ignore_ascii_case("WSTRING") => {
                self.bump();
                let len = self.string_len()?;
                Ok(TypeRef::WString { len, span })
            }
            Tok::Ident => {
                let name = self.dotted_name()?;
                if self.at_p(P::Lt) {
                    return self.generic_arguments(name, span);
                }
                if !self.at_p(P::LParen) {
                    return Ok(TypeRef::Named(name));
                }
                self.bump();
                // `INT (0..100)`, `INT (A, B := 5)`, or a function block's declaration
                // arguments `T(5, 'A')` (compile/fb_init.rs), read as a call's
                let open = self.pos;
                let first = self.expr()?;
                if self.eat_p(P::DotDot) {
                    let hi = self.expr()?;
                    self.expect_p(P::RParen, Want::RParen)?;
                    return Ok(TypeRef::Subrange {
                        base: name,
                        lo: Box::new(first),
                        hi: Box::new(hi),
                        span,
                    });
                }
                self.pos = open;
                let args = self.args()?;
                Ok(TypeRef::Enum(enum_or_arguments(name, args, span)))
            }
            Tok::Kw(Kw::String) => {
                self.bump();
                let len = if self.eat_p(P::LBracket) {
                    let len = self.expr()?;
                    self.expect_p(P::RBracket, Want::RBracket)?;
                    Some(Box::new(len))
                } else if self.eat_p(P::LParen) {
                    let len = self.expr()?;
                    self.expect_p(P::RParen, Want::RParen)?;
                    Some(Box::new(len))
                } else {
                    None
                };
                Ok(TypeRef::String { len, span })
            }
            Tok::Kw(Kw::Array) => {
                self.bump();
                self.expect_p(P::LBracket, Want::LBracket)?;
                if self.eat_p(P::Star) {
                    // `ARRAY [*, *] OF T`: every dimension open
                    let mut rank = 1;
                    while self.eat_p(P::Comma) {
                        self.expect_p(P::Star, Want::Star)?;
                        rank += 1;
                    }
                    self.expect_p(P::RBracket, Want::CommaOrRBracket)?;
                    if !self.eat_kw(Kw::Of) {
                        return Err(self.fail(Want::Of));
                    }
                    self.enter()?;
                    let of = self.type_ref();
                    self.depth -= 1;
                    return Ok(TypeRef::OpenArray { rank, of: Box::new(of?), span });
                }
                let mut dims = Vec::new();
                loop {
                    let lo = self.expr()?;
                    self.expect_p(P::DotDot, Want::DotDot)?;
                    let hi = self.expr()?;
                    dims.push((lo, hi));
                    if self.eat_p(P::Comma) {
                        continue;
                    }
                    self.expect_p(P::RBracket, Want::CommaOrRBracket)?;
                    break;
                }
                if !self.eat_kw(Kw::Of) {
                    return Err(self.fail(Want::Of));
                }
                self.enter()?;
                let of = self.type_ref();
                self.depth -= 1;
                Ok(TypeRef::Array { dims, of: Box::new(of?), span })
            }
            Tok::P(P::LParen) => {
                self.bump();
                let first = self.ident()?;
                Ok(TypeRef::Enum(self.enum_values(None, first, span)?))
            }
            _ => Err(self.fail(Want::Type)),
        }
    }

    /// `<20>`, `<(N * 2), 5>` after a function block's name (TwinCAT 3.1.4026's generic
    /// constants): each argument a sum of terms (a literal, a name) or an expression in
    /// parentheses, as `>` ends them.
    fn generic_arguments(&mut self, name: Ident, span: Span) -> PResult<TypeRef> {
        self.habit(Habit::GenericConstants);
        self.bump();
        let mut args = Vec::new();
        loop {
            args.push(self.binary(LEVEL_ADD)?);
            if self.eat_p(P::Comma) {
                continue;
            }
            self.expect_p(P::Gt, Want::CommaOrAngle)?;
            return Ok(TypeRef::Generic { name, args, span });
        }
    }

    /// Whether a reference type starts here: `REF_TO`, `POINTER TO`, `REFERENCE TO`.
    fn at_ref_type(&self) -> bool {
        let word = self.text_of(self.pos);
        word.eq_ignore_ascii_case("REF_TO")
            || ((word.eq_ignore_ascii_case("POINTER") || word.eq_ignore_ascii_case("REFERENCE"))
                && *self.tok_at(1) == Tok::Kw(Kw::To))
    }

    /// The values of an enumeration after its first name, to its `)`.
    fn enum_values(&mut self, base: Option<Ident>, first: Ident, span: Span) -> PResult<EnumDef> {
        let mut values = Vec::new();
        let mut name = first;
        loop {
            let value = if self.eat_p(P::Assign) { Some(self.expr()?) } else { None };
            values.push((name, value));
            if self.eat_p(P::Comma) {
                name = self.ident()?;
                continue;
            }
            self.expect_p(P::RParen, Want::CommaOrRParen)?;
            return Ok(EnumDef { base, values, args: Vec::new(), span });
        }
    }

    /// `TYPE … END_TYPE`: its declarations.
    fn type_block(&mut self) -> Vec<TypeDecl> {
        let opened = self.span();
        self.bump();
        let mut decls = Vec::new();
        loop {
            let tok = self.tok();
            if *tok == Tok::Ident {
                match self.type_decl() {
                    Ok(decl) => decls.push(decl),
                    Err(_) => self.sync_decl(),
                }
            } else if *tok == Tok::Kw(Kw::EndType) {
                self.bump();
                return decls;
            } else if is_top(tok)
                || is_stmt_keyword(tok)
                || is_closer(tok)
                || var_kind(tok).is_some()
            {
                self.close(Closer::Type, "TYPE", opened);
                return decls;
            } else {
                let _ = self.fail(Want::TypeDecl);
                self.bump();
                self.sync_decl();
            }
        }
    }

    fn type_decl(&mut self) -> PResult<TypeDecl> {
        let span = self.span();
        let name = self.ident()?;
        self.expect_p(P::Colon, Want::Colon)?;
        let def = if self.at_kw(Kw::Struct) || self.at_kw(Kw::Union) {
            // a STRUCT, or CODESYS's UNION: the same list of members
            let union = self.at_kw(Kw::Union);
            let (closer, opener, want) = if union {
                (Closer::Union, "UNION", Want::UnionMember)
            } else {
                (Closer::Struct, "STRUCT", Want::StructMember)
            };
            let made = |members| {
                if union {
                    TypeDef::Union { members }
                } else {
                    TypeDef::Struct { members }
                }
            };
            let opened = self.span();
            self.bump();
            let mut members = Vec::new();
            loop {
                let tok = self.tok();
                if self.at_decl() {
                    match self.var_decl(Want::SemiAfterDecl) {
                        Ok(decl) => members.push(decl),
                        Err(_) => self.sync_decl(),
                    }
                } else if *tok == Tok::Kw(closer.end_kw()) {
                    self.bump();
                    break;
                } else if *tok == Tok::Ident
                    || is_top(tok)
                    || is_stmt_keyword(tok)
                    || is_closer(tok)
                    || var_kind(tok).is_some()
                {
                    self.close(closer, opener, opened);
                    if !self.at_p(P::Semi) {
                        return Ok(TypeDecl { name, def: made(members), span });
                    }
                    break;
                } else {
                    let _ = self.fail(want);
                    self.bump();
                    self.sync_decl();
                }
            }
            made(members)
        } else {
            match self.type_ref()? {
                TypeRef::Enum(mut def) => {
                    // CODESYS and TwinCAT write the base type after the values, `(A, B) BYTE`:
                    // a name there not followed by `:` (which starts the next type)
                    if def.base.is_none()
                        && self.at(&Tok::Ident)
                        && *self.tok_at(1) != Tok::P(P::Colon)
                    {
                        self.habit(Habit::EnumBaseAfterValues);
                        def.base = Some(self.ident()?);
                    }
                    let init = if self.eat_p(P::Assign) { Some(self.ident()?) } else { None };
                    TypeDef::Enum { def, init }
                }
                ty => {
                    let init = if self.eat_p(P::Assign) { Some(self.init()?) } else { None };
                    TypeDef::Alias { ty, init }
                }
            }
        };
        if !self.at_p(P::Semi) && self.at_type_decl_end() {
            self.habit(Habit::NoSemicolonAfterType);
        } else {
            self.end_decl(Want::SemiAfterDecl);
        }
        Ok(TypeDecl { name, def, span })
    }

    /// Whether a type's declaration ends here without its `;`, as CODESYS writes it: at
    /// `END_TYPE` or where the next type's `Name :` starts.
    fn at_type_decl_end(&self) -> bool {
        self.at_kw(Kw::EndType) || (self.at(&Tok::Ident) && *self.tok_at(1) == Tok::P(P::Colon))
    }

    /// An initial value: an expression, `[…]` for an array, `(a := …)` for a struct.
    fn init(&mut self) -> PResult<Init> {
        self.enter()?;
        let init = self.init_inner();
        self.depth -= 1;
        init
    }

    fn init_inner(&mut self) -> PResult<Init> {
        let span = self.span();
        if self.eat_p(P::LBracket) {
            let mut elems = Vec::new();
            loop {
                if matches!(self.tok(), Tok::Int(_)) && *self.tok_at(1) == Tok::P(P::LParen) {
                    let count = self.primary()?;
                    self.bump();
                    let value = if self.eat_p(P::RParen) {
                        None
                    } else {
                        let value = self.init()?;
                        self.expect_p(P::RParen, Want::RParen)?;
                        Some(value)
                    };
                    elems.push(ArrayInit::Repeat { count, value });
                } else {
                    elems.push(ArrayInit::One(self.init()?));
                }
                if self.eat_p(P::Comma) {
                    continue;
                }
                self.expect_p(P::RBracket, Want::CommaOrRBracket)?;
                return Ok(Init::Array { elems, span });
            }
        }
        if self.at_p(P::LParen)
            && *self.tok_at(1) == Tok::Ident
            && *self.tok_at(2) == Tok::P(P::Assign)
        {
            self.bump();
            let mut members = Vec::new();
            loop {
                let name = self.ident()?;
                self.expect_p(P::Assign, Want::Assign)?;
                members.push((name, self.init()?));
                if self.eat_p(P::Comma) {
                    continue;
                }
                self.expect_p(P::RParen, Want::CommaOrRParen)?;
                return Ok(Init::Struct { members, span });
            }
        }
        Ok(Init::Expr(self.expr()?))
    }

    // ----- statements -----

    /// Statements up to the keyword that ends their list. `nested`: inside a statement (a
    /// stray `END_…` then ends the list, for the statement to report); `in_case`: a CASE arm
    /// (a label ends the list).
    fn stmt_list(&mut self, nested: bool, in_case: bool) -> Vec<Stmt> {
        let mut stmts = Vec::new();
        loop {
            let tok = self.tok().clone();
            if is_top(&tok) {
                return stmts;
            }
            if let Tok::Kw(kw) = tok {
                if is_closer(&tok) {
                    let open = self.open.iter().any(|c| c.accepts(kw));
                    if open || (nested && kw.is_end()) || is_pou_end(kw) {
                        return stmts;
                    }
                    let _ = self.fail(Want::Stmt);
                    self.bump();
                    continue;
                }
                if var_kind(&tok).is_some() {
                    let _ = self.fail(Want::Stmt);
                    self.var_block();
                    continue;
                }
            }
            if in_case && self.at_case_label() {
                return stmts;
            }
            if !nested && !in_case && self.at_sfc_element() {
                return stmts;
            }
            match self.stmt() {
                Ok(stmt) => stmts.push(stmt),
                Err(_) => self.sync_stmt(),
            }
        }
    }

    fn stmt(&mut self) -> PResult<Stmt> {
        let span = self.span();
        let kind = match *self.tok() {
            Tok::P(P::Semi) => {
                self.bump();
                return Ok(Stmt { kind: StmtKind::Empty, span });
            }
            Tok::Kw(Kw::If) => self.if_stmt()?,
            Tok::Kw(Kw::Case) => self.case_stmt()?,
            Tok::Kw(Kw::For) => self.for_stmt()?,
            Tok::Kw(Kw::While) => self.while_stmt()?,
            Tok::Kw(Kw::Repeat) => self.repeat_stmt()?,
            Tok::Kw(Kw::Exit) => {
                self.bump();
                StmtKind::Exit
            }
            Tok::Kw(Kw::Continue) => {
                self.bump();
                StmtKind::Continue
            }
            Tok::Kw(Kw::Return) => {
                self.bump();
                StmtKind::Return
            }
            // `label:` before a statement (CODESYS): a statement of its own, no `;`
            Tok::Ident if *self.tok_at(1) == Tok::P(P::Colon) => {
                self.habit(Habit::Jump);
                let label = self.ident()?;
                self.bump();
                return Ok(Stmt { kind: StmtKind::Label(label), span });
            }
            // `JMP label;` (CODESYS): JMP is no keyword, since no other statement starts
            // with two names
            Tok::Ident
                if self.text_of(self.pos).eq_ignore_ascii_case("JMP")
                    && *self.tok_at(1) == Tok::Ident =>
            {
                self.habit(Habit::Jump);
                self.bump();
                StmtKind::Jump(self.ident()?)
            }
            Tok::Ident | Tok::P(P::Dot) => {
                let target = self.postfix()?;
                if self.eat_p(P::Assign) {
                    let value = self.assigned_value()?;
                    StmtKind::Assign { target, value }
                } else if *self.tok() == Tok::Ident
                    && self.text_of(self.pos).eq_ignore_ascii_case("REF")
                    && *self.tok_at(1) == Tok::P(P::Eq)
                {
                    self.bump();
                    self.bump();
                    let value = self.expr()?;
                    StmtKind::RefAssign { target, value }
                } else if matches!(target.kind, ExprKind::Call { .. }) {
                    StmtKind::Call(target)
                } else {
                    return Err(self.fail(Want::Assign));
                }
            }
            _ => return Err(self.fail(Want::Stmt)),
        };
        if !self.eat_p(P::Semi) {
            // CODESYS and TwinCAT take a compound statement's `END_…` for its end.
            match compound_end(&kind) {
                Some(end) => self.habit(Habit::NoSemicolonAfterEnd(end)),
                None => {
                    let _ = self.fail(Want::SemiAfterStmt);
                }
            }
        }
        Ok(Stmt { kind, span })
    }

    /// A condition or bound up to one of `stops`; after an error, skips to one of them and
    /// stands in `FALSE`.
    fn expr_until(&mut self, stops: &[Kw]) -> Expr {
        let span = self.span();
        match self.expr() {
            Ok(expr) => expr,
            Err(_) => {
                loop {
                    let tok = self.tok();
                    if matches!(tok, Tok::Kw(kw) if stops.contains(kw)) {
                        break;
                    }
                    if *tok == Tok::P(P::Semi)
                        || is_top(tok)
                        || is_stmt_keyword(tok)
                        || is_closer(tok)
                        || var_kind(tok).is_some()
                    {
                        // No error at the token where the skip ended: one was just reported.
                        self.last_error = Some(self.pos);
                        break;
                    }
                    self.bump();
                }
                dummy_expr(span)
            }
        }
    }

    /// A nested list of statements inside `closer`.
    fn block(&mut self, closer: Closer, in_case: bool) -> PResult<Vec<Stmt>> {
        self.enter()?;
        self.open.push(closer);
        let body = self.stmt_list(true, in_case);
        self.open.pop();
        self.depth -= 1;
        Ok(body)
    }

    fn if_stmt(&mut self) -> PResult<StmtKind> {
        let opened = self.span();
        self.bump();
        let mut branches = Vec::new();
        let mut otherwise = None;
        loop {
            let cond = self.condition_until(&[Kw::Then]);
            self.expect_kw_soft(Kw::Then, Want::Then);
            branches.push((cond, self.block(Closer::If, false)?));
            if self.eat_kw(Kw::Elsif) {
                continue;
            }
            let span = self.span();
            if self.eat_kw(Kw::Else) {
                otherwise = Some((span, self.block(Closer::If, false)?));
            }
            break;
        }
        self.close(Closer::If, "IF", opened);
        Ok(StmtKind::If { branches, otherwise })
    }

    /// Whether a CASE label (`1`, `-2`, `Red`, `Color#Red`, `3..5`) starts here.
    fn at_case_label(&self) -> bool {
        match self.tok() {
            Tok::Int(_)
            | Tok::Real(_)
            | Tok::Str(_)
            | Tok::WStr(_)
            | Tok::Time(_)
            | Tok::Calendar(..)
            | Tok::TypedPrefix
            | Tok::P(P::Minus | P::Plus)
            | Tok::Kw(Kw::True | Kw::False) => true,
            Tok::Ident => {
                let mut n = 1;
                while *self.tok_at(n) == Tok::P(P::Dot) && *self.tok_at(n + 1) == Tok::Ident {
                    n += 2;
                }
                matches!(self.tok_at(n), Tok::P(P::Colon | P::Comma | P::DotDot))
            }
            _ => false,
        }
    }

    fn case_stmt(&mut self) -> PResult<StmtKind> {
        let opened = self.span();
        self.bump();
        let selector = self.expr_until(&[Kw::Of]);
        self.expect_kw_soft(Kw::Of, Want::Of);
        let mut arms = Vec::new();
        let mut otherwise = None;
        self.open.push(Closer::Case);
        loop {
            let tok = self.tok();
            if *tok == Tok::Kw(Kw::Else) {
                let span = self.span();
                self.bump();
                self.open.pop();
                otherwise = Some((span, self.block(Closer::Case, false)?));
                self.open.push(Closer::Case);
                break;
            }
            if is_top(tok) || is_closer(tok) || var_kind(tok).is_some() {
                break;
            }
            let before = self.pos;
            if !self.at_case_label() {
                let _ = self.fail(Want::CaseLabel);
                self.sync_stmt_from(before);
                continue;
            }
            match self.case_arm() {
                Ok(arm) => arms.push(arm),
                Err(_) => self.sync_stmt_from(before),
            }
        }
        self.open.pop();
        self.close(Closer::Case, "CASE", opened);
        Ok(StmtKind::Case { selector, arms, otherwise })
    }

    fn case_arm(&mut self) -> PResult<CaseArm> {
        let span = self.span();
        let mut labels = Vec::new();
        loop {
            let value = self.expr()?;
            if self.eat_p(P::DotDot) {
                labels.push(CaseLabel::Range(value, self.expr()?));
            } else {
                labels.push(CaseLabel::Value(value));
            }
            if !self.eat_p(P::Comma) {
                break;
            }
        }
        self.expect_p(P::Colon, Want::Colon)?;
        self.open.pop();
        let body = self.block(Closer::Case, true);
        self.open.push(Closer::Case);
        Ok(CaseArm { labels, body: body?, span })
    }

    fn for_stmt(&mut self) -> PResult<StmtKind> {
        let opened = self.span();
        self.bump();
        let start = self.pos;
        let var = match self.ident() {
            // `FOR a[i] := …`, `FOR s.n := …` (TwinCAT): IEC 61131-3 counts in a name alone
            Ok(_) if matches!(self.tok(), Tok::P(P::LBracket | P::Dot)) => {
                self.habit(Habit::ForElement);
                self.pos = start;
                self.postfix()?
            }
            Ok(var) => Expr { span: var.span, kind: ExprKind::Name(var) },
            Err(_) => {
                // `FOR 1 := …`: on after the bad token.
                if *self.tok_at(1) == Tok::P(P::Assign) {
                    self.bump();
                }
                Expr {
                    kind: ExprKind::Name(Ident { name: String::new(), span: opened }),
                    span: opened,
                }
            }
        };
        self.expect_p_soft(P::Assign, Want::Assign);
        let from = self.expr_until(&[Kw::To]);
        self.expect_kw_soft(Kw::To, Want::To);
        let to = self.expr_until(&[Kw::By, Kw::Do]);
        let by = if self.eat_kw(Kw::By) { Some(self.expr_until(&[Kw::Do])) } else { None };
        self.expect_kw_soft(Kw::Do, Want::Do);
        let body = self.block(Closer::For, false)?;
        self.close(Closer::For, "FOR", opened);
        Ok(StmtKind::For { var, from, to, by, body })
    }

    fn while_stmt(&mut self) -> PResult<StmtKind> {
        let opened = self.span();
        self.bump();
        let cond = self.condition_until(&[Kw::Do]);
        self.expect_kw_soft(Kw::Do, Want::Do);
        let body = self.block(Closer::While, false)?;
        self.close(Closer::While, "WHILE", opened);
        Ok(StmtKind::While { cond, body })
    }

    fn repeat_stmt(&mut self) -> PResult<StmtKind> {
        let opened = self.span();
        self.bump();
        let body = self.block(Closer::Repeat, false)?;
        let span = self.span();
        if self.close(Closer::Repeat, "REPEAT", opened).is_none() {
            return Ok(StmtKind::Repeat { body, until: dummy_expr(span) });
        }
        let until = self.condition_until(&[Kw::EndRepeat]);
        self.expect_kw_soft(Kw::EndRepeat, Want::EndRepeat);
        Ok(StmtKind::Repeat { body, until })
    }

    // ----- expressions -----

    pub(crate) fn expr(&mut self) -> PResult<Expr> {
        self.enter()?;
        let expr = self.binary(LEVEL_OR);
        self.depth -= 1;
        expr
    }

    /// Binary operators of `level` and above, left-associative.
    fn binary(&mut self, level: u8) -> PResult<Expr> {
        if level > LEVEL_MUL {
            return self.unary();
        }
        let span = self.span();
        let mut lhs = self.binary(level + 1)?;
        while let Some(op) = binary_op(self.tok(), level) {
            self.bump();
            let rhs = self.binary(level + 1)?;
            lhs = Expr { kind: ExprKind::Binary(op, Box::new(lhs), Box::new(rhs)), span };
        }
        Ok(lhs)
    }

    /// `-x`, `+x`, `NOT x`: below `**`, so `-2 ** 2` is `-(2 ** 2)`.
    fn unary(&mut self) -> PResult<Expr> {
        let span = self.span();
        match unary_op(self.tok()) {
            Some(op) => {
                self.bump();
                self.enter()?;
                let operand = self.unary();
                self.depth -= 1;
                Ok(Expr { kind: ExprKind::Unary(op, Box::new(operand?)), span })
            }
            None => self.power(),
        }
    }

    /// `a ** b ** c` is `(a ** b) ** c`.
    fn power(&mut self) -> PResult<Expr> {
        let span = self.span();
        let mut lhs = self.power_operand()?;
        while self.eat_p(P::Power) {
            let rhs = self.power_operand()?;
            lhs =
                Expr { kind: ExprKind::Binary(BinaryOp::Pow, Box::new(lhs), Box::new(rhs)), span };
        }
        Ok(lhs)
    }

    /// An operand of `**`: a signed one is accepted (`2 ** -1`), binding to the operand only.
    fn power_operand(&mut self) -> PResult<Expr> {
        let span = self.span();
        match unary_op(self.tok()) {
            Some(op) => {
                self.bump();
                self.enter()?;
                let operand = self.power_operand();
                self.depth -= 1;
                Ok(Expr { kind: ExprKind::Unary(op, Box::new(operand?)), span })
            }
            None => self.postfix(),
        }
    }

    /// A primary and its `.member`, `.3`, `[i, j]` and `(args)`.
    fn postfix(&mut self) -> PResult<Expr> {
        let span = self.span();
        let mut expr = self.primary()?;
        // A partial access token that ends with a dot (`%D1.` of `lw.%D1.%B0`: the lexer
        // reads the dot into the address) leaves the next token after a dot.
        let mut after_dot = false;
        loop {
            let dotted = after_dot || matches!(self.tok(), Tok::P(P::Dot));
            let kind = match *self.tok() {
                _ if dotted => {
                    if !after_dot {
                        self.bump();
                    }
                    after_dot = false;
                    match *self.tok() {
                        Tok::Ident => ExprKind::Member(Box::new(expr), self.ident()?),
                        Tok::Int(n) => {
                            let Ok(bit) = u8::try_from(n) else {
                                let text = self.text_of(self.pos).to_string();
                                self.report(Msg::BitTooLarge { text });
                                return Err(Failed);
                            };
                            self.bump();
                            ExprKind::Bit(Box::new(expr), bit)
                        }
                        // IEC's partial access: a bit `w.%X3`, a part `dw.%B2`, nested
                        Tok::Location => {
                            let Some((steps, dot)) = self.partial() else {
                                return Err(self.fail(Want::Field));
                            };
                            self.bump();
                            after_dot = dot;
                            let mut steps = steps.into_iter();
                            let first = steps.next().expect("a partial access has a step at least");
                            let mut kind = partial_kind(expr, first);
                            for step in steps {
                                kind = partial_kind(Expr { kind, span }, step);
                            }
                            kind
                        }
                        _ => return Err(self.fail(Want::Field)),
                    }
                }
                Tok::P(P::LBracket) => {
                    self.bump();
                    let mut index = vec![self.expr()?];
                    while self.eat_p(P::Comma) {
                        index.push(self.expr()?);
                    }
                    self.expect_p(P::RBracket, Want::CommaOrRBracket)?;
                    ExprKind::Index(Box::new(expr), index)
                }
                Tok::P(P::LParen) => {
                    self.bump();
                    let args = match dynamic_memory(&expr) {
                        Some(operator) => {
                            self.habits.push(Noted { span, habit: Habit::DynamicMemory(operator) });
                            if operator == "__NEW" {
                                self.type_args(true)?
                            } else {
                                self.args()?
                            }
                        }
                        // `SIZEOF(POINTER TO BYTE)`, `SIZEOF(STRING(255))` (TwinCAT)
                        None if is_sizeof(&expr) && self.at_type_only() => self.type_args(false)?,
                        None => self.args()?,
                    };
                    ExprKind::Call { callee: Box::new(expr), args }
                }
                Tok::P(P::Caret) => {
                    self.bump();
                    ExprKind::Deref(Box::new(expr))
                }
                _ => return Ok(expr),
            };
            expr = Expr { kind, span };
        }
    }

    /// Whether the current token starts a type that no expression can start (`POINTER TO`,
    /// `STRING`, `ARRAY`).
    fn at_type_only(&self) -> bool {
        self.at_ref_type()
            || self.at_kw(Kw::String)
            || self.at_kw(Kw::Array)
            || (*self.tok() == Tok::Ident && self.text_of(self.pos).eq_ignore_ascii_case("WSTRING"))
    }

    /// The arguments after the `(` of `__NEW(T[, n])` (`count`) or `SIZEOF(T)`, through the `)`
    /// (TwinCAT): a type first, which no expression can be. A named type stays a name; any other
    /// (`POINTER TO I`, `STRING(255)`) becomes a hidden alias of the file named
    /// [`TYPE_ARGUMENT_PREFIX`] and a number, which compile/heap.rs renames for the project.
    fn type_args(&mut self, count: bool) -> PResult<Vec<Arg>> {
        let span = self.span();
        let ty = match self.type_ref()? {
            TypeRef::Named(id) => id,
            ty => {
                let name = Ident {
                    name: format!("{TYPE_ARGUMENT_PREFIX}{}", self.hidden_types.len()),
                    span,
                };
                let def = TypeDef::Alias { ty, init: None };
                self.hidden_types.push(TypeDecl { name: name.clone(), def, span });
                name
            }
        };
        let mut args = vec![Arg::Positional(Expr { kind: ExprKind::Name(ty), span })];
        if count && self.eat_p(P::Comma) {
            args.push(Arg::Positional(self.expr()?));
        }
        self.expect_p(P::RParen, Want::CommaOrRParen)?;
        Ok(args)
    }

    /// A call's arguments after its `(`, through its `)`.
    fn args(&mut self) -> PResult<Vec<Arg>> {
        let mut args = Vec::new();
        if self.eat_p(P::RParen) {
            return Ok(args);
        }
        loop {
            let arg = match (self.tok(), self.tok_at(1), self.tok_at(2)) {
                (Tok::Ident, Tok::P(P::Assign), _) => {
                    let name = self.ident()?;
                    self.bump();
                    if self.empty_argument(&name, false) {
                        None
                    } else {
                        Some(Arg::Input { name, value: self.expr()? })
                    }
                }
                (Tok::Ident, Tok::P(P::Arrow), _) => {
                    let name = self.ident()?;
                    self.bump();
                    if self.empty_argument(&name, true) {
                        None
                    } else {
                        Some(Arg::Output { name, target: self.expr()?, negated: false })
                    }
                }
                (Tok::Kw(Kw::Not), Tok::Ident, Tok::P(P::Arrow)) => {
                    self.bump();
                    let name = self.ident()?;
                    self.bump();
                    if self.empty_argument(&name, true) {
                        None
                    } else {
                        Some(Arg::Output { name, target: self.expr()?, negated: true })
                    }
                }
                _ => Some(Arg::Positional(self.expr()?)),
            };
            args.extend(arg);
            let comma = self.span();
            if self.eat_p(P::Comma) {
                // `fb(IN := x, Q => q, );`: a `,` and then the end of the call
                if matches!(self.tok(), Tok::P(P::RParen)) {
                    self.habits.push(Noted { span: comma, habit: Habit::TrailingComma });
                    self.bump();
                    return Ok(args);
                }
                continue;
            }
            self.expect_p(P::RParen, Want::CommaOrRParen)?;
            return Ok(args);
        }
    }

    /// Whether the argument after `:=` or `=>` is empty (`ET => )`, `A := ,`), as TwinCAT's
    /// input assistant writes them: noted, and left out of the call, so that an empty input
    /// is one not given (its default, or the instance's value) and an empty output binds
    /// nothing. Its name is not looked up: it names nothing the call does.
    fn empty_argument(&mut self, name: &Ident, output: bool) -> bool {
        let empty = matches!(self.tok(), Tok::P(P::Comma | P::RParen));
        if empty {
            self.habits.push(Noted { span: name.span, habit: Habit::EmptyArgument { output } });
        }
        empty
    }

    fn primary(&mut self) -> PResult<Expr> {
        let span = self.span();
        let literal = match self.tok() {
            Tok::Int(n) if self.text_of(self.pos).contains('#') => Literal::Based(*n),
            Tok::Int(n) => Literal::Int(*n),
            Tok::Real(x) => Literal::Real(*x),
            Tok::Time(ns) => Literal::Time(*ns),
            Tok::Calendar(cal, count) => Literal::Calendar(*cal, *count),
            Tok::Str(s) => Literal::String(s.clone()),
            Tok::WStr(s) => Literal::WString(s.clone()),
            Tok::Kw(Kw::True) => Literal::Bool(true),
            Tok::Kw(Kw::False) => Literal::Bool(false),
            Tok::Ident => return Ok(Expr { kind: ExprKind::Name(self.ident()?), span }),
            // `.x`, CODESYS's global scope operator: the name keeps its dot for the checker,
            // which looks it up among the globals only
            Tok::P(P::Dot) if *self.tok_at(1) == Tok::Ident => {
                self.habit(Habit::GlobalScope);
                self.bump();
                let id = self.ident()?;
                let name = Ident { name: format!(".{}", id.name), span };
                return Ok(Expr { kind: ExprKind::Name(name), span });
            }
            // The operators that are also standard functions, in their call form: `AND(a, b)`,
            // `MOD(a, b)` (IEC 61131-3 lists them among the functions).
            Tok::Kw(kw @ (Kw::And | Kw::Or | Kw::Xor | Kw::Mod))
                if *self.tok_at(1) == Tok::P(P::LParen) =>
            {
                let name = match kw {
                    Kw::And => "AND",
                    Kw::Or => "OR",
                    Kw::Xor => "XOR",
                    _ => "MOD",
                };
                self.bump();
                return Ok(Expr { kind: ExprKind::Name(Ident { name: name.into(), span }), span });
            }
            Tok::TypedPrefix => {
                let text = {
                    let at = self.bump();
                    self.text_of(at)
                };
                let ty = Ident { name: text[..text.len() - 1].to_string(), span };
                let value = self.typed_value()?;
                let kind = ExprKind::Literal(Literal::Typed { ty, value: Box::new(value) });
                return Ok(Expr { kind, span });
            }
            Tok::P(P::LParen) => {
                self.bump();
                let inner = self.expr()?;
                let inner = self.assignment_after(inner)?;
                self.expect_p(P::RParen, Want::RParen)?;
                return Ok(inner);
            }
            _ => return Err(self.fail(Want::Expr)),
        };
        self.bump();
        Ok(Expr { kind: ExprKind::Literal(literal), span })
    }

    /// What follows `INT#`: a literal or a name, signed or not.
    fn typed_value(&mut self) -> PResult<Expr> {
        let span = self.span();
        if let Some(op @ (UnaryOp::Neg | UnaryOp::Plus)) = unary_op(self.tok()) {
            self.bump();
            let operand = self.typed_value()?;
            return Ok(Expr { kind: ExprKind::Unary(op, Box::new(operand)), span });
        }
        match self.tok() {
            Tok::Int(_)
            | Tok::Real(_)
            | Tok::Str(_)
            | Tok::WStr(_)
            | Tok::Time(_)
            | Tok::Calendar(..)
            | Tok::Ident
            | Tok::Kw(Kw::True | Kw::False) => self.primary(),
            _ => Err(self.fail(Want::TypedValue)),
        }
    }
}

/// `Base (…)` read as a call's arguments: an enumeration's values when each is a name, with a
/// value or without (`INT (A, B := 5)`; also a function block's named declaration arguments,
/// `T(x := 5)`); otherwise a function block's declaration arguments as written (`T(5, 'A')`),
/// which compile/fb_init.rs reads and refuses anywhere else.
fn enum_or_arguments(base: Ident, args: Vec<Arg>, span: Span) -> EnumDef {
    let value = |arg: &Arg| match arg {
        Arg::Positional(Expr { kind: ExprKind::Name(n), .. }) => Some((n.clone(), None)),
        Arg::Input { name, value } => Some((name.clone(), Some(value.clone()))),
        _ => None,
    };
    match args.iter().map(value).collect::<Option<Vec<_>>>() {
        Some(values) => EnumDef { base: Some(base), values, args: Vec::new(), span },
        None => EnumDef { base: Some(base), values: Vec::new(), args, span },
    }
}

/// `__NEW` or `__DELETE` (TwinCAT's dynamic memory, compile/heap.rs) when `callee` names one.
fn dynamic_memory(callee: &Expr) -> Option<&'static str> {
    let ExprKind::Name(id) = &callee.kind else { return None };
    ["__NEW", "__DELETE"].into_iter().find(|op| id.name.eq_ignore_ascii_case(op))
}

/// Whether `callee` names `SIZEOF`.
fn is_sizeof(callee: &Expr) -> bool {
    matches!(&callee.kind, ExprKind::Name(id) if id.name.eq_ignore_ascii_case("SIZEOF"))
}

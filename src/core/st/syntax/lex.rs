//! The lexer: text → tokens with their 1-based line and column (columns count characters).
//!
//! Comments (`(* *)` and `/* */`, both nestable, and `// …`) and pragmas (`{ … }`) are skipped;
//! the conditional pragmas (`{IF defined (x)}` … `{END_IF}`) decide which tokens are kept
//! (`super::cond`).
//! Literals are decoded here: integers in bases 2, 8, 10 and 16, reals, durations (in
//! nanoseconds) and strings with their `$` escapes. A malformed literal is reported and still
//! yields a token, so that the parser goes on without a second error for the same mistake.

use super::cond::{Conditions, Pragma};
use super::{Msg, DESCRIPTION, DESCRIPTION_END};
use crate::st::ast::Span;
use crate::st::dialect::{Habit, Noted};
use crate::value::{calendar_body, Calendar, CalendarKind};

/// The keywords, recognised whatever their case.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Kw {
    Program,
    EndProgram,
    Function,
    EndFunction,
    FunctionBlock,
    EndFunctionBlock,
    Action,
    EndAction,
    Method,
    EndMethod,
    Property,
    EndProperty,
    EndGet,
    EndSet,
    Interface,
    EndInterface,
    Class,
    EndClass,
    Configuration,
    EndConfiguration,
    EndResource,
    VarConfig,
    VarAccess,
    Type,
    EndType,
    Struct,
    EndStruct,
    /// `UNION` (CODESYS): a type whose members share their bytes.
    Union,
    EndUnion,
    Var,
    VarInput,
    VarOutput,
    VarInOut,
    VarTemp,
    VarStat,
    VarInst,
    VarGlobal,
    VarExternal,
    EndVar,
    Constant,
    Retain,
    NonRetain,
    At,
    Array,
    Of,
    String,
    If,
    Then,
    Elsif,
    Else,
    EndIf,
    Case,
    EndCase,
    For,
    To,
    By,
    Do,
    EndFor,
    While,
    EndWhile,
    Repeat,
    Until,
    EndRepeat,
    Exit,
    Continue,
    Return,
    Not,
    And,
    /// `AND_THEN` (CODESYS): `AND` that skips its right operand when the left is FALSE.
    AndThen,
    Or,
    /// `OR_ELSE` (CODESYS): `OR` that skips its right operand when the left is TRUE.
    OrElse,
    Xor,
    Mod,
    True,
    False,
}

impl Kw {
    /// The keyword spelled `upper` (in capitals), if any.
    fn from_upper(upper: &[u8]) -> Option<Kw> {
        Some(match upper {
            b"PROGRAM" => Kw::Program,
            b"END_PROGRAM" => Kw::EndProgram,
            b"FUNCTION" => Kw::Function,
            b"END_FUNCTION" => Kw::EndFunction,
            b"FUNCTION_BLOCK" => Kw::FunctionBlock,
            b"END_FUNCTION_BLOCK" => Kw::EndFunctionBlock,
            b"ACTION" => Kw::Action,
            b"METHOD" => Kw::Method,
            b"END_METHOD" => Kw::EndMethod,
            b"PROPERTY" => Kw::Property,
            b"END_PROPERTY" => Kw::EndProperty,
            b"END_GET" => Kw::EndGet,
            b"END_SET" => Kw::EndSet,
            b"INTERFACE" => Kw::Interface,
            b"END_INTERFACE" => Kw::EndInterface,
            b"CLASS" => Kw::Class,
            b"END_CLASS" => Kw::EndClass,
            b"CONFIGURATION" => Kw::Configuration,
            b"END_CONFIGURATION" => Kw::EndConfiguration,
            b"END_RESOURCE" => Kw::EndResource,
            b"VAR_CONFIG" => Kw::VarConfig,
            b"VAR_ACCESS" => Kw::VarAccess,
            b"END_ACTION" => Kw::EndAction,
            b"TYPE" => Kw::Type,
            b"END_TYPE" => Kw::EndType,
            b"STRUCT" => Kw::Struct,
            b"END_STRUCT" => Kw::EndStruct,
            b"UNION" => Kw::Union,
            b"END_UNION" => Kw::EndUnion,
            b"VAR" => Kw::Var,
            b"VAR_INPUT" => Kw::VarInput,
            b"VAR_OUTPUT" => Kw::VarOutput,
            b"VAR_IN_OUT" => Kw::VarInOut,
            b"VAR_TEMP" => Kw::VarTemp,
            b"VAR_STAT" => Kw::VarStat,
            b"VAR_INST" => Kw::VarInst,
            b"VAR_GLOBAL" => Kw::VarGlobal,
            b"VAR_EXTERNAL" => Kw::VarExternal,
            b"END_VAR" => Kw::EndVar,
            b"CONSTANT" => Kw::Constant,
            b"RETAIN" => Kw::Retain,
            b"NON_RETAIN" => Kw::NonRetain,
            b"AT" => Kw::At,
            b"ARRAY" => Kw::Array,
            b"OF" => Kw::Of,
            b"STRING" => Kw::String,
            b"IF" => Kw::If,
            b"THEN" => Kw::Then,
            b"ELSIF" => Kw::Elsif,
            b"ELSE" => Kw::Else,
            b"END_IF" => Kw::EndIf,
            b"CASE" => Kw::Case,
            b"END_CASE" => Kw::EndCase,
            b"FOR" => Kw::For,
            b"TO" => Kw::To,
            b"BY" => Kw::By,
            b"DO" => Kw::Do,
            b"END_FOR" => Kw::EndFor,
            b"WHILE" => Kw::While,
            b"END_WHILE" => Kw::EndWhile,
            b"REPEAT" => Kw::Repeat,
            b"UNTIL" => Kw::Until,
            b"END_REPEAT" => Kw::EndRepeat,
            b"EXIT" => Kw::Exit,
            b"CONTINUE" => Kw::Continue,
            b"RETURN" => Kw::Return,
            b"NOT" => Kw::Not,
            b"AND" => Kw::And,
            b"AND_THEN" => Kw::AndThen,
            b"OR_ELSE" => Kw::OrElse,
            b"OR" => Kw::Or,
            b"XOR" => Kw::Xor,
            b"MOD" => Kw::Mod,
            b"TRUE" => Kw::True,
            b"FALSE" => Kw::False,
            _ => return None,
        })
    }

    /// Whether it is an `END_…` keyword.
    pub(crate) fn is_end(self) -> bool {
        matches!(
            self,
            Kw::EndProgram
                | Kw::EndFunction
                | Kw::EndFunctionBlock
                | Kw::EndAction
                | Kw::EndMethod
                | Kw::EndProperty
                | Kw::EndGet
                | Kw::EndSet
                | Kw::EndInterface
                | Kw::EndClass
                | Kw::EndConfiguration
                | Kw::EndResource
                | Kw::EndType
                | Kw::EndStruct
                | Kw::EndUnion
                | Kw::EndVar
                | Kw::EndIf
                | Kw::EndCase
                | Kw::EndFor
                | Kw::EndWhile
                | Kw::EndRepeat
        )
    }
}

/// Punctuation and operators.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum P {
    Assign,
    Arrow,
    Colon,
    Semi,
    Comma,
    Dot,
    DotDot,
    LParen,
    RParen,
    LBracket,
    RBracket,
    Plus,
    Minus,
    Star,
    Power,
    Slash,
    Lt,
    Gt,
    Le,
    Ge,
    Eq,
    Ne,
    Amp,
    /// `^`: dereference.
    Caret,
}

#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Tok {
    /// A name; its text is the token's.
    Ident,
    Kw(Kw),
    Int(u128),
    Real(f64),
    /// A duration in nanoseconds.
    Time(i128),
    /// `D#2024-03-01`, `TOD#12:30:00`, `DT#…` and the long forms: the stored count.
    Calendar(Calendar, u64),
    /// A string with its escapes resolved.
    Str(String),
    /// A double-quoted (`WSTRING`) string with its escapes resolved.
    WStr(String),
    /// `INT#`: the type's name is the token's text without the `#`.
    TypedPrefix,
    /// `%D00100`: the address is the token's text without the `%`.
    Location,
    P(P),
    Eof,
}

#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Token {
    pub kind: Tok,
    pub span: Span,
    /// Byte range in the text.
    pub start: u32,
    pub end: u32,
}

pub(crate) struct Lexed {
    pub tokens: Vec<Token>,
    pub errors: Vec<(Span, Msg)>,
    /// The text ends inside a comment or pragma (already reported: the parser stays quiet
    /// about the end of file).
    pub eof_in_comment: bool,
    /// The tokens that follow an unterminated string, in order: what the parser finds wrong
    /// there is the string's fault, already reported.
    pub quiet: Vec<usize>,
    /// The tokens a `{attribute 'qualified_only'}` pragma stands before, in order: the one
    /// pragma that has an effect (see `compile::qualified`).
    pub qualified_only: Vec<usize>,
    /// The conditional pragmas (`{IF …}`, `{define …}`), noted for `[st] strict`.
    pub habits: Vec<Noted>,
}

/// Splits `text` into tokens; the last is [`Tok::Eof`].
#[cfg(test)]
pub(crate) fn lex(text: &str) -> Lexed {
    lex_with(text, &[])
}

/// Splits `text` into tokens, `defines` defined for its conditional pragmas (`[st] defines`,
/// [`super::cond`]); the last token is [`Tok::Eof`].
pub(crate) fn lex_with(text: &str, defines: &[String]) -> Lexed {
    let mut lexer = Lexer {
        text,
        bytes: text.as_bytes(),
        pos: 0,
        line: 1,
        col: 1,
        tokens: Vec::with_capacity(text.len() / 4 + 1),
        errors: Vec::new(),
        eof_in_comment: false,
        quiet: Vec::new(),
        qualified_only: Vec::new(),
        cond: Conditions::new(defines),
        habits: Vec::new(),
    };
    lexer.run();
    Lexed {
        tokens: lexer.tokens,
        errors: lexer.errors,
        eof_in_comment: lexer.eof_in_comment,
        quiet: lexer.quiet,
        qualified_only: lexer.qualified_only,
        habits: lexer.habits,
    }
}

struct Lexer<'a> {
    text: &'a str,
    bytes: &'a [u8],
    pos: usize,
    line: u32,
    col: u32,
    tokens: Vec<Token>,
    errors: Vec<(Span, Msg)>,
    eof_in_comment: bool,
    quiet: Vec<usize>,
    qualified_only: Vec<usize>,
    cond: Conditions,
    habits: Vec<Noted>,
}

/// Whether a pragma's text (between `{` and `}`) is `attribute 'qualified_only'`, spaced and
/// cased in any way.
fn is_qualified_only(pragma: &str) -> bool {
    let mut words = pragma.split_whitespace();
    words.next().is_some_and(|w| w.eq_ignore_ascii_case("attribute"))
        && words.next().is_some_and(|w| w.eq_ignore_ascii_case("'qualified_only'"))
        && words.next().is_none()
}

fn is_word(b: u8) -> bool {
    b.is_ascii_alphanumeric() || b == b'_'
}

impl Lexer<'_> {
    fn peek(&self) -> Option<u8> {
        self.bytes.get(self.pos).copied()
    }

    fn peek_at(&self, n: usize) -> Option<u8> {
        self.bytes.get(self.pos + n).copied()
    }

    fn span(&self) -> Span {
        Span { line: self.line, col: self.col }
    }

    /// Moves over one character.
    fn bump(&mut self) {
        let Some(b) = self.peek() else { return };
        if b < 0x80 {
            self.pos += 1;
        } else {
            let ch = self.text[self.pos..].chars().next().unwrap_or('\u{fffd}');
            self.pos += ch.len_utf8();
        }
        if b == b'\n' {
            self.line += 1;
            self.col = 1;
        } else {
            self.col += 1;
        }
    }

    /// Moves over ASCII word characters (letters, digits, `_`), and `extra` ones.
    fn bump_while(&mut self, extra: &[u8]) {
        while let Some(b) = self.peek() {
            if is_word(b) || extra.contains(&b) {
                self.bump();
            } else {
                break;
            }
        }
    }

    fn error(&mut self, span: Span, msg: Msg) {
        self.errors.push((span, msg));
    }

    fn push(&mut self, kind: Tok, span: Span, start: usize) {
        self.tokens.push(Token { kind, span, start: start as u32, end: self.pos as u32 });
    }

    fn run(&mut self) {
        loop {
            self.skip_trivia();
            let (start, span) = (self.pos, self.span());
            let Some(b) = self.peek() else {
                self.cond.finish(&mut self.errors);
                self.push(Tok::Eof, span, start);
                return;
            };
            // the text a conditional pragma leaves out is lexed, then dropped
            let kept = (self.tokens.len(), self.errors.len(), self.quiet.len());
            match b {
                b'a'..=b'z' | b'A'..=b'Z' | b'_' => self.word(start, span),
                b'0'..=b'9' => self.number(start, span),
                b'\'' => self.string(start, span),
                b'"' => self.wstring(start, span),
                b'%' => {
                    self.bump();
                    self.bump_while(b".");
                    // a partly specified address: `%I*`, `%QX*`, `%MW*`
                    let area = self.text[start + 1..self.pos].to_ascii_uppercase();
                    if self.peek() == Some(b'*') && is_partial_area(&area) {
                        self.bump();
                    }
                    if self.pos == start + 1 {
                        self.error(span, Msg::NoAddress);
                    }
                    self.push(Tok::Location, span, start);
                }
                _ => match self.punct() {
                    Some(p) => self.push(Tok::P(p), span, start),
                    None => {
                        self.bump();
                        let ch = self.text[start..self.pos].to_string();
                        self.error(span, Msg::UnexpectedChar { ch });
                    }
                },
            }
            if !self.cond.active() {
                self.tokens.truncate(kept.0);
                self.errors.truncate(kept.1);
                self.quiet.truncate(kept.2);
            }
        }
    }

    /// Skips white space, comments and pragmas.
    fn skip_trivia(&mut self) {
        while let Some(b) = self.peek() {
            match (b, self.peek_at(1)) {
                (b' ' | b'\t' | b'\r' | b'\n' | b'\x0c', _) => self.bump(),
                (b'(', Some(b'*')) => {
                    let (line, start) = (self.line, self.pos);
                    self.block_comment(b"(*", b"*)");
                    if self.text[start..self.pos].eq_ignore_ascii_case(DESCRIPTION) {
                        self.description(line);
                    }
                }
                (b'/', Some(b'*')) => self.block_comment(b"/*", b"*/"),
                (b'/', Some(b'/')) => {
                    while self.peek().is_some_and(|b| b != b'\n') {
                        self.bump();
                    }
                }
                (b'{', _) => {
                    let (line, start, at) = (self.line, self.pos + 1, self.span());
                    while self.peek().is_some_and(|b| b != b'}') {
                        self.bump();
                    }
                    if self.peek().is_none() {
                        let span = self.span();
                        self.error(span, Msg::UnterminatedPragma { line: line.to_string() });
                        self.eof_in_comment = true;
                    } else {
                        let text = &self.text[start..self.pos];
                        let active = self.cond.active();
                        if self.cond.pragma(text, at, &mut self.errors) == Pragma::Conditional {
                            self.habits.push(Noted { span: at, habit: Habit::ConditionalPragma });
                        } else if active && is_qualified_only(text) {
                            self.qualified_only.push(self.tokens.len());
                        }
                    }
                    self.bump();
                }
                _ => return,
            }
        }
    }

    /// The free text of a POU's description in the ST files KW-Software's MULTIPROG (Phoenix
    /// Contact's PC WORX) exports, after its `(*@KEY@:DESCRIPTION*)`, which `line` opens: up to
    /// and with `(*@KEY@:END_DESCRIPTION*)`, skipped as a comment (the text between is the
    /// description, written without comment brackets).
    fn description(&mut self, line: u32) {
        let rest = &self.text.as_bytes()[self.pos..];
        // looked for in place, any case: a copy of the rest of the file for each of a library
        // export's hundreds of descriptions would make the file's lexing quadratic
        let closer = DESCRIPTION_END.as_bytes();
        let end = rest.windows(closer.len()).position(|w| w.eq_ignore_ascii_case(closer));
        let target = self.pos + end.map_or(rest.len(), |at| at + closer.len());
        while self.pos < target {
            // one character at a time, so that lines are counted
            self.bump();
        }
        if end.is_none() {
            let span = self.span();
            self.error(span, Msg::UnterminatedDescription { line: line.to_string() });
            self.eof_in_comment = true;
        }
    }

    /// A comment from `open` to `close`, nesting.
    fn block_comment(&mut self, open: &[u8; 2], close: &[u8; 2]) {
        let line = self.line;
        self.bump();
        self.bump();
        let mut depth = 1;
        while let Some(b) = self.peek() {
            let next = self.peek_at(1);
            if b == close[0] && next == Some(close[1]) {
                self.bump();
                self.bump();
                depth -= 1;
                if depth == 0 {
                    return;
                }
            } else if b == open[0] && next == Some(open[1]) {
                self.bump();
                self.bump();
                depth += 1;
            } else {
                self.bump();
            }
        }
        let span = self.span();
        self.error(span, Msg::UnterminatedComment { line: line.to_string() });
        self.eof_in_comment = true;
    }

    fn punct(&mut self) -> Option<P> {
        let b = self.peek()?;
        let next = self.peek_at(1);
        let (p, len) = match (b, next) {
            (b':', Some(b'=')) => (P::Assign, 2),
            (b':', _) => (P::Colon, 1),
            (b'=', Some(b'>')) => (P::Arrow, 2),
            (b'=', _) => (P::Eq, 1),
            (b';', _) => (P::Semi, 1),
            (b',', _) => (P::Comma, 1),
            (b'.', Some(b'.')) => (P::DotDot, 2),
            (b'.', _) => (P::Dot, 1),
            (b'(', _) => (P::LParen, 1),
            (b')', _) => (P::RParen, 1),
            (b'[', _) => (P::LBracket, 1),
            (b']', _) => (P::RBracket, 1),
            (b'+', _) => (P::Plus, 1),
            (b'-', _) => (P::Minus, 1),
            (b'*', Some(b'*')) => (P::Power, 2),
            (b'*', _) => (P::Star, 1),
            (b'/', _) => (P::Slash, 1),
            (b'<', Some(b'=')) => (P::Le, 2),
            (b'<', Some(b'>')) => (P::Ne, 2),
            (b'<', _) => (P::Lt, 1),
            (b'>', Some(b'=')) => (P::Ge, 2),
            (b'>', _) => (P::Gt, 1),
            (b'&', _) => (P::Amp, 1),
            (b'^', _) => (P::Caret, 1),
            _ => return None,
        };
        for _ in 0..len {
            self.bump();
        }
        Some(p)
    }

    /// A name, a keyword, a typed literal's prefix (`INT#`) or a duration (`T#1s`).
    fn word(&mut self, start: usize, span: Span) {
        self.bump_while(&[]);
        let word = &self.bytes[start..self.pos];
        let mut upper = [0u8; 20];
        let kw = if word.len() <= upper.len() {
            for (u, b) in upper.iter_mut().zip(word) {
                *u = b.to_ascii_uppercase();
            }
            let upper = &upper[..word.len()];
            if self.peek() == Some(b'#') {
                self.bump();
                if matches!(upper, b"T" | b"TIME" | b"LT" | b"LTIME") {
                    return self.duration(start, span);
                }
                let calendar = std::str::from_utf8(upper).ok().and_then(Calendar::from_prefix);
                if let Some(cal) = calendar {
                    return self.calendar(cal, start, span);
                }
                return self.push(Tok::TypedPrefix, span, start);
            }
            Kw::from_upper(upper)
        } else {
            None
        };
        if kw.is_none() && self.peek() == Some(b'#') {
            self.bump();
            return self.push(Tok::TypedPrefix, span, start);
        }
        self.push(kw.map_or(Tok::Ident, Tok::Kw), span, start);
    }

    /// `T#…` after its `#`: the value is everything up to the next character that cannot be
    /// part of a duration.
    fn duration(&mut self, start: usize, span: Span) {
        if matches!(self.peek(), Some(b'-' | b'+')) {
            self.bump();
        }
        self.bump_while(b".");
        let text = &self.text[start..self.pos];
        let body = &text[text.find('#').map_or(0, |i| i + 1)..];
        let ns = match parse_duration(body) {
            Ok(ns) => ns,
            Err(why) => {
                let text = text.to_string();
                let msg = match why {
                    DurationError::Unit(unit) => Msg::DurationUnit { text, unit },
                    DurationError::NoUnit(after) => Msg::DurationNoUnit { text, after },
                    DurationError::NoNumber(found) => Msg::DurationNoNumber { text, found },
                    DurationError::Range => Msg::OutOfRange { text },
                };
                self.error(span, msg);
                0
            }
        };
        self.push(Tok::Time(ns), span, start);
    }

    /// `D#…`, `TOD#…`, `DT#…` and the long forms after their `#`: digits, with the `-`, `:`
    /// and `.` of the type's form where a digit follows them (so `D#2024-03-01-d` stops before
    /// the minus).
    fn calendar(&mut self, cal: Calendar, start: usize, span: Span) {
        let (dashes, colons) = match cal.kind() {
            CalendarKind::Date => (2, false),
            CalendarKind::Tod => (0, true),
            CalendarKind::Dt => (3, true),
        };
        let mut dashes_left = dashes;
        loop {
            let digit_next = self.peek_at(1).is_some_and(|b| b.is_ascii_digit());
            match self.peek() {
                Some(b'0'..=b'9') => {}
                Some(b'-') if dashes_left > 0 && digit_next => dashes_left -= 1,
                Some(b':' | b'.') if colons && digit_next => {}
                _ => break,
            }
            self.bump();
        }
        let text = &self.text[start..self.pos];
        let body = &text[text.find('#').map_or(0, |i| i + 1)..];
        let count = match calendar_body(cal, body) {
            Ok(count) => count,
            Err(why) => {
                let msg = Msg::Calendar {
                    text: text.to_string(),
                    ty: cal.name().into(),
                    why: why.to_string(),
                };
                self.error(span, msg);
                0
            }
        };
        self.push(Tok::Calendar(cal, count), span, start);
    }

    /// An integer (any base) or a real. Right after a `.`, only digits: `x.3` is a bit.
    fn number(&mut self, start: usize, span: Span) {
        let after_dot = matches!(self.tokens.last(), Some(Token { kind: Tok::P(P::Dot), .. }));
        self.bump_while_digits();
        let mut real = false;
        let mut base = 10;
        if after_dot {
            // a bit number: nothing else
        } else if self.peek() == Some(b'#') {
            base = match &self.text[start..self.pos] {
                "2" => 2,
                "8" => 8,
                "16" => 16,
                _ => 0,
            };
            self.bump();
            self.bump_while(&[]);
        } else {
            if self.peek() == Some(b'.') && self.peek_at(1).is_some_and(|b| b.is_ascii_digit()) {
                real = true;
                self.bump();
                self.bump_while_digits();
            }
            if matches!(self.peek(), Some(b'e' | b'E')) {
                let digit_at = if matches!(self.peek_at(1), Some(b'+' | b'-')) { 2 } else { 1 };
                if self.peek_at(digit_at).is_some_and(|b| b.is_ascii_digit()) {
                    real = true;
                    for _ in 0..digit_at {
                        self.bump();
                    }
                    self.bump_while_digits();
                }
            }
        }
        // Letters glued to a number make it no number (`12ab`, `1.5x`, `16#FG`).
        let glued = self.peek().is_some_and(is_word);
        self.bump_while(&[]);
        let text = &self.text[start..self.pos];
        let kind = match number_value(text, base, real && !glued) {
            Ok(kind) => kind,
            Err(bad) => {
                let text = text.to_string();
                let msg = if bad { Msg::NotANumber { text } } else { Msg::OutOfRange { text } };
                self.error(span, msg);
                Tok::Int(0)
            }
        };
        self.push(kind, span, start);
    }

    fn bump_while_digits(&mut self) {
        while self.peek().is_some_and(|b| b.is_ascii_digit() || b == b'_') {
            self.bump();
        }
    }

    /// `'…'` with `$` escapes; a string ends at its line's end at the latest.
    fn string(&mut self, start: usize, span: Span) {
        self.quoted(start, span, false);
    }

    /// `"…"` (a `WSTRING`) with `$` escapes, `$hhhh` a UTF-16 code unit.
    fn wstring(&mut self, start: usize, span: Span) {
        self.quoted(start, span, true);
    }

    /// A string in single quotes, or in double quotes when `wide`.
    fn quoted(&mut self, start: usize, span: Span, wide: bool) {
        let (quote, token): (u8, fn(String) -> Tok) =
            if wide { (b'"', Tok::WStr) } else { (b'\'', Tok::Str) };
        self.bump();
        let mut value = String::new();
        while let Some(b) = self.peek() {
            match b {
                b if b == quote => {
                    self.bump();
                    return self.push(token(value), span, start);
                }
                b'\n' | b'\r' => break,
                b'$' => {
                    let at = self.span();
                    let from = self.pos;
                    self.bump();
                    let escaped = match self.peek() {
                        Some(b'$') => Some('$'),
                        Some(q) if q == quote => Some(char::from(q)),
                        Some(b'L' | b'l' | b'N' | b'n') => Some('\n'),
                        Some(b'P' | b'p') => Some('\x0c'),
                        Some(b'R' | b'r') => Some('\r'),
                        Some(b'T' | b't') => Some('\t'),
                        _ => None,
                    };
                    if let Some(ch) = escaped {
                        self.bump();
                        value.push(ch);
                        continue;
                    }
                    let hex = |b: Option<u8>| b.and_then(|b| (b as char).to_digit(16));
                    let unit = (0..4).try_fold(0, |u, i| Some(u * 16 + hex(self.peek_at(i))?));
                    if let Some(unit) = unit.filter(|_| wide) {
                        (0..4).for_each(|_| self.bump());
                        // a surrogate half is no character on its own: a bad escape
                        match char::from_u32(unit) {
                            Some(ch) => value.push(ch),
                            None => {
                                let escape = self.text[from..self.pos].to_string();
                                self.error(at, Msg::BadEscape { escape });
                            }
                        }
                        continue;
                    }
                    if let (false, Some(hi), Some(lo)) =
                        (wide, hex(self.peek()), hex(self.peek_at(1)))
                    {
                        self.bump();
                        self.bump();
                        value.push(crate::value::decode_byte((hi * 16 + lo) as u8));
                        continue;
                    }
                    if self.peek().is_some_and(|b| b != b'\n' && b != b'\r') {
                        self.bump();
                    }
                    let escape = self.text[from..self.pos].to_string();
                    self.error(at, Msg::BadEscape { escape });
                }
                _ => {
                    let from = self.pos;
                    self.bump();
                    value.push_str(&self.text[from..self.pos]);
                }
            }
        }
        self.error(span, Msg::UnterminatedString);
        self.push(token(value), span, start);
        self.quiet.push(self.tokens.len());
    }
}

/// The value of a number's text: `Err(true)` when it is no number, `Err(false)` when it is one
/// out of range.
fn number_value(text: &str, base: u32, real: bool) -> Result<Tok, bool> {
    let digits = match text.find('#') {
        Some(i) => &text[i + 1..],
        None => text,
    };
    let underscores_ok = !digits.starts_with('_')
        && !digits.ends_with('_')
        && !digits.contains("__")
        && !digits.contains("_.")
        && !digits.contains("._");
    if base == 0 || digits.is_empty() || !underscores_ok {
        return Err(true);
    }
    if real {
        let clean: String = digits.chars().filter(|&c| c != '_').collect();
        let value: f64 = clean.parse().map_err(|_| true)?;
        return if value.is_finite() { Ok(Tok::Real(value)) } else { Err(false) };
    }
    let mut value: u128 = 0;
    for c in digits.chars().filter(|&c| c != '_') {
        let digit = c.to_digit(base).ok_or(true)?;
        value = value
            .checked_mul(u128::from(base))
            .and_then(|v| v.checked_add(u128::from(digit)))
            .ok_or(false)?;
    }
    Ok(Tok::Int(value))
}

#[derive(Debug, PartialEq, Eq)]
pub(crate) enum DurationError {
    /// A unit that is none of d h m s ms us ns.
    Unit(String),
    /// A number without its unit.
    NoUnit(String),
    /// Not a number where one must be: what is there instead (`` `x` `` or `nothing`).
    NoNumber(String),
    /// Fewer nanoseconds than an `i64` holds, or more than a `u64` does (between the two: the
    /// compiler's to judge, CODESYS's unsigned `LTIME`).
    Range,
}

/// The nanoseconds of a duration's text after `T#`: an optional sign, then numbers (a fraction
/// allowed) each with its unit, `_` between them allowed.
pub(crate) fn parse_duration(body: &str) -> Result<i128, DurationError> {
    let (negative, mut rest) = match body.as_bytes().first() {
        Some(b'-') => (true, &body[1..]),
        Some(b'+') => (false, &body[1..]),
        _ => (false, body),
    };
    let mut total: i128 = 0;
    let mut first = true;
    loop {
        if !first {
            rest = rest.trim_start_matches('_');
        }
        if rest.is_empty() && !first {
            break;
        }
        first = false;
        let digits = rest.bytes().take_while(|b| b.is_ascii_digit() || *b == b'_').count();
        let mut len = digits;
        if digits > 0 && rest.as_bytes().get(len) == Some(&b'.') {
            len += 1 + rest[len + 1..].bytes().take_while(u8::is_ascii_digit).count();
        }
        if digits == 0 || rest.starts_with('_') {
            let found = match rest.chars().next() {
                None => "nothing".to_string(),
                Some(_) => {
                    let n = rest.bytes().take_while(|b| b.is_ascii_alphabetic()).count().max(1);
                    format!("`{}`", rest.get(..n).unwrap_or(rest))
                }
            };
            return Err(DurationError::NoNumber(found));
        }
        let number = &rest[..len];
        rest = &rest[len..];
        let unit_len = rest.bytes().take_while(u8::is_ascii_alphabetic).count();
        let unit = &rest[..unit_len];
        rest = &rest[unit_len..];
        let scale: i128 = match unit.to_ascii_lowercase().as_str() {
            "d" => 86_400_000_000_000,
            "h" => 3_600_000_000_000,
            "m" => 60_000_000_000,
            "s" => 1_000_000_000,
            "ms" => 1_000_000,
            "us" => 1_000,
            "ns" => 1,
            "" => return Err(DurationError::NoUnit(number.to_string())),
            _ => return Err(DurationError::Unit(unit.to_string())),
        };
        let (whole, fraction) = number.split_once('.').unwrap_or((number, ""));
        let mut value: i128 = 0;
        for b in whole.bytes().filter(|&b| b != b'_') {
            value = value
                .checked_mul(10)
                .and_then(|v| v.checked_add(i128::from(b - b'0')))
                .ok_or(DurationError::Range)?;
        }
        value = value.checked_mul(scale).ok_or(DurationError::Range)?;
        // The fraction's digits, as far as they matter for whole nanoseconds.
        let mut part = scale;
        for b in fraction.bytes() {
            part /= 10;
            value += i128::from(b - b'0') * part;
        }
        total = total.checked_add(value).ok_or(DurationError::Range)?;
        if total > i128::from(u64::MAX) {
            return Err(DurationError::Range);
        }
    }
    let total = if negative { -total } else { total };
    if total < i128::from(i64::MIN) {
        return Err(DurationError::Range);
    }
    Ok(total)
}

/// Whether `area` (the letters after `%`) may be followed by `*`: `I`, `Q` or `M`, with a
/// size letter or without.
fn is_partial_area(area: &str) -> bool {
    let mut chars = area.chars();
    matches!(chars.next(), Some('I' | 'Q' | 'M'))
        && matches!(chars.next(), None | Some('X' | 'B' | 'W' | 'D' | 'L'))
        && chars.next().is_none()
}

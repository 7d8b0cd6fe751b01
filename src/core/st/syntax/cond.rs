//! Conditional compilation, as CODESYS and TwinCAT write it in pragmas (docs/ST.md,
//! "Pragmas"): `{define name}`, `{undefine name}`, and `{IF cond}` … `{ELSIF cond}` … `{ELSE}`
//! … `{END_IF}` around any text, declarations as well as statements (TwinCAT 3.1.4024
//! evaluates them in both). A condition is `defined (name)`, joined with `NOT`, `AND`, `OR`
//! and parentheses; the names are the file's `{define}`s above and `[st] defines`.
//!
//! The lexer reads every pragma's text here ([`Conditions::pragma`]) and drops the tokens of
//! the text a condition leaves out, having lexed them all the same: the lines and columns of
//! what follows stay right, and a `}` or `{END_IF}` inside a comment or a string of that text
//! is the comment's or the string's. The predicates that need the compiler's knowledge
//! (`defined (variable: x)`, `hastype`, `hasvalue`, `hasattribute`, `defined
//! (IsLittleEndian)`…) are errors naming the one written.

use super::Msg;
use crate::st::ast::Span;

/// One `{IF}` open.
#[derive(Debug)]
struct Open {
    /// Where its `{IF` is.
    span: Span,
    /// Whether the text around it is kept.
    outer: bool,
    /// A branch of it was kept already (or is being kept).
    taken: bool,
    /// The branch the text is in now is kept.
    active: bool,
    /// Its `{ELSE}` was seen.
    in_else: bool,
}

/// The defines and the open `{IF}`s of a file, as the lexer reads it.
#[derive(Debug)]
pub(super) struct Conditions {
    /// Defined names, in lower case (names are case-insensitive in plcd).
    defines: Vec<String>,
    open: Vec<Open>,
}

/// What a pragma was.
#[derive(Debug, PartialEq, Eq)]
pub(super) enum Pragma {
    /// Not a conditional pragma: an attribute, a message, a comment-like one.
    Other,
    /// `{define}`, `{undefine}`, `{IF}`: conditional compilation, a habit (noted once for an
    /// `{IF}` and the pragmas that go on with it).
    Conditional,
    /// `{ELSIF}`, `{ELSE}`, `{END_IF}`: the rest of an `{IF}`.
    Continued,
}

impl Conditions {
    pub(super) fn new(defines: &[String]) -> Conditions {
        Conditions {
            defines: defines.iter().map(|d| d.to_ascii_lowercase()).collect(),
            open: Vec::new(),
        }
    }

    /// Whether the text here is kept.
    pub(super) fn active(&self) -> bool {
        self.open.last().is_none_or(|o| o.active)
    }

    /// Reads the pragma `text` (between `{` and `}`) that starts at `span`; errors into
    /// `errors`.
    pub(super) fn pragma(
        &mut self,
        text: &str,
        span: Span,
        errors: &mut Vec<(Span, Msg)>,
    ) -> Pragma {
        let trimmed = text.trim_start();
        let word_end = trimmed
            .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
            .unwrap_or(trimmed.len());
        let (word, rest) = trimmed.split_at(word_end);
        let directive = word.to_ascii_uppercase();
        let active = self.active();
        match directive.as_str() {
            "DEFINE" | "UNDEFINE" => {
                let Some(name) = rest.split_whitespace().next().filter(|n| is_name(n)) else {
                    errors.push((span, Msg::CondName { directive: word.to_string() }));
                    return Pragma::Conditional;
                };
                if active {
                    let name = name.to_ascii_lowercase();
                    self.defines.retain(|d| *d != name);
                    if directive == "DEFINE" {
                        // `{define name 'value'}`: the value matters to `hasvalue` only
                        self.defines.push(name);
                    }
                }
            }
            "IF" => {
                let value = if active { self.condition(rest, span, errors) } else { false };
                self.open.push(Open {
                    span,
                    outer: active,
                    taken: value,
                    active: value,
                    in_else: false,
                });
            }
            "ELSIF" | "ELSE" => {
                let Some(last) = self.open.len().checked_sub(1) else {
                    errors.push((span, Msg::CondStray { directive: word.to_string() }));
                    return Pragma::Continued;
                };
                if self.open[last].in_else {
                    errors.push((span, Msg::CondAfterElse { directive: word.to_string() }));
                }
                let (outer, taken) = (self.open[last].outer, self.open[last].taken);
                let value = if directive == "ELSE" {
                    if !rest.trim().is_empty() {
                        errors.push((span, Msg::CondExpr));
                    }
                    self.open[last].in_else = true;
                    outer && !taken
                } else {
                    outer && !taken && self.condition(rest, span, errors)
                };
                let open = &mut self.open[last];
                open.active = value;
                open.taken |= value;
                return Pragma::Continued;
            }
            "END_IF" => {
                if self.open.pop().is_none() {
                    errors.push((span, Msg::CondStray { directive: word.to_string() }));
                }
                return Pragma::Continued;
            }
            _ => return Pragma::Other,
        }
        Pragma::Conditional
    }

    /// At the end of the file: an error at each `{IF}` left open.
    pub(super) fn finish(&mut self, errors: &mut Vec<(Span, Msg)>) {
        for open in self.open.drain(..) {
            errors.push((open.span, Msg::CondUnclosed));
        }
    }

    /// The value of a condition; `false` and an error when it cannot be read.
    fn condition(&self, text: &str, span: Span, errors: &mut Vec<(Span, Msg)>) -> bool {
        let words = words(text);
        let mut reader = Reader { words: &words, at: 0, defines: &self.defines };
        match reader.or() {
            Ok(value) if reader.at == words.len() => value,
            Ok(_) => {
                errors.push((span, Msg::CondExpr));
                false
            }
            Err(msg) => {
                errors.push((span, msg));
                false
            }
        }
    }
}

fn is_name(word: &str) -> bool {
    let mut chars = word.chars();
    chars.next().is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_')
}

/// A condition's words: names, `(`, `)`, `:`, `,` and anything else one character at a time.
fn words(text: &str) -> Vec<&str> {
    let mut out = Vec::new();
    let mut rest = text;
    loop {
        rest = rest.trim_start();
        let Some(c) = rest.chars().next() else { return out };
        let len = if c.is_ascii_alphanumeric() || c == '_' {
            rest.find(|c: char| !(c.is_ascii_alphanumeric() || c == '_')).unwrap_or(rest.len())
        } else if c == '\'' {
            // a quoted value (`hasvalue (x, '1')`): one word
            rest[1..].find('\'').map_or(rest.len(), |end| end + 2)
        } else {
            c.len_utf8()
        };
        out.push(&rest[..len]);
        rest = &rest[len..];
    }
}

/// Reads a condition: `or := and (OR and)*`, `and := not (AND not)*`, `not := NOT not |
/// ( or ) | defined ( name )`.
struct Reader<'a> {
    words: &'a [&'a str],
    at: usize,
    defines: &'a [String],
}

impl<'a> Reader<'a> {
    fn peek(&self) -> Option<&'a str> {
        self.words.get(self.at).copied()
    }

    fn eat(&mut self, word: &str) -> bool {
        let found = self.peek().is_some_and(|w| w.eq_ignore_ascii_case(word));
        self.at += usize::from(found);
        found
    }

    fn or(&mut self) -> Result<bool, Msg> {
        let mut value = self.and()?;
        while self.eat("OR") {
            value |= self.and()?;
        }
        Ok(value)
    }

    fn and(&mut self) -> Result<bool, Msg> {
        let mut value = self.not()?;
        while self.eat("AND") {
            value &= self.not()?;
        }
        Ok(value)
    }

    fn not(&mut self) -> Result<bool, Msg> {
        if self.eat("NOT") {
            return Ok(!self.not()?);
        }
        if self.eat("(") {
            let value = self.or()?;
            return if self.eat(")") { Ok(value) } else { Err(Msg::CondExpr) };
        }
        let Some(word) = self.peek().filter(|w| is_name(w)) else { return Err(Msg::CondExpr) };
        self.at += 1;
        if !word.eq_ignore_ascii_case("defined") {
            // hasvalue, hastype, hasattribute, project_defined, a constant…
            return Err(Msg::CondPredicate { predicate: word.to_string() });
        }
        if !self.eat("(") {
            return Err(Msg::CondExpr);
        }
        let name = self.peek().filter(|w| is_name(w)).ok_or(Msg::CondExpr)?;
        self.at += 1;
        if self.peek() == Some(":") || name.eq_ignore_ascii_case("IsLittleEndian") {
            // `defined (variable: x)`, `(type: T)`, `(pou: P)`… ask the compiler's knowledge
            let what = if self.peek() == Some(":") {
                format!("defined ({name}: …)")
            } else {
                format!("defined ({name})")
            };
            return Err(Msg::CondPredicate { predicate: what });
        }
        if !self.eat(")") {
            return Err(Msg::CondExpr);
        }
        Ok(self.defines.iter().any(|d| d.eq_ignore_ascii_case(name)))
    }
}

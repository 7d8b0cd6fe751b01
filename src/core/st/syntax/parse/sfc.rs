//! The textual Sequential Function Chart in a POU's body (IEC 61131-3 ed3 §6.7.2 and the
//! grammar of its annex B): `INITIAL_STEP`, `STEP`, `TRANSITION` → [`crate::st::sfc::Sfc`].
//!
//! Its words (`STEP`, `INITIAL_STEP`, `END_STEP`, `TRANSITION`, `END_TRANSITION`, `FROM`,
//! `PRIORITY`) are no keywords, so that existing programs may keep variables called `step` or
//! `from`: an element starts only where a statement cannot (`STEP name`, two names in a row;
//! `TRANSITION FROM`, `TRANSITION name FROM`, `TRANSITION (PRIORITY`).
//! Recovery: an error inside an element skips to its `END_STEP` / `END_TRANSITION`, or to
//! the next element, `ACTION` or the end of the POU.

use super::super::lex::{Kw, Tok, P};
use super::super::Want;
use super::{PResult, Parser};
use crate::st::ast::Ident;
use crate::st::sfc::{Association, Qualifier, Sfc, Step, Transition};

impl Parser<'_> {
    /// Whether the word at `n` tokens on is `word`.
    fn word_at(&self, n: usize, word: &str) -> bool {
        let index = (self.pos + n).min(self.tokens.len() - 1);
        *self.tok_at(n) == Tok::Ident && self.text_of(index).eq_ignore_ascii_case(word)
    }

    /// Whether an SFC element starts here.
    pub(super) fn at_sfc_element(&self) -> bool {
        if (self.word_at(0, "STEP") || self.word_at(0, "INITIAL_STEP"))
            && *self.tok_at(1) == Tok::Ident
        {
            return true;
        }
        if !self.word_at(0, "TRANSITION") {
            return false;
        }
        self.word_at(1, "FROM")
            || (*self.tok_at(1) == Tok::Ident && self.word_at(2, "FROM"))
            || (*self.tok_at(1) == Tok::P(P::LParen) && self.word_at(2, "PRIORITY"))
            || (*self.tok_at(1) == Tok::Ident
                && *self.tok_at(2) == Tok::P(P::LParen)
                && self.word_at(3, "PRIORITY"))
    }

    /// One step or transition, added to `sfc` (the caller has seen [`Parser::at_sfc_element`]).
    pub(super) fn sfc_element(&mut self, sfc: &mut Sfc) {
        if self.word_at(0, "TRANSITION") {
            match self.transition() {
                Ok(transition) => sfc.transitions.push(transition),
                Err(_) => self.sync_sfc("END_TRANSITION"),
            }
        } else {
            match self.step() {
                Ok(step) => sfc.steps.push(step),
                Err(_) => self.sync_sfc("END_STEP"),
            }
        }
    }

    /// After an error in an element: past its `end` word, or to the next element, `ACTION`,
    /// an `END_…` keyword or a top-level keyword.
    fn sync_sfc(&mut self, end: &str) {
        loop {
            if self.word_at(0, end) {
                self.bump();
                self.eat_p(P::Semi);
                return;
            }
            let tok = self.tok();
            let stop = matches!(tok, Tok::Eof | Tok::Kw(Kw::Action))
                || matches!(tok, Tok::Kw(kw) if kw.is_end())
                || super::is_top(tok);
            if stop || self.at_sfc_element() {
                return;
            }
            self.bump();
        }
    }

    /// `[INITIAL_]STEP Name: {association ;} END_STEP`.
    fn step(&mut self) -> PResult<Step> {
        let span = self.span();
        let initial = self.word_at(0, "INITIAL_STEP");
        self.bump();
        let name = self.ident()?;
        self.expect_p(P::Colon, Want::Colon)?;
        let mut associations = Vec::new();
        loop {
            if self.word_at(0, "END_STEP") {
                self.bump();
                self.eat_p(P::Semi);
                break;
            }
            if self.eat_p(P::Semi) {
                continue;
            }
            if *self.tok() != Tok::Ident || self.at_sfc_element() {
                return Err(self.fail(Want::EndStep));
            }
            associations.push(self.association()?);
        }
        Ok(Step { name, initial, associations, span })
    }

    /// `Action([Qualifier[, duration][, indicator…]]);`.
    fn association(&mut self) -> PResult<Association> {
        let span = self.span();
        let action = self.ident()?;
        let mut qualifier: Option<Ident> = None;
        let mut duration = None;
        let mut indicators = Vec::new();
        self.expect_p(P::LParen, Want::LParen)?;
        if !self.eat_p(P::RParen) {
            qualifier = Some(self.ident()?);
            let timed = qualifier
                .as_ref()
                .and_then(|q| Qualifier::from_name(&q.name))
                .is_some_and(Qualifier::timed);
            while self.eat_p(P::Comma) {
                let arg = self.expr()?;
                if timed && duration.is_none() {
                    duration = Some(arg);
                } else {
                    indicators.push(arg);
                }
            }
            self.expect_p(P::RParen, Want::CommaOrRParen)?;
        }
        self.expect_p(P::Semi, Want::SemiAfterDecl)?;
        Ok(Association { action, qualifier, duration, indicators, span })
    }

    /// `TRANSITION [Name] [(PRIORITY := n)] FROM steps TO steps := condition; END_TRANSITION`.
    fn transition(&mut self) -> PResult<Transition> {
        let span = self.span();
        self.bump();
        let name = if *self.tok() == Tok::Ident && !self.word_at(0, "FROM") {
            Some(self.ident()?)
        } else {
            None
        };
        let mut priority = None;
        if self.eat_p(P::LParen) {
            if !self.word_at(0, "PRIORITY") {
                return Err(self.fail(Want::Name));
            }
            self.bump();
            self.expect_p(P::Assign, Want::Assign)?;
            priority = Some(self.expr()?);
            self.expect_p(P::RParen, Want::RParen)?;
        }
        if !self.word_at(0, "FROM") {
            return Err(self.fail(Want::From));
        }
        self.bump();
        let from = self.step_names()?;
        if !self.eat_kw(Kw::To) {
            return Err(self.fail(Want::To));
        }
        let to = self.step_names()?;
        self.expect_p(P::Assign, Want::Assign)?;
        let condition = self.expr()?;
        self.expect_p(P::Semi, Want::SemiAfterStmt)?;
        if !self.word_at(0, "END_TRANSITION") {
            return Err(self.fail(Want::EndTransition));
        }
        self.bump();
        self.eat_p(P::Semi);
        Ok(Transition { name, priority, from, to, condition, span })
    }

    /// `step` or `(step, step, …)`.
    fn step_names(&mut self) -> PResult<Vec<Ident>> {
        if !self.eat_p(P::LParen) {
            return Ok(vec![self.ident()?]);
        }
        let mut names = vec![self.ident()?];
        while self.eat_p(P::Comma) {
            names.push(self.ident()?);
        }
        self.expect_p(P::RParen, Want::CommaOrRParen)?;
        Ok(names)
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use crate::st::ast::{ExprKind, Item, Literal, Pou, Span, StmtKind};
    use crate::st::syntax::parse_file;

    fn pou(text: &str) -> Pou {
        let (file, diags) = parse_file(Path::new("t.st"), text);
        assert!(diags.0.is_empty(), "{:?}", diags.0);
        match file.items.into_iter().next() {
            Some(Item::Pou(pou)) => pou,
            other => panic!("{other:?}"),
        }
    }

    fn errors(text: &str) -> Vec<String> {
        let (_, diags) = parse_file(Path::new("t.st"), text);
        diags.0.iter().map(|d| format!("{}:{}: {}", d.line, d.col, d.message)).collect()
    }

    #[test]
    fn steps_associations_and_transitions() {
        let p = pou("PROGRAM p
INITIAL_STEP s0: A(N); B(L, T#5s, ind); C(); D(P0); END_STEP
STEP s1: END_STEP
TRANSITION t (PRIORITY := 2) FROM s0 TO (s1, s2) := x AND y; END_TRANSITION
TRANSITION FROM (s1, s2) TO s0 := TRUE; END_TRANSITION
ACTION A: x := 1; END_ACTION
END_PROGRAM");
        assert!(p.body.is_empty());
        assert_eq!(p.actions.len(), 1);
        let sfc = p.sfc.expect("a chart");
        assert_eq!(sfc.steps.len(), 2);
        let s0 = &sfc.steps[0];
        assert!(s0.initial && !sfc.steps[1].initial);
        assert_eq!(s0.span, Span { line: 2, col: 1 });
        let assoc: Vec<(&str, Option<&str>, bool, usize)> = s0
            .associations
            .iter()
            .map(|a| {
                let q = a.qualifier.as_ref().map(|q| q.name.as_str());
                (a.action.name.as_str(), q, a.duration.is_some(), a.indicators.len())
            })
            .collect();
        assert_eq!(
            assoc,
            [
                ("A", Some("N"), false, 0),
                ("B", Some("L"), true, 1),
                ("C", None, false, 0),
                ("D", Some("P0"), false, 0)
            ]
        );
        let t = &sfc.transitions[0];
        assert_eq!(t.name.as_ref().map(|n| n.name.as_str()), Some("t"));
        assert!(matches!(
            t.priority.as_ref().map(|p| &p.kind),
            Some(ExprKind::Literal(Literal::Int(2)))
        ));
        let names = |l: &[crate::st::ast::Ident]| -> Vec<String> {
            l.iter().map(|i| i.name.clone()).collect()
        };
        assert_eq!(names(&t.from), ["s0"]);
        assert_eq!(names(&t.to), ["s1", "s2"]);
        assert_eq!(names(&sfc.transitions[1].from), ["s1", "s2"]);
    }

    #[test]
    fn the_words_stay_names_elsewhere() {
        let p = pou("PROGRAM p
VAR step, from, transition : INT; END_VAR
step := from + 1;
transition := step;
END_PROGRAM");
        assert!(p.sfc.is_none());
        assert_eq!(p.body.len(), 2);
        assert!(matches!(p.body[0].kind, StmtKind::Assign { .. }));
    }

    #[test]
    fn statements_before_a_chart_are_kept_for_the_checker() {
        let p = pou("PROGRAM p
x := 1;
INITIAL_STEP s0: END_STEP
END_PROGRAM");
        assert_eq!(p.body.len(), 1);
        assert_eq!(p.sfc.map(|s| s.steps.len()), Some(1));
    }

    #[test]
    fn each_broken_element_makes_one_error_and_the_rest_parses() {
        let errs = errors(
            "PROGRAM p
INITIAL_STEP s0: A(N) END_STEP
STEP s3: B; END_STEP
STEP s1: END_STEP
TRANSITION FROM s0 s1 := TRUE; END_TRANSITION
TRANSITION FROM s1 TO s0 := TRUE;
STEP s2: END_STEP
END_PROGRAM",
        );
        assert_eq!(
            errs,
            [
                "2:23: expected `;` after the declaration, found `END_STEP`",
                "3:11: expected `(`, found `;`",
                "5:20: expected `TO`, found `s1`",
                "7:1: expected `END_TRANSITION`, found `STEP`",
            ]
        );
    }
}

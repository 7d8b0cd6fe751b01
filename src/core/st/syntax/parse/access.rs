//! `VAR_ACCESS … END_VAR` (IEC 61131-3 §6.8.2), in a CONFIGURATION, a RESOURCE or a PROGRAM:
//! each entry `name : path : TYPE [READ_ONLY | READ_WRITE];` names a variable for clients. The
//! compiler checks what the path names (`compile::access_paths`).

use super::super::lex::{Tok, P};
use super::super::{Closer, Want};
use super::{PResult, Parser};
use crate::st::ast::{AccessDecl, Expr, Ident};

impl Parser<'_> {
    /// A `VAR_ACCESS` block, at its keyword: its entries.
    pub(super) fn access_block(&mut self) -> Vec<AccessDecl> {
        let opened = self.span();
        self.bump();
        let mut entries = Vec::new();
        while self.at(&Tok::Ident) {
            match self.access_decl() {
                Ok(entry) => entries.push(entry),
                Err(_) => self.sync_decl(),
            }
        }
        self.close(Closer::Var, "VAR_ACCESS", opened);
        entries
    }

    /// `name : path : TYPE [READ_ONLY | READ_WRITE];`
    fn access_decl(&mut self) -> PResult<AccessDecl> {
        let span = self.span();
        let name = self.ident()?;
        self.expect_p(P::Colon, Want::Colon)?;
        let mut path = vec![self.access_path_part()?];
        let mut subscripts = vec![self.access_subscripts()?];
        while self.eat_p(P::Dot) {
            path.push(self.access_path_part()?);
            subscripts.push(self.access_subscripts()?);
        }
        self.expect_p(P::Colon, Want::Colon)?;
        let ty = self.type_ref()?;
        let mut read_write = false;
        if self.at_word("READ_WRITE") {
            self.bump();
            read_write = true;
        } else if self.at_word("READ_ONLY") {
            self.bump();
        }
        self.end_decl(Want::SemiAfterDecl);
        Ok(AccessDecl { name, path, subscripts, ty, read_write, span })
    }

    /// The subscripts after a part of an access path (`arr[3]`, `m[1, 2]`, `a[1][2]`): each
    /// bracket's expressions, constants the compiler evaluates.
    fn access_subscripts(&mut self) -> PResult<Vec<Vec<Expr>>> {
        let mut groups = Vec::new();
        while self.eat_p(P::LBracket) {
            let mut index = vec![self.expr()?];
            while self.eat_p(P::Comma) {
                index.push(self.expr()?);
            }
            self.expect_p(P::RBracket, Want::CommaOrRBracket)?;
            groups.push(index);
        }
        Ok(groups)
    }

    /// A part of an access path: a name, or a direct address (`%IX1.1`, kept with its `%`).
    fn access_path_part(&mut self) -> PResult<Ident> {
        if self.at(&Tok::Location) {
            let span = self.span();
            let at = self.bump();
            return Ok(Ident { name: self.text_of(at).to_string(), span });
        }
        self.ident()
    }
}

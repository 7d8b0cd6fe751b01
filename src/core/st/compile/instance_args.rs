//! The arguments of a configuration's program instance, `PROGRAM i WITH t : P (a := x, b => y);`
//! (docs/ST.md, Configurations): checked against the PROGRAM's VAR_INPUTs and VAR_OUTPUTs,
//! their values and targets in the configuration's scope (the globals and direct addresses),
//! and turned into assignments the instance's own code makes: the inputs before the body, the
//! outputs after it (`emit::compile_copies`, placed by `link`). Being ordinary statements, the
//! copies run the same on the VM and in native code, and the debugger and an online change see
//! them as any other.

use crate::device::Address;
use crate::st::ast::{self, ConfigValue, ExprKind, VarKind};

use super::ctx::{suggest, Ctx, Scope, Storage};
use super::decl::iec_address;
use super::expr::{Access, TExpr, TK};
use super::stmt::{TStmt, TS};
use super::types::{Prim, Ty};

/// One instance's arguments as statements.
#[derive(Debug, Default)]
pub struct Copies {
    /// `a := x`: `a` assigned before each run of the body.
    pub inputs: Vec<TStmt>,
    /// `b => y`: `y` assigned from `b` after each run.
    pub outputs: Vec<TStmt>,
}

impl Ctx<'_> {
    /// Checks the arguments `args` of an instance of the PROGRAM `p`, written in `file` (every
    /// error reported).
    pub fn check_instance_args(
        &mut self,
        p: usize,
        file: usize,
        args: &[ast::ProgramArg],
    ) -> Copies {
        let globals = Scope { pou: None, visible: 0, file };
        let mut copies = Copies::default();
        for arg in args {
            let (name, span, line) = (&arg.name.name, arg.name.span, arg.name.span.line);
            let pou = &self.pous[p];
            let Some(var) = pou.lookup(name).map(|i| pou.vars[i].clone()) else {
                let names = pou
                    .vars
                    .iter()
                    .filter(|v| matches!(v.kind, VarKind::Input | VarKind::Output))
                    .map(|v| v.name.as_str());
                let hint = suggest(name, names);
                let msg = format!("`{}` has no VAR_INPUT or VAR_OUTPUT `{name}`{hint}", pou.name);
                self.error(file, span, msg);
                continue;
            };
            let wanted = if arg.output { VarKind::Output } else { VarKind::Input };
            if var.kind != wanted {
                let p = &pou.name;
                let msg = if arg.output {
                    format!("`{name}` is not a VAR_OUTPUT of `{p}`: `=>` copies an output out after each run")
                } else {
                    format!("`{name}` is not a VAR_INPUT of `{p}`: `:=` gives an input its value before each run")
                };
                self.error(file, span, msg);
                continue;
            }
            if matches!(var.ty, Ty::Fb(_)) {
                self.error(file, span, "a function block instance cannot be assigned");
                continue;
            }
            let place = TExpr {
                k: TK::Var { storage: var.storage, by_ref: false },
                ty: var.ty.clone(),
                span,
            };
            let at = arg.value.span();
            if matches!(&arg.value, ConfigValue::Expr(e) if calls(e)) {
                let msg = "a program instance's argument calls no FUNCTION: it is a constant, \
                           a global variable or a direct address";
                self.error(file, at, msg);
                continue;
            }
            let given = match (&arg.value, arg.output) {
                (ConfigValue::Location(location), _) => self.direct_variable(location, file),
                (ConfigValue::Expr(e), false) => self.check_given(e, globals, &var.ty),
                (ConfigValue::Expr(e), true) => match e.kind {
                    ExprKind::Name(_)
                    | ExprKind::Member(..)
                    | ExprKind::Index(..)
                    | ExprKind::Bit(..)
                    | ExprKind::Part(..) => self.check_place(e, globals, Access::Write, None),
                    _ => {
                        let msg = "`=>` copies to a variable: a global variable or a direct \
                                   address (`%QX0.1`)";
                        self.error(file, at, msg);
                        continue;
                    }
                },
            };
            if given.ty.is_error() || var.ty.is_error() {
                continue;
            }
            if arg.output {
                if !self.output_assignable(&var.ty, &given.ty, at, file) {
                    continue;
                }
                let value = self.coerce(place, &given.ty, file);
                copies.outputs.push(TStmt { k: TS::Assign(given, value), line });
            } else {
                let value = self.coerce(given, &var.ty, file);
                if value.ty.is_error() {
                    continue;
                }
                copies.inputs.push(TStmt { k: TS::Assign(place, value), line });
            }
        }
        copies
    }

    /// A direct address as a variable (`%IX0.1` a BOOL; `%IW3`, `%MD10`, `%ML4` a WORD, DWORD,
    /// LWORD, and `%QB2` a BYTE as a located variable takes it; a plcd bit device a BOOL, a
    /// word device a WORD).
    fn direct_variable(&mut self, location: &ast::Ident, file: usize) -> TExpr {
        let span = location.span;
        let (text, bits) = match iec_address(&location.name, &self.dialect.iec) {
            Ok(Some(found)) => found,
            Ok(None) => (location.name.clone(), None),
            Err(msg) => {
                self.error(file, span, msg);
                return TExpr::error(span);
            }
        };
        let address = match Address::parse(&text) {
            Ok(address) => address,
            Err(e) => {
                self.error(file, span, e.to_string());
                return TExpr::error(span);
            }
        };
        let (storage, prim) = match (address.as_bit(), address.as_word()) {
            // a byte of a byte image (`%QB1`): its first bit, 8 bits (`device::iec::Direct`)
            (Ok(bit), _) if bits == Some(8) => {
                let byte = u32::from(bit.word) * 2 + bit.mask.trailing_zeros() / 8;
                (Storage::Byte(byte), Prim::Byte)
            }
            (Ok(bit), _) => (Storage::Bit(bit), Prim::Bool),
            (_, Ok(word)) => {
                let prim = match bits {
                    Some(8) => Prim::Byte,
                    Some(32) => Prim::DWord,
                    Some(64) => Prim::LWord,
                    _ => Prim::Word,
                };
                (Storage::Word(word.0), prim)
            }
            (Err(e), Err(_)) => {
                self.error(file, span, e.to_string());
                return TExpr::error(span);
            }
        };
        TExpr { k: TK::Var { storage, by_ref: false }, ty: Ty::Prim(prim), span }
    }
}

/// Whether `e` calls something (IEC gives a program instance constants, globals and direct
/// addresses; the checker, outside any POU, would ask a call for a constant expression).
fn calls(e: &ast::Expr) -> bool {
    match &e.kind {
        ExprKind::Call { .. } => true,
        ExprKind::Literal(_) | ExprKind::Name(_) => false,
        ExprKind::Member(a, _)
        | ExprKind::Bit(a, _)
        | ExprKind::Part(a, ..)
        | ExprKind::Deref(a)
        | ExprKind::Unary(_, a) => calls(a),
        ExprKind::Index(a, ix) => calls(a) || ix.iter().any(calls),
        ExprKind::Binary(_, a, b) | ExprKind::Assign(a, b) => calls(a) || calls(b),
    }
}

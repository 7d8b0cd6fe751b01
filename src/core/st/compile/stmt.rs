//! Statements: checked into a typed tree (assignments, calls, IF, CASE with its labels
//! resolved and checked for overlaps and coverage, FOR, WHILE, REPEAT, EXIT, CONTINUE,
//! RETURN, labels and JMP (bound by `jumps`)).

use crate::st::ast::{self, CaseLabel, ExprKind, PouKind, Stmt, StmtKind, VarKind};

use super::ctx::{Ctx, Cv, Scope};
use super::expr::{expr_text, Access, CallT, TExpr};
use super::types::{Prim, Ty};

#[derive(Debug, Clone, PartialEq)]
pub struct TStmt {
    pub k: TS,
    pub line: u32,
}

/// One CASE arm: its inclusive label ranges and its statements.
pub type Arm = (Vec<(i128, i128)>, Vec<TStmt>);

#[derive(Debug, Clone, PartialEq)]
#[allow(clippy::large_enum_variant)]
pub enum TS {
    Assign(TExpr, TExpr),
    /// A FUNCTION call whose result is dropped.
    Eval(TExpr),
    /// A FUNCTION_BLOCK instance called.
    FbCall(TExpr, CallT),
    If(Vec<(TExpr, Vec<TStmt>)>, Vec<TStmt>),
    Case {
        sel: TExpr,
        /// Inclusive ranges of each arm.
        arms: Vec<Arm>,
        otherwise: Vec<TStmt>,
    },
    For {
        var: TExpr,
        from: TExpr,
        to: TExpr,
        by: TExpr,
        body: Vec<TStmt>,
        /// Whether the body writes the variable (CODESYS's habit, `for_written`).
        written: bool,
    },
    While(TExpr, Vec<TStmt>),
    Repeat(Vec<TStmt>, TExpr),
    Exit,
    Continue,
    Return,
    /// A label (its number, `jumps`): where jumps to it go on.
    Label(u32),
    /// `JMP`: the label's number, and whether the label is before it (a loop).
    Jump(u32, bool),
}

impl<'a> Ctx<'a> {
    pub fn check_body(&mut self, body: &[Stmt], scope: Scope) -> Vec<TStmt> {
        body.iter().filter_map(|s| self.check_stmt(s, scope)).collect()
    }

    fn cond(&mut self, e: &ast::Expr, scope: Scope, what: &str) -> TExpr {
        let t = self.check_expr(e, scope, Some(&Ty::Prim(Prim::Bool)));
        if t.ty.is_error() || t.ty.is_bool() {
            return t;
        }
        let n = self.ty_name(&t.ty);
        self.error(
            scope.file,
            e.span,
            format!("the condition of {what} must be `BOOL`, not `{n}`"),
        );
        TExpr::error(e.span)
    }

    fn check_stmt(&mut self, s: &Stmt, scope: Scope) -> Option<TStmt> {
        let file = scope.file;
        let line = s.span.line;
        let k = match &s.kind {
            StmtKind::Empty => return None,
            StmtKind::Assign { target, value } => {
                if let Some(setter) = self.property_write(target, value, scope) {
                    return setter.map(|k| TStmt { k, line });
                }
                if let Some(binding) = self.in_out_binding(target, value, scope) {
                    return binding.map(|k| TStmt { k, line });
                }
                let t = self.check_place(target, scope, Access::Write, None);
                let v = self.check_given(value, scope, &t.ty);
                if t.ty.is_error() || v.ty.is_error() {
                    return None;
                }
                if matches!(t.ty, Ty::Fb(_)) {
                    // a copy of the whole instance (compile/fb_value.rs)
                    return self
                        .instance_assignment(t, v, file, s.span)
                        .map(|(t, v)| TStmt { k: TS::Assign(t, v), line });
                }
                if v.ty == Ty::Void {
                    self.error(file, value.span, format!("`{}` has no result", expr_text(value)));
                    return None;
                }
                let v = self.coerce(v, &t.ty, file);
                if v.ty.is_error() {
                    return None;
                }
                TS::Assign(t, v)
            }
            StmtKind::RefAssign { target, value } => {
                let (t, v) = self.ref_assign(target, value, scope)?;
                TS::Assign(t, v)
            }
            StmtKind::Call(e) => {
                let ExprKind::Call { callee, args } = &e.kind else {
                    self.error(file, e.span, "this expression does nothing: a statement is needed");
                    return None;
                };
                if let Some(k) = self.oop_statement(callee, args, e.span, scope) {
                    k?
                } else if let Some(call) = self.action_call(callee, args, e.span, scope) {
                    let (inst, call) = call?;
                    TS::FbCall(inst, call)
                } else if self.is_instance(callee, scope) {
                    let (inst, call) = self.fb_call(callee, args, e.span, scope)?;
                    TS::FbCall(inst, call)
                } else {
                    let t = self.check_expr(e, scope, None);
                    if t.ty.is_error() {
                        return None;
                    }
                    TS::Eval(t)
                }
            }
            StmtKind::If { branches, otherwise } => {
                let mut out = Vec::new();
                for (c, body) in branches {
                    let c = self.cond(c, scope, "IF");
                    let body = self.check_body(body, scope);
                    out.push((c, body));
                }
                let other =
                    otherwise.as_ref().map(|(_, b)| self.check_body(b, scope)).unwrap_or_default();
                TS::If(out, other)
            }
            StmtKind::While { cond, body } => {
                let c = self.cond(cond, scope, "WHILE");
                self.loop_depth += 1;
                let body = self.check_body(body, scope);
                self.loop_depth -= 1;
                TS::While(c, body)
            }
            StmtKind::Repeat { body, until } => {
                self.loop_depth += 1;
                let body = self.check_body(body, scope);
                self.loop_depth -= 1;
                let c = self.cond(until, scope, "REPEAT … UNTIL");
                TS::Repeat(body, c)
            }
            StmtKind::Exit | StmtKind::Continue => {
                if self.loop_depth == 0 {
                    let w = if matches!(s.kind, StmtKind::Exit) { "EXIT" } else { "CONTINUE" };
                    self.error(file, s.span, format!("`{w}` outside a loop"));
                    return None;
                }
                if matches!(s.kind, StmtKind::Exit) {
                    TS::Exit
                } else {
                    TS::Continue
                }
            }
            StmtKind::Return => TS::Return,
            StmtKind::Label(_) => TS::Label(self.jumps.label(file, s.span)?),
            StmtKind::Jump(_) => {
                let (label, backward) = self.jumps.jump(file, s.span)?;
                TS::Jump(label, backward)
            }
            StmtKind::For { var, from, to, by, body } => {
                return self.check_for(s, var, from, to, by.as_ref(), body, scope)
            }
            StmtKind::Case { selector, arms, otherwise } => {
                return self.check_case(s, selector, arms, otherwise.as_ref(), scope);
            }
        };
        Some(TStmt { k, line })
    }

    fn is_instance(&mut self, callee: &ast::Expr, scope: Scope) -> bool {
        if let ExprKind::Name(id) = &callee.kind {
            let local = scope.pou.and_then(|p| {
                self.pous[p].lookup(&id.name).map(|i| self.pous[p].vars[i].ty.clone())
            });
            let global = self
                .global_names
                .get(&id.name.to_ascii_lowercase())
                .map(|&g| self.globals[g].ty.clone());
            return matches!(local.or(global), Some(Ty::Fb(_)));
        }
        // a member or an element: an FB instance inside a struct, an array of instances
        let saved = self.diags.len();
        let t = self.check_place(callee, scope, Access::Read, None);
        self.diags.truncate(saved);
        matches!(t.ty, Ty::Fb(_))
    }

    #[allow(clippy::too_many_arguments)]
    fn check_for(
        &mut self,
        s: &Stmt,
        var: &ast::Expr,
        from: &ast::Expr,
        to: &ast::Expr,
        by: Option<&ast::Expr>,
        body: &[Stmt],
        scope: Scope,
    ) -> Option<TStmt> {
        let file = scope.file;
        let named = matches!(var.kind, ExprKind::Name(_));
        let v = self.check_place(var, scope, Access::Write, None);
        let mut ok = !v.ty.is_error();
        let p = v.ty.prim(&self.types);
        if ok && (!p.is_some_and(Prim::is_int) || matches!(v.ty, Ty::Enum(_))) {
            let n = self.ty_name(&v.ty);
            self.error(
                file,
                var.span,
                format!("the FOR variable `{}` must be an integer, not `{n}`", expr_text(var)),
            );
            ok = false;
        }
        if ok {
            let root = super::for_element::control_root(var);
            let local = root.and_then(|id| {
                scope.pou.and_then(|pi| {
                    self.pous[pi].lookup(&id.name).map(|i| self.pous[pi].vars[i].kind)
                })
            });
            // a FUNCTION's result is one of its variables too (OSCAT's FSTRING_TO_MONTH)
            let result = root.is_some_and(|id| {
                scope.pou.is_some_and(|pi| {
                    self.pous[pi].kind == PouKind::Function && id.is(&self.pous[pi].name)
                })
            });
            if !result && (matches!(local, Some(VarKind::InOut)) || local.is_none()) {
                self.error(
                    file,
                    var.span,
                    format!(
                        "the FOR variable `{}` must be a local variable of the POU",
                        expr_text(var)
                    ),
                );
                ok = false;
            }
        }
        if ok && !named {
            ok = self.for_element_fixed(var, &v, file);
        }
        let ty = match &v.ty {
            Ty::Sub(p, _, _) => Ty::Prim(*p),
            t => t.clone(),
        };
        let f = self.check_expr(from, scope, Some(&ty));
        let f = self.coerce(f, &ty, file);
        let t = self.check_expr(to, scope, Some(&ty));
        let t = self.coerce(t, &ty, file);
        let b = match by {
            Some(b) => {
                let e = self.check_expr(b, scope, Some(&ty));
                let e = self.coerce(e, &ty, file);
                if e.const_int() == Some(0) && !e.ty.is_error() {
                    self.error(file, b.span, "a FOR step of 0 never ends the loop");
                    ok = false;
                }
                e
            }
            None => TExpr::konst(Cv::Int(1), ty.clone(), var.span),
        };
        // An element or member may be written through another name of it (`a[k]`, a
        // reference): its loop always tests the bound after the body, which costs nothing
        // when the body leaves it alone (`for_element`).
        let name = match &var.kind {
            ExprKind::Name(id) => id.name.clone(),
            _ => String::new(),
        };
        self.for_vars.push(name);
        self.for_written.push(!named);
        self.loop_depth += 1;
        let body = self.check_body(body, scope);
        self.loop_depth -= 1;
        self.for_vars.pop();
        let written = self.for_written.pop().unwrap_or(false);
        if !ok || f.ty.is_error() || t.ty.is_error() || b.ty.is_error() {
            return None;
        }
        let v = TExpr { ty, ..v };
        Some(TStmt {
            k: TS::For { var: v, from: f, to: t, by: b, body, written },
            line: s.span.line,
        })
    }

    fn check_case(
        &mut self,
        s: &Stmt,
        selector: &ast::Expr,
        arms: &[ast::CaseArm],
        otherwise: Option<&(ast::Span, Vec<Stmt>)>,
        scope: Scope,
    ) -> Option<TStmt> {
        let file = scope.file;
        let sel = self.check_expr(selector, scope, None);
        let sel_ok = match sel.ty.prim(&self.types) {
            _ if sel.ty.is_error() => false,
            Some(p) if p.is_integral() || matches!(sel.ty, Ty::Enum(_)) => true,
            // a character, its labels one-character literals (`'a':`, `'0'..'9':`)
            Some(Prim::Char | Prim::WChar) => true,
            _ if sel.ty == Ty::IntLit => true,
            _ => {
                let n = self.ty_name(&sel.ty);
                self.error(
                    file,
                    selector.span,
                    format!("a CASE selector must be an integer or an enumeration, not `{n}`"),
                );
                false
            }
        };
        let sel_ty = match &sel.ty {
            Ty::IntLit => Ty::Prim(Prim::DInt),
            Ty::Sub(p, _, _) => Ty::Prim(*p),
            t => t.clone(),
        };
        let sel = if sel.ty == Ty::IntLit { self.coerce(sel, &sel_ty, file) } else { sel };
        let mut seen: Vec<(i128, i128, ast::Span)> = Vec::new();
        let mut out_arms = Vec::new();
        for arm in arms {
            let mut ranges = Vec::new();
            for label in &arm.labels {
                let (lo_e, hi_e) = match label {
                    CaseLabel::Value(e) => (e, None),
                    CaseLabel::Range(a, b) => (a, Some(b)),
                };
                let lo = self.case_label(lo_e, &sel_ty, sel_ok, scope);
                let hi = match hi_e {
                    Some(h) => self.case_label(h, &sel_ty, sel_ok, scope),
                    None => lo,
                };
                let (Some(lo), Some(hi)) = (lo, hi) else { continue };
                if lo > hi {
                    self.error(file, lo_e.span, format!("the CASE range `{lo}..{hi}` is empty"));
                    continue;
                }
                if let Some((a, b, sp)) = seen.iter().find(|(a, b, _)| lo <= *b && *a <= hi) {
                    let what = |a: i128, b: i128| {
                        if a == b {
                            format!("{a}")
                        } else {
                            format!("{a}..{b}")
                        }
                    };
                    if lo == hi && a == b {
                        self.error(
                            file,
                            lo_e.span,
                            format!("duplicate CASE label `{lo}` (also at line {})", sp.line),
                        );
                    } else {
                        self.error(
                            file,
                            lo_e.span,
                            format!(
                                "CASE labels `{}` and `{}` overlap (line {})",
                                what(lo, hi),
                                what(*a, *b),
                                sp.line
                            ),
                        );
                    }
                    continue;
                }
                seen.push((lo, hi, lo_e.span));
                ranges.push((lo, hi));
            }
            let body = self.check_body(&arm.body, scope);
            out_arms.push((ranges, body));
        }
        let mut other = Vec::new();
        if let Some((sp, body)) = otherwise {
            if sel_ok {
                let all: Option<Vec<i128>> = match &sel_ty {
                    Ty::Enum(e) => Some(self.types.enums[*e].values.iter().map(|v| v.1).collect()),
                    Ty::Prim(Prim::Bool) => Some(vec![0, 1]),
                    _ => None,
                };
                if let Some(all) = all {
                    // CODESYS accepts it: an enumeration variable may hold a number no value has
                    if all.iter().all(|v| seen.iter().any(|(a, b, _)| a <= v && v <= b)) {
                        self.habit(crate::st::dialect::Habit::CoveredCaseElse, file, *sp);
                    }
                }
            }
            other = self.check_body(body, scope);
        }
        if !sel_ok {
            return None;
        }
        Some(TStmt { k: TS::Case { sel, arms: out_arms, otherwise: other }, line: s.span.line })
    }

    fn case_label(&mut self, e: &ast::Expr, sel: &Ty, sel_ok: bool, scope: Scope) -> Option<i128> {
        let t = self.check_expr(e, scope, Some(sel));
        if t.ty.is_error() || !sel_ok {
            return None;
        }
        if !t.is_const() {
            self.error(scope.file, e.span, "a CASE label must be a constant");
            return None;
        }
        // An enumeration's value as the label of an integer selector (CODESYS: TcUnit's
        // `CASE UDINT_TO_INT(AnyTypeClass) OF TypeClass.TYPE_BOOL: …`): its number.
        if let Some(number) = self.enum_as_integer(t.clone(), sel, scope.file) {
            return number.const_int();
        }
        let ok = match (&t.ty, sel) {
            (Ty::IntLit, _) => !matches!(sel, Ty::Prim(Prim::Char | Prim::WChar)),
            (Ty::Str(_), Ty::Prim(Prim::Char)) | (Ty::WStr(_), Ty::Prim(Prim::WChar)) => true,
            (a, b) if a == b => true,
            (Ty::Enum(_), _) | (_, Ty::Enum(_)) => false,
            (a, b) => {
                a.prim(&self.types).zip(b.prim(&self.types)).is_some_and(|(x, y)| x.widens_to(y))
            }
        };
        if !ok {
            let (a, b) = (self.ty_name(&t.ty), self.ty_name(sel));
            self.error(
                scope.file,
                e.span,
                format!("a CASE label of type `{a}` does not match the selector's type `{b}`"),
            );
            return None;
        }
        let t = self.coerce(t, sel, scope.file);
        t.const_int()
    }

    /// Checks a POU's body.
    pub fn check_pou_body(&mut self, p: usize) -> Vec<TStmt> {
        let statements = self.pous[p].statements();
        let file = self.pous[p].file;
        let scope = Scope { pou: Some(p), visible: self.pous[p].vars.len(), file };
        self.in_prelude = self.is_shipped(file);
        self.loop_depth = 0;
        self.for_vars.clear();
        self.for_written.clear();
        self.resolve_jumps(statements, file);
        // A FUNCTION's result never assigned on some path keeps its type's initial value.
        self.check_body(statements, scope)
    }
}

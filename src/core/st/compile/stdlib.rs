//! The standard functions of IEC 61131-3, checked and lowered to the typed ops: numeric
//! (ABS SQRT LN LOG EXP EXPT SIN COS TAN ASIN ACOS ATAN, ADD SUB MUL DIV MOD, MIN MAX LIMIT,
//! SEL MUX, MOVE, TRUNC), comparisons (GT GE EQ LE LT NE), bit strings (SHL SHR ROL ROR, AND
//! OR XOR NOT), every `<T1>_TO_<T2>` between elementary types and the overloaded `TO_<T>`,
//! `TRUNC_<T>`, and strings (LEN LEFT RIGHT MID CONCAT FIND INSERT DELETE REPLACE, on STRING
//! and on WSTRING, and the conversions between the two and their characters CHAR and WCHAR);
//! each with `EN` and `ENO`. CODESYS's `SIZEOF` and `TIME()` are here too (`super::codesys`); the BCD
//! conversions are FUNCTIONs of the prelude.
//!
//! Conversions of TIME follow CODESYS: `TIME_TO_DINT(T#1s)` is 1000 (milliseconds, truncated
//! toward zero), `DINT_TO_TIME(1000)` is `T#1s`; `TIME_TO_REAL` gives milliseconds with their
//! fraction. Conversions between numbers and STRING are not supported (an error says so).
//! `MUX` with a selector beyond its inputs gives the last input.

use crate::lang::ops::CmpOp;
use crate::st::ast::{Arg, BinaryOp, Expr, ExprKind, Ident, Span, TypeRef};
use crate::value::{BinOp, UnOp};

use super::ctx::{suggest, Ctx, Cv, Scope};
use super::expr::{Access, GateT, TExpr, TK};
use super::types::{Prim, Ty};
use crate::st::dialect::Habit;

/// A standard function that is more than one op.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Std {
    /// `SEL(G, IN0, IN1)`: args `[G, IN0, IN1]`.
    Sel,
    /// `MUX(K, IN0, …)`.
    Mux,
    /// `__NOW()`: the clock, a TIME.
    Now,
    /// `__UTC()`: the calendar time, an LDT (the real-time clock).
    Utc,
    /// plcd's system functions, the instruction list's system instructions: `INIT_DONE()`
    /// (the init task is finished) and `WDT()` (restart the scan watchdog). TRUE.
    System(crate::lang::ops::SystemRequest),
    /// `LEN(s)`, an INT.
    Len,
    /// `LEFT(IN, L)`, `RIGHT(IN, L)`, `MID(IN, L, P)`, `CONCAT(a, b)`: a STRING (the node's
    /// type gives the capacity); the counts are LINT.
    Left,
    Right,
    Mid,
    Concat,
    /// `FIND(IN1, IN2)`, an INT.
    Find,
    /// `GT(a, b, c, …)` and the others of three inputs or more: a BOOL, TRUE when the
    /// comparison holds for each input and the next (each evaluated once).
    Chain(CmpOp),
    /// `<T>_TO_STRING(v)`: the text of a scalar (the node's type gives the capacity).
    ToString(crate::value::Scalar),
    /// `STRING_TO_<T>(s)`: the value a text gives a scalar, 0 for one it does not.
    FromString(crate::value::Scalar),
    /// `STRING_TO_WSTRING(s)`: each Windows-1252 character as its UTF-16 code unit.
    Widen,
    /// `WSTRING_TO_STRING(w)`: each code unit as its Windows-1252 byte, `?` for one it has not.
    Narrow,
    /// `CHAR_TO_STRING(c)`, `WCHAR_TO_WSTRING(c)`: the string of the one character (the node's
    /// type says which).
    CharToString,
    /// `STRING_TO_CHAR(s)`, `WSTRING_TO_WCHAR(s)`: the first character, 0 for an empty string.
    StringToChar,
    /// `__QUERYINTERFACE(src, dest)`: args `[src, dest]`, dest of interface `.0` (compile/query.rs).
    QueryInterface(usize),
    /// `__QUERYPOINTER(src, dest)`: args `[src, dest]`, dest a pointer (compile/query.rs).
    QueryPointer,
}

/// The string type a conversion's name gives (`STRING`, `WSTRING`), of the default length.
fn string_type(name: &str) -> Option<Ty> {
    match name {
        "STRING" => Some(Ty::Str(80)),
        "WSTRING" => Some(Ty::WStr(80)),
        _ => None,
    }
}

/// `s` (a STRING or WSTRING of one character or more) converted to a one-character string of
/// the other kind, as `STRING_TO_WSTRING` (`to_wide`) or `WSTRING_TO_STRING` convert: the
/// character conversions across the kinds are these after or before the one-character ones.
fn widened(s: TExpr, to_wide: bool, span: Span) -> TExpr {
    let (op, ty) = if to_wide { (Std::Widen, Ty::WStr(1)) } else { (Std::Narrow, Ty::Str(1)) };
    TExpr { k: TK::Std(op, vec![s]), ty, span }
}

/// The name of a string type's kind, for messages.
fn kind_name(ty: &Ty) -> &'static str {
    if ty.is_wide() {
        "a WSTRING"
    } else {
        "a STRING"
    }
}

const NAMES: &[&str] = &[
    "ABS",
    "SQRT",
    "LN",
    "LOG",
    "EXP",
    "EXPT",
    "SIN",
    "COS",
    "TAN",
    "ASIN",
    "ACOS",
    "ATAN",
    "ADD",
    "SUB",
    "MUL",
    "DIV",
    "MOD",
    "MIN",
    "MAX",
    "LIMIT",
    "SEL",
    "MUX",
    "SHL",
    "SHR",
    "ROL",
    "ROR",
    "AND",
    "OR",
    "XOR",
    "NOT",
    "MOVE",
    "TRUNC",
    "LEN",
    "LEFT",
    "RIGHT",
    "MID",
    "CONCAT",
    "FIND",
    "INSERT",
    "DELETE",
    "REPLACE",
    "GT",
    "GE",
    "EQ",
    "LE",
    "LT",
    "NE",
    "SIZEOF",
    "LOWER_BOUND",
    "UPPER_BOUND",
];

/// Whether `name` is a standard function's (`SEL`, `INT_TO_REAL`…): reserved, so that no
/// declaration can replace it for the callers that mean the standard one.
pub fn is_standard_function(name: &str) -> bool {
    let upper = name.to_ascii_uppercase();
    if NAMES.contains(&upper.as_str()) {
        return true;
    }
    let elementary = |t: &str| Prim::from_name(t).is_some() || string_type(t).is_some();
    upper.split_once("_TO_").is_some_and(|(from, to)| elementary(from) && elementary(to))
}

/// The formal parameter names of a standard function with `n` arguments.
fn formals(name: &str, n: usize) -> Vec<String> {
    let fixed: &[&str] = match name {
        "LIMIT" => &["MN", "IN", "MX"],
        "SEL" => &["G", "IN0", "IN1"],
        "SHL" | "SHR" | "ROL" | "ROR" => &["IN", "N"],
        "LEFT" | "RIGHT" => &["IN", "L"],
        "MID" => &["IN", "L", "P"],
        "INSERT" => &["IN1", "IN2", "P"],
        "DELETE" => &["IN", "L", "P"],
        "REPLACE" => &["IN1", "IN2", "L", "P"],
        "MUX" => {
            let mut v = vec!["K".to_string()];
            v.extend((0..n.saturating_sub(1)).map(|i| format!("IN{i}")));
            return v;
        }
        "EXPT" | "SUB" | "DIV" | "MOD" | "FIND" | "NE" => &["IN1", "IN2"],
        _ if super::calendar::function(name).is_some() => &["IN1", "IN2"],
        "ADD" | "MUL" | "MIN" | "MAX" | "AND" | "OR" | "XOR" | "CONCAT" | "GT" | "GE" | "EQ"
        | "LE" | "LT" => {
            return (1..=n).map(|i| format!("IN{i}")).collect();
        }
        _ => &["IN"],
    };
    fixed.iter().map(|s| s.to_string()).collect()
}

impl<'a> Ctx<'a> {
    /// The one argument of a conversion (`IN`, positional or named); `None` after an error.
    fn conversion_arg<'e>(
        &mut self,
        name: &str,
        args: &'e [Arg],
        span: Span,
        file: usize,
    ) -> Option<&'e Expr> {
        let a = self.std_args("CONV", args, span, file)?;
        self.arity(name, a.len(), 1, 1, span, file).then(|| a[0])
    }

    fn std_args<'e>(
        &mut self,
        name: &str,
        args: &'e [Arg],
        span: Span,
        file: usize,
    ) -> Option<Vec<&'e Expr>> {
        if !self.argument_order(name, args, span, file) {
            return None;
        }
        let names = formals(name, args.len());
        let mut out: Vec<Option<&Expr>> = vec![None; names.len().max(args.len())];
        for (i, a) in args.iter().enumerate() {
            match a {
                Arg::Positional(e) => out[i] = Some(e),
                Arg::Input { name: pn, value } => {
                    // CODESYS's name of the input (`LEN(STR := s)`)
                    let codesys = super::codesys::string_parameters(name)
                        .iter()
                        .find(|(c, _)| pn.is(c) && !names.iter().any(|n| pn.is(n)));
                    if let Some(&(c, iec)) = codesys {
                        self.habit(Habit::CodesysParameter(c, iec), file, pn.span);
                    }
                    let formal = codesys.map_or(pn.name.as_str(), |(_, iec)| iec);
                    match names.iter().position(|n| n.eq_ignore_ascii_case(formal)) {
                        Some(k) if out[k].is_some() => {
                            self.error(file, pn.span, format!("`{}` is given twice", pn.name));
                            return None;
                        }
                        Some(k) => out[k] = Some(value),
                        None => {
                            let hint = suggest(&pn.name, names.iter().map(String::as_str));
                            self.error(
                                file,
                                pn.span,
                                format!("`{name}` has no parameter `{}`{hint}", pn.name),
                            );
                            return None;
                        }
                    }
                }
                Arg::Output { name: pn, .. } => {
                    self.error(file, pn.span, format!("`{name}` has no output `{}`", pn.name));
                    return None;
                }
            }
        }

        let given: Vec<&Expr> =
            out.iter().take_while(|e| e.is_some()).map(|e| e.expect("some")).collect();
        if given.len() != out.iter().filter(|e| e.is_some()).count() {
            self.error(file, span, format!("the call of `{name}` leaves out an argument"));
            return None;
        }
        Some(given)
    }

    fn arity(
        &mut self,
        name: &str,
        n: usize,
        min: usize,
        max: usize,
        span: Span,
        file: usize,
    ) -> bool {
        if n < min || n > max {
            let want = if min == max {
                format!("{min}")
            } else if max == usize::MAX {
                format!("at least {min}")
            } else {
                format!("{min} to {max}")
            };
            self.error(file, span, format!("`{name}` takes {want} argument(s), {n} given"));
            return false;
        }
        true
    }

    /// A value of an elementary type from an argument (literals given `lit` when untyped).
    fn scalar_arg(&mut self, e: &Expr, scope: Scope, expected: Option<&Ty>, lit: Prim) -> TExpr {
        let t = self.check_expr(e, scope, expected);
        match t.ty {
            Ty::IntLit | Ty::RealLit => {
                let to = match expected.and_then(|x| x.prim(&self.types)) {
                    Some(p)
                        if !matches!(expected, Some(Ty::Enum(_))) && literal_target(p, &t.ty) =>
                    {
                        p
                    }
                    _ if t.ty == Ty::RealLit && !lit.is_real() => Prim::LReal,
                    _ => lit,
                };
                self.coerce(t, &Ty::Prim(to), scope.file)
            }
            Ty::Sub(p, _, _) => TExpr { ty: Ty::Prim(p), ..t },
            _ => t,
        }
    }

    fn want(&mut self, t: &TExpr, ok: bool, fname: &str, what: &str, file: usize) -> bool {
        if t.ty.is_error() {
            return false;
        }
        if !ok {
            let n = self.ty_name(&t.ty);
            self.error(file, t.span, format!("`{fname}` needs {what}, not `{n}`"));
        }
        ok
    }

    /// A call of a standard function (or an unknown name), with `EN` and `ENO` as the standard
    /// gives every function (IEC 61131-3 ed3): `EN := c` runs it only when `c` is
    /// TRUE (its value is then its type's default), `ENO => v` gives `v` whether it ran (a
    /// standard function's errors are operation errors, not ENO).
    pub fn std_call(
        &mut self,
        id: &Ident,
        args: &[Arg],
        span: Span,
        scope: Scope,
        expected: Option<&Ty>,
    ) -> TExpr {
        let file = scope.file;
        let enable = |a: &Arg| match a {
            Arg::Input { name, .. } => name.is("EN"),
            Arg::Output { name, .. } => name.is("ENO"),
            Arg::Positional(_) => false,
        };
        if !args.iter().any(enable) {
            return self.std_call_plain(id, args, span, scope, expected);
        }
        if args.iter().any(|a| matches!(a, Arg::Positional(_))) {
            self.error(
                file,
                span,
                format!("the call of `{}` mixes positional and named arguments", id.name),
            );
            return TExpr::error(span);
        }
        let bool_ty = Ty::Prim(Prim::Bool);
        let mut en: Option<TExpr> = None;
        let mut eno = Vec::new();
        let mut rest = Vec::new();
        let mut ok = true;
        for a in args {
            match a {
                Arg::Input { name, value } if name.is("EN") => {
                    if en.is_some() {
                        self.error(file, value.span, format!("`{}` is given twice", name.name));
                        ok = false;
                        continue;
                    }
                    let t = self.check_expr(value, scope, Some(&bool_ty));
                    let t = self.coerce(t, &bool_ty, file);
                    ok &= !t.ty.is_error();
                    en = Some(t);
                }
                Arg::Output { name, target, negated } if name.is("ENO") => {
                    let t = self.check_place(target, scope, Access::Write, None);
                    if t.ty.is_error() {
                        ok = false;
                        continue;
                    }
                    if !self.output_assignable(&bool_ty, &t.ty, target.span, file) {
                        ok = false;
                        continue;
                    }
                    eno.push((t, *negated));
                }
                other => rest.push(other.clone()),
            }
        }
        let value = self.std_call_plain(id, &rest, span, scope, expected);
        if value.ty.is_error() || !ok {
            return TExpr::error(span);
        }
        // a constant of no type yet: the type its context wants, as an argument would take
        let value = match value.ty {
            Ty::IntLit | Ty::RealLit => {
                let to = match expected.and_then(|e| e.prim(&self.types)) {
                    Some(p) if p.is_num() && !matches!(expected, Some(Ty::Enum(_))) => p,
                    _ if value.ty == Ty::RealLit => Prim::LReal,
                    _ => Prim::DInt,
                };
                self.coerce(value, &Ty::Prim(to), file)
            }
            _ => value,
        };
        let ty = value.ty.clone();
        TExpr { k: TK::Gate(Box::new(GateT { en, value, eno })), ty, span }
    }

    /// A standard function's call, without `EN` and `ENO`.
    fn std_call_plain(
        &mut self,
        id: &Ident,
        args: &[Arg],
        span: Span,
        scope: Scope,
        expected: Option<&Ty>,
    ) -> TExpr {
        let file = scope.file;
        let upper = id.name.to_ascii_uppercase();
        if upper == "__NOW" && self.in_prelude {
            if !args.is_empty() {
                self.error(file, span, "`__NOW` takes no arguments");
            }
            return TExpr { k: TK::Std(Std::Now, vec![]), ty: Ty::Prim(Prim::Time), span };
        }
        if upper == "__UTC" && self.in_prelude {
            let ty = Ty::Prim(Prim::Cal(crate::value::Calendar::LDt));
            return TExpr { k: TK::Std(Std::Utc, vec![]), ty, span };
        }
        // CODESYS: `TIME()`, the clock the timers read, as a TIME.
        if upper == "TIME" && self.habit(Habit::TimeClock, file, span) {
            if !args.is_empty() {
                self.error(file, span, format!("`{upper}` takes no arguments"));
                return TExpr::error(span);
            }
            return TExpr { k: TK::Std(Std::Now, vec![]), ty: Ty::Prim(Prim::Time), span };
        }
        use crate::lang::ops::SystemRequest;
        let system = match upper.as_str() {
            "INIT_DONE" => Some(SystemRequest::InitDone),
            "WDT" => Some(SystemRequest::ResetWatchdog),
            "STOP" => Some(SystemRequest::Stop),
            "IORF" => Some(SystemRequest::RefreshIo),
            "DI" | "EI" => {
                // `DI()` all tasks, `DI(n)` the task numbered n (a constant; the project checks
                // that a task has it).
                let task = match args {
                    [] => None,
                    [Arg::Positional(e)] => {
                        let Some(n) = self.const_int(e, scope) else {
                            return TExpr::error(span);
                        };
                        let numbers = crate::config::TASK_NUMBERS;
                        if !i64::try_from(n).is_ok_and(|n| numbers.contains(&n)) {
                            let (lo, hi) = (numbers.start(), numbers.end());
                            let msg =
                                format!("`{upper}` takes a task number from {lo} to {hi}, not {n}");
                            self.error(file, e.span, msg);
                            return TExpr::error(span);
                        }
                        Some(n as u8)
                    }
                    _ => {
                        self.error(
                            file,
                            span,
                            format!("`{upper}` takes one task number or nothing"),
                        );
                        return TExpr::error(span);
                    }
                };
                Some(if upper == "DI" {
                    SystemRequest::DisableTasks(task)
                } else {
                    SystemRequest::EnableTasks(task)
                })
            }
            _ => None,
        };
        if let Some(request) = system {
            if !args.is_empty() && !matches!(upper.as_str(), "DI" | "EI") {
                self.error(file, span, format!("`{upper}` takes no arguments"));
            }
            return TExpr {
                k: TK::Std(Std::System(request), vec![]),
                ty: Ty::Prim(Prim::Bool),
                span,
            };
        }
        if let Some((pa, pb)) = super::calendar::function(&upper) {
            let Some(a) = self.std_args(&upper, args, span, file) else {
                return TExpr::error(span);
            };
            if !self.arity(&upper, a.len(), 2, 2, span, file) {
                return TExpr::error(span);
            }
            let x = self.check_expr(a[0], scope, Some(&Ty::Prim(pa)));
            let x = self.coerce(x, &Ty::Prim(pa), file);
            let y = self.check_expr(a[1], scope, Some(&Ty::Prim(pb)));
            let y = self.coerce(y, &Ty::Prim(pb), file);
            return self.calendar_function(&upper, x, y, span, file);
        }
        // `TO_<T>(x)`: the conversion of x's type to T; `TRUNC_<T>(r)`, `<R>_TRUNC_<T>(r)`.
        if let Some(to) = upper.strip_prefix("TO_") {
            let dst = Prim::from_name(to).map(Ty::Prim).or(string_type(to));
            if let Some(dst) = dst {
                return self.overloaded_conversion(&upper, dst, args, span, scope);
            }
        }
        if let Some((from, to)) = upper.split_once("TRUNC_") {
            let src = match from {
                "" => Some(None),
                "REAL_" => Some(Some(Prim::Real)),
                "LREAL_" => Some(Some(Prim::LReal)),
                _ => None,
            };
            if let (Some(src), Some(dst)) = (src, Prim::from_name(to).filter(|p| p.is_int())) {
                return self.trunc_to(&upper, src, dst, args, span, scope);
            }
        }
        if let Some((from, to)) = upper.split_once("_TO_") {
            let src = Prim::from_name(from).map(Ty::Prim).or(string_type(from));
            let dst = Prim::from_name(to).map(Ty::Prim).or(string_type(to));
            if let (Some(src), Some(dst)) = (src, dst) {
                return self.convert_call(&upper, src, dst, args, span, scope);
            }
        }
        if !NAMES.contains(&upper.as_str()) {
            let mut names: Vec<String> = self
                .pous
                .iter()
                .filter(|p| p.kind == crate::st::ast::PouKind::Function)
                .map(|p| p.name.clone())
                .collect();
            names.extend(NAMES.iter().map(|s| s.to_string()));
            names.extend(self.names_in(scope));
            let hint = suggest(&id.name, names.iter().map(String::as_str));
            self.error(file, id.span, format!("`{}` is not declared{hint}", id.name));
            return TExpr::error(span);
        }
        let Some(a) = self.std_args(&upper, args, span, file) else {
            return TExpr::error(span);
        };
        let n = a.len();
        let name = upper.as_str();
        match name {
            "ABS" => {
                if !self.arity(name, n, 1, 1, span, file) {
                    return TExpr::error(span);
                }
                let t = self.scalar_arg(a[0], scope, expected, Prim::DInt);
                let p = t.ty.prim(&self.types);
                if !self.want(
                    &t,
                    p.is_some_and(Prim::is_num) && !matches!(t.ty, Ty::Enum(_)),
                    name,
                    "a number",
                    file,
                ) {
                    return TExpr::error(span);
                }
                self.un(UnOp::Abs, t, span)
            }
            "SQRT" | "LN" | "LOG" | "EXP" | "SIN" | "COS" | "TAN" | "ASIN" | "ACOS" | "ATAN" => {
                if !self.arity(name, n, 1, 1, span, file) {
                    return TExpr::error(span);
                }
                let t = self.scalar_arg(a[0], scope, expected, Prim::LReal);
                let p = t.ty.prim(&self.types);
                if !self.want(&t, p.is_some_and(Prim::is_real), name, "a `REAL` or `LREAL`", file) {
                    return TExpr::error(span);
                }
                let op = match name {
                    "SQRT" => UnOp::Sqrt,
                    "LN" => UnOp::Ln,
                    "LOG" => UnOp::Log,
                    "EXP" => UnOp::Exp,
                    "SIN" => UnOp::Sin,
                    "COS" => UnOp::Cos,
                    "TAN" => UnOp::Tan,
                    "ASIN" => UnOp::Asin,
                    "ACOS" => UnOp::Acos,
                    _ => UnOp::Atan,
                };
                self.un(op, t, span)
            }
            "TRUNC" => {
                if !self.arity(name, n, 1, 1, span, file) {
                    return TExpr::error(span);
                }
                let t = self.scalar_arg(a[0], scope, None, Prim::LReal);
                let p = t.ty.prim(&self.types);
                if !self.want(&t, p.is_some_and(Prim::is_real), name, "a `REAL` or `LREAL`", file) {
                    return TExpr::error(span);
                }
                let t = self.un(UnOp::Trunc, t, span);
                let t = self.conv(t, Prim::DInt, Ty::Prim(Prim::DInt));
                // a DINT, or the integer type its use asks (compile/trunc.rs)
                self.any_int_trunc(t)
            }
            "MOVE" => {
                if !self.arity(name, n, 1, 1, span, file) {
                    return TExpr::error(span);
                }
                self.check_expr(a[0], scope, expected)
            }
            "EXPT" => {
                if !self.arity(name, n, 2, 2, span, file) {
                    return TExpr::error(span);
                }
                let x = self.scalar_arg(a[0], scope, expected, Prim::LReal);
                let mut p = x.ty.prim(&self.types);
                // CODESYS raises an integer too: in the real type wanted, LREAL without one
                let x = if p.is_some_and(Prim::is_integral) && !matches!(x.ty, Ty::Enum(_)) {
                    self.habit(Habit::IntegerExpt, file, a[0].span);
                    let r = match expected.and_then(|e| e.prim(&self.types)) {
                        Some(Prim::Real) => Prim::Real,
                        _ => Prim::LReal,
                    };
                    p = Some(r);
                    self.conv(x, r, Ty::Prim(r))
                } else {
                    x
                };
                if !self.want(
                    &x,
                    p.is_some_and(Prim::is_real),
                    name,
                    "a `REAL` or `LREAL` base",
                    file,
                ) {
                    return TExpr::error(span);
                }
                let p = p.expect("real");
                let y = self.scalar_arg(a[1], scope, Some(&Ty::Prim(p)), p);
                let yp = y.ty.prim(&self.types);
                if !self.want(&y, yp.is_some_and(Prim::is_num), name, "a number exponent", file) {
                    return TExpr::error(span);
                }
                let y = self.conv(y, p, Ty::Prim(p));
                self.make_bin(BinOp::Expt, x, y, Ty::Prim(p), span, file)
            }
            "ADD" | "MUL" | "SUB" | "DIV" | "MOD" | "AND" | "OR" | "XOR" => {
                let (min, max) =
                    if matches!(name, "SUB" | "DIV" | "MOD") { (2, 2) } else { (2, usize::MAX) };
                if !self.arity(name, n, min, max, span, file) {
                    return TExpr::error(span);
                }
                let op = match name {
                    "ADD" => BinaryOp::Add,
                    "MUL" => BinaryOp::Mul,
                    "SUB" => BinaryOp::Sub,
                    "DIV" => BinaryOp::Div,
                    "MOD" => BinaryOp::Mod,
                    "AND" => BinaryOp::And,
                    "OR" => BinaryOp::Or,
                    _ => BinaryOp::Xor,
                };
                let mut acc = self.check_expr(a[0], scope, expected);
                for e in &a[1..] {
                    let hint = if matches!(acc.ty, Ty::IntLit | Ty::RealLit) {
                        expected.cloned()
                    } else {
                        Some(acc.ty.clone())
                    };
                    let b = self.check_expr(e, scope, hint.as_ref());
                    acc = self.binary_pub(op, acc, b, span, file);
                }
                acc
            }
            "MIN" | "MAX" | "LIMIT" => {
                let (min, max) = if name == "LIMIT" { (3, 3) } else { (1, usize::MAX) };
                if !self.arity(name, n, min, max, span, file) {
                    return TExpr::error(span);
                }
                let mut items: Vec<TExpr> = Vec::new();
                for e in &a {
                    let t = self.check_expr(e, scope, expected);
                    items.push(t);
                }
                // one type for all
                let mut ty = items[0].ty.clone();
                for t in &items[1..] {
                    let probe_a = TExpr { k: TK::Const(Cv::Int(0)), ty: ty.clone(), span };
                    let probe_b =
                        TExpr { k: TK::Const(Cv::Int(0)), ty: t.ty.clone(), span: t.span };
                    let saved = self.diags.len();
                    match self.unify(probe_a, probe_b, name, t.span, file) {
                        Some((_, _, u)) => ty = u,
                        None => {
                            if self.diags.len() == saved {
                                return TExpr::error(span);
                            }
                            return TExpr::error(span);
                        }
                    }
                }
                if matches!(ty, Ty::IntLit | Ty::RealLit) {
                    ty = match expected.and_then(|e| e.prim(&self.types)) {
                        Some(p) if literal_target(p, &ty) => Ty::Prim(p),
                        _ if ty == Ty::RealLit => Ty::Prim(Prim::LReal),
                        _ => Ty::Prim(Prim::DInt),
                    };
                }
                let Some(p) = ty.prim(&self.types) else {
                    let tn = self.ty_name(&ty);
                    self.error(file, span, format!("`{name}` needs elementary values, not `{tn}`"));
                    return TExpr::error(span);
                };
                let mut conv: Vec<TExpr> = Vec::new();
                for t in items {
                    let t = if matches!(t.ty, Ty::IntLit | Ty::RealLit) {
                        self.coerce(t, &ty, file)
                    } else if matches!(ty, Ty::Enum(_)) {
                        t
                    } else {
                        self.conv(t, p, ty.clone())
                    };
                    if t.ty.is_error() {
                        return TExpr::error(span);
                    }
                    conv.push(t);
                }
                if name == "LIMIT" {
                    let mx = conv.pop().expect("3");
                    let x = conv.pop().expect("3");
                    let mn = conv.pop().expect("3");
                    let lo = self.make_bin(BinOp::Max, x, mn, ty.clone(), span, file);
                    return self.make_bin(BinOp::Min, lo, mx, ty, span, file);
                }
                let op = if name == "MIN" { BinOp::Min } else { BinOp::Max };
                let mut it = conv.into_iter();
                let mut acc = it.next().expect("1");
                for b in it {
                    acc = self.make_bin(op, acc, b, ty.clone(), span, file);
                }
                acc
            }
            "SEL" => {
                if !self.arity(name, n, 3, 3, span, file) {
                    return TExpr::error(span);
                }
                let g = self.check_expr(a[0], scope, Some(&Ty::Prim(Prim::Bool)));
                let g = self.coerce(g, &Ty::Prim(Prim::Bool), file);
                let x = self.check_expr(a[1], scope, expected);
                let y = self.check_expr(a[2], scope, expected);
                let Some((x, y, ty)) = self.unify_values(x, y, expected, name, span, file) else {
                    return TExpr::error(span);
                };
                if g.ty.is_error() {
                    return TExpr::error(span);
                }
                if let Some(v) = g.const_int() {
                    return if v != 0 { y } else { x };
                }
                TExpr { k: TK::Std(Std::Sel, vec![g, x, y]), ty, span }
            }
            "MUX" => {
                if !self.arity(name, n, 2, usize::MAX, span, file) {
                    return TExpr::error(span);
                }
                let k = self.scalar_arg(a[0], scope, None, Prim::DInt);
                let kp = k.ty.prim(&self.types);
                if !self.want(
                    &k,
                    kp.is_some_and(Prim::is_integral) && !matches!(k.ty, Ty::Enum(_)),
                    name,
                    "an integer selector",
                    file,
                ) {
                    return TExpr::error(span);
                }
                let mut vals = vec![self.check_expr(a[1], scope, expected)];
                for e in &a[2..] {
                    let t = self.check_expr(e, scope, expected);
                    let first = vals[0].clone();
                    let Some((_, _, ty)) =
                        self.unify_values(first, t.clone(), expected, name, e.span, file)
                    else {
                        return TExpr::error(span);
                    };
                    vals[0].ty = vals[0].ty.clone();
                    vals.push(t);
                    let _ = ty;
                }
                // bring all to one type
                let mut ty = vals[0].ty.clone();
                for v in &vals[1..] {
                    let pa = TExpr { k: TK::Const(Cv::Int(0)), ty: ty.clone(), span };
                    if let Some((_, _, u)) =
                        self.unify_values(pa, v.clone(), expected, name, v.span, file)
                    {
                        ty = u;
                    }
                }
                let mut out = vec![k];
                for v in vals {
                    let v = self.value_as(v, &ty, file);
                    if v.ty.is_error() {
                        return TExpr::error(span);
                    }
                    out.push(v);
                }
                TExpr { k: TK::Std(Std::Mux, out), ty, span }
            }
            "SHL" | "SHR" | "ROL" | "ROR" => {
                if !self.arity(name, n, 2, 2, span, file) {
                    return TExpr::error(span);
                }
                let x = self.scalar_arg(a[0], scope, expected, Prim::DWord);
                let p = x.ty.prim(&self.types).filter(|_| !matches!(x.ty, Ty::Enum(_)));
                // CODESYS: an integer is shifted as the bit pattern of its width.
                let integer =
                    p.is_some_and(Prim::is_int) && self.habit(Habit::IntegerShift, file, a[0].span);
                if !self.want(
                    &x,
                    p.is_some_and(Prim::is_bits) || integer,
                    name,
                    "a bit string (BYTE, WORD, DWORD, LWORD)",
                    file,
                ) {
                    return TExpr::error(span);
                }
                let int_ty = p.filter(|_| integer);
                let (x, p) = match int_ty {
                    Some(i) => {
                        let b = super::codesys::bits_of(i);
                        (self.conv(x, b, Ty::Prim(b)), b)
                    }
                    None => (x, p.expect("bits")),
                };
                let c = self.scalar_arg(a[1], scope, None, Prim::LInt);
                let cp = c.ty.prim(&self.types);
                if !self.want(&c, cp.is_some_and(Prim::is_integral), name, "an integer count", file)
                {
                    return TExpr::error(span);
                }
                // a bit string count as CODESYS takes it (`SHR(w, n)` with a BYTE n)
                if cp.is_some_and(Prim::is_bits) {
                    self.habit(Habit::BitShiftCount, file, a[1].span);
                }
                let op = match name {
                    "SHL" => BinOp::Shl,
                    "SHR" => BinOp::Shr,
                    "ROL" => BinOp::Rol,
                    _ => BinOp::Ror,
                };
                // The count is N taken as an unsigned 64-bit number (a negative N is huge),
                // brought into IN's type without changing what it does: a shift by the width
                // or more gives 0, so it is capped at the width; a rotation is by N modulo the
                // width. Both fit any bit string type.
                let rotate = matches!(op, BinOp::Rol | BinOp::Ror);
                let width = u64::from(p.bits());
                let c = if c.is_const() {
                    let n = (c.const_int().unwrap_or(0) as i64) as u64;
                    let n = if rotate { n % width } else { n.min(width) };
                    TExpr::konst(Cv::Int(i128::from(n)), Ty::Prim(p), c.span)
                } else {
                    let ulint = Ty::Prim(Prim::ULInt);
                    let c = self.conv(c, Prim::LInt, Ty::Prim(Prim::LInt));
                    let c = self.conv(c, Prim::ULInt, ulint.clone());
                    let w = TExpr::konst(Cv::Int(i128::from(width)), ulint.clone(), span);
                    let bring = if rotate { BinOp::Mod } else { BinOp::Min };
                    let c = self.make_bin(bring, c, w, ulint, span, file);
                    self.conv(c, p, Ty::Prim(p))
                };
                let r = self.make_bin(op, x, c, Ty::Prim(p), span, file);
                match int_ty {
                    Some(i) => self.conv(r, i, Ty::Prim(i)),
                    None => r,
                }
            }
            "GT" | "GE" | "EQ" | "LE" | "LT" | "NE" => {
                // extensible but NE (IEC 61131-3 ed3): `GT(a, b, c)` is
                // `a > b AND b > c`, each input evaluated once
                let max = if name == "NE" { 2 } else { usize::MAX };
                if !self.arity(name, n, 2, max, span, file) {
                    return TExpr::error(span);
                }
                let op = match name {
                    "GT" => BinaryOp::Gt,
                    "GE" => BinaryOp::Ge,
                    "EQ" => BinaryOp::Eq,
                    "LE" => BinaryOp::Le,
                    "LT" => BinaryOp::Lt,
                    _ => BinaryOp::Ne,
                };
                let mut items: Vec<TExpr> = Vec::new();
                for e in &a {
                    let hint = items.iter().find(|t| !matches!(t.ty, Ty::IntLit | Ty::RealLit));
                    let hint = hint.map(|t| t.ty.clone());
                    items.push(self.check_expr(e, scope, hint.as_ref()));
                }
                if n == 2 {
                    let y = items.pop().expect("2");
                    let x = items.pop().expect("2");
                    return self.binary_op(op, x, y, span, file);
                }
                // the type of all: each pair checked as the operator checks it
                let mut ty = items[0].ty.clone();
                for t in &items[1..] {
                    let pa = TExpr { k: TK::Const(Cv::Int(0)), ty: ty.clone(), span };
                    let pb = TExpr { k: TK::Const(Cv::Int(0)), ty: t.ty.clone(), span: t.span };
                    let Some((_, _, u)) =
                        self.unify(pa, pb, super::expr::op_text(op), t.span, file)
                    else {
                        return TExpr::error(span);
                    };
                    ty = u;
                }
                if matches!(ty, Ty::IntLit | Ty::RealLit) {
                    ty = Ty::Prim(if ty == Ty::RealLit { Prim::LReal } else { Prim::LInt });
                }
                let mut conv: Vec<TExpr> = Vec::new();
                for t in items {
                    let t = if matches!(t.ty, Ty::IntLit | Ty::RealLit) {
                        self.coerce(t, &ty, file)
                    } else {
                        self.value_as(t, &ty, file)
                    };
                    if t.ty.is_error() {
                        return TExpr::error(span);
                    }
                    conv.push(t);
                }
                // checked as the operator on the first pair (the type allows it or not)
                let probe = self.binary_op(op, conv[0].clone(), conv[1].clone(), span, file);
                if probe.ty.is_error() {
                    return probe;
                }
                let cmp = match op {
                    BinaryOp::Gt => CmpOp::Gt,
                    BinaryOp::Ge => CmpOp::Ge,
                    BinaryOp::Eq => CmpOp::Eq,
                    BinaryOp::Le => CmpOp::Le,
                    _ => CmpOp::Lt,
                };
                if conv.iter().all(TExpr::is_const) {
                    // folded pair by pair
                    let mut all = true;
                    for w in conv.windows(2) {
                        let r = self.binary_op(op, w[0].clone(), w[1].clone(), span, file);
                        all &= r.const_int() == Some(1);
                    }
                    return TExpr::konst(Cv::Int(i128::from(all)), Ty::Prim(Prim::Bool), span);
                }
                TExpr { k: TK::Std(Std::Chain(cmp), conv), ty: Ty::Prim(Prim::Bool), span }
            }
            "LOWER_BOUND" | "UPPER_BOUND" => {
                if !self.arity(name, n, 2, 2, span, file) {
                    return TExpr::error(span);
                }
                self.array_bound(&a, name == "UPPER_BOUND", span, scope)
            }
            "SIZEOF" => {
                if !self.arity(name, n, 1, 1, span, file) {
                    return TExpr::error(span);
                }
                self.sizeof(a[0], span, scope)
            }
            "NOT" => {
                if !self.arity(name, n, 1, 1, span, file) {
                    return TExpr::error(span);
                }
                let t = self.scalar_arg(a[0], scope, expected, Prim::DWord);
                let p = t.ty.prim(&self.types);
                if !self.want(
                    &t,
                    p.is_some_and(|p| p.is_bits() || p == Prim::Bool)
                        && !matches!(t.ty, Ty::Enum(_)),
                    name,
                    "a BOOL or bit string",
                    file,
                ) {
                    return TExpr::error(span);
                }
                if let Some(v) = t.const_int() {
                    let p = p.expect("bits");
                    let r = if p == Prim::Bool {
                        i128::from(v == 0)
                    } else {
                        super::types::wrap(p, !v)
                    };
                    return TExpr::konst(Cv::Int(r), t.ty, span);
                }
                let ty = t.ty.clone();
                TExpr { k: TK::Un(UnOp::Not, Box::new(t)), ty, span }
            }
            "LEN" => {
                if !self.arity(name, n, 1, 1, span, file) {
                    return TExpr::error(span);
                }
                let Some(s) = self.string_arg(a[0], scope, name) else { return TExpr::error(span) };
                if let TK::Const(Cv::Str(v)) = &s.k {
                    return TExpr::konst(Cv::Int(v.len() as i128), Ty::Prim(Prim::Int), span);
                }
                if let TK::Const(Cv::WStr(v)) = &s.k {
                    return TExpr::konst(Cv::Int(v.len() as i128), Ty::Prim(Prim::Int), span);
                }
                TExpr { k: TK::Std(Std::Len, vec![s]), ty: Ty::Prim(Prim::Int), span }
            }
            "FIND" => {
                if !self.arity(name, n, 2, 2, span, file) {
                    return TExpr::error(span);
                }
                let (Some(x), Some(y)) =
                    (self.string_arg(a[0], scope, name), self.string_arg(a[1], scope, name))
                else {
                    return TExpr::error(span);
                };
                if !self.same_kind(&x, &y, name, file) {
                    return TExpr::error(span);
                }
                TExpr { k: TK::Std(Std::Find, vec![x, y]), ty: Ty::Prim(Prim::Int), span }
            }
            "LEFT" | "RIGHT" | "MID" => {
                let k = if name == "MID" { 3 } else { 2 };
                if !self.arity(name, n, k, k, span, file) {
                    return TExpr::error(span);
                }
                let Some(s) = self.string_arg(a[0], scope, name) else { return TExpr::error(span) };
                let mut out = vec![s.clone()];
                for e in &a[1..] {
                    let Some(c) = self.count_arg(e, scope, name) else { return TExpr::error(span) };
                    out.push(c);
                }
                let op = match name {
                    "LEFT" => Std::Left,
                    "RIGHT" => Std::Right,
                    _ => Std::Mid,
                };
                TExpr { k: TK::Std(op, out), ty: s.ty, span }
            }
            "CONCAT" => {
                if !self.arity(name, n, 2, usize::MAX, span, file) {
                    return TExpr::error(span);
                }
                let Some(mut acc) = self.string_arg(a[0], scope, name) else {
                    return TExpr::error(span);
                };
                for e in &a[1..] {
                    let Some(b) = self.string_arg(e, scope, name) else {
                        return TExpr::error(span);
                    };
                    if !self.same_kind(&acc, &b, name, file) {
                        return TExpr::error(span);
                    }
                    acc = concat(acc, b, span);
                }
                acc
            }
            "INSERT" | "DELETE" | "REPLACE" => {
                // composed of LEFT, RIGHT, LEN and CONCAT
                let k = match name {
                    "INSERT" => 3,
                    "DELETE" => 3,
                    _ => 4,
                };
                if !self.arity(name, n, k, k, span, file) {
                    return TExpr::error(span);
                }
                let Some(s) = self.string_arg(a[0], scope, name) else { return TExpr::error(span) };
                let (mid, l, p) = match name {
                    "INSERT" => {
                        let Some(m) = self.string_arg(a[1], scope, name) else {
                            return TExpr::error(span);
                        };
                        if !self.same_kind(&s, &m, name, file) {
                            return TExpr::error(span);
                        }
                        let Some(p) = self.count_arg(a[2], scope, name) else {
                            return TExpr::error(span);
                        };
                        // INSERT(IN1, IN2, P) = LEFT(IN1, P) & IN2 & RIGHT(IN1, LEN(IN1) - P)
                        let len = self.lint_len(&s, span);
                        let left = TExpr {
                            k: TK::Std(Std::Left, vec![s.clone(), p.clone()]),
                            ty: s.ty.clone(),
                            span,
                        };
                        let rest =
                            self.make_bin(BinOp::Sub, len, p, Ty::Prim(Prim::LInt), span, file);
                        let right = TExpr {
                            k: TK::Std(Std::Right, vec![s.clone(), rest]),
                            ty: s.ty.clone(),
                            span,
                        };
                        return concat(concat(left, m, span), right, span);
                    }
                    "DELETE" => {
                        let Some(l) = self.count_arg(a[1], scope, name) else {
                            return TExpr::error(span);
                        };
                        let Some(p) = self.count_arg(a[2], scope, name) else {
                            return TExpr::error(span);
                        };
                        (None, l, p)
                    }
                    _ => {
                        let Some(m) = self.string_arg(a[1], scope, name) else {
                            return TExpr::error(span);
                        };
                        if !self.same_kind(&s, &m, name, file) {
                            return TExpr::error(span);
                        }
                        let Some(l) = self.count_arg(a[2], scope, name) else {
                            return TExpr::error(span);
                        };
                        let Some(p) = self.count_arg(a[3], scope, name) else {
                            return TExpr::error(span);
                        };
                        (Some(m), l, p)
                    }
                };
                // LEFT(IN, P - 1) [& IN2] & RIGHT(IN, LEN(IN) - (P - 1) - L)
                let one = TExpr::konst(Cv::Int(1), Ty::Prim(Prim::LInt), span);
                let before = self.make_bin(BinOp::Sub, p, one, Ty::Prim(Prim::LInt), span, file);
                let left = TExpr {
                    k: TK::Std(Std::Left, vec![s.clone(), before.clone()]),
                    ty: s.ty.clone(),
                    span,
                };
                let len = self.lint_len(&s, span);
                let rest = self.make_bin(BinOp::Sub, len, before, Ty::Prim(Prim::LInt), span, file);
                let rest = self.make_bin(BinOp::Sub, rest, l, Ty::Prim(Prim::LInt), span, file);
                let right =
                    TExpr { k: TK::Std(Std::Right, vec![s.clone(), rest]), ty: s.ty.clone(), span };
                match mid {
                    Some(m) => concat(concat(left, m, span), right, span),
                    None => concat(left, right, span),
                }
            }
            _ => unreachable!("listed in NAMES"),
        }
    }

    /// CODESYS's `SIZEOF(x)`: the bytes of a variable (of any expression's type, which is not
    /// evaluated) or of a type named, as an untyped integer constant.
    fn sizeof(&mut self, e: &Expr, span: Span, scope: Scope) -> TExpr {
        let file = scope.file;
        if !self.habit(Habit::Sizeof, file, span) {
            return TExpr::error(span);
        }
        if let ExprKind::Name(id) = &e.kind {
            let is_var = scope
                .pou
                .is_some_and(|p| self.pous[p].lookup(&id.name).is_some_and(|i| i < scope.visible))
                || self.global_names.contains_key(&id.name.to_ascii_lowercase());
            let is_type = Prim::from_name(&id.name).is_some()
                || self.type_names.contains_key(&id.name.to_ascii_lowercase())
                || self
                    .pou_names
                    .get(&id.name.to_ascii_lowercase())
                    .is_some_and(|&p| self.pous[p].kind == crate::st::ast::PouKind::FunctionBlock);
            if is_type && !is_var {
                let ty = self.resolve_type_ref(&TypeRef::Named(id.clone()), scope);
                let size = self.types.size(&ty);
                return TExpr::konst(Cv::Int(i128::from(size)), Ty::IntLit, span);
            }
        }
        // No code: what it would call is not called (but a call in it is checked).
        let saved = self.pous.iter().map(|p| p.callees.len()).collect::<Vec<_>>();
        let t = self.check_expr(e, scope, None);
        for (p, n) in saved.into_iter().enumerate() {
            self.pous[p].callees.truncate(n);
        }
        let sized = !matches!(t.ty, Ty::IntLit | Ty::RealLit | Ty::Void | Ty::OpenArray(_));
        if !self.want(&t, sized, "SIZEOF", "a variable or a type", file) {
            return TExpr::error(span);
        }
        let size = self.types.size(&t.ty);
        TExpr::konst(Cv::Int(i128::from(size)), Ty::IntLit, span)
    }

    fn lint_len(&mut self, s: &TExpr, span: Span) -> TExpr {
        let len = TExpr { k: TK::Std(Std::Len, vec![s.clone()]), ty: Ty::Prim(Prim::Int), span };
        self.conv(len, Prim::LInt, Ty::Prim(Prim::LInt))
    }

    fn string_arg(&mut self, e: &Expr, scope: Scope, fname: &str) -> Option<TExpr> {
        let t = self.check_expr(e, scope, None);
        match t.ty {
            Ty::Error => None,
            Ty::Str(_) | Ty::WStr(_) => Some(t),
            _ => {
                let n = self.ty_name(&t.ty);
                self.error(scope.file, t.span, format!("`{fname}` needs a STRING, not `{n}`"));
                None
            }
        }
    }

    /// Whether two string inputs of `fname` are of one kind (both STRING or both WSTRING):
    /// the standard overloads its string functions on each, never on a mix.
    fn same_kind(&mut self, a: &TExpr, b: &TExpr, fname: &str, file: usize) -> bool {
        if a.ty.is_wide() == b.ty.is_wide() {
            return true;
        }
        let (x, y) = (kind_name(&a.ty), kind_name(&b.ty));
        let msg = format!(
            "`{fname}` cannot mix {x} and {y}: convert one with STRING_TO_WSTRING or WSTRING_TO_STRING"
        );
        self.error(file, b.span, msg);
        false
    }

    fn count_arg(&mut self, e: &Expr, scope: Scope, fname: &str) -> Option<TExpr> {
        let t = self.scalar_arg(e, scope, None, Prim::LInt);
        let p = t.ty.prim(&self.types);
        if !self.want(&t, p.is_some_and(Prim::is_int), fname, "an integer", scope.file) {
            return None;
        }
        Some(self.conv(t, Prim::LInt, Ty::Prim(Prim::LInt)))
    }

    fn un(&mut self, op: UnOp, t: TExpr, span: Span) -> TExpr {
        let ty = t.ty.clone();
        if let (TK::Const(cv), Some(p)) = (&t.k, ty.prim(&self.types)) {
            if let Some(r) = fold_un(op, p, cv) {
                return TExpr::konst(r, ty, span);
            }
        }
        TExpr { k: TK::Un(op, Box::new(t)), ty, span }
    }

    /// Two values of one type (SEL, MUX): numbers unify, other types must be equal.
    fn unify_values(
        &mut self,
        x: TExpr,
        y: TExpr,
        expected: Option<&Ty>,
        name: &str,
        span: Span,
        file: usize,
    ) -> Option<(TExpr, TExpr, Ty)> {
        if let (Ty::Str(a), Ty::Str(b)) = (&x.ty, &y.ty) {
            let ty = Ty::Str(*a.max(b));
            return Some((x, y, ty));
        }
        if let (Ty::WStr(a), Ty::WStr(b)) = (&x.ty, &y.ty) {
            let ty = Ty::WStr(*a.max(b));
            return Some((x, y, ty));
        }
        if matches!(x.ty, Ty::Array(_) | Ty::Struct(_))
            || matches!(y.ty, Ty::Array(_) | Ty::Struct(_))
        {
            if x.ty == y.ty {
                let ty = x.ty.clone();
                return Some((x, y, ty));
            }
            let (a, b) = (self.ty_name(&x.ty), self.ty_name(&y.ty));
            self.error(file, span, format!("`{name}` cannot be applied to `{a}` and `{b}`"));
            return None;
        }
        let (x, y, ty) = self.unify(x, y, name, span, file)?;
        if matches!(ty, Ty::IntLit | Ty::RealLit) {
            let to = match expected.and_then(|e| e.prim(&self.types)) {
                Some(p) if literal_target(p, &ty) => Ty::Prim(p),
                _ if ty == Ty::RealLit => Ty::Prim(Prim::LReal),
                _ => Ty::Prim(Prim::DInt),
            };
            let x = self.coerce(x, &to, file);
            let y = self.coerce(y, &to, file);
            return Some((x, y, to));
        }
        Some((x, y, ty))
    }

    fn value_as(&mut self, v: TExpr, ty: &Ty, file: usize) -> TExpr {
        if matches!((ty, &v.ty), (Ty::Str(_), Ty::Str(_)) | (Ty::WStr(_), Ty::WStr(_))) {
            return v;
        }
        if &v.ty == ty {
            return v;
        }
        if matches!(v.ty, Ty::IntLit | Ty::RealLit) {
            return self.coerce(v, ty, file);
        }
        match ty.prim(&self.types) {
            Some(p) if !matches!(ty, Ty::Enum(_)) => self.conv(v, p, ty.clone()),
            _ => v,
        }
    }

    /// `<T>_TO_STRING`, `STRING_TO_<T>` (and `STRING_TO_STRING`, a copy) of `t`, checked
    /// already (a value of `src` when it is no STRING).
    fn string_conversion(
        &mut self,
        name: &str,
        src: Ty,
        dst: Ty,
        t: TExpr,
        span: Span,
        file: usize,
    ) -> TExpr {
        let scalar = |cx: &Self, t: &Ty| t.prim(&cx.types).and_then(|p| p.value_type().scalar());
        // the input must be of the source's kind: a STRING for `STRING_TO_*`
        let of_src = |t: &TExpr| t.ty.string_cap().is_some() && t.ty.is_wide() == src.is_wide();
        match (&src, &dst) {
            (Ty::Str(_), Ty::Str(_)) | (Ty::WStr(_), Ty::WStr(_)) => {
                self.want(&t, of_src(&t), name, kind_name(&src), file).then_some(t)
            }
            (Ty::Str(_), Ty::WStr(_)) | (Ty::WStr(_), Ty::Str(_)) => {
                let op = if dst.is_wide() { Std::Widen } else { Std::Narrow };
                self.want(&t, of_src(&t), name, kind_name(&src), file).then(|| TExpr {
                    k: TK::Std(op, vec![t]),
                    ty: dst,
                    span,
                })
            }
            (Ty::Str(_) | Ty::WStr(_), _) => {
                let to = scalar(self, &dst).expect("a prim");
                self.want(&t, of_src(&t), name, kind_name(&src), file).then(|| TExpr {
                    k: TK::Std(Std::FromString(to), vec![t]),
                    ty: dst,
                    span,
                })
            }
            _ => {
                let t = self.coerce(t, &src, file);
                let from = scalar(self, &src).expect("a prim");
                (!t.ty.is_error()).then(|| TExpr {
                    k: TK::Std(Std::ToString(from), vec![t]),
                    ty: dst,
                    span,
                })
            }
        }
        .unwrap_or_else(|| TExpr::error(span))
    }

    fn convert_call(
        &mut self,
        name: &str,
        src: Ty,
        dst: Ty,
        args: &[Arg],
        span: Span,
        scope: Scope,
    ) -> TExpr {
        let file = scope.file;
        let Some(arg) = self.conversion_arg(name, args, span, file) else {
            return TExpr::error(span);
        };
        let expected = if src.string_cap().is_some() { None } else { Some(&src) };
        let t = self.check_expr(arg, scope, expected);
        self.convert(name, src, dst, t, span, file)
    }

    /// `TO_<T>(x)` (IEC 61131-3 ed3, the overloaded conversions): `<X>_TO_<T>(x)` for
    /// the type X of x; an untyped constant is a `DINT` (a `LINT`, `ULINT` when it needs it) or
    /// an `LREAL`, an enumeration value its base type's number.
    fn overloaded_conversion(
        &mut self,
        name: &str,
        dst: Ty,
        args: &[Arg],
        span: Span,
        scope: Scope,
    ) -> TExpr {
        let file = scope.file;
        let Some(arg) = self.conversion_arg(name, args, span, file) else {
            return TExpr::error(span);
        };
        let t = self.check_expr(arg, scope, None);
        let src = match &t.ty {
            Ty::Error => return TExpr::error(span),
            Ty::IntLit => {
                let v = t.const_int().unwrap_or(0);
                let p = [Prim::DInt, Prim::LInt, Prim::ULInt]
                    .into_iter()
                    .find(|&p| super::types::fits(p, v))
                    .unwrap_or(Prim::ULInt);
                Ty::Prim(p)
            }
            Ty::RealLit => Ty::Prim(Prim::LReal),
            Ty::Str(_) => Ty::Str(80),
            Ty::WStr(_) => Ty::WStr(80),
            Ty::Prim(p) | Ty::Sub(p, _, _) => Ty::Prim(*p),
            Ty::Enum(e) => Ty::Prim(self.types.enums[*e].base),
            _ => {
                self.want(&t, false, name, "an elementary value", file);
                return TExpr::error(span);
            }
        };
        // an enumeration's value is its number, of its base type
        let t = if matches!(t.ty, Ty::Enum(_)) { TExpr { ty: src.clone(), ..t } } else { t };
        self.convert(name, src, dst, t, span, file)
    }

    /// `<SRC>_TO_<DST>` of `t`, checked already.
    fn convert(
        &mut self,
        name: &str,
        src: Ty,
        dst: Ty,
        t: TExpr,
        span: Span,
        file: usize,
    ) -> TExpr {
        let char_of = |t: &Ty| match t {
            Ty::Prim(Prim::Char) => Some(false),
            Ty::Prim(Prim::WChar) => Some(true),
            _ => None,
        };
        let string_of = |t: &Ty| t.string_cap().map(|_| t.is_wide());
        match (char_of(&src), string_of(&dst), string_of(&src), char_of(&dst)) {
            (Some(wide), Some(to_wide), ..) => {
                let t = self.coerce(t, &src, file);
                if t.ty.is_error() {
                    return TExpr::error(span);
                }
                let ty = if wide { Ty::WStr(1) } else { Ty::Str(1) };
                let one = TExpr { k: TK::Std(Std::CharToString, vec![t]), ty, span };
                // CHAR_TO_WSTRING, WCHAR_TO_STRING (CODESYS): the character's string, then
                // converted as STRING_TO_WSTRING or WSTRING_TO_STRING convert it
                return if wide == to_wide { one } else { widened(one, to_wide, span) };
            }
            (_, _, Some(wide), Some(to_wide)) => {
                let ok = t.ty.string_cap().is_some() && t.ty.is_wide() == wide;
                if !self.want(&t, ok, name, kind_name(&src), file) {
                    return TExpr::error(span);
                }
                // STRING_TO_WCHAR, WSTRING_TO_CHAR (CODESYS): the first character converted
                let t = if wide == to_wide { t } else { widened(t, to_wide, span) };
                return TExpr { k: TK::Std(Std::StringToChar, vec![t]), ty: dst, span };
            }
            _ => {}
        }
        if src.string_cap().is_some() || dst.string_cap().is_some() {
            return self.string_conversion(name, src, dst, t, span, file);
        }
        let (sp, dp) = (src.prim(&self.types).expect("prim"), dst.prim(&self.types).expect("prim"));
        let t = if t.ty == Ty::IntLit && sp == Prim::Bool {
            match t.const_int() {
                Some(v @ (0 | 1)) => TExpr::konst(Cv::Int(v), src.clone(), t.span),
                _ => self.coerce(t, &src, file),
            }
        } else {
            self.coerce(t, &src, file)
        };
        if t.ty.is_error() {
            return TExpr::error(span);
        }
        if sp.calendar().is_some() || dp.calendar().is_some() {
            return self.calendar_conversion(name, sp, dp, dst, t, span, file);
        }
        let ns = |v: i128| TExpr::konst(Cv::Int(v), Ty::Prim(Prim::LInt), span);
        let ns_real = |v: f64| TExpr::konst(Cv::Real(v), Ty::Prim(Prim::LReal), span);
        match (sp.is_time(), dp.is_time()) {
            (true, true) => self.conv(t, dp, dst),
            (true, false) => {
                // milliseconds
                let t = TExpr { ty: Ty::Prim(Prim::LInt), ..t };
                if dp.is_real() {
                    let f = self.conv(t, Prim::LReal, Ty::Prim(Prim::LReal));
                    let ms = self.make_bin(
                        BinOp::Div,
                        f,
                        ns_real(1e6),
                        Ty::Prim(Prim::LReal),
                        span,
                        file,
                    );
                    self.conv(ms, dp, dst)
                } else {
                    let ms = self.make_bin(
                        BinOp::Div,
                        t,
                        ns(1_000_000),
                        Ty::Prim(Prim::LInt),
                        span,
                        file,
                    );
                    self.conv(ms, dp, dst)
                }
            }
            (false, true) => {
                if sp.is_real() {
                    let f = self.conv(t, Prim::LReal, Ty::Prim(Prim::LReal));
                    let n = self.make_bin(
                        BinOp::Mul,
                        f,
                        ns_real(1e6),
                        Ty::Prim(Prim::LReal),
                        span,
                        file,
                    );
                    let n = self.conv(n, Prim::LInt, Ty::Prim(Prim::LInt));
                    TExpr { ty: dst, ..n }
                } else {
                    let i = self.conv(t, Prim::LInt, Ty::Prim(Prim::LInt));
                    let n = self.make_bin(
                        BinOp::Mul,
                        i,
                        ns(1_000_000),
                        Ty::Prim(Prim::LInt),
                        span,
                        file,
                    );
                    TExpr { ty: dst, ..n }
                }
            }
            (false, false) => self.conv(t, dp, dst),
        }
    }

    /// `TRUNC_<T>(r)` and `<R>_TRUNC_<T>(r)` (`src` R, or any real when `None`): `r` toward
    /// zero, as an integer T (saturated at T's range, NaN 0, as `TRUNC`).
    fn trunc_to(
        &mut self,
        name: &str,
        src: Option<Prim>,
        dst: Prim,
        args: &[Arg],
        span: Span,
        scope: Scope,
    ) -> TExpr {
        let file = scope.file;
        let Some(arg) = self.conversion_arg(name, args, span, file) else {
            return TExpr::error(span);
        };
        let t = match src {
            Some(r) => {
                let t = self.check_expr(arg, scope, Some(&Ty::Prim(r)));
                self.coerce(t, &Ty::Prim(r), file)
            }
            None => self.scalar_arg(arg, scope, None, Prim::LReal),
        };
        let p = t.ty.prim(&self.types);
        if !self.want(&t, p.is_some_and(Prim::is_real), name, "a `REAL` or `LREAL`", file) {
            return TExpr::error(span);
        }
        let t = self.un(UnOp::Trunc, t, span);
        self.conv(t, dst, Ty::Prim(dst))
    }

    /// Binary operators for the function forms (`ADD(a, b)`).
    pub fn binary_pub(
        &mut self,
        op: BinaryOp,
        a: TExpr,
        b: TExpr,
        span: Span,
        file: usize,
    ) -> TExpr {
        self.binary_op(op, a, b, span, file)
    }
}

fn concat(a: TExpr, b: TExpr, span: Span) -> TExpr {
    if let (TK::Const(Cv::Str(x)), TK::Const(Cv::Str(y))) = (&a.k, &b.k) {
        let mut s = [x.as_slice(), y.as_slice()].concat();
        s.truncate(255);
        let n = s.len().max(1) as u32;
        return TExpr::konst(Cv::Str(s), Ty::Str(n), span);
    }
    if let (TK::Const(Cv::WStr(x)), TK::Const(Cv::WStr(y))) = (&a.k, &b.k) {
        let mut s = [x.as_slice(), y.as_slice()].concat();
        s.truncate(255);
        let n = s.len().max(1) as u32;
        return TExpr::konst(Cv::WStr(s), Ty::WStr(n), span);
    }
    let cap = match (a.ty.string_cap(), b.ty.string_cap()) {
        (Some(x), Some(y)) => (x + y).min(255),
        _ => 255,
    };
    let ty = if a.ty.is_wide() { Ty::WStr(cap) } else { Ty::Str(cap) };
    TExpr { k: TK::Std(Std::Concat, vec![a, b]), ty, span }
}

fn fold_un(op: UnOp, p: Prim, cv: &Cv) -> Option<Cv> {
    let f = match cv {
        Cv::Int(v) => {
            return match op {
                UnOp::Abs => Some(Cv::Int(super::types::wrap(p, v.abs()))),
                _ => None,
            }
        }
        Cv::Real(f) => *f,
        Cv::Str(_) | Cv::WStr(_) => return None,
    };
    let r = match op {
        UnOp::Abs => f.abs(),
        UnOp::Sqrt => f.sqrt(),
        UnOp::Ln => f.ln(),
        UnOp::Log => f.log10(),
        UnOp::Exp => f.exp(),
        UnOp::Sin => f.sin(),
        UnOp::Cos => f.cos(),
        UnOp::Tan => f.tan(),
        UnOp::Asin => f.asin(),
        UnOp::Acos => f.acos(),
        UnOp::Atan => f.atan(),
        UnOp::Trunc => f.trunc(),
        _ => return None,
    };
    // a REAL is computed in f32 by the VM: fold only what f64 rounds the same way
    if p == Prim::Real && !matches!(op, UnOp::Abs | UnOp::Trunc) {
        return None;
    }
    Some(Cv::Real(r))
}

/// Whether untyped literals of type `lit` (`IntLit`, `RealLit`) take the expected type `p`: a
/// number, or a bit string for integer literals (`b := SEL(g, 0, 255)` with a BYTE `b`).
fn literal_target(p: Prim, lit: &Ty) -> bool {
    p.is_num() || (p.is_bits() && *lit == Ty::IntLit)
}

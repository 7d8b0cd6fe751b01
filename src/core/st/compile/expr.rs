//! Expressions: names resolved, types checked and made explicit (implicit widenings become
//! conversion nodes), constants folded with the VM's wrapping rules, calls bound to their
//! parameters. The result is a typed tree the code generator walks.

use crate::lang::ops::CmpOp;
use crate::st::ast::{
    self, Arg, BinaryOp, Expr, ExprKind, Literal, PartSize, PouKind, RefKind, Span, UnaryOp,
    VarKind,
};
use crate::st::dialect::Habit;
use crate::value::{BinOp, UnOp};

use super::codesys;
use super::ctx::{suggest, Callee, Ctx, Cv, Scope, Storage, VarInfo};
use super::stdlib::Std;
use super::types::{fits, int_slot, real_slot, wrap, Prim, Ty};

/// A typed expression.
#[derive(Debug, Clone, PartialEq)]
pub struct TExpr {
    pub k: TK,
    pub ty: Ty,
    pub span: Span,
}

#[derive(Debug, Clone, PartialEq)]
pub enum TK {
    Const(Cv),
    /// A variable: where it is, and whether that place holds a pointer to it (VAR_IN_OUT).
    Var {
        storage: Storage,
        by_ref: bool,
    },
    /// A struct member or an FB instance's variable, at a byte offset; `by_ref` when that
    /// variable holds a pointer (an instance's VAR_IN_OUT).
    Member(Box<TExpr>, u32, bool),
    Index(Box<TExpr>, Vec<TExpr>),
    Bit(Box<TExpr>, u8),
    /// A part of a bit string (`dw.%B2`): the bits of the node's type starting at this bit of
    /// the operand (nested parts are one: `lw.%D1.%B0` starts at bit 32 of `lw`).
    Part(Box<TExpr>, u8),
    Un(UnOp, Box<TExpr>),
    /// Both operands of the node's type (comparisons excepted: [`TK::Cmp`]).
    Bin(BinOp, Box<TExpr>, Box<TExpr>),
    /// Operands of the same type; the node is a BOOL.
    Cmp(CmpOp, Box<TExpr>, Box<TExpr>),
    /// The operand converted to the node's type.
    Conv(Box<TExpr>),
    /// A user FUNCTION.
    Call(Box<CallT>),
    /// A standard function needing more than one op.
    Std(Std, Vec<TExpr>),
    /// What a reference refers to (`r^`, a `REFERENCE TO` used): a place reached through
    /// the reference value of the operand, checked at run time.
    Deref(Box<TExpr>),
    /// A reference to a place (`REF(v)`, `ADR(v)`, `REF=`).
    Ref(Box<TExpr>),
    /// A pointer moved by a number of bytes (a `LINT`): `p + n`, `p - n`.
    RefAdd(Box<TExpr>, Box<TExpr>),
    /// The distance in bytes between two pointers (a `DINT`): `p - q`.
    RefDiff(Box<TExpr>, Box<TExpr>),
    /// A standard function called with `EN` or `ENO`.
    Gate(Box<GateT>),
    /// An assignment inside an expression (CODESYS, `assign_expr`): the place written, and
    /// the value, of the place's type, which is the node's value too.
    Assign(Box<TExpr>, Box<TExpr>),
    /// `AND_THEN` (`false`) or `OR_ELSE` (`true`) of two BOOLs: when the left operand has this
    /// value it is the result and the right one is not evaluated.
    ShortCircuit(bool, Box<TExpr>, Box<TExpr>),
}

/// A standard function's call with `EN := en` and `ENO => …` (IEC 61131-3 ed3): when
/// `en` is FALSE, nothing of `value` runs, the node's value is its type's default and every
/// ENO target gets FALSE; when TRUE (or not given), each ENO target gets TRUE, then `value`
/// runs.
#[derive(Debug, Clone, PartialEq)]
pub struct GateT {
    pub en: Option<TExpr>,
    pub value: TExpr,
    /// `ENO => target` (`NOT ENO => target` when negated).
    pub eno: Vec<(TExpr, bool)>,
}

/// A call's bound arguments.
#[derive(Debug, Clone, PartialEq)]
pub struct CallT {
    pub pou: usize,
    /// Values of inputs (`by_ref`: VAR_IN_OUT, the argument is a place) at their offsets
    /// (the callee's frame for a FUNCTION, the instance for an FB).
    pub args: Vec<ArgT>,
    pub outs: Vec<OutT>,
    /// The implicit `EN := …` (the callee declares no EN): when FALSE, nothing of the call
    /// happens (no argument evaluated, no input assigned, no output read), ENO is FALSE.
    pub en: Option<Box<TExpr>>,
    /// A method call: the instance it runs on (`this`).
    pub this: Option<Box<TExpr>>,
    /// A method called through a place whose function block may be a derived one (or an
    /// interface): the bodies to choose from by the instance's type tag, in order; a `None`
    /// tag is the default (`oop`). Empty: `pou` is called.
    pub dispatch: Vec<(Option<u32>, usize)>,
}

#[derive(Debug, Clone, PartialEq)]
pub struct ArgT {
    pub offset: u32,
    pub ty: Ty,
    pub by_ref: bool,
    pub value: TExpr,
}

#[derive(Debug, Clone, PartialEq)]
pub struct OutT {
    pub offset: u32,
    /// The output's own type.
    pub ty: Ty,
    pub target: TExpr,
    pub negated: bool,
    /// `ENO => target`: given FALSE when an implicit EN is FALSE.
    pub eno: bool,
}

impl TExpr {
    pub fn error(span: Span) -> TExpr {
        TExpr { k: TK::Const(Cv::Int(0)), ty: Ty::Error, span }
    }

    pub fn konst(cv: Cv, ty: Ty, span: Span) -> TExpr {
        TExpr { k: TK::Const(cv), ty, span }
    }

    pub fn is_const(&self) -> bool {
        matches!(self.k, TK::Const(_))
    }

    pub fn const_int(&self) -> Option<i128> {
        match self.k {
            TK::Const(Cv::Int(v)) => Some(v),
            _ => None,
        }
    }

    /// Whether evaluating it calls a FUNCTION (whose frame area another call would reuse).
    pub fn has_call(&self) -> bool {
        match &self.k {
            TK::Const(_) | TK::Var { .. } => false,
            TK::Call(_) => true,
            TK::Member(a, _, _)
            | TK::Bit(a, _)
            | TK::Part(a, _)
            | TK::Un(_, a)
            | TK::Conv(a)
            | TK::Deref(a)
            | TK::Ref(a) => a.has_call(),
            TK::RefAdd(a, b) | TK::RefDiff(a, b) | TK::Assign(a, b) => a.has_call() || b.has_call(),
            TK::Index(a, ix) => a.has_call() || ix.iter().any(TExpr::has_call),
            TK::Bin(_, a, b) | TK::Cmp(_, a, b) | TK::ShortCircuit(_, a, b) => {
                a.has_call() || b.has_call()
            }
            TK::Std(_, args) => args.iter().any(TExpr::has_call),
            TK::Gate(g) => {
                g.en.as_ref().is_some_and(TExpr::has_call)
                    || g.value.has_call()
                    || g.eno.iter().any(|(t, _)| t.has_call())
            }
        }
    }

    /// Whether it names memory (a variable, a member, an element).
    pub fn is_place(&self) -> bool {
        matches!(self.k, TK::Var { .. } | TK::Index(..) | TK::Member(..) | TK::Deref(..))
    }
}

/// The slot of a constant as a value of `p`.
pub fn cv_slot(cv: &Cv, p: Prim) -> u64 {
    match cv {
        Cv::Int(v) if p.is_real() => real_slot(p, *v as f64),
        Cv::Int(v) => int_slot(p, *v),
        Cv::Real(f) if p.is_real() => real_slot(p, *f),
        Cv::Real(f) => int_slot(p, *f as i128),
        Cv::Str(_) | Cv::WStr(_) => 0,
    }
}

/// A conversion folded, with `crate::value::convert`'s rules.
pub fn fold_conv(cv: &Cv, from: Prim, to: Prim) -> Cv {
    let as_f64 = |cv: &Cv| match cv {
        Cv::Int(v) => *v as f64,
        Cv::Real(f) => *f,
        Cv::Str(_) | Cv::WStr(_) => 0.0,
    };
    if to == Prim::Bool {
        return Cv::Int(i128::from(as_f64(cv) != 0.0 || matches!(cv, Cv::Int(v) if *v != 0)));
    }
    if to.is_real() {
        // An integer goes to the nearest REAL in one rounding, as the VM converts (through an
        // LREAL, a 64-bit integer would be rounded twice).
        return Cv::Real(match (cv, to) {
            (Cv::Int(v), Prim::Real) => f64::from(*v as f32),
            (_, Prim::Real) => f64::from(as_f64(cv) as f32),
            _ => as_f64(cv),
        });
    }
    match cv {
        Cv::Int(v) => Cv::Int(wrap(to, *v)),
        Cv::Real(f) => {
            let _ = from;
            if f.is_nan() {
                return Cv::Int(0);
            }
            // Saturated in integers: the bounds of the 64-bit types are no LREALs (2^63 - 1
            // rounds up to 2^63), and a float cast to i128 saturates at i128's range.
            let (lo, hi) = to.range().expect("integer");
            Cv::Int((f.round() as i128).clamp(lo, hi))
        }
        Cv::Str(_) | Cv::WStr(_) => Cv::Int(0),
    }
}

/// A binary operation folded with the VM's rules (wrapping, truncating division); `None` on a
/// division by zero.
pub fn fold_bin(op: BinOp, p: Option<Prim>, a: &Cv, b: &Cv) -> Option<Cv> {
    match (a, b) {
        (Cv::Int(x), Cv::Int(y)) if !p.is_some_and(Prim::is_real) => {
            let (x, y) = (*x, *y);
            let r = match op {
                BinOp::Add => x.checked_add(y)?,
                BinOp::Sub => x.checked_sub(y)?,
                BinOp::Mul => x.checked_mul(y)?,
                BinOp::Div => x.checked_div(y)?,
                BinOp::Mod => x.checked_rem(y)?,
                BinOp::And => x & y,
                BinOp::Or => x | y,
                BinOp::Xor => x ^ y,
                BinOp::Min => x.min(y),
                BinOp::Max => x.max(y),
                BinOp::Shl | BinOp::Shr | BinOp::Rol | BinOp::Ror => {
                    let p = p?;
                    let bits = p.bits() as i128;
                    let mask = (1u128 << bits) - 1;
                    let ux = (x as u128) & mask;
                    let n = y.max(0);
                    let r = match op {
                        BinOp::Shl if n >= bits => 0,
                        BinOp::Shr if n >= bits => 0,
                        BinOp::Shl => (ux << n) & mask,
                        BinOp::Shr => ux >> n,
                        BinOp::Rol => {
                            let n = n % bits;
                            ((ux << n) | (ux >> ((bits - n) % bits))) & mask
                        }
                        _ => {
                            let n = n % bits;
                            ((ux >> n) | (ux << ((bits - n) % bits))) & mask
                        }
                    };
                    r as i128
                }
                BinOp::Expt => return None,
            };
            Some(Cv::Int(match p {
                Some(p) => wrap(p, r),
                None => r,
            }))
        }
        _ => {
            let f = |c: &Cv| match c {
                Cv::Int(v) => *v as f64,
                Cv::Real(f) => *f,
                Cv::Str(_) | Cv::WStr(_) => 0.0,
            };
            let (x, y) = (f(a), f(b));
            let r = match op {
                BinOp::Add => x + y,
                BinOp::Sub => x - y,
                BinOp::Mul => x * y,
                BinOp::Div if y == 0.0 => return None,
                BinOp::Div => x / y,
                BinOp::Expt => x.powf(y),
                BinOp::Min => x.min(y),
                BinOp::Max => x.max(y),
                _ => return None,
            };
            Some(Cv::Real(if p == Some(Prim::Real) { f64::from(r as f32) } else { r }))
        }
    }
}

fn fold_cmp(op: CmpOp, a: &Cv, b: &Cv) -> Option<bool> {
    use std::cmp::Ordering;
    let ord = match (a, b) {
        (Cv::Int(x), Cv::Int(y)) => Some(x.cmp(y)),
        (Cv::Str(x), Cv::Str(y)) => Some(x.cmp(y)),
        (Cv::WStr(x), Cv::WStr(y)) => Some(x.cmp(y)),
        (Cv::Real(x), Cv::Real(y)) => x.partial_cmp(y),
        (Cv::Int(x), Cv::Real(y)) => (*x as f64).partial_cmp(y),
        (Cv::Real(x), Cv::Int(y)) => x.partial_cmp(&(*y as f64)),
        _ => return None,
    };
    Some(match ord {
        None => op == CmpOp::Ne,
        Some(Ordering::Less) => matches!(op, CmpOp::Lt | CmpOp::Le | CmpOp::Ne),
        Some(Ordering::Equal) => matches!(op, CmpOp::Eq | CmpOp::Le | CmpOp::Ge),
        Some(Ordering::Greater) => matches!(op, CmpOp::Gt | CmpOp::Ge | CmpOp::Ne),
    })
}

pub fn op_text(op: BinaryOp) -> &'static str {
    match op {
        BinaryOp::Or => "OR",
        BinaryOp::OrElse => "OR_ELSE",
        BinaryOp::AndThen => "AND_THEN",
        BinaryOp::Xor => "XOR",
        BinaryOp::And => "AND",
        BinaryOp::Eq => "=",
        BinaryOp::Ne => "<>",
        BinaryOp::Lt => "<",
        BinaryOp::Le => "<=",
        BinaryOp::Gt => ">",
        BinaryOp::Ge => ">=",
        BinaryOp::Add => "+",
        BinaryOp::Sub => "-",
        BinaryOp::Mul => "*",
        BinaryOp::Div => "/",
        BinaryOp::Mod => "MOD",
        BinaryOp::Pow => "**",
    }
}

/// How a place is used.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Access {
    Read,
    /// Assigned (`:=`, `=>`, a FOR variable).
    Write,
    /// Passed to a VAR_IN_OUT: read and written.
    Ref,
}

impl<'a> Ctx<'a> {
    /// Checks an expression; `expected` guides untyped literals and ambiguous enumeration
    /// values (the result may still need [`Ctx::coerce`]).
    pub fn check_expr(&mut self, e: &Expr, scope: Scope, expected: Option<&Ty>) -> TExpr {
        let span = e.span;
        let file = scope.file;
        match &e.kind {
            ExprKind::Literal(lit) => self.literal(lit, span, scope, expected),
            ExprKind::Name(_)
            | ExprKind::Member(..)
            | ExprKind::Index(..)
            | ExprKind::Bit(..)
            | ExprKind::Part(..)
            | ExprKind::Deref(..) => self.check_place(e, scope, Access::Read, expected),
            ExprKind::Unary(op, a) => {
                let a = self.check_expr(a, scope, expected);
                self.unary(*op, a, span, file)
            }
            ExprKind::Binary(op, a, b) => {
                let (ea, eb) = match op {
                    BinaryOp::Eq
                    | BinaryOp::Ne
                    | BinaryOp::Lt
                    | BinaryOp::Le
                    | BinaryOp::Gt
                    | BinaryOp::Ge => (None, None),
                    _ => (expected, expected),
                };
                let ta = self.check_expr(a, scope, ea);
                let hint = if matches!(ta.ty, Ty::IntLit | Ty::RealLit | Ty::Error) {
                    eb
                } else {
                    Some(&ta.ty)
                };
                let hint = hint.cloned();
                let tb = self.check_expr(b, scope, hint.as_ref());
                let ta = if matches!(ta.ty, Ty::IntLit | Ty::RealLit)
                    && !matches!(tb.ty, Ty::IntLit | Ty::RealLit)
                {
                    // an enumeration value on the left guessed without context: nothing to redo
                    ta
                } else {
                    ta
                };
                self.binary_op(*op, ta, tb, span, file)
            }
            ExprKind::Call { callee, args } => {
                self.check_call_expr(callee, args, span, scope, expected)
            }
            ExprKind::Assign(target, value) => self.check_assign_expr(target, value, span, scope),
        }
    }

    /// An expression given whole to a value of `ty` (assigned to it, its initial value, the
    /// value of a typed literal): as [`Ctx::check_expr`] with `ty` expected, except that a
    /// based literal given to a signed integer type may be the bit pattern of its width
    /// (`x := 16#FFFF` for an INT is -1, `INT#16#FFFF` too, as in CODESYS). Only given whole:
    /// inside an expression a literal takes the type of its own operation.
    pub fn check_given(&mut self, e: &Expr, scope: Scope, ty: &Ty) -> TExpr {
        if let ExprKind::Literal(Literal::Based(v)) = &e.kind {
            let signed = ty.prim(&self.types).filter(|p| p.is_int() && p.elem().is_signed());
            if let Some(p) = signed.filter(|_| !matches!(ty, Ty::Enum(_))) {
                let (v, width) = (*v as i128, 1i128 << p.bits());
                let max = p.range().map_or(i128::MAX, |(_, hi)| hi);
                if v > max && v < width {
                    return TExpr::konst(Cv::Int(v - width), Ty::IntLit, e.span);
                }
            }
        }
        self.check_expr(e, scope, Some(ty))
    }

    pub(super) fn literal(
        &mut self,
        lit: &Literal,
        span: Span,
        scope: Scope,
        expected: Option<&Ty>,
    ) -> TExpr {
        let file = scope.file;
        match lit {
            Literal::Int(v) => {
                let v = *v as i128;
                TExpr::konst(Cv::Int(v), Ty::IntLit, span)
            }
            Literal::Based(v) => TExpr::konst(Cv::Int(*v as i128), Ty::IntLit, span),
            Literal::Real(f) => TExpr::konst(Cv::Real(*f), Ty::RealLit, span),
            Literal::Bool(b) => TExpr::konst(Cv::Int(i128::from(*b)), Ty::Prim(Prim::Bool), span),
            Literal::Time(ns) => {
                let p = match expected.and_then(|t| t.prim(&self.types)) {
                    Some(Prim::LTime) => Prim::LTime,
                    _ => Prim::Time,
                };
                let mut ns = *ns;
                if !fits(Prim::LInt, ns) {
                    if !fits(Prim::ULInt, ns) {
                        self.error(file, span, "the duration does not fit `TIME`");
                        return TExpr::error(span);
                    }
                    // CODESYS's and TwinCAT's LTIME is unsigned: its 64 bits (TcUnit's tests
                    // write the maximum), which plcd's signed LTIME reads as negative.
                    self.habit(Habit::UnsignedLtime, file, span);
                    ns -= 1 << 64;
                }
                TExpr::konst(Cv::Int(ns), Ty::Prim(p), span)
            }
            Literal::Calendar(cal, count) => {
                TExpr::konst(Cv::Int(i128::from(*count)), Ty::Prim(Prim::Cal(*cal)), span)
            }
            Literal::String(s) => {
                // one byte a character: Windows-1252, as CODESYS and TwinCAT store STRING
                let bytes = match crate::value::encode_str(s) {
                    Ok(bytes) => bytes,
                    Err(c) => {
                        let msg = format!("`{c}` is not a character of STRING: a STRING holds the characters of Windows-1252");
                        self.error(file, span, msg);
                        return TExpr::error(span);
                    }
                };
                if bytes.len() > 255 {
                    self.error(file, span, "a string constant is at most 255 characters");
                    return TExpr::error(span);
                }
                let n = bytes.len().max(1) as u32;
                TExpr::konst(Cv::Str(bytes), Ty::Str(n), span)
            }
            Literal::WString(s) => {
                // UTF-16 code units, as CODESYS and TwinCAT store WSTRING
                let units: Vec<u16> = s.encode_utf16().collect();
                if units.len() > 255 {
                    self.error(file, span, "a string constant is at most 255 characters");
                    return TExpr::error(span);
                }
                let n = units.len().max(1) as u32;
                TExpr::konst(Cv::WStr(units), Ty::WStr(n), span)
            }
            Literal::Typed { ty, value } => {
                if let Some(p) = Prim::from_name(&ty.name) {
                    let inner = self.check_given(value, scope, &Ty::Prim(p));
                    if p == Prim::Bool {
                        if let Some(v @ (0 | 1)) =
                            inner.const_int().filter(|_| inner.ty == Ty::IntLit)
                        {
                            return TExpr::konst(Cv::Int(v), Ty::Prim(Prim::Bool), span);
                        }
                    }
                    return self.coerce(inner, &Ty::Prim(p), file);
                }
                if ty.is("STRING") {
                    let inner = self.check_expr(value, scope, None);
                    return inner;
                }
                if ty.is("WSTRING") {
                    // `WSTRING#'…'`: the characters of a single-quoted literal as a WSTRING's
                    let inner = self.check_expr(value, scope, None);
                    return match &inner.k {
                        TK::Const(Cv::Str(bytes)) => {
                            let units: Vec<u16> = bytes
                                .iter()
                                .map(|&b| crate::value::decode_byte(b) as u32 as u16)
                                .collect();
                            let n = units.len().max(1) as u32;
                            TExpr::konst(Cv::WStr(units), Ty::WStr(n), span)
                        }
                        _ => inner,
                    };
                }
                // `Color#Red`
                let Some(&t) = self.type_names.get(&ty.name.to_ascii_lowercase()) else {
                    self.error(file, ty.span, format!("unknown type `{}`", ty.name));
                    return TExpr::error(span);
                };
                let enum_ty = self.resolve_type_decl(t);
                let Ty::Enum(ei) = enum_ty else {
                    let inner = self.check_expr(value, scope, Some(&enum_ty));
                    return self.coerce(inner, &enum_ty, file);
                };
                let ExprKind::Name(id) = &value.kind else {
                    self.error(file, value.span, format!("`{}#` needs a value name", ty.name));
                    return TExpr::error(span);
                };
                let en = &self.types.enums[ei];
                match en.values.iter().find(|(n, _)| id.is(n)) {
                    Some((_, v)) => TExpr::konst(Cv::Int(*v), Ty::Enum(ei), span),
                    None => {
                        let hint = suggest(&id.name, en.values.iter().map(|v| v.0.as_str()));
                        let n = en.name.clone();
                        self.error(
                            file,
                            id.span,
                            format!("`{n}` has no value `{}`{hint}", id.name),
                        );
                        TExpr::error(span)
                    }
                }
            }
        }
    }

    /// A name, member, element or bit, as a value or as a place to write.
    pub fn check_place(
        &mut self,
        e: &Expr,
        scope: Scope,
        access: Access,
        expected: Option<&Ty>,
    ) -> TExpr {
        // a `REFERENCE TO` (a variable, a member, an element) stands for what it refers to
        let te = self.check_place_whole(e, scope, access, expected);
        self.refuse_struct_on_devices(te, e, scope.file)
    }

    /// [`Ctx::check_place`], a struct some of whose members are at devices accepted: the base
    /// of a member access.
    fn check_place_whole(
        &mut self,
        e: &Expr,
        scope: Scope,
        access: Access,
        expected: Option<&Ty>,
    ) -> TExpr {
        let te = self.check_place_itself(e, scope, access, expected);
        let te = self.auto_deref(te);
        if access == Access::Ref {
            self.refuse_open_string_in_out(&te, scope.file);
        }
        te
    }

    /// Refuses a struct variable used whole (assigned, compared, passed, its address or size
    /// taken) when a binding placed some of its members at devices: its bytes in memory do not
    /// hold those members, so no whole use of it would be right.
    fn refuse_struct_on_devices(&mut self, te: TExpr, e: &Expr, file: usize) -> TExpr {
        let Ty::Struct(s) = te.ty else { return te };
        let Some(name) = self.member_on_device(s) else { return te };
        let span = te.span;
        let msg = format!(
            "`{}.{name}` is bound to a device (VAR_CONFIG, [iec.variables]): `{}` can be used \
             only member by member",
            expr_text(e),
            expr_text(e)
        );
        self.error(file, span, msg);
        TExpr::error(span)
    }

    /// The path from a value of the struct `s` to a member of it a binding placed at a device:
    /// one of its own (`IN`), or of a struct member at any depth (`axis.hw.IN`, a member of a
    /// member bound).
    fn member_on_device(&self, s: usize) -> Option<String> {
        self.types.structs[s].members.iter().find_map(|m| match m.ty {
            _ if m.device.is_some() => Some(m.name.clone()),
            Ty::Struct(inner) => self.member_on_device(inner).map(|p| format!("{}.{p}", m.name)),
            _ => None,
        })
    }

    /// [`Ctx::check_place`], a `REFERENCE TO` as itself.
    fn check_place_itself(
        &mut self,
        e: &Expr,
        scope: Scope,
        access: Access,
        expected: Option<&Ty>,
    ) -> TExpr {
        let span = e.span;
        let file = scope.file;
        match &e.kind {
            ExprKind::Name(id) => self.name(id, scope, access, expected),
            ExprKind::Deref(base) => {
                if let Some(t) = self.this_place(base, span, scope) {
                    return t;
                }
                let b = self.check_place(base, scope, Access::Read, None);
                self.deref(b, span, &expr_text(base), file)
            }
            ExprKind::Member(base, id) => {
                if access == Access::Read {
                    if let Some(v) = self.system_type_class(e, span, file) {
                        return v;
                    }
                    if let Some(v) = self.dotted_enum_value(base, id, span, scope, expected) {
                        return v;
                    }
                }
                let b = self.check_place_whole(
                    base,
                    scope,
                    if access == Access::Read { Access::Read } else { Access::Ref },
                    None,
                );
                match b.ty.clone() {
                    Ty::Error => TExpr::error(span),
                    Ty::Iface(i) => self.interface_property(b, i, id, access, scope),
                    // a member a binding placed at a device (`fb_config.rs`): the device, as
                    // a located variable (the struct is one variable's, `b` has no effects)
                    Ty::Struct(s)
                        if self.types.structs[s]
                            .members
                            .iter()
                            .any(|m| id.is(&m.name) && m.device.is_some()) =>
                    {
                        let st = &self.types.structs[s];
                        let m = st.members.iter().find(|m| id.is(&m.name)).expect("found");
                        let storage = m.device.expect("a device");
                        TExpr { k: TK::Var { storage, by_ref: false }, ty: m.ty.clone(), span }
                    }
                    Ty::Struct(s) => {
                        let st = &self.types.structs[s];
                        match st.members.iter().find(|m| id.is(&m.name)) {
                            Some(m) => {
                                let (ty, off) = (m.ty.clone(), m.offset);
                                TExpr { k: TK::Member(Box::new(b), off, false), ty, span }
                            }
                            None => {
                                let hint =
                                    suggest(&id.name, st.members.iter().map(|m| m.name.as_str()));
                                let n = st.name.clone();
                                self.error(
                                    file,
                                    id.span,
                                    format!("`{n}` has no member `{}`{hint}", id.name),
                                );
                                TExpr::error(span)
                            }
                        }
                    }
                    Ty::Fb(p) => {
                        if self.pous[p].lookup(&id.name).is_none() {
                            if let Some(t) = self.property_read(&b, p, id, access, scope) {
                                return t;
                            }
                        }
                        let pou = &self.pous[p];
                        let Some(v) = pou.lookup(&id.name).map(|i| pou.vars[i].clone()) else {
                            let names: Vec<&str> = pou
                                .vars
                                .iter()
                                .filter(|v| matches!(v.kind, VarKind::Input | VarKind::Output))
                                .map(|v| v.name.as_str())
                                .collect();
                            let hint = suggest(&id.name, names);
                            let n = pou.name.clone();
                            self.error(
                                file,
                                id.span,
                                format!("`{n}` has no input or output `{}`{hint}", id.name),
                            );
                            return TExpr::error(span);
                        };
                        let n = pou.name.clone();
                        if let (VarKind::InOut, Storage::Inst(off)) = (v.kind, v.storage) {
                            let own = super::oop::is_own_instance(base);
                            return self.instance_in_out(
                                b, base, &v, off, id, access, own, &n, file, span,
                            );
                        }
                        // a variable of a block's copy that VAR_CONFIG binds to a device
                        // (`fb_config.rs`): the device, whatever the instance
                        let located = matches!(
                            v.storage,
                            Storage::Bit(_) | Storage::Word(_) | Storage::Byte(_)
                        );
                        let off = match v.storage {
                            Storage::Inst(off) => off,
                            _ if located => 0,
                            _ => {
                                self.not_an_input_or_output(file, id, &n);
                                return TExpr::error(span);
                            }
                        };
                        match (v.kind, access) {
                            // `THIS^.x`, `SUPER^.x`: the block's own variable, as `x`
                            _ if super::oop::is_own_instance(base) => {}
                            (VarKind::Input | VarKind::Output, Access::Read)
                            | (VarKind::Input, _) => {}
                            // CODESYS reads an instance's own variables from outside
                            (
                                VarKind::Local | VarKind::Instance | VarKind::Static,
                                Access::Read,
                            ) => {
                                self.habit(Habit::ReadFbInternal, file, id.span);
                            }
                            (VarKind::Output, _) => {
                                self.error(
                                    file,
                                    id.span,
                                    format!(
                                        "`{}` is a VAR_OUTPUT of `{n}`: it cannot be written here",
                                        id.name
                                    ),
                                );
                                return TExpr::error(span);
                            }
                            _ => {
                                self.not_an_input_or_output(file, id, &n);
                                return TExpr::error(span);
                            }
                        }
                        if located {
                            let k = TK::Var { storage: v.storage, by_ref: false };
                            return TExpr { k, ty: v.ty, span };
                        }
                        TExpr { k: TK::Member(Box::new(b), off, false), ty: v.ty, span }
                    }
                    other => {
                        let n = self.ty_name(&other);
                        self.error(
                            file,
                            id.span,
                            format!("`{n}` has no members (looking for `{}`)", id.name),
                        );
                        TExpr::error(span)
                    }
                }
            }
            ExprKind::Index(base, idx) => {
                let b = self.check_place(
                    base,
                    scope,
                    if access == Access::Read { Access::Read } else { Access::Ref },
                    None,
                );
                let mut ix = Vec::new();
                for i in idx {
                    let t = self.check_expr(i, scope, Some(&Ty::Prim(Prim::DInt)));
                    let t = match &t.ty {
                        Ty::IntLit => self.coerce(t, &Ty::Prim(Prim::DInt), file),
                        Ty::Error => t,
                        ty if ty.prim(&self.types).is_some_and(Prim::is_integral)
                            && !matches!(ty, Ty::Enum(_)) =>
                        {
                            t
                        }
                        ty => {
                            let n = self.ty_name(ty);
                            self.error(
                                file,
                                i.span,
                                format!("an array index must be an integer, not `{n}`"),
                            );
                            TExpr::error(i.span)
                        }
                    };
                    ix.push(t);
                }
                match b.ty.clone() {
                    Ty::Error => TExpr::error(span),
                    Ty::Array(a) => {
                        if a.dims.len() != ix.len() {
                            let name = expr_text(base);
                            self.error(
                                file,
                                span,
                                format!(
                                    "`{name}` has {} dimension(s), {} index(es) given",
                                    a.dims.len(),
                                    ix.len()
                                ),
                            );
                            return TExpr::error(span);
                        }
                        for (t, (lo, hi)) in ix.iter().zip(&a.dims) {
                            if let Some(v) = t.const_int() {
                                if v < i128::from(*lo) || v > i128::from(*hi) {
                                    self.error(
                                        file,
                                        t.span,
                                        format!("index {v} is out of the bounds `{lo}..{hi}`"),
                                    );
                                }
                            }
                        }
                        TExpr { k: TK::Index(Box::new(b), ix), ty: a.of.clone(), span }
                    }
                    Ty::OpenArray(a) => {
                        self.open_array_element(b, ix, &a, &expr_text(base), span, file)
                    }
                    Ty::Ref(RefKind::Pointer, _) => {
                        self.pointer_element(b, ix, span, &expr_text(base), file)
                    }
                    other => {
                        let n = self.ty_name(&other);
                        let name = expr_text(base);
                        self.error(file, span, format!("`{name}` is `{n}`, not an array"));
                        TExpr::error(span)
                    }
                }
            }
            ExprKind::Bit(base, n) => {
                if access == Access::Ref {
                    self.error(file, span, "a bit of a variable cannot be passed to a VAR_IN_OUT");
                    return TExpr::error(span);
                }
                let b = self.check_place(base, scope, access, None);
                if b.ty.is_error() {
                    return b;
                }
                match b.ty.prim(&self.types) {
                    Some(p) if p.is_integral() && !matches!(b.ty, Ty::Enum(_)) => {
                        if u32::from(*n) >= p.bits() {
                            self.error(file, span, format!("`{}` has no bit {n}", p.name()));
                            return TExpr::error(span);
                        }
                        if let TK::Const(Cv::Int(v)) = b.k {
                            let bit = (v as u128 >> n) & 1;
                            return TExpr::konst(Cv::Int(bit as i128), Ty::Prim(Prim::Bool), span);
                        }
                        // a bit of a part is a bit of the whole (`dw.%B1.3` is `dw.11`)
                        let (b, n) = match b.k {
                            TK::Part(whole, start) => (*whole, start + n),
                            _ => (b, *n),
                        };
                        TExpr { k: TK::Bit(Box::new(b), n), ty: Ty::Prim(Prim::Bool), span }
                    }
                    _ => {
                        let t = self.ty_name(&b.ty);
                        self.error(
                            file,
                            span,
                            format!("bit access needs an integer or bit string, not `{t}`"),
                        );
                        TExpr::error(span)
                    }
                }
            }
            ExprKind::Part(base, size, n) => self.check_part(base, *size, *n, span, scope, access),
            _ => match access {
                Access::Read => self.check_expr(e, scope, expected),
                Access::Write => {
                    self.error(file, span, "only a variable can be assigned");
                    TExpr::error(span)
                }
                Access::Ref => {
                    self.error(file, span, "a VAR_IN_OUT argument must be a variable");
                    TExpr::error(span)
                }
            },
        }
    }

    /// A part of a bit string, `base.%B<n>` (`%W`, `%D`): BYTE, WORD or DWORD by its size, of
    /// a variable (element, member, what a reference points to) of a wider bit string type.
    fn check_part(
        &mut self,
        base: &Expr,
        size: PartSize,
        n: u8,
        span: Span,
        scope: Scope,
        access: Access,
    ) -> TExpr {
        let file = scope.file;
        let access_text = format!(".%{}", size.letter());
        if access == Access::Ref {
            self.error(file, span, "a part of a variable cannot be passed to a VAR_IN_OUT");
            return TExpr::error(span);
        }
        if !matches!(
            base.kind,
            ExprKind::Name(_)
                | ExprKind::Member(..)
                | ExprKind::Index(..)
                | ExprKind::Deref(..)
                | ExprKind::Part(..)
        ) {
            self.error(file, span, format!("partial access `{access_text}` needs a variable"));
            return TExpr::error(span);
        }
        let b = self.check_place(base, scope, access, None);
        if b.ty.is_error() {
            return b;
        }
        let whole = match b.ty.prim(&self.types) {
            Some(p) if p.is_bits() && !matches!(b.ty, Ty::Enum(_)) => p,
            _ => {
                let t = self.ty_name(&b.ty);
                self.error(
                    file,
                    span,
                    format!(
                        "partial access `{access_text}` needs a BYTE, WORD, DWORD or LWORD, \
                         not `{t}`"
                    ),
                );
                return TExpr::error(span);
            }
        };
        let (part, unit) = match size {
            PartSize::Byte => (Prim::Byte, "byte"),
            PartSize::Word => (Prim::Word, "word"),
            PartSize::DWord => (Prim::DWord, "double word"),
            PartSize::LWord => (Prim::LWord, "long word"),
        };
        if size.bits() >= whole.bits() {
            self.error(
                file,
                span,
                format!(
                    "`{}` has no {unit} part: it is not wider than a `{}`",
                    whole.name(),
                    part.name()
                ),
            );
            return TExpr::error(span);
        }
        let count = whole.bits() / size.bits();
        if u32::from(n) >= count {
            self.error(
                file,
                span,
                format!(
                    "`{}` has no {unit} {n}: its {unit}s are `{access_text}0` to `{access_text}{}`",
                    whole.name(),
                    count - 1
                ),
            );
            return TExpr::error(span);
        }
        // below 64: n < count keeps the part inside the whole
        let start = n * size.bits() as u8;
        let ty = Ty::Prim(part);
        if let TK::Const(Cv::Int(v)) = b.k {
            let bits = (v as u128 >> start) & ((1u128 << size.bits()) - 1);
            return TExpr::konst(Cv::Int(bits as i128), ty, span);
        }
        // a part of a part is a part of the whole (`lw.%D1.%B0` starts at bit 32 of `lw`)
        let (b, start) = match b.k {
            TK::Part(whole, outer) => (*whole, outer + start),
            _ => (b, start),
        };
        TExpr { k: TK::Part(Box::new(b), start), ty, span }
    }

    /// Whether the variable `v` (a local or a global) that `id` names may be written (or
    /// passed to a VAR_IN_OUT) here: not CONSTANT, not at a device a program cannot write, not
    /// the variable of an enclosing FOR loop. Reports why not.
    fn may_write(&mut self, v: &VarInfo, id: &ast::Ident, access: Access, file: usize) -> bool {
        let span = id.span;
        if v.constant {
            self.error(file, span, format!("`{}` is CONSTANT: it cannot be written", v.name));
            return false;
        }
        if let Some(a) = v.located {
            if !self.writable(&a, &v.ty) {
                let msg = format!("`{}` is at `{a}`, which a program cannot write", v.name);
                self.error(file, span, msg);
                return false;
            }
        }
        if access == Access::Write {
            // CODESYS goes on from the value written (`for_written`)
            if let Some(k) = self.for_vars.iter().rposition(|f| id.is(f)) {
                self.for_variable_written(k, &v.name, file, span);
            }
        }
        true
    }

    /// The global `g`, named `id`: its value when it is a constant read, else the variable.
    pub(super) fn global_var(
        &mut self,
        g: usize,
        id: &ast::Ident,
        access: Access,
        file: usize,
    ) -> TExpr {
        let span = id.span;
        let v = self.globals[g].clone();
        if access != Access::Read {
            if !self.may_write(&v, id, access, file) {
                return TExpr::error(span);
            }
        } else if let (true, Some(cv)) = (v.constant, &v.value) {
            return TExpr::konst(cv.clone(), v.ty.clone(), span);
        }
        TExpr { k: TK::Var { storage: v.storage, by_ref: false }, ty: v.ty, span }
    }

    fn name(
        &mut self,
        id: &ast::Ident,
        scope: Scope,
        access: Access,
        expected: Option<&Ty>,
    ) -> TExpr {
        let span = id.span;
        let file = scope.file;
        if id.name.starts_with('.') {
            return self.global_scope_operator(id, scope, access);
        }
        if let Some(p) = scope.pou {
            let pou = &self.pous[p];
            if let Some(i) = pou.lookup(&id.name).filter(|&i| i < scope.visible) {
                let v = pou.vars[i].clone();
                if access != Access::Read {
                    // A POU may write its own inputs (IEC: they are its local copies).
                    if !self.may_write(&v, id, access, file) {
                        return TExpr::error(span);
                    }
                } else if let (true, Some(cv)) = (v.constant, &v.value) {
                    return TExpr::konst(cv.clone(), v.ty.clone(), span);
                }
                if access != Access::Read && self.pous[p].eno == Some(i) {
                    self.pous[p].eno_assigned = true;
                }
                // An edge input reads, in its body, the edge computed at the call's entry.
                let storage = match v.edge_value {
                    Some(at) => Storage::Inst(at),
                    None => v.storage,
                };
                return TExpr { k: TK::Var { storage, by_ref: v.by_ref }, ty: v.ty, span };
            }
            if pou.kind == PouKind::Function
                && super::libraries::is_own_name(id, &pou.ast.name.name)
                && scope.visible == pou.vars.len()
            {
                let ty = pou.result.clone();
                if ty == Ty::Void {
                    self.error(file, span, format!("`{}` has no result type", pou.name));
                    return TExpr::error(span);
                }
                return TExpr {
                    k: TK::Var { storage: Storage::Frame(0), by_ref: false },
                    ty,
                    span,
                };
            }
        }
        if let Some(&g) = self.global_names.get(&id.name.to_ascii_lowercase()) {
            return self.global_var(g, id, access, file);
        }
        if let Some(t) = self.own_member(id, access, scope) {
            return t;
        }
        if id.is("NULL") && access == Access::Read {
            return TExpr::konst(Cv::Int(0), Ty::Null, span);
        }
        if let Some(cands) = self.enum_values.get(&id.name.to_ascii_lowercase()).cloned() {
            if access != Access::Read {
                self.error(file, span, "only a variable can be assigned");
                return TExpr::error(span);
            }
            let pick = if cands.len() == 1 {
                Some(cands[0])
            } else {
                match expected {
                    Some(Ty::Enum(e)) => cands.iter().find(|c| c.0 == *e).copied(),
                    _ => None,
                }
            };
            return match pick {
                Some((e, v)) => TExpr::konst(Cv::Int(v), Ty::Enum(e), span),
                None => {
                    let names: Vec<String> =
                        cands.iter().map(|c| format!("`{}`", self.types.enums[c.0].name)).collect();
                    self.error(
                        file,
                        span,
                        format!(
                            "`{}` is ambiguous: a value of {} (write `{}#{}`)",
                            id.name,
                            names.join(" and "),
                            self.types.enums[cands[0].0].name,
                            id.name
                        ),
                    );
                    TExpr::error(span)
                }
            };
        }
        if let Some(&p) = self.pou_names.get(&id.name.to_ascii_lowercase()) {
            let kind = match self.pous[p].kind {
                PouKind::Function => "a FUNCTION: call it with `(…)`",
                PouKind::FunctionBlock => "a FUNCTION_BLOCK type, not a variable",
                PouKind::Program => "a PROGRAM, not a variable",
            };
            self.error(file, span, format!("`{}` is {kind}", id.name));
            return TExpr::error(span);
        }
        let names = self.names_in(scope);
        let hint = suggest(&id.name, names.iter().map(String::as_str));
        self.error(file, span, format!("`{}` is not declared{hint}", id.name));
        TExpr::error(span)
    }

    /// `te` as a value of `to`: an implicit widening, a literal typed, or an error.
    pub fn coerce(&mut self, te: TExpr, to: &Ty, file: usize) -> TExpr {
        let span = te.span;
        if te.ty.is_error() || to.is_error() {
            return TExpr { ty: to.clone(), ..te };
        }
        if matches!(to, Ty::OpenArray(_)) || matches!(te.ty, Ty::OpenArray(_)) {
            return self.open_array_whole(span, file);
        }
        // a TRUNC typed by its use (`trunc`)
        let te = self.trunc_by_use(te, to);
        if &te.ty == to {
            return te;
        }
        if let Some(number) = self.integer_as_type_class(&te, to, file) {
            return number;
        }
        if matches!(to, Ty::Iface(_)) || matches!(te.ty, Ty::Iface(_)) {
            return self.as_interface(te, to, file);
        }
        if matches!(te.ty, Ty::Ref(..) | Ty::Null) || matches!(to, Ty::Ref(..)) {
            let te = self.zero_as_null(te, to);
            if self.ref_assignable(&te.ty, to) {
                return TExpr { ty: to.clone(), ..te };
            }
            // CODESYS: a POINTER TO as a 64-bit number and back (its value is plcd's area
            // and offset; every access through it stays checked)
            if self.pointer_integer(&te.ty, to) {
                self.habit(Habit::PointerInteger, file, span);
                return TExpr { ty: to.clone(), ..te };
            }
            return self.mismatch(te, to, file);
        }
        match (&te.ty, to) {
            // `'a'` where a CHAR is expected, `"ä"` where a WCHAR is: the character's code
            (Ty::Str(_), Ty::Prim(Prim::Char)) | (Ty::WStr(_), Ty::Prim(Prim::WChar)) => {
                let code = match &te.k {
                    TK::Const(Cv::Str(s)) if s.len() == 1 => Some(i128::from(s[0])),
                    TK::Const(Cv::WStr(s)) if s.len() == 1 => Some(i128::from(s[0])),
                    _ => None,
                };
                match code {
                    Some(code) => TExpr::konst(Cv::Int(code), to.clone(), span),
                    None if matches!(te.k, TK::Const(_)) => {
                        let n = self.ty_name(to);
                        self.error(file, span, format!("a `{n}` literal is one character"));
                        TExpr::error(span)
                    }
                    None => self.mismatch(te, to, file),
                }
            }
            (Ty::IntLit, _) => {
                let v = te.const_int().unwrap_or(0);
                match to {
                    Ty::Sub(_, lo, hi) => {
                        if v < *lo || v > *hi {
                            let n = self.ty_name(to);
                            self.error(file, span, format!("constant `{v}` is outside `{n}`"));
                            return TExpr::error(span);
                        }
                        TExpr::konst(Cv::Int(v), to.clone(), span)
                    }
                    Ty::Prim(p) if p.is_integral() => {
                        if !fits(*p, v) {
                            self.error(
                                file,
                                span,
                                format!("constant `{v}` does not fit `{}`", p.name()),
                            );
                            return TExpr::error(span);
                        }
                        TExpr::konst(Cv::Int(v), to.clone(), span)
                    }
                    Ty::Prim(p) if p.is_real() => {
                        TExpr::konst(fold_conv(&Cv::Int(v), Prim::LInt, *p), to.clone(), span)
                    }
                    // IEC's BOOL literals `0` and `1` (`BOOL#0`, `BOOL#1` without the prefix)
                    Ty::Prim(Prim::Bool) if v == 0 || v == 1 => {
                        TExpr::konst(Cv::Int(v), to.clone(), span)
                    }
                    _ => self.mismatch(te, to, file),
                }
            }
            (Ty::RealLit, Ty::Prim(p)) if p.is_real() => {
                let TK::Const(cv) = &te.k else { unreachable!() };
                TExpr::konst(fold_conv(cv, Prim::LReal, *p), to.clone(), span)
            }
            // a UNION's overlapped string keeps its own capacity, which bounds its read (union.rs)
            (Ty::Str(_), Ty::Str(_)) | (Ty::WStr(_), Ty::WStr(_))
                if self.open_union_string(&te).is_some() =>
            {
                TExpr { k: TK::Conv(Box::new(te)), ty: to.clone(), span }
            }
            (Ty::Str(_), Ty::Str(_)) | (Ty::WStr(_), Ty::WStr(_)) => TExpr { ty: to.clone(), ..te },
            (Ty::Sub(a, _, _), _) | (Ty::Prim(a), _)
                if to.prim(&self.types).is_some() && !matches!(to, Ty::Enum(_)) =>
            {
                let b = to.prim(&self.types).expect("scalar");
                if let (Ty::Sub(_, lo, hi), Some(v)) = (to, te.const_int()) {
                    if v < *lo || v > *hi {
                        let n = self.ty_name(to);
                        self.error(file, span, format!("constant `{v}` is outside `{n}`"));
                        return TExpr::error(span);
                    }
                }
                if *a == b {
                    return TExpr { ty: to.clone(), ..te };
                }
                if a.widens_to(b) {
                    return self.conv(te, b, to.clone());
                }
                // CODESYS converts a bit string to an integer, and back, where no value is
                // lost: `i := b` with a BYTE b and an INT i
                if codesys::implicit_bits(*a, b) {
                    self.habit(Habit::ImplicitConversion, file, span);
                    return self.conv(te, b, to.clone());
                }
                // CODESYS converts the other integer pairs too, with a warning (`implicit`)
                if self.lossy_conversion(*a, b, file, span) {
                    return self.conv(te, b, to.clone());
                }
                self.mismatch(te, to, file)
            }
            (Ty::Enum(_), _) => match self.enum_as_integer(te.clone(), to, file) {
                Some(te) => te,
                None => self.mismatch(te, to, file),
            },
            _ => self.mismatch(te, to, file),
        }
    }

    /// A conversion node (folded for a constant).
    pub fn conv(&mut self, te: TExpr, to_prim: Prim, to: Ty) -> TExpr {
        let span = te.span;
        let from = te.ty.prim(&self.types);
        if let (TK::Const(cv), Some(from)) = (&te.k, from) {
            return TExpr::konst(fold_conv(cv, from, to_prim), to, span);
        }
        if let (TK::Const(cv), Ty::IntLit) = (&te.k, &te.ty) {
            return TExpr::konst(fold_conv(cv, Prim::LInt, to_prim), to, span);
        }
        if let (TK::Const(cv), Ty::RealLit) = (&te.k, &te.ty) {
            return TExpr::konst(fold_conv(cv, Prim::LReal, to_prim), to, span);
        }
        if from == Some(to_prim) {
            return TExpr { ty: to, ..te };
        }
        TExpr { k: TK::Conv(Box::new(te)), ty: to, span }
    }

    pub(super) fn mismatch(&mut self, te: TExpr, to: &Ty, file: usize) -> TExpr {
        let span = te.span;
        let (a, b) = (self.ty_name(&te.ty), self.ty_name(to));
        let hint = match (te.ty.prim(&self.types), to.prim(&self.types)) {
            (Some(x), Some(y))
                if !matches!(te.ty, Ty::Enum(_))
                    && !matches!(to, Ty::Enum(_))
                    && super::calendar::convertible(x, y) =>
            {
                format!(" (use {}_TO_{})", x.name(), y.name())
            }
            // a STRING where a WSTRING is expected, or the other way
            _ if te.ty.string_cap().is_some()
                && to.string_cap().is_some()
                && te.ty.is_wide() != to.is_wide() =>
            {
                let kind = |t: &Ty| if t.is_wide() { "WSTRING" } else { "STRING" };
                format!(" (use {}_TO_{})", kind(&te.ty), kind(to))
            }
            _ => String::new(),
        };
        let a = match te.ty {
            Ty::IntLit => format!("integer constant `{}`", te.const_int().unwrap_or(0)),
            Ty::RealLit => "a real constant".to_string(),
            _ => format!("`{a}`"),
        };
        self.error(file, span, format!("type mismatch: {a} cannot be assigned to `{b}`{hint}"));
        TExpr::error(span)
    }

    fn unary(&mut self, op: UnaryOp, a: TExpr, span: Span, file: usize) -> TExpr {
        if a.ty.is_error() {
            return a;
        }
        match op {
            UnaryOp::Plus => {
                if matches!(a.ty, Ty::IntLit | Ty::RealLit)
                    || a.ty.prim(&self.types).is_some_and(|p| p.is_num() || p.is_time())
                {
                    return TExpr { span, ..a };
                }
                let n = self.ty_name(&a.ty);
                self.error(file, span, format!("`+` cannot be applied to `{n}`"));
                TExpr::error(span)
            }
            UnaryOp::Neg => match (&a.k, &a.ty) {
                (TK::Const(Cv::Int(v)), Ty::IntLit) => TExpr::konst(Cv::Int(-v), Ty::IntLit, span),
                (TK::Const(Cv::Real(v)), Ty::RealLit) => {
                    TExpr::konst(Cv::Real(-v), Ty::RealLit, span)
                }
                _ => match a.ty.prim(&self.types) {
                    Some(p) if (p.is_num() || p.is_time()) && !matches!(a.ty, Ty::Enum(_)) => {
                        if let TK::Const(cv) = &a.k {
                            // A real is negated as IEEE does it (-0.0 for 0.0, as the VM),
                            // not as 0 - x.
                            let r = match cv {
                                Cv::Real(x) if p.is_real() => Cv::Real(-x),
                                _ => fold_bin(BinOp::Sub, Some(p), &zero(p), cv)
                                    .expect("no division"),
                            };
                            return TExpr::konst(r, Ty::Prim(p), span);
                        }
                        TExpr { k: TK::Un(UnOp::Neg, Box::new(a)), ty: Ty::Prim(p), span }
                    }
                    // CODESYS negates a bit string as a signed integer wide enough for it
                    Some(p) if p.is_bits() && !matches!(a.ty, Ty::Enum(_)) => {
                        self.habit(Habit::BitArithmetic, file, span);
                        let signed = codesys::signed_of(p);
                        let a = self.conv(a, signed, Ty::Prim(signed));
                        TExpr { k: TK::Un(UnOp::Neg, Box::new(a)), ty: Ty::Prim(signed), span }
                    }
                    _ => {
                        let n = self.ty_name(&a.ty);
                        self.error(file, span, format!("`-` cannot be applied to `{n}`"));
                        TExpr::error(span)
                    }
                },
            },
            UnaryOp::Not => match a.ty.prim(&self.types) {
                Some(p) if (p == Prim::Bool || p.is_bits()) && !matches!(a.ty, Ty::Enum(_)) => {
                    if let TK::Const(Cv::Int(v)) = a.k {
                        let r = if p == Prim::Bool { i128::from(v == 0) } else { wrap(p, !v) };
                        return TExpr::konst(Cv::Int(r), Ty::Prim(p), span);
                    }
                    TExpr { k: TK::Un(UnOp::Not, Box::new(a)), ty: Ty::Prim(p), span }
                }
                _ => {
                    let n = self.ty_name(&a.ty);
                    self.error(file, span, format!("`NOT` cannot be applied to `{n}`"));
                    TExpr::error(span)
                }
            },
        }
    }

    /// The integer type CODESYS computes in when an integer literal does not fit the other
    /// operand's integer type (`i * 60000` with an INT `i`: DINT, as CODESYS computes in 32
    /// bits at least): the narrowest of DINT and LINT that holds both. `None` when the literal
    /// fits, or the other operand is no plain integer.
    fn widened_for(&self, literal: &TExpr, other: &Ty) -> Option<Prim> {
        let (TK::Const(Cv::Int(v)), Ty::IntLit, Ty::Prim(p)) = (&literal.k, &literal.ty, other)
        else {
            return None;
        };
        if !p.is_int() || fits(*p, *v) {
            return None;
        }
        [Prim::DInt, Prim::LInt].into_iter().find(|w| fits(*w, *v) && p.widens_to(*w))
    }

    /// Brings two operands to one type: `None` (after an error) when they have none.
    pub fn unify(
        &mut self,
        a: TExpr,
        b: TExpr,
        what: &str,
        span: Span,
        file: usize,
    ) -> Option<(TExpr, TExpr, Ty)> {
        if a.ty.is_error() || b.ty.is_error() {
            return None;
        }
        let lit = |t: &Ty| matches!(t, Ty::IntLit | Ty::RealLit);
        // a character and a one-character literal (`c = 'a'`): the literal is the character
        let char_ty = |t: &Ty| matches!(t, Ty::Prim(Prim::Char | Prim::WChar));
        let text = |t: &TExpr| matches!(t.k, TK::Const(Cv::Str(_) | Cv::WStr(_)));
        if char_ty(&a.ty) && text(&b) {
            let ty = a.ty.clone();
            let b = self.coerce(b, &ty, file);
            return (!b.ty.is_error()).then_some((a, b, ty));
        }
        if char_ty(&b.ty) && text(&a) {
            let ty = b.ty.clone();
            let a = self.coerce(a, &ty, file);
            return (!a.ty.is_error()).then_some((a, b, ty));
        }
        match (&a.ty, &b.ty) {
            (Ty::IntLit, Ty::IntLit) => Some((a, b, Ty::IntLit)),
            (Ty::RealLit | Ty::IntLit, Ty::RealLit | Ty::IntLit) => {
                let a = to_real_lit(a);
                let b = to_real_lit(b);
                Some((a, b, Ty::RealLit))
            }
            (x, y) if lit(x) && !lit(y) => {
                // a real constant beside an integer: the integer converts (`implicit`)
                if let Some(w) = self.real_beside(&a, y) {
                    let b = self.conv(b, w, Ty::Prim(w));
                    let a = self.coerce(a, &Ty::Prim(w), file);
                    return Some((a, b, Ty::Prim(w)));
                }
                if let Some(w) = self.widened_for(&a, y) {
                    self.habit(Habit::WidenedLiteral, file, a.span);
                    let b = self.conv(b, w, Ty::Prim(w));
                    let a = self.coerce(a, &Ty::Prim(w), file);
                    return Some((a, b, Ty::Prim(w)));
                }
                let ty = base_ty(y, &self.types);
                let a = self.coerce(a, &ty, file);
                if a.ty.is_error() {
                    return None;
                }
                let b = TExpr { ty: ty.clone(), ..b };
                Some((a, b, ty))
            }
            (x, y) if !lit(x) && lit(y) => {
                // a real constant beside an integer: the integer converts (`implicit`)
                if let Some(w) = self.real_beside(&b, x) {
                    let a = self.conv(a, w, Ty::Prim(w));
                    let b = self.coerce(b, &Ty::Prim(w), file);
                    return Some((a, b, Ty::Prim(w)));
                }
                if let Some(w) = self.widened_for(&b, x) {
                    self.habit(Habit::WidenedLiteral, file, b.span);
                    let a = self.conv(a, w, Ty::Prim(w));
                    let b = self.coerce(b, &Ty::Prim(w), file);
                    return Some((a, b, Ty::Prim(w)));
                }
                let ty = base_ty(x, &self.types);
                let b = self.coerce(b, &ty, file);
                if b.ty.is_error() {
                    return None;
                }
                let a = TExpr { ty: ty.clone(), ..a };
                Some((a, b, ty))
            }
            (Ty::Enum(x), Ty::Enum(y)) if x == y => {
                let t = a.ty.clone();
                Some((a, b, t))
            }
            // an enumeration's value beside an integer (`UDINT_TO_INT(tc) = E.x`): its number,
            // CODESYS's habit (`implicit::enum_as_integer`)
            (Ty::Enum(_), y) if self.plain_integer(y) => {
                let ty = base_ty(y, &self.types);
                let a = self.enum_as_integer(a, &ty, file)?;
                Some((a, TExpr { ty: ty.clone(), ..b }, ty))
            }
            (x, Ty::Enum(_)) if self.plain_integer(x) => {
                let ty = base_ty(x, &self.types);
                let b = self.enum_as_integer(b, &ty, file)?;
                Some((TExpr { ty: ty.clone(), ..a }, b, ty))
            }
            (Ty::Str(_), Ty::Str(_)) | (Ty::WStr(_), Ty::WStr(_)) => {
                let t = a.ty.clone();
                Some((a, b, t))
            }
            (x, y)
                if !matches!(x, Ty::Enum(_))
                    && !matches!(y, Ty::Enum(_))
                    && x.prim(&self.types).is_some()
                    && y.prim(&self.types).is_some() =>
            {
                let (px, py) =
                    (x.prim(&self.types).expect("scalar"), y.prim(&self.types).expect("scalar"));
                match Prim::common(px, py) {
                    Some(c) => {
                        let a = self.conv(a, c, Ty::Prim(c));
                        let b = self.conv(b, c, Ty::Prim(c));
                        Some((a, b, Ty::Prim(c)))
                    }
                    None => {
                        self.error(
                            file,
                            span,
                            format!(
                                "`{what}` cannot be applied to `{}` and `{}`",
                                px.name(),
                                py.name()
                            ),
                        );
                        None
                    }
                }
            }
            (x, y) => {
                let (nx, ny) = (self.ty_name(x), self.ty_name(y));
                self.error(file, span, format!("`{what}` cannot be applied to `{nx}` and `{ny}`"));
                None
            }
        }
    }

    pub fn binary_op(
        &mut self,
        op: BinaryOp,
        a: TExpr,
        b: TExpr,
        span: Span,
        file: usize,
    ) -> TExpr {
        let what = op_text(op);
        if matches!(op, BinaryOp::AndThen | BinaryOp::OrElse) {
            return self.short_circuit(op, a, b, span, file);
        }
        if a.ty.is_error() || b.ty.is_error() {
            return TExpr::error(span);
        }
        if matches!(a.ty, Ty::Iface(_)) || matches!(b.ty, Ty::Iface(_)) {
            return self.interface_compare(op, a, b, span, file);
        }
        if matches!(a.ty, Ty::Ref(..) | Ty::Null) || matches!(b.ty, Ty::Ref(..) | Ty::Null) {
            return self.ref_binary(op, a, b, span, file);
        }
        // TIME * integer, TIME / integer
        if matches!(op, BinaryOp::Mul | BinaryOp::Div) {
            let time = |t: &Ty, s: &Self| t.prim(&s.types).is_some_and(Prim::is_time);
            // a bit string counts too, as CODESYS computes it (`CYCLE_TIME * b`, OSCAT
            // BUILDING's ACTUATOR_2P)
            let int = |t: &Ty, s: &Self| {
                matches!(t, Ty::IntLit)
                    || (t.prim(&s.types).is_some_and(Prim::is_integral)
                        && !matches!(t, Ty::Enum(_)))
            };
            if time(&a.ty, self) && int(&b.ty, self)
                || (op == BinaryOp::Mul && int(&a.ty, self) && time(&b.ty, self))
            {
                let (t, n) = if time(&a.ty, self) { (a, b) } else { (b, a) };
                if n.ty.prim(&self.types).is_some_and(Prim::is_bits) {
                    self.habit(Habit::BitArithmetic, file, n.span);
                }
                let tp = t.ty.prim(&self.types).expect("time");
                let n = if n.ty == Ty::IntLit {
                    self.coerce(n, &Ty::Prim(Prim::LInt), file)
                } else {
                    self.conv(n, Prim::LInt, Ty::Prim(Prim::LInt))
                };
                let n = TExpr { ty: Ty::Prim(tp), ..n };
                let bop = if op == BinaryOp::Mul { BinOp::Mul } else { BinOp::Div };
                return self.make_bin(bop, t, n, Ty::Prim(tp), span, file);
            }
        }
        let (pa, pb) = (a.ty.prim(&self.types), b.ty.prim(&self.types));
        if super::calendar::is_calendar_arith(op, pa, pb) {
            return self.calendar_arith(op, a, b, span, file);
        }
        if let Some(t) = self.bit_arithmetic(op, &a, &b, span, file) {
            let bop = arith_op(op);
            let a = self.conv(a, t, Ty::Prim(t));
            let b = self.conv(b, t, Ty::Prim(t));
            return self.make_bin(bop, a, b, Ty::Prim(t), span, file);
        }
        let Some((a, b, ty)) = self.unify(a, b, what, span, file) else {
            return TExpr::error(span);
        };
        let p = ty.prim(&self.types);
        let name = self.ty_name(&ty);
        let is_lit = matches!(ty, Ty::IntLit | Ty::RealLit);
        let is_enum = matches!(ty, Ty::Enum(_));
        let bad = |s: &mut Self| {
            s.error(file, span, format!("`{what}` cannot be applied to `{name}`"));
            TExpr::error(span)
        };
        match op {
            BinaryOp::Eq
            | BinaryOp::Ne
            | BinaryOp::Lt
            | BinaryOp::Le
            | BinaryOp::Gt
            | BinaryOp::Ge => {
                let cmp = match op {
                    BinaryOp::Eq => CmpOp::Eq,
                    BinaryOp::Ne => CmpOp::Ne,
                    BinaryOp::Lt => CmpOp::Lt,
                    BinaryOp::Le => CmpOp::Le,
                    BinaryOp::Gt => CmpOp::Gt,
                    _ => CmpOp::Ge,
                };
                if matches!(ty, Ty::Array(_) | Ty::Struct(_) | Ty::Fb(_)) {
                    return bad(self);
                }
                if let (TK::Const(x), TK::Const(y)) = (&a.k, &b.k) {
                    if let Some(r) = fold_cmp(cmp, x, y) {
                        return TExpr::konst(Cv::Int(i128::from(r)), Ty::Prim(Prim::Bool), span);
                    }
                }
                let (a, b) = if is_lit {
                    // both literals but not folded: cannot happen; type them anyway
                    let t = if ty == Ty::IntLit { Prim::LInt } else { Prim::LReal };
                    (self.coerce(a, &Ty::Prim(t), file), self.coerce(b, &Ty::Prim(t), file))
                } else {
                    (a, b)
                };
                TExpr { k: TK::Cmp(cmp, Box::new(a), Box::new(b)), ty: Ty::Prim(Prim::Bool), span }
            }
            // checked by `short_circuit` before
            BinaryOp::AndThen | BinaryOp::OrElse => bad(self),
            BinaryOp::And | BinaryOp::Or | BinaryOp::Xor => {
                let bop = match op {
                    BinaryOp::And => BinOp::And,
                    BinaryOp::Or => BinOp::Or,
                    _ => BinOp::Xor,
                };
                match p {
                    _ if ty == Ty::IntLit => self.make_bin(bop, a, b, ty, span, file),
                    Some(p) if (p == Prim::Bool || p.is_bits()) && !is_enum => {
                        self.make_bin(bop, a, b, ty, span, file)
                    }
                    // CODESYS: bitwise on an integer's two's complement bits
                    Some(p) if p.is_int() && !is_enum => {
                        self.habit(Habit::BitwiseInteger, file, span);
                        self.make_bin(bop, a, b, ty, span, file)
                    }
                    _ => bad(self),
                }
            }
            BinaryOp::Add | BinaryOp::Sub | BinaryOp::Mul | BinaryOp::Div | BinaryOp::Mod => {
                let bop = arith_op(op);
                let bits = p.is_some_and(Prim::is_bits)
                    && !is_enum
                    && self.habit(Habit::BitArithmetic, file, span);
                let ok = is_lit && !(op == BinaryOp::Mod && ty == Ty::RealLit)
                    || bits
                    || match p {
                        Some(p) if !is_enum => {
                            if op == BinaryOp::Mod {
                                p.is_int()
                            } else if matches!(op, BinaryOp::Add | BinaryOp::Sub) {
                                p.is_num() || p.is_time()
                            } else {
                                p.is_num()
                            }
                        }
                        _ => false,
                    };
                if !ok {
                    return bad(self);
                }
                self.make_bin(bop, a, b, ty, span, file)
            }
            BinaryOp::Pow => {
                let (a, b, ty) = match (&a.ty, p) {
                    (Ty::IntLit | Ty::RealLit, _) if a.is_const() && b.is_const() => {
                        let (a, b) = (to_real_lit(a), to_real_lit(b));
                        return self.make_bin(BinOp::Expt, a, b, Ty::RealLit, span, file);
                    }
                    (Ty::IntLit | Ty::RealLit, _) => {
                        let a = self.coerce(to_real_lit(a), &Ty::Prim(Prim::LReal), file);
                        let b = self.coerce(to_real_lit(b), &Ty::Prim(Prim::LReal), file);
                        (a, b, Ty::Prim(Prim::LReal))
                    }
                    (_, Some(p)) if p.is_real() => (a, b, ty),
                    _ => {
                        self.error(
                            file,
                            span,
                            format!("`**` needs a `REAL` or `LREAL` base, not `{name}`"),
                        );
                        return TExpr::error(span);
                    }
                };
                self.make_bin(BinOp::Expt, a, b, ty, span, file)
            }
        }
    }

    /// The type of `a op b` when CODESYS computes it and IEC 61131-3 has none: arithmetic
    /// (`+ - * / MOD`) between a bit string and another bit string, an integer or a real, of
    /// different types ([`codesys::bit_arithmetic_type`]). `None` for the standard's cases.
    fn bit_arithmetic(
        &mut self,
        op: BinaryOp,
        a: &TExpr,
        b: &TExpr,
        span: Span,
        file: usize,
    ) -> Option<Prim> {
        if !matches!(
            op,
            BinaryOp::Add | BinaryOp::Sub | BinaryOp::Mul | BinaryOp::Div | BinaryOp::Mod
        ) {
            return None;
        }
        let scalar = |t: &Ty| match t {
            Ty::Enum(_) => None,
            t => t.prim(&self.types),
        };
        let (x, y) = (scalar(&a.ty)?, scalar(&b.ty)?);
        let t = codesys::bit_arithmetic_type(x, y).filter(|_| x != y)?;
        if op == BinaryOp::Mod && t.is_real() {
            return None;
        }
        let habit = if t.is_real() { Habit::BitWithReal } else { Habit::BitArithmetic };
        self.habit(habit, file, span).then_some(t)
    }

    /// A binary node, folded when both sides are constants.
    pub fn make_bin(
        &mut self,
        op: BinOp,
        a: TExpr,
        b: TExpr,
        ty: Ty,
        span: Span,
        file: usize,
    ) -> TExpr {
        if let (TK::Const(x), TK::Const(y)) = (&a.k, &b.k) {
            let p = ty.prim(&self.types);
            match fold_bin(op, p, x, y) {
                Some(r) => return TExpr::konst(r, ty, span),
                None if matches!(op, BinOp::Div | BinOp::Mod) => {
                    self.error(file, b.span, "division by zero");
                    return TExpr::error(span);
                }
                None => {}
            }
        }
        if matches!(op, BinOp::Div | BinOp::Mod) && matches!(b.k, TK::Const(Cv::Int(0))) {
            self.error(file, b.span, "division by zero");
            return TExpr::error(span);
        }
        TExpr { k: TK::Bin(op, Box::new(a), Box::new(b)), ty, span }
    }

    fn check_call_expr(
        &mut self,
        callee: &Expr,
        args: &[Arg],
        span: Span,
        scope: Scope,
        expected: Option<&Ty>,
    ) -> TExpr {
        let file = scope.file;
        if let Some(t) = self.method_call(callee, args, span, scope) {
            return t;
        }
        if let ExprKind::Name(id) = &callee.kind {
            let is_var = scope
                .pou
                .is_some_and(|p| self.pous[p].lookup(&id.name).is_some_and(|i| i < scope.visible))
                || self.global_names.contains_key(&id.name.to_ascii_lowercase());
            if !is_var {
                if let Some(&p) = self.pou_names.get(&id.name.to_ascii_lowercase()) {
                    return match self.pous[p].kind {
                        PouKind::Function => self.function_call(p, args, span, scope),
                        PouKind::Program => {
                            self.error(
                                file,
                                span,
                                format!("`{}` is a PROGRAM: a PROGRAM cannot be called", id.name),
                            );
                            TExpr::error(span)
                        }
                        PouKind::FunctionBlock => {
                            self.error(
                                file,
                                span,
                                format!("`{}` is a function block type: declare an instance and call that", id.name),
                            );
                            TExpr::error(span)
                        }
                    };
                }
                if let Some(t) = self.ref_call(id, args, span, scope) {
                    return t;
                }
                if let Some(t) = self.query_call(id, args, span, scope) {
                    return t;
                }
                return self.std_call(id, args, span, scope, expected);
            }
        }
        let inst = self.check_place(callee, scope, Access::Read, None);
        match inst.ty {
            Ty::Error => inst,
            Ty::Fb(_) => {
                self.error(file, span, "a function block call is a statement, not a value");
                TExpr::error(span)
            }
            _ => {
                let n = expr_text(callee);
                self.error(
                    file,
                    span,
                    format!("`{n}` is not a function or a function block instance"),
                );
                TExpr::error(span)
            }
        }
    }

    /// Records that the body of `scope` calls `callee` (each callee once, at its first call).
    pub(super) fn record_call(&mut self, scope: Scope, callee: usize, span: Span) {
        self.record_callee(scope, callee, span, false);
    }

    /// Records the bodies a call may dispatch to at run time ([`Callee::dispatched`]).
    pub(super) fn record_dispatch(
        &mut self,
        scope: Scope,
        dispatch: &[(Option<u32>, usize)],
        span: Span,
    ) {
        for &(_, callee) in dispatch {
            self.record_callee(scope, callee, span, true);
        }
    }

    /// Records a call of `callee` that runs one of `dispatch` when there are any (`callee`'s
    /// own body among them), else `callee` itself.
    pub(super) fn record_call_of(
        &mut self,
        scope: Scope,
        callee: usize,
        dispatch: &[(Option<u32>, usize)],
        span: Span,
    ) {
        match dispatch {
            [] => self.record_call(scope, callee, span),
            _ => self.record_dispatch(scope, dispatch, span),
        }
    }

    fn record_callee(&mut self, scope: Scope, callee: usize, span: Span, dispatched: bool) {
        let Some(p) = scope.pou else { return };
        let calls = &mut self.pous[p].callees;
        match calls.iter_mut().find(|c| c.pou == callee) {
            // a callee called directly once is called directly
            Some(known) => known.dispatched &= dispatched,
            None => calls.push(Callee { pou: callee, span, dispatched }),
        }
    }

    fn function_call(&mut self, p: usize, args: &[Arg], span: Span, scope: Scope) -> TExpr {
        let file = scope.file;
        if scope.pou.is_none() || scope.visible < self.pous[scope.pou.unwrap_or(0)].vars.len() {
            self.error(file, span, "a constant expression is needed here");
            return TExpr::error(span);
        }
        self.record_call(scope, p, span);
        if self.pous[p].file == self.prelude_file
            && codesys::UTIL_BCD.iter().any(|n| self.pous[p].name.eq_ignore_ascii_case(n))
        {
            self.habit(Habit::UtilBcd, file, span);
        }
        let bound = self.bind_args(p, args, span, scope);
        let ty = self.pous[p].result.clone();
        match bound {
            Some(call) => TExpr { k: TK::Call(Box::new(call)), ty, span },
            None => TExpr::error(span),
        }
    }

    /// The action `callee` names, with the instance it runs on: `Name` in its POU (or in
    /// another action of it) runs on the POU's own instance, `inst.Name` on `inst`. `None` when
    /// `callee` names no action; `Some(None)` after an error.
    pub fn action_call(
        &mut self,
        callee: &Expr,
        args: &[Arg],
        span: Span,
        scope: Scope,
    ) -> Option<Option<(TExpr, CallT)>> {
        let file = scope.file;
        let (inst, action, fb, own) = match &callee.kind {
            ExprKind::Name(id) => {
                let p = scope.pou?;
                if self.pous[p].lookup(&id.name).is_some() {
                    return None;
                }
                // the POU's, an action's or a method's function block
                let owner = self.own_instance(p).unwrap_or(p);
                let action = self.find_action(owner, &id.name)?;
                // the POU's own instance: its variables start at offset 0
                let k = TK::Var { storage: Storage::Inst(0), by_ref: false };
                (TExpr { k, ty: Ty::Fb(action), span: callee.span }, action, owner, true)
            }
            ExprKind::Member(base, id) => {
                let saved = self.diags.len();
                let probe = self.check_place(base, scope, Access::Read, None);
                self.diags.truncate(saved);
                let Ty::Fb(owner) = probe.ty else { return None };
                let action = self.find_action(owner, &id.name)?;
                // `THIS^.Act()` may run a derived block's action, `SUPER^.Act()` runs the base's
                let this = matches!(&base.kind, ExprKind::Deref(b)
                    if matches!(&b.kind, ExprKind::Name(t) if t.is("THIS")));
                (self.check_place(base, scope, Access::Ref, None), action, owner, this)
            }
            _ => return None,
        };
        if !args.is_empty() {
            let name = self.pous[action].name.clone();
            self.error(file, span, format!("`{name}` is an action: it takes no arguments"));
            return Some(None);
        }
        // a derived block's action of the same name replaces it (compile/action_dispatch.rs)
        let dispatch = self.action_candidates(&inst, own, fb, action);
        self.record_call_of(scope, action, &dispatch, span);
        Some(Some((
            inst,
            CallT {
                pou: action,
                args: Vec::new(),
                outs: Vec::new(),
                en: None,
                this: None,
                dispatch,
            },
        )))
    }

    /// A function block instance called as a statement.
    pub fn fb_call(
        &mut self,
        callee: &Expr,
        args: &[Arg],
        span: Span,
        scope: Scope,
    ) -> Option<(TExpr, CallT)> {
        let file = scope.file;
        let access = self.called_instance_access(callee, scope);
        let inst = self.check_place(callee, scope, access, None);
        match inst.ty {
            Ty::Error => None,
            Ty::Fb(p) => {
                if self.class_called(p, file, span) {
                    return None;
                }
                let dispatch = self.body_candidates(&inst, p);
                self.record_call_of(scope, p, &dispatch, span);
                let mut call = self.bind_args(p, args, span, scope)?;
                self.rebind_omitted(&inst, p, &mut call);
                call.dispatch = dispatch;
                Some((inst, call))
            }
            _ => {
                let n = expr_text(callee);
                self.error(
                    file,
                    span,
                    format!("`{n}` is not a function or a function block instance"),
                );
                None
            }
        }
    }

    /// Binds a call's arguments to `p`'s parameters (an implicit `EN := …` included).
    pub(super) fn bind_args(
        &mut self,
        p: usize,
        args: &[Arg],
        span: Span,
        scope: Scope,
    ) -> Option<CallT> {
        let file = scope.file;
        let name = self.pous[p].name.clone();
        let mut ok = true;
        if !self.argument_order(&name, args, span, file) {
            return None;
        }
        let mut given: Vec<usize> = Vec::new();
        let mut out_args = Vec::new();
        let mut outs = Vec::new();
        let mut en: Option<Box<TExpr>> = None;
        // A positional argument binds by its place in the list (mixed_args.rs).
        for (pos, arg) in args.iter().enumerate() {
            let (vi, value) = match arg {
                // The standard's EN, implicit: a condition of the call, not stored.
                Arg::Input { name: pn, value } if pn.is("EN") && self.pous[p].en.is_none() => {
                    if en.is_some() {
                        self.error(file, value.span, format!("`{}` is given twice", pn.name));
                        ok = false;
                        continue;
                    }
                    let bool_ty = Ty::Prim(Prim::Bool);
                    let t = self.check_expr(value, scope, Some(&bool_ty));
                    let t = self.coerce(t, &bool_ty, file);
                    if t.ty.is_error() {
                        ok = false;
                        continue;
                    }
                    self.pous[p].called_with_en = true;
                    en = Some(Box::new(t));
                    continue;
                }
                Arg::Positional(e) => {
                    let Some(&vi) = self.pous[p].positional.get(pos) else {
                        let n = self.pous[p].positional.len();
                        self.error(
                            file,
                            e.span,
                            format!("too many arguments for `{name}` (it takes {n})"),
                        );
                        return None;
                    };
                    (vi, e)
                }
                Arg::Input { name: pn, value } => {
                    let Some(vi) = self.formal_param(p, pn, false, &name, file) else {
                        ok = false;
                        continue;
                    };
                    (vi, value)
                }
                Arg::Output { name: pn, target, negated } => {
                    let Some(vi) = self.formal_param(p, pn, true, &name, file) else {
                        ok = false;
                        continue;
                    };
                    let v = self.pous[p].vars[vi].clone();
                    // An output may be bound more than once (`Q => a, NOT Q => b`): each binding
                    // is an assignment from it after the call.
                    let t = self.check_place(target, scope, Access::Write, None);
                    if t.ty.is_error() || v.ty.is_error() {
                        ok = false;
                        continue;
                    }
                    if *negated && !v.ty.is_bool() {
                        self.error(
                            file,
                            pn.span,
                            format!("`NOT {} =>` needs a BOOL output", pn.name),
                        );
                        ok = false;
                        continue;
                    }
                    if !self.output_assignable(&v.ty, &t.ty, target.span, file) {
                        ok = false;
                        continue;
                    }
                    let (Storage::Inst(off) | Storage::Frame(off)) = v.storage else { continue };
                    let eno = self.pous[p].eno == Some(vi);
                    outs.push(OutT { offset: off, ty: v.ty, target: t, negated: *negated, eno });
                    continue;
                }
            };
            let v = self.pous[p].vars[vi].clone();
            if given.contains(&vi) {
                self.error(file, value.span, format!("`{}` is given twice", v.name));
                ok = false;
                continue;
            }
            given.push(vi);
            let (Storage::Inst(off) | Storage::Frame(off)) = v.storage else { continue };
            if v.by_ref {
                let t = self.check_place(value, scope, Access::Ref, None);
                if t.ty.is_error() || v.ty.is_error() {
                    ok = false;
                    continue;
                }
                if !self.in_out_argument(&v, &t, &name, value.span, file) {
                    ok = false;
                    continue;
                }
                if let Ty::OpenArray(_) = v.ty {
                    match self.open_array_args(&v, off, t, &name, file) {
                        Some(args) => out_args.extend(args),
                        None => ok = false,
                    }
                    continue;
                }
                out_args.push(ArgT { offset: off, ty: v.ty, by_ref: true, value: t });
            } else {
                if self.generic_category(&v.ty).is_some() {
                    match self.generic_args(&v, off, value, &name, scope) {
                        Some(args) => out_args.extend(args),
                        None => ok = false,
                    }
                    continue;
                }
                let t = match v.ty {
                    Ty::Ref(RefKind::Reference, _) => self.bound_reference(value, scope, &v.ty),
                    _ => self.check_expr(value, scope, Some(&v.ty)),
                };
                let t = self.coerce(t, &v.ty, file);
                if t.ty.is_error() {
                    ok = false;
                    continue;
                }
                out_args.push(ArgT { offset: off, ty: v.ty, by_ref: false, value: t });
            }
        }
        let missing: Vec<String> = self.pous[p]
            .vars
            .iter()
            .enumerate()
            .filter(|(i, v)| v.kind == VarKind::InOut && !given.contains(i))
            .map(|(_, v)| v.name.clone())
            .collect();
        for m in missing {
            // a function block's keeps its binding (matiec; `Ctx::rebind_omitted`)
            if self.pous[p].kind == PouKind::FunctionBlock {
                self.habit(Habit::InOutOmitted, file, span);
                continue;
            }
            self.error(file, span, format!("the call of `{name}` is missing VAR_IN_OUT `{m}`"));
            ok = false;
        }
        ok.then_some(CallT { pou: p, args: out_args, outs, en, this: None, dispatch: Vec::new() })
    }

    /// The parameter `pn` of `name` given as a formal argument: an input or in-out with `:=`,
    /// an output with `=>` (`output`). Reports a name that is no parameter, and a parameter
    /// given the wrong way.
    fn formal_param(
        &mut self,
        p: usize,
        pn: &ast::Ident,
        output: bool,
        name: &str,
        file: usize,
    ) -> Option<usize> {
        let vi = self.param(p, pn, file)?;
        let msg = match (self.pous[p].vars[vi].kind, output) {
            (VarKind::Input | VarKind::InOut, false) | (VarKind::Output, true) => return Some(vi),
            (VarKind::Output, false) => format!("`{}` is an output of `{name}`: use `=>`", pn.name),
            (VarKind::Input | VarKind::InOut, true) => {
                format!("`{}` is an input of `{name}`: use `:=`", pn.name)
            }
            _ => format!("`{}` is not a parameter of `{name}`", pn.name),
        };
        self.error(file, pn.span, msg);
        None
    }

    fn param(&mut self, p: usize, pn: &ast::Ident, file: usize) -> Option<usize> {
        let pou = &self.pous[p];
        match pou.lookup(&pn.name) {
            Some(i) => Some(i),
            None => {
                let names: Vec<&str> = pou
                    .vars
                    .iter()
                    .filter(|v| matches!(v.kind, VarKind::Input | VarKind::Output | VarKind::InOut))
                    .map(|v| v.name.as_str())
                    .collect();
                let hint = suggest(&pn.name, names);
                let n = pou.name.clone();
                self.error(file, pn.span, format!("`{n}` has no parameter `{}`{hint}", pn.name));
                None
            }
        }
    }

    /// Whether a value of `from` may be stored in a `to` without a conversion.
    /// Whether an output of type `from` may go to a `=>` target of type `to`; reports why not
    /// at the target.
    pub fn output_assignable(&mut self, from: &Ty, to: &Ty, at: Span, file: usize) -> bool {
        if self.assignable(from, to) {
            return true;
        }
        // CODESYS's implicit conversions of integers, as an assignment makes them (`implicit`)
        if let (Some(a), Some(b)) = (from.prim(&self.types), to.prim(&self.types)) {
            let enums = matches!(from, Ty::Enum(_)) || matches!(to, Ty::Enum(_));
            if !enums && codesys::implicit_bits(a, b) {
                return self.habit(Habit::ImplicitConversion, file, at);
            }
            if !enums && self.lossy_conversion(a, b, file, at) {
                return true;
            }
        }
        let (a, b) = (self.ty_name(from), self.ty_name(to));
        self.error(file, at, format!("type mismatch: `{a}` cannot be assigned to `{b}`"));
        false
    }

    pub fn assignable(&self, from: &Ty, to: &Ty) -> bool {
        if from == to {
            return true;
        }
        match (from, to) {
            (Ty::Str(_), Ty::Str(_)) | (Ty::WStr(_), Ty::WStr(_)) => true,
            (Ty::Ref(..) | Ty::Null, _) | (_, Ty::Ref(..)) => self.ref_assignable(from, to),
            (Ty::Enum(_), _) | (_, Ty::Enum(_)) => false,
            _ => match (from.prim(&self.types), to.prim(&self.types)) {
                (Some(a), Some(b)) => a.widens_to(b),
                _ => false,
            },
        }
    }
}

fn zero(p: Prim) -> Cv {
    if p.is_real() {
        Cv::Real(0.0)
    } else {
        Cv::Int(0)
    }
}

fn to_real_lit(e: TExpr) -> TExpr {
    match (&e.k, &e.ty) {
        (TK::Const(Cv::Int(v)), Ty::IntLit) => {
            TExpr::konst(Cv::Real(*v as f64), Ty::RealLit, e.span)
        }
        _ => e,
    }
}

/// A subrange computes as its base type.
fn base_ty(t: &Ty, _types: &super::types::Types) -> Ty {
    match t {
        Ty::Sub(p, _, _) => Ty::Prim(*p),
        other => other.clone(),
    }
}

/// An expression as the user wrote it (a name path), for messages.
pub fn expr_text(e: &Expr) -> String {
    match &e.kind {
        ExprKind::Name(id) => id.name.clone(),
        ExprKind::Member(b, id) => format!("{}.{}", expr_text(b), id.name),
        ExprKind::Index(b, _) => format!("{}[…]", expr_text(b)),
        ExprKind::Bit(b, n) => format!("{}.{n}", expr_text(b)),
        ExprKind::Part(b, size, n) => format!("{}.%{}{n}", expr_text(b), size.letter()),
        ExprKind::Deref(b) => format!("{}^", expr_text(b)),
        ExprKind::Call { callee, .. } => format!("{}(…)", expr_text(callee)),
        _ => "expression".into(),
    }
}

/// The VM's operation for an arithmetic operator (`+ - * / MOD`).
fn arith_op(op: BinaryOp) -> BinOp {
    match op {
        BinaryOp::Add => BinOp::Add,
        BinaryOp::Sub => BinOp::Sub,
        BinaryOp::Mul => BinOp::Mul,
        BinaryOp::Div => BinOp::Div,
        _ => BinOp::Mod,
    }
}

/// Whether a place is in device words (a variable located at a word device, or an element or
/// member of one).
pub(super) fn at_device_words(t: &TExpr) -> bool {
    match &t.k {
        TK::Var { storage, .. } => matches!(storage, Storage::Word(_)),
        TK::Index(b, _) | TK::Member(b, _, _) => at_device_words(b),
        _ => false,
    }
}

impl Ctx<'_> {
    /// `id`, a variable of the block `block`, named from outside where only its inputs and
    /// outputs (or, under its habits, its internal variables read) may be.
    fn not_an_input_or_output(
        &mut self,
        file: usize,
        id: &ast::Ident,
        block: &dyn std::fmt::Display,
    ) {
        let message = format!("`{}` is not an input or output of `{block}`", id.name);
        self.error(file, id.span, message);
    }
}

//! Generic parameters of user POUs as CODESYS has them (docs/ST.md, "Generic parameters"): a
//! VAR_INPUT of a FUNCTION, FUNCTION_BLOCK or METHOD declared `ANY`, `ANY_INT`, `ANY_NUM`, …
//! receives, instead of a value, CODESYS's `__SYSTEM.AnyType`: `TypeClass` (the class of the
//! argument's type, numbered as CODESYS's `__SYSTEM.TYPE_CLASS`), `pValue` (a `POINTER TO
//! BYTE` to the argument) and `diSize` (its bytes).
//!
//! The structure types, one per category, and the enumeration of the type classes are written
//! in the prelude (`__ANY_INT`, `__SYSTEM_TYPE_CLASS`). A call checks that its argument is a
//! variable of the category and stores the three members as hidden arguments, as it stores any
//! input; the body reads them as members of a STRUCT, and reaches the argument through
//! `pValue`, a checked pointer.

use crate::st::ast::{Expr, ExprKind, Ident, PouKind, RefKind, Span, TypeRef, VarKind};
use crate::st::dialect::Habit;
use crate::value::Calendar;

use super::ctx::{Ctx, Cv, Scope, VarInfo};
use super::expr::{ArgT, TExpr, TK};
use super::types::{Prim, Ty};

/// The generic categories a VAR_INPUT may have.
const CATEGORIES: [&str; 10] = [
    "ANY",
    "ANY_ELEMENTARY",
    "ANY_MAGNITUDE",
    "ANY_NUM",
    "ANY_REAL",
    "ANY_INT",
    "ANY_BIT",
    "ANY_STRING",
    "ANY_DATE",
    "ANY_DURATION",
];

/// The category a type name names (`ANY_INT`), upper case.
fn category(name: &str) -> Option<&'static str> {
    let upper = name.to_ascii_uppercase();
    CATEGORIES.into_iter().find(|c| *c == upper)
}

/// The prelude's name of CODESYS's type classes' enumeration.
pub(super) const TYPE_CLASS: &str = "__SYSTEM_TYPE_CLASS";

/// The prelude's type a dotted name of CODESYS's stands for, as a declaration's type or before
/// a value: `__SYSTEM.TYPE_CLASS` and its alias of the CODESYS Base Interfaces library,
/// `IBaseLibrary.TypeClass` (TcUnit's), are the type classes' enumeration; `__SYSTEM.AnyType`
/// is `__ANY`.
pub(super) fn system_type_name(name: &str) -> Option<&'static str> {
    let compact: String = name.chars().filter(|c| !c.is_whitespace()).collect();
    match compact.to_ascii_lowercase().as_str() {
        "__system.type_class" | "ibaselibrary.typeclass" => Some(TYPE_CLASS),
        "__system.anytype" => Some("__ANY"),
        _ => None,
    }
}

/// CODESYS's `__SYSTEM.TYPE_CLASS` of an elementary type; `None` for `CHAR` and `WCHAR`,
/// which CODESYS has not.
fn prim_class(p: Prim) -> Option<i128> {
    Some(match p {
        Prim::Bool => 0,
        Prim::Byte => 2,
        Prim::Word => 3,
        Prim::DWord => 4,
        Prim::LWord => 5,
        Prim::SInt => 6,
        Prim::Int => 7,
        Prim::DInt => 8,
        Prim::LInt => 9,
        Prim::USInt => 10,
        Prim::UInt => 11,
        Prim::UDInt => 12,
        Prim::ULInt => 13,
        Prim::Real => 14,
        Prim::LReal => 15,
        Prim::Time => 18,
        Prim::Cal(Calendar::Date) => 19,
        Prim::Cal(Calendar::Dt) => 20,
        Prim::Cal(Calendar::Tod) => 21,
        Prim::LTime => 37,
        Prim::Cal(Calendar::LDate) => 46,
        Prim::Cal(Calendar::LDt) => 47,
        Prim::Cal(Calendar::LTod) => 48,
        Prim::Char | Prim::WChar => return None,
    })
}

/// Whether an elementary type is of a category.
fn prim_in(p: Prim, category: &str) -> bool {
    let int = p.is_integral() && !p.is_bits();
    let real = matches!(p, Prim::Real | Prim::LReal);
    let time = matches!(p, Prim::Time | Prim::LTime);
    let bits = p == Prim::Bool || p.is_bits();
    match category {
        "ANY" | "ANY_ELEMENTARY" => true,
        "ANY_MAGNITUDE" => int || real || time,
        "ANY_NUM" => int || real,
        "ANY_REAL" => real,
        "ANY_INT" => int,
        "ANY_BIT" => bits,
        "ANY_DATE" => matches!(p, Prim::Cal(_)),
        "ANY_DURATION" => time,
        _ => false,
    }
}

impl<'a> Ctx<'a> {
    /// The type of a generic VAR_INPUT (`x : ANY_INT`): its category's `AnyType` structure;
    /// `None` when `ty` names no category or the variable is not such an input.
    pub(super) fn generic_input_type(
        &mut self,
        ty: &TypeRef,
        kind: PouKind,
        block: VarKind,
        scope: Scope,
    ) -> Option<Ty> {
        let TypeRef::Named(id) = ty else { return None };
        let category = category(&id.name)?;
        if block != VarKind::Input || !matches!(kind, PouKind::Function | PouKind::FunctionBlock) {
            return None;
        }
        self.habit(Habit::GenericInput, scope.file, id.span);
        let hidden = Ident { name: format!("__{category}"), span: id.span };
        Some(self.resolve_type_ref(&TypeRef::Named(hidden), scope))
    }

    /// A category's name used as a type elsewhere than as a VAR_INPUT's: an error, or `None`
    /// when `name` is no category's.
    pub(super) fn misplaced_generic(&mut self, file: usize, id: &Ident) -> Option<Ty> {
        let category = category(&id.name)?;
        self.error(
            file,
            id.span,
            format!(
                "`{category}` is only the type of a VAR_INPUT of a FUNCTION, FUNCTION_BLOCK or METHOD"
            ),
        );
        Some(Ty::Error)
    }

    /// The category of a generic input's type, `None` for any other type.
    pub(super) fn generic_category(&self, ty: &Ty) -> Option<&'static str> {
        let Ty::Struct(i) = ty else { return None };
        let name = self.types.structs[*i].name.strip_prefix("__")?;
        category(name)
    }

    /// The arguments that give the variable `value` to the generic input `v` (at `offset` in
    /// the callee) of `callee`: its type class, a pointer to it, its size. `None` (and an
    /// error) when it is not a variable of the input's category.
    pub(super) fn generic_args(
        &mut self,
        v: &VarInfo,
        offset: u32,
        value: &Expr,
        callee: &str,
        scope: Scope,
    ) -> Option<Vec<ArgT>> {
        let file = scope.file;
        let category = self.generic_category(&v.ty).expect("a generic input");
        let t = self.check_expr(value, scope, None);
        if t.ty.is_error() {
            return None;
        }
        let class = match &t.ty {
            Ty::Prim(p) => prim_class(*p).filter(|_| prim_in(*p, category)),
            Ty::Sub(p, _, _) if prim_in(*p, category) => Some(24),
            Ty::Str(_) if matches!(category, "ANY" | "ANY_ELEMENTARY" | "ANY_STRING") => Some(16),
            Ty::WStr(_) if matches!(category, "ANY" | "ANY_ELEMENTARY" | "ANY_STRING") => Some(17),
            Ty::Enum(_) if category == "ANY" => Some(25),
            Ty::Array(_) if category == "ANY" => Some(26),
            Ty::Struct(_) if category == "ANY" => Some(28),
            Ty::Ref(RefKind::Pointer | RefKind::RefTo, _) if category == "ANY" => Some(22),
            _ => None,
        };
        let literal = !t.is_place();
        let Some(class) = class.filter(|_| !literal) else {
            let n = self.ty_name(&t.ty);
            let what = if literal { "a value".to_string() } else { format!("`{n}`") };
            self.error(
                file,
                value.span,
                format!(
                    "`{}` of `{callee}` is `{category}`: it needs a variable of that category, not {what}",
                    v.name
                ),
            );
            return None;
        };
        let span = t.span;
        let size = self.types.size(&t.ty);
        let Ty::Struct(s) = &v.ty else { unreachable!("a generic input is a structure") };
        let members = self.types.structs[*s].members.clone();
        let member = |name: &str| {
            let m = members.iter().find(|m| m.name.eq_ignore_ascii_case(name));
            m.expect("the prelude's AnyType").clone()
        };
        let (class_m, value_m, size_m) = (member("TypeClass"), member("pValue"), member("diSize"));
        let pointer = TExpr { k: TK::Ref(Box::new(t)), ty: value_m.ty.clone(), span };
        Some(vec![
            ArgT {
                offset: offset + class_m.offset,
                ty: class_m.ty.clone(),
                by_ref: false,
                value: TExpr::konst(Cv::Int(class), class_m.ty, span),
            },
            ArgT { offset: offset + value_m.offset, ty: value_m.ty, by_ref: false, value: pointer },
            ArgT {
                offset: offset + size_m.offset,
                ty: size_m.ty.clone(),
                by_ref: false,
                value: TExpr::konst(Cv::Int(i128::from(size)), size_m.ty, span),
            },
        ])
    }

    /// `__SYSTEM.TYPE_CLASS.TYPE_INT` (or `IBaseLibrary.TypeClass.TYPE_INT`), CODESYS's
    /// name of a type class: the value of the prelude's enumeration; `None` for any other
    /// expression.
    pub(super) fn system_type_class(&mut self, e: &Expr, span: Span, file: usize) -> Option<TExpr> {
        let ExprKind::Member(base, value) = &e.kind else { return None };
        let ExprKind::Member(system, class) = &base.kind else { return None };
        let ExprKind::Name(system) = &system.kind else { return None };
        let written = format!("{}.{}", system.name, class.name);
        if system_type_name(&written) != Some(TYPE_CLASS) {
            return None;
        }
        let Ty::Enum(ei) = self.resolve_type_ref(
            &TypeRef::Named(Ident { name: TYPE_CLASS.into(), span }),
            Scope { pou: None, visible: 0, file: self.prelude_file },
        ) else {
            return Some(TExpr::error(span));
        };
        let found = self.types.enums[ei].values.iter().find(|(n, _)| value.is(n)).map(|v| v.1);
        Some(match found {
            Some(v) => TExpr::konst(Cv::Int(v), Ty::Enum(ei), span),
            None => {
                self.error(file, value.span, format!("`{written}` has no value `{}`", value.name));
                TExpr::error(span)
            }
        })
    }
}

//! `DATE`, `TOD`, `DT` and their long forms in expressions: their conversions, the arithmetic
//! IEC 61131-3 ed3 allows on them (table 36: `ADD_TOD_TIME`, `SUB_DT_DT`, `CONCAT_DATE_TOD`, …,
//! and the `+` and `-` operators that stand for them, as CODESYS accepts them), lowered to
//! the integer ops of their stored counts ([`crate::value::Calendar`]). Nothing here needs an op
//! of its own: native code compiles all of it.
//!
//! Arithmetic with a `TIME` converts the duration to the calendar type's unit first, cut
//! toward zero (`DT#… + T#1500ms` adds 1 s), and wraps at the type's width as CODESYS does
//! (`TOD#23:00:00 + T#2h` is 25 h after midnight, not 01:00). A difference of two calendar
//! values is a `TIME` (an `LTIME` for the long forms), negative when the second is later.

use crate::st::ast::{BinaryOp, Span};
use crate::value::{BinOp, Calendar, CalendarKind, DAY_NS};

use super::ctx::{Ctx, Cv};
use super::expr::{op_text, TExpr};
use super::types::{Prim, Ty};
use crate::st::dialect::Habit;

/// The calendar functions of IEC 61131-3 ed3 table 36 that are one operation on two values:
/// the name, the operation and the types of the two inputs.
const FUNCTIONS: [(&str, Arith, Prim, Prim); 17] = {
    use Calendar::*;
    use Prim::{Cal, LTime, Time};
    [
        ("ADD_TOD_TIME", Arith::Add, Cal(Tod), Time),
        ("ADD_LTOD_LTIME", Arith::Add, Cal(LTod), LTime),
        ("ADD_DT_TIME", Arith::Add, Cal(Dt), Time),
        ("ADD_LDT_LTIME", Arith::Add, Cal(LDt), LTime),
        ("SUB_TOD_TIME", Arith::Sub, Cal(Tod), Time),
        ("SUB_LTOD_LTIME", Arith::Sub, Cal(LTod), LTime),
        ("SUB_DT_TIME", Arith::Sub, Cal(Dt), Time),
        ("SUB_LDT_LTIME", Arith::Sub, Cal(LDt), LTime),
        ("SUB_DATE_DATE", Arith::Sub, Cal(Date), Cal(Date)),
        ("SUB_LDATE_LDATE", Arith::Sub, Cal(LDate), Cal(LDate)),
        ("SUB_TOD_TOD", Arith::Sub, Cal(Tod), Cal(Tod)),
        ("SUB_LTOD_LTOD", Arith::Sub, Cal(LTod), Cal(LTod)),
        ("SUB_DT_DT", Arith::Sub, Cal(Dt), Cal(Dt)),
        ("SUB_LDT_LDT", Arith::Sub, Cal(LDt), Cal(LDt)),
        ("CONCAT_DATE_TOD", Arith::Concat, Cal(Date), Cal(Tod)),
        ("CONCAT_DATE_LTOD", Arith::Concat, Cal(Date), Cal(LTod)),
        ("CONCAT_LDATE_LTOD", Arith::Concat, Cal(LDate), Cal(LTod)),
    ]
};

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Arith {
    Add,
    Sub,
    /// A date and a time of day into a date and time.
    Concat,
}

/// The inputs' types of a calendar function of [`FUNCTIONS`] (`ADD_TOD_TIME`), by its name in
/// capitals.
pub(super) fn function(upper: &str) -> Option<(Prim, Prim)> {
    FUNCTIONS.iter().find(|f| f.0 == upper).map(|f| (f.2, f.3))
}

/// Whether `+` or `-` has a calendar operand, and so means [`Ctx::calendar_arith`].
pub(super) fn is_calendar_arith(op: BinaryOp, a: Option<Prim>, b: Option<Prim>) -> bool {
    matches!(op, BinaryOp::Add | BinaryOp::Sub)
        && (a.and_then(Prim::calendar).is_some() || b.and_then(Prim::calendar).is_some())
}

/// Whether `<FROM>_TO_<TO>` exists between two elementary types as far as the date and time
/// types go: a date and a time of day have nothing to convert, nor a date and a `TIME`.
pub(super) fn convertible(from: Prim, to: Prim) -> bool {
    let timed = |p: Prim| p.is_time() || p.calendar().is_some();
    if from.calendar().is_none() && to.calendar().is_none() || !(timed(from) && timed(to)) {
        return true;
    }
    // TIME takes the place of a time of day: both count from a zero.
    let kind = |p: Prim| p.calendar().map_or(CalendarKind::Tod, |c| c.kind());
    match (kind(from), kind(to)) {
        (a, b) if a == b => true,
        (CalendarKind::Dt, _) | (CalendarKind::Date, CalendarKind::Dt) => true,
        _ => false,
    }
}

impl Ctx<'_> {
    /// A calendar function of [`FUNCTIONS`] on its two checked inputs (of the types
    /// [`function`] gave).
    pub(super) fn calendar_function(
        &mut self,
        upper: &str,
        a: TExpr,
        b: TExpr,
        span: Span,
        file: usize,
    ) -> TExpr {
        let arith = FUNCTIONS.iter().find(|f| f.0 == upper).map_or(Arith::Add, |f| f.1);
        if a.ty.is_error() || b.ty.is_error() {
            return TExpr::error(span);
        }
        match arith {
            Arith::Concat => self.concat_date_tod(a, b, span, file),
            Arith::Add => self.calendar_arith(BinaryOp::Add, a, b, span, file),
            Arith::Sub => self.calendar_arith(BinaryOp::Sub, a, b, span, file),
        }
    }

    /// `+` or `-` with a calendar operand: a time of day or a date and time plus or minus a
    /// `TIME` (`+` in either order), or the `TIME` between two values of one calendar type.
    pub(super) fn calendar_arith(
        &mut self,
        op: BinaryOp,
        a: TExpr,
        b: TExpr,
        span: Span,
        file: usize,
    ) -> TExpr {
        if a.ty.is_error() || b.ty.is_error() {
            return TExpr::error(span);
        }
        let (pa, pb) = (a.ty.prim(&self.types), b.ty.prim(&self.types));
        let shifts =
            |p: Option<Prim>| p.and_then(Prim::calendar).filter(|c| c.kind() != CalendarKind::Date);
        let time = |p: Option<Prim>| p.is_some_and(Prim::is_time);
        if let (Some(cal), true) = (shifts(pa), time(pb)) {
            return self.shift(op, cal, a, b, span, file);
        }
        if let (true, Some(cal), BinaryOp::Add) = (time(pa), shifts(pb), op) {
            return self.shift(op, cal, b, a, span, file);
        }
        // a date and a duration, CODESYS's and TwinCAT's habit (OSCAT's `dat + t#1d`)
        let date =
            |p: Option<Prim>| p.and_then(Prim::calendar).filter(|c| c.kind() == CalendarKind::Date);
        if let (Some(cal), true) = (date(pa), time(pb)) {
            return self.date_shift(op, cal, a, b, span, file);
        }
        if let (true, Some(cal), BinaryOp::Add) = (time(pa), date(pb), op) {
            return self.date_shift(op, cal, b, a, span, file);
        }
        if let (Some(x), Some(y), BinaryOp::Sub) =
            (pa.and_then(Prim::calendar), pb.and_then(Prim::calendar), op)
        {
            if x == y {
                return self.difference(x, a, b, span, file);
            }
        }
        let (x, y) = (self.ty_name(&a.ty), self.ty_name(&b.ty));
        let what = op_text(op);
        self.error(file, span, format!("`{what}` cannot be applied to `{x}` and `{y}`"));
        TExpr::error(span)
    }

    /// `cal ± duration`: the duration in `cal`'s unit, cut toward zero, added in `cal`'s width.
    fn shift(
        &mut self,
        op: BinaryOp,
        cal: Calendar,
        value: TExpr,
        duration: TExpr,
        span: Span,
        file: usize,
    ) -> TExpr {
        let count = self.in_units(cal, duration, span, file);
        let ty = Ty::Prim(Prim::Cal(cal));
        let count = self.conv(count, Prim::Cal(cal), ty.clone());
        let value = TExpr { ty: ty.clone(), ..value };
        let bop = if op == BinaryOp::Add { BinOp::Add } else { BinOp::Sub };
        self.make_bin(bop, value, count, ty, span, file)
    }

    /// `duration` (a `TIME` or `LTIME`: nanoseconds) in `cal`'s unit, cut toward zero, an
    /// `LINT`.
    fn in_units(&mut self, cal: Calendar, duration: TExpr, span: Span, file: usize) -> TExpr {
        let lint = Ty::Prim(Prim::LInt);
        let ns = TExpr { ty: lint.clone(), ..duration };
        if cal.unit_ns() == 1 {
            return ns;
        }
        let unit = TExpr::konst(Cv::Int(i128::from(cal.unit_ns())), lint.clone(), span);
        self.make_bin(BinOp::Div, ns, unit, lint, span, file)
    }

    /// `date ± duration` (`Habit::DateArithmetic`): the day of the instant the duration moves
    /// the date's midnight to, as `DT_TO_DATE(DATE_TO_DT(date) ± duration)` gives it: the
    /// duration in the date's unit cut toward zero, then the count cut to its day (a result
    /// before 1970 wraps as the count does).
    fn date_shift(
        &mut self,
        op: BinaryOp,
        cal: Calendar,
        value: TExpr,
        duration: TExpr,
        span: Span,
        file: usize,
    ) -> TExpr {
        self.habit(Habit::DateArithmetic, file, span);
        let lint = Ty::Prim(Prim::LInt);
        let konst = |n: u64| TExpr::konst(Cv::Int(i128::from(n)), Ty::Prim(Prim::LInt), span);
        let moved = self.in_units(cal, duration, span, file);
        let count = self.conv(value, Prim::LInt, lint.clone());
        let bop = if op == BinaryOp::Add { BinOp::Add } else { BinOp::Sub };
        let sum = self.make_bin(bop, count, moved, lint.clone(), span, file);
        let day = DAY_NS / cal.unit_ns();
        let days = self.make_bin(BinOp::Div, sum, konst(day), lint.clone(), span, file);
        let midnight = self.make_bin(BinOp::Mul, days, konst(day), lint, span, file);
        self.conv(midnight, Prim::Cal(cal), Ty::Prim(Prim::Cal(cal)))
    }

    /// `a - b` of one calendar type: the `TIME` (`LTIME` for a long form) from `b` to `a`.
    fn difference(&mut self, cal: Calendar, a: TExpr, b: TExpr, span: Span, file: usize) -> TExpr {
        let lint = Ty::Prim(Prim::LInt);
        let a = self.conv(a, Prim::LInt, lint.clone());
        let b = self.conv(b, Prim::LInt, lint.clone());
        let count = self.make_bin(BinOp::Sub, a, b, lint.clone(), span, file);
        let time = if cal.is_long() { Prim::LTime } else { Prim::Time };
        let ns = if cal.unit_ns() == 1 {
            count
        } else {
            let unit = TExpr::konst(Cv::Int(i128::from(cal.unit_ns())), lint.clone(), span);
            self.make_bin(BinOp::Mul, count, unit, lint, span, file)
        };
        TExpr { ty: Ty::Prim(time), ..ns }
    }

    /// `CONCAT_DATE_TOD(date, tod)`: the date and time of that time of day on that day.
    fn concat_date_tod(&mut self, date: TExpr, tod: TExpr, span: Span, file: usize) -> TExpr {
        let (Some(d), Some(t)) = (
            date.ty.prim(&self.types).and_then(Prim::calendar),
            tod.ty.prim(&self.types).and_then(Prim::calendar),
        ) else {
            return TExpr::error(span);
        };
        let dt = if d.is_long() || t.is_long() { Calendar::LDt } else { Calendar::Dt };
        let day = self.calendar_conversion(
            "",
            Prim::Cal(d),
            Prim::Cal(dt),
            Ty::Prim(Prim::Cal(dt)),
            date,
            span,
            file,
        );
        let time = self.calendar_conversion(
            "",
            Prim::Cal(t),
            Prim::Time,
            Ty::Prim(Prim::Time),
            tod,
            span,
            file,
        );
        self.shift(BinaryOp::Add, dt, day, time, span, file)
    }

    /// A conversion from or to `DATE`, `TOD`, `DT` or a long form (docs/ST.md, "Conversion
    /// functions"): to and from a number, a bit string or `BOOL`, the stored count, as CODESYS
    /// (`DT_TO_DWORD` gives seconds since 1970, `TOD_TO_UDINT` milliseconds since midnight);
    /// between the calendar types, and between a time of day and `TIME`, the same instant in
    /// the target's unit: a date and time keeps its day (`DT_TO_DATE`) or its time of day
    /// (`DT_TO_TOD`), a date becomes its midnight (`DATE_TO_DT`), finer parts are cut
    /// (`LTOD_TO_TOD`). A date and a time of day have nothing to convert (`DATE_TO_TOD`).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn calendar_conversion(
        &mut self,
        name: &str,
        sp: Prim,
        dp: Prim,
        dst: Ty,
        t: TExpr,
        span: Span,
        file: usize,
    ) -> TExpr {
        let timed = |p: Prim| p.is_time() || p.calendar().is_some();
        let unit = |p: Prim| p.calendar().map_or(1, |c| c.unit_ns());
        if !convertible(sp, dp) {
            self.error(
                file,
                span,
                format!("`{name}`: no conversion from {} to {}", sp.name(), dp.name()),
            );
            return TExpr::error(span);
        }
        if sp.calendar().is_none() && dp.calendar().is_none() || !(timed(sp) && timed(dp)) {
            return self.conv(t, dp, dst);
        }
        // Computed in 64 bits: signed when a TIME is involved (it may be negative).
        let work = if sp.is_time() || dp.is_time() { Prim::LInt } else { Prim::ULInt };
        let k = |v: u64| TExpr::konst(Cv::Int(i128::from(v)), Ty::Prim(work), span);
        let mut v = if sp.elem() == work.elem() {
            TExpr { ty: Ty::Prim(work), ..t }
        } else {
            self.conv(t, work, Ty::Prim(work))
        };
        let day = DAY_NS / unit(sp);
        let kind = |p: Prim| p.calendar().map_or(CalendarKind::Tod, |c| c.kind());
        let wt = Ty::Prim(work);
        match (kind(sp), kind(dp)) {
            (CalendarKind::Dt, CalendarKind::Date) => {
                let days = self.make_bin(BinOp::Div, v, k(day), wt.clone(), span, file);
                v = self.make_bin(BinOp::Mul, days, k(day), wt.clone(), span, file);
            }
            (CalendarKind::Dt, CalendarKind::Tod) => {
                v = self.make_bin(BinOp::Mod, v, k(day), wt.clone(), span, file);
            }
            _ => {}
        }
        let (from, to) = (unit(sp), unit(dp));
        if from > to {
            v = self.make_bin(BinOp::Mul, v, k(from / to), wt, span, file);
        } else if from < to {
            v = self.make_bin(BinOp::Div, v, k(to / from), wt, span, file);
        }
        if dp.elem() == work.elem() {
            TExpr { ty: dst, ..v }
        } else {
            self.conv(v, dp, dst)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_date_and_a_time_of_day_do_not_convert() {
        let (date, tod, dt) =
            (Prim::Cal(Calendar::Date), Prim::Cal(Calendar::Tod), Prim::Cal(Calendar::Dt));
        let ltod = Prim::Cal(Calendar::LTod);
        assert!(convertible(dt, date) && convertible(dt, tod) && convertible(date, dt));
        assert!(convertible(tod, Prim::Time) && convertible(Prim::LTime, ltod));
        assert!(convertible(date, Prim::DWord) && convertible(Prim::LReal, dt));
        assert!(!convertible(date, tod) && !convertible(tod, dt) && !convertible(date, Prim::Time));
        assert!(!convertible(Prim::Time, dt) && !convertible(ltod, Prim::Cal(Calendar::LDate)));
        assert!(convertible(Prim::Int, Prim::Time), "not a calendar question");
        assert_eq!(function("ADD_TOD_TIME"), Some((tod, Prim::Time)));
        assert_eq!(function("ADD_DATE_TIME"), None);
    }
}

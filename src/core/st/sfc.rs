//! The Sequential Function Chart of a PROGRAM or FUNCTION_BLOCK (IEC 61131-3 ed3 §6.7, in its
//! textual form): the network of steps and transitions and the actions' associations, as the
//! parser reads them (`syntax::parse`'s `sfc` module) and as an import of a graphical chart
//! (PLCopen XML) would build them. Names keep their spelling and place; nothing here is checked:
//! the compiler's `sfc` module checks a chart and turns it into statements.
//!
//! ```text
//! INITIAL_STEP Idle: END_STEP
//! STEP Fill: Valve(N); Timeout(D, T#5s); END_STEP
//! TRANSITION FROM Idle TO Fill := start; END_TRANSITION
//! TRANSITION (PRIORITY := 1) FROM Fill TO (Heat, Stir) := level > 80; END_TRANSITION
//! ```

use crate::st::ast::{Expr, Ident, Span};

/// The chart of one POU: its steps and transitions in the order written. A POU may hold
/// several networks (sets of steps linked by transitions), each with its own initial step.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Sfc {
    pub steps: Vec<Step>,
    pub transitions: Vec<Transition>,
}

/// `STEP Name: associations END_STEP`, or `INITIAL_STEP`.
#[derive(Debug, Clone, PartialEq)]
pub struct Step {
    pub name: Ident,
    pub initial: bool,
    pub associations: Vec<Association>,
    /// Where `STEP` or `INITIAL_STEP` is.
    pub span: Span,
}

/// `Action(Qualifier[, duration][, indicator…])`: while the step is active, the action (an
/// `ACTION` of the POU, or a BOOL variable) is controlled as the qualifier says.
#[derive(Debug, Clone, PartialEq)]
pub struct Association {
    pub action: Ident,
    /// As written; `None` (`Action()`) is `N`.
    pub qualifier: Option<Ident>,
    /// The duration of a timed qualifier (`L`, `D`, `SD`, `DS`, `SL`): a TIME expression.
    pub duration: Option<Expr>,
    /// The indicator variables after the qualifier (display only: read by nothing).
    pub indicators: Vec<Expr>,
    pub span: Span,
}

/// `TRANSITION [Name] [(PRIORITY := n)] FROM steps TO steps := condition; END_TRANSITION`.
#[derive(Debug, Clone, PartialEq)]
pub struct Transition {
    pub name: Option<Ident>,
    /// The expression after `PRIORITY :=` (an integer literal; 0 is the highest).
    pub priority: Option<Expr>,
    /// The preceding steps: more than one is a simultaneous convergence.
    pub from: Vec<Ident>,
    /// The following steps: more than one is a simultaneous divergence.
    pub to: Vec<Ident>,
    pub condition: Expr,
    /// Where `TRANSITION` is.
    pub span: Span,
}

/// The action qualifiers of IEC 61131-3 ed3 table 56.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Qualifier {
    /// Non-stored: while the step is active.
    N,
    /// Overriding reset of the stored qualifiers.
    R,
    /// Set (stored) until an `R`.
    S,
    /// Time limited: while the step is active, for at most the duration.
    L,
    /// Time delayed: while the step has been active for at least the duration.
    D,
    /// Pulse: for one scan when the step becomes active (the body then runs a final scan).
    P,
    /// Pulse on the step's activation: the body runs once, Q stays FALSE.
    P1,
    /// Pulse on the step's deactivation: the body runs once, Q stays FALSE.
    P0,
    /// Stored and delayed: stored at the step's activation, Q after the duration until `R`.
    SD,
    /// Delayed and stored: stored once the step has been active for the duration, until `R`.
    DS,
    /// Stored and time limited: stored at the step's activation, Q for the duration or until `R`.
    SL,
}

impl Qualifier {
    /// All of them, in the standard's order.
    pub const ALL: [Qualifier; 11] = [
        Qualifier::N,
        Qualifier::R,
        Qualifier::S,
        Qualifier::L,
        Qualifier::D,
        Qualifier::P,
        Qualifier::P1,
        Qualifier::P0,
        Qualifier::SD,
        Qualifier::DS,
        Qualifier::SL,
    ];

    /// The qualifier spelled `name` (any case).
    pub fn from_name(name: &str) -> Option<Qualifier> {
        Qualifier::ALL.into_iter().find(|q| q.name().eq_ignore_ascii_case(name))
    }

    /// Its name as the standard writes it.
    pub fn name(self) -> &'static str {
        match self {
            Qualifier::N => "N",
            Qualifier::R => "R",
            Qualifier::S => "S",
            Qualifier::L => "L",
            Qualifier::D => "D",
            Qualifier::P => "P",
            Qualifier::P1 => "P1",
            Qualifier::P0 => "P0",
            Qualifier::SD => "SD",
            Qualifier::DS => "DS",
            Qualifier::SL => "SL",
        }
    }

    /// Whether it takes a duration (`A(L, T#5s)`).
    pub fn timed(self) -> bool {
        matches!(self, Qualifier::L | Qualifier::D | Qualifier::SD | Qualifier::DS | Qualifier::SL)
    }
}

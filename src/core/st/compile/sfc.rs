//! Sequential Function Charts → statements: checks each POU's chart (docs/ST.md, "Sequential
//! Function Chart") and replaces it by variables and statements of plain ST, before anything
//! else of the compiler reads the files, so that a chart needs no operation of its own and runs
//! in native code as any body does.
//!
//! What a chart becomes, in the POU:
//! - each step, a `VAR` instance of the prelude's `__SFC_STEP` named as the step (`s1.X`,
//!   `s1.T` are its outputs); an `INITIAL_STEP`'s instance has `INITIAL := TRUE`;
//! - each associated action, an instance `sfc$<action>` of `__SFC_ACTION` (the standard's
//!   ACTION_CONTROL); `$` cannot be written in a name, so no variable of the program meets it;
//! - each transition, a `VAR_TEMP` BOOL `sfc$<k>`: it clears in this scan;
//! - the body: (1) every step brought up to the clock; (2) every transition's clearing, on the
//!   steps' state at the start of the scan, then the lower priorities of a divergence given up
//!   to the higher ones; (3) every step left and entered; (4) every action's control, then its
//!   body while its `A` (or the BOOL variable set to its `Q`);
//! - `Action.Q`, `Action.A` in the POU's text: `sfc$Action.Q`, `sfc$Action.A`.
//!
//! Checks (each mistake one located error, the rest still lowered): a chart in a FUNCTION,
//! statements beside a chart, names declared twice, unknown steps, one INITIAL_STEP per
//! network (steps linked by transitions), qualifiers and their durations, a variable
//! associated that is surely no BOOL. Types of conditions and durations are the checker's.

use std::borrow::Cow;
use std::collections::{HashMap, HashSet};

use super::types::Prim;
use crate::diag::Diagnostic;
use crate::st::ast::{
    self, Arg, BinaryOp, Expr, ExprKind, Ident, Init, Item, Literal, PouKind, Span, Stmt, StmtKind,
    TypeRef, UnaryOp, VarBlock, VarDecl, VarKind,
};
use crate::st::sfc::{Qualifier, Sfc};

/// The prelude's block a step is an instance of.
const STEP_BLOCK: &str = "__SFC_STEP";
/// The prelude's block an action's control is an instance of.
const ACTION_BLOCK: &str = "__SFC_ACTION";

/// The files with every chart replaced by its statements (a file without a chart is
/// borrowed as it is); every error of every chart is added to `diags`.
pub(super) fn lower<'f>(
    files: &'f [ast::File],
    diags: &mut Vec<Diagnostic>,
) -> Vec<Cow<'f, ast::File>> {
    let outside = outside_actions(files);
    files
        .iter()
        .map(|file| {
            let has_chart = file.items.iter().any(|i| matches!(i, Item::Pou(p) if p.sfc.is_some()));
            if !has_chart {
                return Cow::Borrowed(file);
            }
            let mut file = file.clone();
            let path = file.path.clone();
            // the actions with a control, by POU, both in lower case
            let mut controlled: HashMap<String, HashSet<String>> = HashMap::new();
            for item in &mut file.items {
                if let Item::Pou(pou) = item {
                    if let Some(sfc) = pou.sfc.take() {
                        let mut lowering = Lowering { path: &path, diags: &mut *diags };
                        let actions = lowering.pou(pou, &sfc, &outside);
                        controlled.insert(pou.name.name.to_ascii_lowercase(), actions);
                    }
                }
            }
            // `Action.Q` in the actions written after their POU in this file
            let mut last_pou: Option<String> = None;
            for item in &mut file.items {
                match item {
                    Item::Pou(p) => last_pou = Some(p.name.name.to_ascii_lowercase()),
                    Item::Action { owner, action } => {
                        let owner = owner.as_ref().map(|o| o.name.to_ascii_lowercase());
                        if let Some(actions) =
                            owner.or(last_pou.clone()).and_then(|o| controlled.get(&o))
                        {
                            flags_in_stmts(&mut action.body, actions);
                        }
                    }
                    _ => {}
                }
            }
            Cow::Owned(file)
        })
        .collect()
}

/// The actions written outside their POU, as `(pou, action)` in lower case.
fn outside_actions(files: &[ast::File]) -> HashSet<(String, String)> {
    let mut found = HashSet::new();
    for file in files {
        let mut last_pou: Option<&str> = None;
        for item in &file.items {
            match item {
                Item::Pou(p) => last_pou = Some(&p.name.name),
                Item::Action { owner, action } => {
                    let owner = owner.as_ref().map(|o| o.name.as_str()).or(last_pou);
                    if let Some(owner) = owner {
                        found.insert((
                            owner.to_ascii_lowercase(),
                            action.name.name.to_ascii_lowercase(),
                        ));
                    }
                }
                _ => {}
            }
        }
    }
    found
}

struct Lowering<'a> {
    path: &'a std::path::Path,
    diags: &'a mut Vec<Diagnostic>,
}

/// A transition whose steps are all known: its preceding and following steps (indices in
/// [`Sfc::steps`]) and its priority (`u64::MAX` when none is written).
struct Link {
    from: Vec<usize>,
    to: Vec<usize>,
    priority: u64,
}

/// One association, checked: its step, qualifier and duration.
struct Checked<'s> {
    step: usize,
    qualifier: Qualifier,
    duration: Option<&'s Expr>,
}

impl Lowering<'_> {
    fn error(&mut self, span: Span, msg: impl Into<String>) {
        self.diags.push(Diagnostic::new(self.path, span.line, span.col, msg));
    }

    /// Checks and lowers the chart of `pou`; the actions (not BOOL variables) it controls, in
    /// lower case.
    fn pou(
        &mut self,
        pou: &mut ast::Pou,
        sfc: &Sfc,
        outside: &HashSet<(String, String)>,
    ) -> HashSet<String> {
        let first = sfc
            .steps
            .iter()
            .map(|s| s.span)
            .chain(sfc.transitions.iter().map(|t| t.span))
            .min()
            .unwrap_or(pou.span);
        if pou.kind == PouKind::Function {
            self.error(
                first,
                format!(
                    "FUNCTION `{}` cannot hold a sequential function chart: a FUNCTION keeps nothing between calls (use a FUNCTION_BLOCK or a PROGRAM)",
                    pou.name.name
                ),
            );
            return HashSet::new();
        }
        if let Some(stmt) = pou.body.iter().find(|s| s.kind != StmtKind::Empty) {
            self.error(
                stmt.span,
                format!(
                    "a statement in the body of `{}`, which is a sequential function chart: a body is statements or a chart, not both (put the statements in an ACTION)",
                    pou.name.name
                ),
            );
        }

        // steps by name; a step declared again is reported and left out
        let mut step_of: HashMap<String, usize> = HashMap::new();
        let mut chart = Sfc { steps: Vec::new(), transitions: sfc.transitions.clone() };
        for step in &sfc.steps {
            let key = step.name.name.to_ascii_lowercase();
            if let Some(&before) = step_of.get(&key) {
                let line = chart.steps[before].span.line;
                self.error(
                    step.name.span,
                    format!("step `{}` is already declared at line {line}", step.name.name),
                );
            } else {
                step_of.insert(key, chart.steps.len());
                chart.steps.push(step.clone());
            }
        }
        let sfc = &chart;

        // transitions: their steps and priority
        let mut names: HashMap<String, Span> = HashMap::new();
        // every transition with the steps that are known (for the networks), and whether all are
        let mut links: Vec<(Link, bool)> = Vec::new();
        for t in &sfc.transitions {
            if let Some(name) = &t.name {
                let key = name.name.to_ascii_lowercase();
                match names.get(&key) {
                    Some(before) => {
                        let msg = format!(
                            "transition `{}` is already declared at line {}",
                            name.name, before.line
                        );
                        self.error(name.span, msg);
                    }
                    None => {
                        names.insert(key, name.span);
                    }
                }
            }
            let mut ok = true;
            let mut ends = [Vec::new(), Vec::new()];
            for (side, list) in [&t.from, &t.to].into_iter().enumerate() {
                for name in list {
                    match step_of.get(&name.name.to_ascii_lowercase()) {
                        Some(&s) if ends[side].contains(&s) => {
                            self.error(
                                name.span,
                                format!("step `{}` is named twice in this transition", name.name),
                            );
                            ok = false;
                        }
                        Some(&s) => ends[side].push(s),
                        None => {
                            self.error(
                                name.span,
                                format!("`{}`: no step of that name in this chart", name.name),
                            );
                            ok = false;
                        }
                    }
                }
            }
            // no PRIORITY: after every transition with one
            let mut priority = u64::MAX;
            if let Some(p) = &t.priority {
                match &p.kind {
                    ExprKind::Literal(Literal::Int(n)) if *n < u128::from(u32::MAX) => {
                        priority = *n as u64;
                    }
                    _ => {
                        self.error(
                            p.span,
                            "PRIORITY takes an integer literal (0 is the highest priority)",
                        );
                    }
                }
            }
            let [from, to] = ends;
            links.push((Link { from, to, priority }, ok));
        }

        self.initial_steps(sfc, &links);
        let resolved: Vec<Option<Link>> =
            links.into_iter().map(|(link, ok)| ok.then_some(link)).collect();

        // associations, by action in the order first associated
        let mut actions: Vec<(Ident, Vec<Checked<'_>>)> = Vec::new();
        for (k, step) in sfc.steps.iter().enumerate() {
            for a in &step.associations {
                let qualifier = match &a.qualifier {
                    None => Some(Qualifier::N),
                    Some(q) => {
                        let found = Qualifier::from_name(&q.name);
                        if found.is_none() {
                            let all: Vec<&str> = Qualifier::ALL.iter().map(|q| q.name()).collect();
                            self.error(
                                q.span,
                                format!("`{}` is no action qualifier: {}", q.name, all.join(", ")),
                            );
                        }
                        found
                    }
                };
                let Some(qualifier) = qualifier else { continue };
                if qualifier.timed() && a.duration.is_none() {
                    self.error(
                        a.span,
                        format!(
                            "qualifier `{}` needs a duration: `{}({}, T#5s)`",
                            qualifier.name(),
                            a.action.name,
                            qualifier.name()
                        ),
                    );
                    continue;
                }
                if let Some(bad) =
                    a.indicators.iter().find(|e| !matches!(e.kind, ExprKind::Name(_)))
                {
                    let what = if qualifier.timed() {
                        "one duration, then indicator variable names"
                    } else {
                        "no duration, only indicator variable names"
                    };
                    self.error(bad.span, format!("qualifier `{}` takes {what}", qualifier.name()));
                    continue;
                }
                let checked = Checked { step: k, qualifier, duration: a.duration.as_ref() };
                match actions.iter_mut().find(|(n, _)| n.name.eq_ignore_ascii_case(&a.action.name))
                {
                    Some((_, list)) => list.push(checked),
                    None => actions.push((a.action.clone(), vec![checked])),
                }
            }
        }

        let pou_key = pou.name.name.to_ascii_lowercase();
        let is_action = |name: &str| {
            pou.actions.iter().any(|a| a.name.is(name))
                || outside.contains(&(pou_key.clone(), name.to_ascii_lowercase()))
        };
        // an association naming a variable sets it: it must be a BOOL
        actions.retain(|(name, _)| {
            if is_action(&name.name) {
                return true;
            }
            let declared = pou.vars.iter().flat_map(|b| &b.decls).find(|d| d.names.iter().any(|n| n.is(&name.name)));
            let Some(ty) = declared.and_then(|d| not_bool(&d.ty)) else { return true };
            let msg = format!(
                "`{}` is a variable of type `{ty}`: an action association names an ACTION of `{}` or a BOOL variable",
                name.name, pou.name.name
            );
            self.diags.push(Diagnostic::new(self.path, name.span.line, name.span.col, msg));
            false
        });
        let bodies: Vec<bool> = actions.iter().map(|(name, _)| is_action(&name.name)).collect();
        let generated = generate(sfc, &resolved, &actions, &bodies);
        pou.vars.extend(generated.vars);
        pou.body.extend(generated.body);
        let controlled: HashSet<String> = actions
            .iter()
            .zip(&bodies)
            .filter(|(_, &body)| body)
            .map(|((name, _), _)| name.name.to_ascii_lowercase())
            .collect();
        flags_in_stmts(&mut pou.body, &controlled);
        for action in &mut pou.actions {
            flags_in_stmts(&mut action.body, &controlled);
        }
        controlled
    }

    /// Each network (steps linked by transitions) needs exactly one INITIAL_STEP.
    fn initial_steps(&mut self, sfc: &Sfc, links: &[(Link, bool)]) {
        let n = sfc.steps.len();
        let mut root: Vec<usize> = (0..n).collect();
        fn find(root: &mut [usize], mut k: usize) -> usize {
            while root[k] != k {
                root[k] = root[root[k]];
                k = root[k];
            }
            k
        }
        for (link, _) in links {
            let mut all = link.from.iter().chain(&link.to);
            if let Some(&first) = all.next() {
                for &other in all {
                    let (a, b) = (find(&mut root, first), find(&mut root, other));
                    root[a] = b;
                }
            }
        }
        let mut initial_of: HashMap<usize, usize> = HashMap::new();
        for (k, step) in sfc.steps.iter().enumerate().filter(|(_, s)| s.initial) {
            let net = find(&mut root, k);
            match initial_of.get(&net) {
                Some(&first) => {
                    let first = &sfc.steps[first];
                    let msg = format!(
                        "a second INITIAL_STEP in one network: `{}` is linked to `{}` (line {}), and a network has exactly one",
                        step.name.name, first.name.name, first.span.line
                    );
                    self.error(step.span, msg);
                }
                None => {
                    initial_of.insert(net, k);
                }
            }
        }
        let mut reported: HashSet<usize> = HashSet::new();
        for (k, step) in sfc.steps.iter().enumerate() {
            let net = find(&mut root, k);
            if !initial_of.contains_key(&net) && reported.insert(net) {
                let msg = format!(
                    "no INITIAL_STEP in the network of step `{}`: one of its steps must be the INITIAL_STEP",
                    step.name.name
                );
                self.error(step.span, msg);
            }
        }
    }
}

/// `Action.Q` and `Action.A` (IEC 61131-3 ed3) in `stmts`, for each action of `controlled`
/// (lower case): the outputs of its control instance. Anything else is left to the checker.
fn flags_in_stmts(stmts: &mut [Stmt], controlled: &HashSet<String>) {
    for stmt in stmts {
        let mut exprs: Vec<&mut Expr> = Vec::new();
        let mut bodies: Vec<&mut Vec<Stmt>> = Vec::new();
        match &mut stmt.kind {
            StmtKind::Assign { target, value } | StmtKind::RefAssign { target, value } => {
                exprs.extend([target, value]);
            }
            StmtKind::Call(call) => exprs.push(call),
            StmtKind::If { branches, otherwise } => {
                for (cond, body) in branches {
                    exprs.push(cond);
                    bodies.push(body);
                }
                bodies.extend(otherwise.as_mut().map(|(_, body)| body));
            }
            StmtKind::Case { selector, arms, otherwise } => {
                exprs.push(selector);
                bodies.extend(arms.iter_mut().map(|arm| &mut arm.body));
                bodies.extend(otherwise.as_mut().map(|(_, body)| body));
            }
            StmtKind::For { var, from, to, by, body } => {
                exprs.extend([var, from, to]);
                exprs.extend(by.as_mut());
                bodies.push(body);
            }
            StmtKind::While { cond, body } => {
                exprs.push(cond);
                bodies.push(body);
            }
            StmtKind::Repeat { body, until } => {
                exprs.push(until);
                bodies.push(body);
            }
            _ => {}
        }
        for e in exprs {
            flags_in_expr(e, controlled);
        }
        for body in bodies {
            flags_in_stmts(body, controlled);
        }
    }
}

fn flags_in_expr(e: &mut Expr, controlled: &HashSet<String>) {
    match &mut e.kind {
        ExprKind::Member(base, field) => {
            if let ExprKind::Name(action) = &mut base.kind {
                let flag = field.is("Q") || field.is("A");
                if flag && controlled.contains(&action.name.to_ascii_lowercase()) {
                    action.name = action_var(&action.name);
                }
            } else {
                flags_in_expr(base, controlled);
            }
        }
        ExprKind::Index(base, indices) => {
            flags_in_expr(base, controlled);
            for i in indices {
                flags_in_expr(i, controlled);
            }
        }
        ExprKind::Bit(base, _)
        | ExprKind::Part(base, _, _)
        | ExprKind::Deref(base)
        | ExprKind::Unary(_, base) => flags_in_expr(base, controlled),
        ExprKind::Binary(_, a, b) | ExprKind::Assign(a, b) => {
            flags_in_expr(a, controlled);
            flags_in_expr(b, controlled);
        }
        ExprKind::Call { callee, args } => {
            flags_in_expr(callee, controlled);
            for arg in args {
                match arg {
                    Arg::Positional(value) | Arg::Input { value, .. } => {
                        flags_in_expr(value, controlled)
                    }
                    Arg::Output { target, .. } => flags_in_expr(target, controlled),
                }
            }
        }
        _ => {}
    }
}

/// The type of a variable declared as `ty`, when it is surely no BOOL: an elementary type or a
/// STRING or ARRAY (a named type may be an alias of BOOL: the checker decides).
fn not_bool(ty: &TypeRef) -> Option<&'static str> {
    match ty {
        TypeRef::Named(name) => {
            Prim::from_name(&name.name).filter(|p| *p != Prim::Bool).map(Prim::name)
        }
        TypeRef::String { .. } => Some("STRING"),
        TypeRef::WString { .. } => Some("WSTRING"),
        TypeRef::Array { .. } => Some("ARRAY"),
        _ => None,
    }
}

/// What a chart adds to its POU.
struct Generated {
    vars: Vec<VarBlock>,
    body: Vec<Stmt>,
}

fn ident(name: &str, span: Span) -> Ident {
    Ident { name: name.to_string(), span }
}

fn expr(kind: ExprKind, span: Span) -> Expr {
    Expr { kind, span }
}

fn name(name: &str, span: Span) -> Expr {
    expr(ExprKind::Name(ident(name, span)), span)
}

fn boolean(value: bool, span: Span) -> Expr {
    expr(ExprKind::Literal(Literal::Bool(value)), span)
}

fn member(of: &str, field: &str, span: Span) -> Expr {
    expr(ExprKind::Member(Box::new(name(of, span)), ident(field, span)), span)
}

fn binary(op: BinaryOp, a: Expr, b: Expr) -> Expr {
    let span = a.span;
    expr(ExprKind::Binary(op, Box::new(a), Box::new(b)), span)
}

/// `a OR b OR …`, FALSE for none.
fn any(terms: Vec<Expr>, span: Span) -> Expr {
    terms.into_iter().reduce(|a, b| binary(BinaryOp::Or, a, b)).unwrap_or(boolean(false, span))
}

fn stmt(kind: StmtKind, span: Span) -> Stmt {
    Stmt { kind, span }
}

fn assign(target: &str, value: Expr, span: Span) -> Stmt {
    stmt(StmtKind::Assign { target: name(target, span), value }, span)
}

/// `instance(input := value, …);`.
fn call(instance: &str, inputs: Vec<(&str, Expr)>, span: Span) -> Stmt {
    let args = inputs
        .into_iter()
        .map(|(input, value)| Arg::Input { name: ident(input, span), value })
        .collect();
    let callee = Box::new(name(instance, span));
    stmt(StmtKind::Call(expr(ExprKind::Call { callee, args }, span)), span)
}

fn transition_var(k: usize) -> String {
    format!("sfc${k}")
}

fn action_var(action: &str) -> String {
    format!("sfc${action}")
}

fn declare(names: &str, ty: &str, init: Option<Init>, span: Span) -> VarDecl {
    VarDecl {
        names: vec![ident(names, span)],
        location: None,
        ty: TypeRef::Named(ident(ty, span)),
        init,
        edge: None,
        span,
    }
}

fn generate(
    sfc: &Sfc,
    resolved: &[Option<Link>],
    actions: &[(Ident, Vec<Checked<'_>>)],
    bodies: &[bool],
) -> Generated {
    let steps = &sfc.steps;
    let step_name = |k: usize| steps[k].name.name.as_str();
    let mut locals = Vec::new();
    let mut temps = Vec::new();
    let mut body = Vec::new();
    for step in steps {
        let init = step.initial.then(|| Init::Struct {
            members: vec![(ident("INITIAL", step.span), Init::Expr(boolean(true, step.span)))],
            span: step.span,
        });
        locals.push(declare(&step.name.name, STEP_BLOCK, init, step.name.span));
        // (1) up to the clock
        let quiet =
            vec![("ENTER", boolean(false, step.span)), ("LEAVE", boolean(false, step.span))];
        body.push(call(&step.name.name, quiet, step.span));
    }

    // (2) which transitions clear, on the state at the start of the scan
    let live: Vec<(usize, &Link)> =
        resolved.iter().enumerate().filter_map(|(k, r)| r.as_ref().map(|r| (k, r))).collect();
    for &(k, Link { from, .. }) in &live {
        let t = &sfc.transitions[k];
        let span = t.span;
        let var = transition_var(k);
        temps.push(declare(&var, "BOOL", None, span));
        let active = from
            .iter()
            .map(|&s| member(step_name(s), "X", span))
            .reduce(|a, b| binary(BinaryOp::And, a, b))
            .unwrap_or(boolean(false, span));
        let set = assign(&var, boolean(true, t.condition.span), t.condition.span);
        let inner = stmt(
            StmtKind::If { branches: vec![(t.condition.clone(), vec![set])], otherwise: None },
            t.condition.span,
        );
        body.push(stmt(
            StmtKind::If { branches: vec![(active, vec![inner])], otherwise: None },
            span,
        ));
    }
    // a divergence's lower priorities give way: PRIORITY, then the order written
    let mut order: Vec<(usize, &Link)> = live.clone();
    order.sort_by_key(|(k, link)| (link.priority, *k));
    for (i, &(k, link)) in order.iter().enumerate() {
        let span = sfc.transitions[k].span;
        for &(u, other) in &order[..i] {
            if link.from.iter().any(|s| other.from.contains(s)) {
                let var = transition_var(k);
                let not_u = expr(
                    ExprKind::Unary(UnaryOp::Not, Box::new(name(&transition_var(u), span))),
                    span,
                );
                body.push(assign(&var, binary(BinaryOp::And, name(&var, span), not_u), span));
            }
        }
    }

    // (3) steps left and entered
    for (s, step) in steps.iter().enumerate() {
        let span = step.span;
        let fired =
            |side: usize| {
                let terms =
                    live.iter()
                        .filter(|(_, link)| {
                            if side == 0 {
                                link.to.contains(&s)
                            } else {
                                link.from.contains(&s)
                            }
                        })
                        .map(|(k, _)| name(&transition_var(*k), span))
                        .collect();
                any(terms, span)
            };
        body.push(call(&step.name.name, vec![("ENTER", fired(0)), ("LEAVE", fired(1))], span));
    }

    // (4) actions
    for ((action, assoc), &has_body) in actions.iter().zip(bodies) {
        let span = action.span;
        let control = action_var(&action.name);
        locals.push(declare(&control, ACTION_BLOCK, None, span));
        let mut inputs: Vec<(&str, Expr)> = Vec::new();
        for q in Qualifier::ALL {
            let of_q: Vec<&Checked<'_>> = assoc.iter().filter(|c| c.qualifier == q).collect();
            if of_q.is_empty() {
                continue;
            }
            let timed = |c: &Checked<'_>, op: BinaryOp| {
                let step = step_name(c.step);
                let elapsed = member(step, "T", span);
                let duration = c.duration.cloned().unwrap_or(boolean(false, span));
                binary(BinaryOp::And, member(step, "X", span), binary(op, elapsed, duration))
            };
            let terms: Vec<Expr> = of_q
                .iter()
                .map(|c| match q {
                    Qualifier::L => timed(c, BinaryOp::Lt),
                    Qualifier::D | Qualifier::DS => timed(c, BinaryOp::Ge),
                    _ => member(step_name(c.step), "X", span),
                })
                .collect();
            inputs.push((q.name(), any(terms, span)));
            // SD and SL: the duration of the active association (the first written, if several)
            let duration_input = match q {
                Qualifier::SD => Some("SD_T"),
                Qualifier::SL => Some("SL_T"),
                _ => None,
            };
            if let Some(input) = duration_input {
                let none = expr(ExprKind::Literal(Literal::Time(0)), span);
                let chosen = of_q.iter().rev().fold(none, |otherwise, c| {
                    let callee = Box::new(name("SEL", span));
                    let args = vec![
                        Arg::Positional(member(step_name(c.step), "X", span)),
                        Arg::Positional(otherwise),
                        Arg::Positional(c.duration.cloned().unwrap_or(boolean(false, span))),
                    ];
                    expr(ExprKind::Call { callee, args }, span)
                });
                inputs.push((input, chosen));
            }
        }
        body.push(call(&control, inputs, span));
        if has_body {
            let run = stmt(
                StmtKind::Call(expr(
                    ExprKind::Call { callee: Box::new(name(&action.name, span)), args: vec![] },
                    span,
                )),
                span,
            );
            body.push(stmt(
                StmtKind::If {
                    branches: vec![(member(&control, "A", span), vec![run])],
                    otherwise: None,
                },
                span,
            ));
        } else {
            body.push(assign(&action.name, member(&control, "Q", span), span));
        }
    }

    let block = |kind: VarKind, decls: Vec<VarDecl>| VarBlock {
        kind,
        constant: false,
        retain: false,
        persistent: false,
        span: steps.first().map_or(Span::default(), |s| s.span),
        decls,
    };
    let mut vars = vec![block(VarKind::Local, locals)];
    if !temps.is_empty() {
        vars.push(block(VarKind::Temp, temps));
    }
    Generated { vars, body }
}

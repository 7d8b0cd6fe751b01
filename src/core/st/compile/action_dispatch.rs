//! Actions dispatched as methods are (CODESYS): a function block's action of the same name as
//! an action of its base replaces it for every call that may reach a derived instance.
//!
//! CODESYS's actions are virtual like its methods: a derived block's action overrides its
//! base's, also when the base's own code calls it (`Act()` in the base's body, as the
//! `{attribute 'no_virtual_actions'}` pragma's documentation describes, the pragma turning it
//! off). plcd compiles such a call as a method call that dispatches: a chain over the type tags
//! of the blocks derived from the one the place is declared as, each with its own action
//! (`oop`'s tags, [`Ctx::body_candidates`]' shape), then the declared block's action. A place
//! that is exactly its declared block (a variable, a member, an element) and `SUPER^.Act()` call
//! the action found by name directly.

use super::ctx::Ctx;
use super::expr::TExpr;

impl Ctx<'_> {
    /// The actions a call of `action` (found on function block `fb`) through `inst` may run, by
    /// tag: one per non-abstract function block derived from `fb` whose action of that name is
    /// another, then `action` itself. Empty when no dispatch is needed: `inst` is exactly an
    /// `fb` (`own`: the own instance, which may be a derived block's), or no derived block
    /// replaces the action.
    pub(super) fn action_candidates(
        &self,
        inst: &TExpr,
        own: bool,
        fb: usize,
        action: usize,
    ) -> Vec<(Option<u32>, usize)> {
        if !Self::is_dynamic(inst, own) || !self.oop.tagged.contains(&fb) {
            return Vec::new();
        }
        let Some((act, _)) = self.pous[action].action else { return Vec::new() };
        let name = act.name.name.clone();
        let mut out: Vec<(Option<u32>, usize)> = (0..self.pous.len())
            .filter(|&d| d != fb && self.oop.tagged.contains(&d) && self.derives_from(d, fb))
            .filter(|&d| !self.pous[d].ast.oop.is_abstract)
            .filter_map(|d| {
                let a = self.find_action(d, &name)?;
                (a != action).then(|| (self.oop.tags.get(&d).copied(), a))
            })
            .collect();
        if !out.is_empty() {
            out.push((None, action));
        }
        out
    }
}

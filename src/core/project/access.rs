//! Access paths (`VAR_ACCESS`, docs/ST.md) as clients name them: by their bare name (`count`),
//! which reads what they name under that name (`count`, `count.q` for an FB instance's), and
//! writes it only when declared `READ_WRITE`. The compiler made the name unique among the
//! globals, the program instances and the other access paths, so a name means one thing.

use std::borrow::Cow;

use super::{names_match, Project, Watched};
use crate::lang::AccessPath;

impl Project {
    /// The access path called `name` (case-insensitive), if any.
    pub fn access_path(&self, name: &str) -> Option<&AccessPath> {
        let name = name.trim();
        self.variables.access.iter().find(|a| names_match(&a.name, name))
    }

    /// The access path `name` is or names a part of (`timer`, `timer.PT`, `table[2]`), and
    /// the name it stands for (`main.t`, `main.t.PT`, `main.tab[2]`).
    pub fn access_of(&self, name: &str) -> Option<(&AccessPath, String)> {
        let name = name.trim();
        self.variables.access.iter().find_map(|path| {
            let head = name.get(..path.name.len())?;
            let rest = &name[path.name.len()..];
            let part = rest.is_empty() || rest.starts_with('.') || rest.starts_with('[');
            (part && head.eq_ignore_ascii_case(&path.name))
                .then(|| (path, format!("{}{rest}", path.target)))
        })
    }

    /// What `name`, an access path or a part of one, names: each leaf under the path's name
    /// (`count`, `timer.PT`); a device as its address.
    pub(super) fn access_watched(&self, name: &str) -> Option<Result<Vec<Watched>, String>> {
        let (path, target) = self.access_of(name)?;
        let found = match self.watched(&target) {
            Ok(found) => found,
            Err(_) => {
                return Some(Err(format!(
                    "no variable `{}`: the access path `{}` names `{}`, which has no `{target}`",
                    name.trim(),
                    path.name,
                    path.target
                )))
            }
        };
        Some(Ok(found
            .into_iter()
            .map(|watched| match watched {
                Watched::Variable(mut symbol) => {
                    let rest = symbol.name.get(path.target.len()..).unwrap_or_default();
                    symbol.name = format!("{}{rest}", path.name);
                    Watched::Variable(symbol)
                }
                other => other,
            })
            .collect()))
    }

    /// The name a client's write of `name` goes to: `name` itself, or what a `READ_WRITE`
    /// access path (or a part of one) names; an error naming the path for a `READ_ONLY` one.
    pub fn written_name<'a>(&self, name: &'a str) -> Result<Cow<'a, str>, String> {
        match self.access_of(name) {
            None => Ok(Cow::Borrowed(name)),
            Some((path, target)) if path.read_write => Ok(Cow::Owned(target)),
            Some((path, _)) => Err(format!(
                "`{}` is a READ_ONLY access path (to `{}`): clients may read it, not write it \
                 (VAR_ACCESS … READ_WRITE allows writes)",
                path.name, path.target
            )),
        }
    }
}

/// The line `plcd check` and the daemon's log show for an access path: `access path count →
/// main.n, read only`.
pub(super) fn note(path: &AccessPath) -> String {
    let direction = if path.read_write { "read and write" } else { "read only" };
    format!("access path {} → {}, {direction}", path.name, path.target)
}

//! Access paths (`VAR_ACCESS`, docs/ST.md) as clients name them: by their bare name (`count`),
//! which reads what they name under that name (`count`, `count.q` for an FB instance's), and
//! writes it only when declared `READ_WRITE`. The compiler made the name unique among the
//! globals, the program instances and the other access paths, so a name means one thing.

use super::{names_match, Project, Watched};
use crate::lang::AccessPath;

impl Project {
    /// The access path called `name` (case-insensitive), if any.
    pub fn access_path(&self, name: &str) -> Option<&AccessPath> {
        let name = name.trim();
        self.variables.access.iter().find(|a| names_match(&a.name, name))
    }

    /// What the access path `path` names, each leaf under the path's name (`count`, or
    /// `count.q` for the member `q` of the FB instance it names); a device as its address.
    pub(super) fn access_watched(&self, path: &AccessPath) -> Result<Vec<Watched>, String> {
        let found = self.watched(&path.target)?;
        Ok(found
            .into_iter()
            .map(|watched| match watched {
                Watched::Variable(mut symbol) => {
                    let rest = symbol.name.get(path.target.len()..).unwrap_or_default();
                    symbol.name = format!("{}{rest}", path.name);
                    Watched::Variable(symbol)
                }
                other => other,
            })
            .collect())
    }

    /// The name a client's write of `name` goes to: `name` itself, or what a `READ_WRITE`
    /// access path names; an error naming the path for a `READ_ONLY` one.
    pub fn written_name<'a>(&'a self, name: &'a str) -> Result<&'a str, String> {
        match self.access_path(name) {
            None => Ok(name),
            Some(path) if path.read_write => Ok(&path.target),
            Some(path) => Err(format!(
                "`{}` is a READ_ONLY access path (to `{}`): clients may read it, not write it \
                 (VAR_ACCESS … READ_WRITE allows writes)",
                path.name, path.target
            )),
        }
    }
}

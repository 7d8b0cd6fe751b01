//! `[users]`: where the users of the network services are (docs/USERS.md). The file itself is
//! parsed by [`crate::users`]; this section only names it.

use std::path::{Path, PathBuf};

use serde::Deserialize;
use toml::Spanned;

use super::common::{resolve, Ctx};
use super::Sink;

/// `[users]`.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct UsersConfig {
    /// `file`: the users file (`name:role:hash` lines), resolved against the config file's
    /// directory when relative, not empty. `None` (the default): no users, and a service that
    /// takes named logins refuses every one of them.
    pub file: Option<PathBuf>,
}

/// `[users]` as written.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawUsers {
    pub file: Option<Spanned<String>>,
}

/// Pass 2 of `[users]`; `config` is the config file, for `file`.
pub(super) fn validate(sink: &mut Sink, raw: RawUsers, config: &Path) -> Option<UsersConfig> {
    let ctx = Ctx::Section("users");
    match raw.file {
        None => Some(UsersConfig::default()),
        Some(file) if file.get_ref().trim().is_empty() => {
            sink.error(file.span().start, format!("{} must not be empty", ctx.key("file")));
            None
        }
        Some(file) => Some(UsersConfig { file: Some(resolve(config, file.get_ref())) }),
    }
}

//! The users file: one `name:role:hash` line per user, `#` comment lines and blank lines;
//! parsed with every bad line reported at once, verified against, and edited line by line.

use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};

use super::hash::{self, DUMMY};
use super::{Role, UsersError};
use crate::diag::{Diagnostic, Diagnostics};

/// The longest user name, in characters (ASCII, so in bytes too).
pub const NAME_MAX: usize = 64;

/// One user of the file. Its `Debug` leaves the hash out, so that no log or panic message
/// carries it.
#[derive(Clone, PartialEq, Eq)]
pub struct User {
    /// The name, `[A-Za-z0-9_.-]{1,64}`, unique in the file.
    pub name: String,
    pub role: Role,
    /// The line of the file, from 1.
    pub line: u32,
    /// The PHC string: checked, never shown.
    hash: String,
}

impl fmt::Debug for User {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("User")
            .field("name", &self.name)
            .field("role", &self.role)
            .field("line", &self.line)
            .finish_non_exhaustive()
    }
}

/// A valid users file: its users, and its text line by line for the edits. Its `Debug` shows
/// the users without their hashes, and not the text.
#[derive(Clone, PartialEq, Eq)]
pub struct UsersFile {
    path: PathBuf,
    /// The lines with their terminators (`\n`, `\r\n`, none for a last line without one):
    /// joined, they are the text exactly as read.
    lines: Vec<String>,
    users: Vec<User>,
}

impl fmt::Debug for UsersFile {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("UsersFile")
            .field("path", &self.path)
            .field("users", &self.users)
            .finish_non_exhaustive()
    }
}

/// What is wrong with a user name, if anything: the offset (in characters) of the culprit and
/// the reason.
fn name_problem(name: &str) -> Option<(usize, String)> {
    if name.is_empty() {
        return Some((0, "a user name must not be empty".into()));
    }
    if let Some((at, c)) =
        name.chars().enumerate().find(|(_, c)| !(c.is_ascii_alphanumeric() || "_.-".contains(*c)))
    {
        return Some((
            at,
            format!(
                "character {c:?} is not allowed in a user name (letters, digits, `_`, `.` and \
                 `-`)"
            ),
        ));
    }
    let length = name.chars().count();
    (length > NAME_MAX).then(|| {
        (0, format!("a user name has at most {NAME_MAX} characters, this one has {length}"))
    })
}

/// Checks a user name: `[A-Za-z0-9_.-]{1,64}`.
pub fn check_name(name: &str) -> Result<(), UsersError> {
    match name_problem(name) {
        None => Ok(()),
        Some((_, reason)) => Err(UsersError::BadName { name: name.into(), reason }),
    }
}

impl UsersFile {
    /// Parses a users file. Pure: `path` only names the file in diagnostics. On error, one
    /// diagnostic for each bad line, in line order; none of them quotes a hash.
    pub fn parse(text: &str, path: &Path) -> Result<UsersFile, Diagnostics> {
        let lines: Vec<String> = text.split_inclusive('\n').map(str::to_string).collect();
        let mut users: Vec<User> = Vec::new();
        // Each name's first line, for the duplicates: a map, so a long file costs no square.
        let mut seen: BTreeMap<&str, u32> = BTreeMap::new();
        let mut diags = Diagnostics::default();
        for (index, raw) in lines.iter().enumerate() {
            let number = index as u32 + 1;
            let mut error = |offset: usize, message: String| {
                // Columns count characters from 1.
                let col = raw[..offset].chars().count() as u32 + 1;
                diags.push(Diagnostic::new(path, number, col, message));
            };
            let content = raw.trim_end_matches(['\n', '\r']);
            let start = content.len() - content.trim_start().len();
            let content = content.trim();
            if content.is_empty() || content.starts_with('#') {
                continue;
            }
            let mut fields = content.splitn(3, ':');
            let (Some(name), Some(role), Some(phc)) = (fields.next(), fields.next(), fields.next())
            else {
                error(start, "expected `name:role:hash`, as `plcd user add` writes it".into());
                continue;
            };
            // The fields' byte offsets in the line: for the columns.
            let role_at = start + name.len() + 1;
            let hash_at = role_at + role.len() + 1;
            let mut ok = true;
            if let Some((at, reason)) = name_problem(name) {
                let offset = start + name.char_indices().nth(at).map_or(0, |(i, _)| i);
                error(offset, reason);
                ok = false;
            } else if let Some(first) = seen.get(name) {
                error(start, format!("user `{name}` is defined again (first on line {first})"));
                ok = false;
            } else {
                seen.insert(name, number);
            }
            // The role is not quoted: a line written wrong may hold a password in its place.
            let role = role.parse::<Role>().map_err(|_| {
                error(role_at, "unknown role, expected viewer, operator or engineer".into())
            });
            if let Err(reason) = hash::check(phc) {
                error(hash_at, reason);
                ok = false;
            }
            if let (true, Ok(role)) = (ok, role) {
                users.push(User { name: name.into(), role, line: number, hash: phc.into() });
            }
        }
        if diags.is_empty() {
            Ok(UsersFile { path: path.to_path_buf(), lines, users })
        } else {
            Err(diags)
        }
    }

    /// The users, in file order.
    pub fn users(&self) -> &[User] {
        &self.users
    }

    /// The user called `name`, if any.
    pub fn user(&self, name: &str) -> Option<&User> {
        self.users.iter().find(|u| u.name == name)
    }

    /// The role of `name` if `password` is theirs. An unknown name costs a verify against a
    /// hash of the default costs, so that it takes about as long as a wrong password of a user
    /// whose hash has those costs (`plcd user` writes every hash with them): the time tells
    /// nothing about which names exist.
    pub fn verify(&self, name: &str, password: &[u8]) -> Option<Role> {
        let (phc, role) = self.hash_for(name);
        // Computed whether or not the name exists: the same work makes the same time.
        let matched = hash::matches(phc, password);
        role.filter(|_| matched)
    }

    /// The hash a login as `name` is checked against and the role it opens: the user's, or,
    /// for a name the file does not have, the dummy hash, which opens nothing.
    fn hash_for(&self, name: &str) -> (&str, Option<Role>) {
        match self.user(name) {
            Some(user) => (&user.hash, Some(user.role)),
            None => (DUMMY, None),
        }
    }

    /// The file's text: as read, with the edits made since.
    pub fn text(&self) -> String {
        self.lines.concat()
    }

    /// Gives `name` the role and the hash `phc` (a PHC string of [`super::hash_password`]):
    /// their line is replaced where they are in the file, or a line is added at its end. Every
    /// other line stays as it was. The role they had, if they were in the file.
    pub fn set(&mut self, name: &str, role: Role, phc: &str) -> Result<Option<Role>, UsersError> {
        check_name(name)?;
        hash::check(phc).map_err(UsersError::BadHash)?;
        let line = format!("{name}:{role}:{phc}");
        let previous = self.user(name).map(|u| (u.line, u.role));
        match previous {
            Some((number, _)) => {
                let old = &mut self.lines[number as usize - 1];
                let ending = &old[old.trim_end_matches(['\n', '\r']).len()..];
                *old = format!("{line}{ending}");
            }
            None => {
                // The file's own line ending; a last line without one gets it first.
                let ending = self
                    .lines
                    .first()
                    .filter(|l| l.ends_with("\r\n"))
                    .map_or("\n", |_| "\r\n")
                    .to_string();
                if let Some(last) = self.lines.last_mut().filter(|l| !l.ends_with('\n')) {
                    last.push_str(&ending);
                }
                self.lines.push(format!("{line}{ending}"));
            }
        }
        self.reparse()?;
        Ok(previous.map(|(_, role)| role))
    }

    /// Removes `name`'s line; every other line stays as it was. The role they had.
    pub fn remove(&mut self, name: &str) -> Result<Role, UsersError> {
        let Some(user) = self.user(name) else {
            return Err(UsersError::NoSuchUser(name.into()));
        };
        let role = user.role;
        self.lines.remove(user.line as usize - 1);
        self.reparse()?;
        Ok(role)
    }

    /// The users and their line numbers anew, after an edit. The lines an edit writes are
    /// checked before, so this finds no error; if it did, the error is returned, not hidden.
    fn reparse(&mut self) -> Result<(), UsersError> {
        *self = UsersFile::parse(&self.text(), &self.path).map_err(UsersError::File)?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::super::{hash_password, HashCosts, SALT_LEN};
    use super::*;

    /// Cheap costs: these tests are about the file, not the hash.
    const CHEAP: HashCosts = HashCosts { memory_kib: 64, passes: 1, lanes: 1 };

    fn phc(password: &str, salt: u8) -> String {
        hash_password(password.as_bytes(), &[salt; SALT_LEN], CHEAP).unwrap()
    }

    fn parse(text: &str) -> Result<UsersFile, Diagnostics> {
        UsersFile::parse(text, Path::new("users"))
    }

    #[test]
    fn users_comments_and_blank_lines() {
        let text = format!(
            "# plcd users\n\nalice:engineer:{}\r\n  # the night shift\nbob:operator:{}\ncarol:viewer:{}",
            phc("a", 1),
            phc("b", 2),
            phc("c", 3)
        );
        let file = parse(&text).unwrap();
        let found: Vec<_> =
            file.users().iter().map(|u| (u.name.as_str(), u.role, u.line)).collect();
        assert_eq!(
            found,
            [("alice", Role::Engineer, 3), ("bob", Role::Operator, 5), ("carol", Role::Viewer, 6)]
        );
        assert_eq!(file.text(), text);
        assert!(!format!("{file:?}").contains("argon2"), "Debug shows no hash");
        assert!(parse("").unwrap().users().is_empty());
    }

    #[test]
    fn verify_answers_the_role_of_the_right_password_only() {
        let file = parse(&format!("alice:engineer:{}\nbob:viewer:{}\n", phc("a", 1), phc("b", 2)))
            .unwrap();
        assert_eq!(file.verify("alice", b"a"), Some(Role::Engineer));
        assert_eq!(file.verify("bob", b"b"), Some(Role::Viewer));
        assert_eq!(file.verify("alice", b"b"), None);
        assert_eq!(file.verify("bob", b""), None);
        assert_eq!(file.verify("mallory", b"a"), None);
        assert_eq!(file.verify("Alice", b"a"), None, "names are case-sensitive");
    }

    /// An unknown name is checked against the dummy hash, whose costs are the default ones
    /// (`hash::tests`): the same work as a wrong password of a user hashed by `plcd user`, so
    /// the time of a refusal tells nothing about which names exist. Tested by what is
    /// computed, not by a clock: a timing test would fail on a loaded machine.
    #[test]
    fn an_unknown_name_is_checked_against_the_dummy_hash_which_opens_nothing() {
        let a = phc("a", 1);
        let file = parse(&format!("alice:engineer:{a}\n")).unwrap();
        assert_eq!(file.hash_for("alice"), (a.as_str(), Some(Role::Engineer)));
        assert_eq!(file.hash_for("mallory"), (DUMMY, None));
        // The dummy's own password (it has one, as every hash) opens nothing either.
        assert!(hash::matches(DUMMY, b"secret"));
        assert_eq!(file.verify("mallory", b"secret"), None);
    }

    #[test]
    fn every_bad_line_is_reported_at_once_without_its_hash() {
        let good = phc("a", 1);
        let argon2i = good.replace("argon2id", "argon2i");
        let text = format!(
            "alice:engineer:{good}\n\
             bad name:viewer:{good}\n\
             bob:admin:{good}\n\
             carol:viewer:hunter2\n\
             alice:viewer:{good}\n\
             dave-only-two:operator\n\
             {long}:viewer:{good}\n\
             erin:viewer:{argon2i}\n",
            long = "x".repeat(65)
        );
        let diags = parse(&text).unwrap_err();
        let lines: Vec<String> = diags.iter().map(|d| d.to_string()).collect();
        assert_eq!(
            lines,
            [
                "users:2:4: error: character ' ' is not allowed in a user name (letters, digits, \
                 `_`, `.` and `-`)",
                "users:3:5: error: unknown role, expected viewer, operator or engineer",
                "users:4:14: error: not a PHC hash string: password hash string missing field",
                "users:5:1: error: user `alice` is defined again (first on line 1)",
                "users:6:1: error: expected `name:role:hash`, as `plcd user add` writes it",
                "users:7:1: error: a user name has at most 64 characters, this one has 65",
                "users:8:13: error: the hash is argon2i, plcd accepts argon2id only (make it with \
                 `plcd user add`)",
            ]
        );
        let hash_part = good.rsplit('$').next().unwrap();
        assert!(!diags.to_string().contains(hash_part) && !diags.to_string().contains("hunter2"));
    }

    #[test]
    fn names_are_letters_digits_and_three_marks() {
        for good in ["a", "Operator_2", "j.doe", "line-3", &"n".repeat(NAME_MAX)] {
            assert_eq!(check_name(good), Ok(()), "{good}");
        }
        for bad in ["", "a:b", "é", "a b", "a/b", &"n".repeat(NAME_MAX + 1)] {
            assert!(matches!(check_name(bad), Err(UsersError::BadName { .. })), "{bad:?}");
        }
    }

    #[test]
    fn set_replaces_a_users_line_or_adds_one_and_keeps_the_rest() {
        let (a, b, c) = (phc("a", 1), phc("b", 2), phc("c", 3));
        let text = format!("# users\r\nalice:operator:{a}\r\n\r\n# end\r\nbob:viewer:{b}");
        let mut file = parse(&text).unwrap();
        assert_eq!(file.set("alice", Role::Engineer, &c), Ok(Some(Role::Operator)));
        assert_eq!(
            file.text(),
            format!("# users\r\nalice:engineer:{c}\r\n\r\n# end\r\nbob:viewer:{b}")
        );
        assert_eq!(file.verify("alice", b"c"), Some(Role::Engineer));
        // A new user after the last line, which gets the file's line ending first.
        assert_eq!(file.set("carol", Role::Viewer, &a), Ok(None));
        assert_eq!(
            file.text(),
            format!("# users\r\nalice:engineer:{c}\r\n\r\n# end\r\nbob:viewer:{b}\r\ncarol:viewer:{a}\r\n")
        );
        assert_eq!(file.user("carol").map(|u| u.line), Some(6));
        // Into an empty file.
        let mut empty = parse("").unwrap();
        assert_eq!(empty.set("dave", Role::Viewer, &a), Ok(None));
        assert_eq!(empty.text(), format!("dave:viewer:{a}\n"));
        // What the file cannot hold is refused, and the file is unchanged.
        let before = file.text();
        assert!(matches!(file.set("no name", Role::Viewer, &a), Err(UsersError::BadName { .. })));
        assert!(matches!(file.set("erin", Role::Viewer, "plain"), Err(UsersError::BadHash(_))));
        assert_eq!(file.text(), before);
    }

    #[test]
    fn remove_takes_out_one_line_and_keeps_the_rest() {
        let (a, b) = (phc("a", 1), phc("b", 2));
        let mut file = parse(&format!("alice:operator:{a}\n# keep\nbob:viewer:{b}\n")).unwrap();
        assert_eq!(file.remove("alice"), Ok(Role::Operator));
        assert_eq!(file.text(), format!("# keep\nbob:viewer:{b}\n"));
        assert_eq!(file.user("bob").map(|u| u.line), Some(2));
        assert_eq!(file.verify("alice", b"a"), None);
        assert_eq!(file.remove("alice"), Err(UsersError::NoSuchUser("alice".into())));
    }
}

//! Users, their password hashes and their roles, for the network services that take named
//! logins (the OPC UA server, the web interface); docs/USERS.md describes the file and the
//! rules.
//!
//! This module owns:
//! - the roles ([`Role`]) and what each may do ([`Role::may`] an [`Action`]): the one table
//!   every service asks;
//! - the users file ([`UsersFile`]): one `name:role:hash` line per user, parsed with every bad
//!   line reported at once, and edited line by line (a user added, replaced or removed) with
//!   the other lines and comments kept as they were;
//! - password hashes: argon2id in the PHC string format, with the costs of [`HashCosts`];
//!   hashing with a salt the caller passes ([`hash_password`]) and verifying
//!   ([`UsersFile::verify`]) in about the same time whether the user exists or not;
//! - login throttling ([`Throttle`]): failures per source, the delay they earn, and the runs of
//!   failures a service logs once.
//!
//! Pure like the rest of the core: the file comes in as text, salts and times as values; no
//! files, clocks or random numbers here. `plcd user` (the `plcd` crate) reads and writes the
//! file and draws the salts from the OS.

mod file;
mod hash;
mod throttle;

use std::fmt;
use std::str::FromStr;

use crate::diag::Diagnostics;

pub use file::{check_name, User, UsersFile, NAME_MAX};
pub use hash::{hash_password, HashCosts, SALT_LEN};
pub use throttle::{source_of, EndedRun, Failure, Throttle, ThrottlePolicy};

/// What went wrong with a users file or an edit of it.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum UsersError {
    /// The file's text has errors, every one of them located (an edit refuses such a file:
    /// what it would keep may not be what was meant).
    #[error("{0}")]
    File(Diagnostics),
    /// A user name the file cannot hold.
    #[error("bad user name {name:?}: {reason}")]
    BadName { name: String, reason: String },
    /// Removing a user the file does not have.
    #[error("no user `{0}` in the file")]
    NoSuchUser(String),
    /// An empty password: nobody may log in with one.
    #[error("the password is empty")]
    EmptyPassword,
    /// A string given as a hash that the file would not accept (the reason quotes no part of
    /// it).
    #[error("not a hash plcd accepts: {0}")]
    BadHash(String),
    /// The hash could not be computed (the argon2 crate's reason; never the password).
    #[error("cannot hash the password: {0}")]
    Hash(String),
}

/// What a user may do, ordered: each role may do everything the roles below it may.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Role {
    /// Reads, browses and subscribes: sees everything, changes nothing.
    Viewer,
    /// Also writes the variables the config makes writable, and changes the mode (RUN, STOP)
    /// and resets the PLC.
    Operator,
    /// Also loads programs, changes them online, forces and debugs.
    Engineer,
}

impl Role {
    /// Every role, lowest first.
    pub const ALL: [Role; 3] = [Role::Viewer, Role::Operator, Role::Engineer];

    /// The role's name in the users file and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Role::Viewer => "viewer",
            Role::Operator => "operator",
            Role::Engineer => "engineer",
        }
    }

    /// Whether this role may do `action`: the one question a service asks.
    pub fn may(self, action: Action) -> bool {
        self >= action.least_role()
    }
}

impl fmt::Display for Role {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A name that is no role; its message lists the roles.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown role `{0}`, expected viewer, operator or engineer")]
pub struct UnknownRole(pub String);

impl FromStr for Role {
    type Err = UnknownRole;

    fn from_str(text: &str) -> Result<Role, UnknownRole> {
        Role::ALL.into_iter().find(|r| r.name() == text).ok_or_else(|| UnknownRole(text.into()))
    }
}

/// Something a logged-in user asks a service to do. Which variables are writable at all is
/// the config's business (`[modbus]`, the OPC UA server's map): [`Action::Write`] is only the
/// role's part of the question.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Action {
    /// Read a variable, the status or the log.
    Read,
    /// Browse the variables and devices.
    Browse,
    /// Subscribe to changes.
    Subscribe,
    /// Write a variable the config makes writable.
    Write,
    /// Change the mode: RUN, STOP.
    ChangeMode,
    /// Reset the PLC (clear the error, warm or cold restart).
    Reset,
    /// Load a project.
    Load,
    /// Change the programs online, in RUN.
    OnlineChange,
    /// Force a device or a variable, and release forces.
    Force,
    /// Debug: breakpoints, stepping.
    Debug,
}

impl Action {
    /// Every action, in the order of the table in docs/USERS.md.
    pub const ALL: [Action; 10] = [
        Action::Read,
        Action::Browse,
        Action::Subscribe,
        Action::Write,
        Action::ChangeMode,
        Action::Reset,
        Action::Load,
        Action::OnlineChange,
        Action::Force,
        Action::Debug,
    ];

    /// The lowest role that may do this.
    pub fn least_role(self) -> Role {
        match self {
            Action::Read | Action::Browse | Action::Subscribe => Role::Viewer,
            Action::Write | Action::ChangeMode | Action::Reset => Role::Operator,
            Action::Load | Action::OnlineChange | Action::Force | Action::Debug => Role::Engineer,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn roles_are_ordered_and_named() {
        assert!(Role::Viewer < Role::Operator && Role::Operator < Role::Engineer);
        for role in Role::ALL {
            assert_eq!(role.name().parse::<Role>(), Ok(role));
            assert_eq!(role.to_string(), role.name());
        }
        let error = "admin".parse::<Role>().unwrap_err();
        assert_eq!(
            error.to_string(),
            "unknown role `admin`, expected viewer, operator or engineer"
        );
        assert!("Viewer".parse::<Role>().is_err(), "names are lower case, as written");
    }

    /// The table of docs/USERS.md, row by row.
    #[test]
    fn each_role_may_what_the_table_says() {
        use Action::*;
        let table: [(Action, [bool; 3]); 10] = [
            //               viewer operator engineer
            (Read, [true, true, true]),
            (Browse, [true, true, true]),
            (Subscribe, [true, true, true]),
            (Write, [false, true, true]),
            (ChangeMode, [false, true, true]),
            (Reset, [false, true, true]),
            (Load, [false, false, true]),
            (OnlineChange, [false, false, true]),
            (Force, [false, false, true]),
            (Debug, [false, false, true]),
        ];
        assert_eq!(table.map(|(a, _)| a), Action::ALL);
        for (action, allowed) in table {
            for (role, allowed) in Role::ALL.into_iter().zip(allowed) {
                assert_eq!(role.may(action), allowed, "{role} {action:?}");
            }
        }
    }
}

//! Who may open an OPC UA session and what it may do: anonymous sessions as `[opcua]
//! anonymous` says, and user names with their passwords from the users file (`[users] file`,
//! docs/USERS.md), verified off the stack's worker threads and throttled per user name. A
//! session's role (`plcd_core::users::Role`) decides, through the stack's questions, whether it
//! may write the variables the config makes writable (`Action::Write`: the write bit of each
//! node's user access level) and call the PLC's methods (`Action::ChangeMode` for RUN and
//! STOP, `Action::Reset` for reset).
//!
//! A named session's token is `user:NAME` (`:` is never part of a user name), so no user can
//! be taken for the stack's anonymous token.
//!
//! Throttled per **user name**, not per client address: the stack hands its authenticator the
//! endpoint, the name and the password, not the peer's address. A name that keeps failing waits
//! ([`plcd_core::users::ThrottlePolicy`]: after 3 failures 1 s, doubling, at most 60 s) before
//! its next attempt is even verified, and an attempt during the wait counts as one more failure,
//! so a guesser gets a handful of tries a minute; the cost is that the same guesser delays the
//! name's owner as long. Each run of failures is logged twice:
//! at its first failure and when it ends, with the count.

use std::sync::{Arc, Mutex};
use std::time::Instant;

use opcua::crypto::SecurityPolicy;
use opcua::nodes::AccessLevel;
use opcua::server::authenticator::{
    user_pass_security_policy_id, AuthManager, Password, UserToken,
};
use opcua::server::ServerEndpoint;
use opcua::types::{Identifier, NodeId, StatusCode, UAString, UserTokenPolicy, UserTokenType};

use crate::files::LiveUsers;
use crate::users::{Action, Role, Throttle, ThrottlePolicy};

/// How a named session's token begins; the user's name follows.
const USER_TOKEN: &str = "user:";

/// The PLC's methods (their node ids' strings) and what each asks of a role.
pub const METHODS: [(&str, Action); 3] = [
    ("PLC.Run", Action::ChangeMode),
    ("PLC.Stop", Action::ChangeMode),
    ("PLC.Reset", Action::Reset),
];

/// The stack's authenticator.
pub struct Access {
    /// The role of an anonymous session (`[opcua] anonymous`); `None`: refused.
    anonymous: Option<Role>,
    /// The users file, read again when it changes; `None` without `[users] file`: no named
    /// login.
    users: Option<Arc<LiveUsers>>,
    throttle: Mutex<Throttle<String>>,
    /// The origin of the throttle's times.
    started: Instant,
}

impl Access {
    pub fn new(anonymous: Option<Role>, users: Option<Arc<LiveUsers>>) -> Access {
        Access {
            anonymous,
            users,
            throttle: Mutex::new(Throttle::new(ThrottlePolicy::default())),
            started: Instant::now(),
        }
    }

    /// The role of the session `token` stands for; `None` for a token of no session this
    /// server opens (or of a user no longer in the file).
    pub fn role(&self, token: &UserToken) -> Option<Role> {
        if token.is_anonymous() {
            return self.anonymous;
        }
        let name = token.0.strip_prefix(USER_TOKEN)?;
        // As the file is now: a user removed since the login can do nothing more.
        self.users.as_ref()?.current().user(name).map(|user| user.role)
    }

    /// Who a session is, for the log: `opcua user "alice"`, `opcua anonymous session`.
    pub fn caller(token: &UserToken) -> String {
        match token.0.strip_prefix(USER_TOKEN) {
            Some(name) if !token.is_anonymous() => format!("opcua user {name:?}"),
            _ => "opcua anonymous session".to_string(),
        }
    }

    /// Whether the session of `token` may do `action`.
    pub fn may(&self, token: &UserToken, action: Action) -> bool {
        self.role(token).is_some_and(|role| role.may(action))
    }

    fn throttle(&self) -> std::sync::MutexGuard<'_, Throttle<String>> {
        self.throttle.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Records a failed login of `username` at `now`, and logs the run's first failure and a
    /// run it ended.
    fn failed(&self, username: &str, now: std::time::Duration) {
        let failure = self.throttle().failure(username.to_string(), now);
        if failure.first_of_run {
            log::warn!(
                "opcua: failed login for user name {username:?} (logged once until it succeeds \
                 or stays quiet for 15 minutes)"
            );
        }
        if let Some(ended) = failure.ended {
            log::info!(
                "opcua: {} failed logins for user name {:?} ended",
                ended.failures,
                ended.source
            );
        }
    }

    /// Whether `endpoint` takes user names: never where the channel has no security (the
    /// password would cross the network as the client chose to send it, possibly in clear).
    fn takes_names(&self, endpoint: &ServerEndpoint) -> bool {
        self.users.is_some() && endpoint.security_policy() != SecurityPolicy::None
    }
}

fn refused(text: &'static str) -> opcua::types::Error {
    opcua::types::Error::new(StatusCode::BadUserAccessDenied, text)
}

#[async_trait::async_trait]
impl AuthManager for Access {
    async fn authenticate_anonymous_token(
        &self,
        _endpoint: &ServerEndpoint,
    ) -> Result<(), opcua::types::Error> {
        if self.anonymous.is_some() {
            Ok(())
        } else {
            Err(opcua::types::Error::new(
                StatusCode::BadIdentityTokenRejected,
                "anonymous sessions are refused ([opcua] anonymous = \"none\")",
            ))
        }
    }

    async fn authenticate_username_identity_token(
        &self,
        endpoint: &ServerEndpoint,
        username: &str,
        password: &Password,
    ) -> Result<UserToken, opcua::types::Error> {
        let Some(users) = self.users.as_ref().filter(|_| self.takes_names(endpoint)) else {
            return Err(opcua::types::Error::new(
                StatusCode::BadIdentityTokenRejected,
                "no user names on this endpoint",
            ));
        };
        let now = self.started.elapsed();
        if self.throttle().check(&username.to_string(), now).is_err() {
            // An attempt while the name waits counts as a failure too (unverified): it lengthens
            // the wait, so that guessing faster than the wait gains nothing.
            self.failed(username, now);
            return Err(refused("too many failed logins for this user name: wait"));
        }
        // Argon2 takes tens of milliseconds by design, and the file may be read again: on a
        // blocking thread, not on one of the two workers that serve every session.
        let (live, name, secret) =
            (Arc::clone(users), username.to_string(), password.get().to_string());
        let role: Option<Role> =
            tokio::task::spawn_blocking(move || live.refresh().verify(&name, secret.as_bytes()))
                .await
                .unwrap_or(None);
        let now = self.started.elapsed();
        match role {
            Some(role) => {
                if let Some(ended) = self.throttle().success(&username.to_string()) {
                    log::info!(
                        "opcua: user {:?} logged in after {} failed attempts",
                        ended.source,
                        ended.failures
                    );
                }
                log::debug!("opcua: user {username:?} ({}) logged in", role.name());
                Ok(UserToken(format!("{USER_TOKEN}{username}")))
            }
            None => {
                self.failed(username, now);
                Err(refused("wrong user name or password"))
            }
        }
    }

    /// A node's write bit for the session: only for a role that may write (the node has it
    /// only if the config makes its variable writable).
    fn effective_user_access_level(
        &self,
        token: &UserToken,
        user_access_level: AccessLevel,
        _node_id: &NodeId,
    ) -> AccessLevel {
        if self.may(token, Action::Write) {
            user_access_level
        } else {
            user_access_level - AccessLevel::CURRENT_WRITE
        }
    }

    /// The PLC's methods for the roles that may do what they do; no other method is served.
    fn is_user_executable(&self, token: &UserToken, method_id: &NodeId) -> bool {
        let Identifier::String(id) = &method_id.identifier else { return false };
        METHODS
            .iter()
            .find(|(name, _)| id.as_ref() == *name)
            .is_some_and(|(_, action)| self.may(token, *action))
    }

    fn user_token_policies(&self, endpoint: &ServerEndpoint) -> Vec<UserTokenPolicy> {
        let mut policies = Vec::new();
        if self.anonymous.is_some() {
            policies.push(UserTokenPolicy {
                policy_id: UAString::from("anonymous"),
                token_type: UserTokenType::Anonymous,
                issued_token_type: UAString::null(),
                issuer_endpoint_url: UAString::null(),
                security_policy_uri: UAString::null(),
            });
        }
        if self.takes_names(endpoint) {
            policies.push(UserTokenPolicy {
                policy_id: user_pass_security_policy_id(endpoint),
                token_type: UserTokenType::UserName,
                issued_token_type: UAString::null(),
                issuer_endpoint_url: UAString::null(),
                security_policy_uri: UAString::null(),
            });
        }
        policies
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use opcua::types::MessageSecurityMode;
    use plcd_core::users::{hash_password, HashCosts};

    /// Small costs: the tests check who gets in, not the hash's strength.
    const COSTS: HashCosts = HashCosts { memory_kib: 64, passes: 1, lanes: 1 };

    fn users() -> Arc<LiveUsers> {
        let phc = hash_password(b"correct horse", &[7; plcd_core::users::SALT_LEN], COSTS).unwrap();
        let path = std::env::temp_dir().join(format!(
            "plcd-opcua-users-{}-{:?}",
            std::process::id(),
            std::thread::current().id()
        ));
        std::fs::write(&path, format!("alice:operator:{phc}\n")).unwrap();
        let live = LiveUsers::open(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        Arc::new(live)
    }

    fn secure() -> ServerEndpoint {
        ServerEndpoint::new(
            "/",
            SecurityPolicy::Basic256Sha256,
            MessageSecurityMode::SignAndEncrypt,
            &[],
        )
    }

    fn kinds(access: &Access, endpoint: &ServerEndpoint) -> Vec<UserTokenType> {
        access.user_token_policies(endpoint).iter().map(|p| p.token_type).collect()
    }

    fn login(access: &Access, name: &str, password: &str) -> Result<UserToken, StatusCode> {
        let runtime = tokio::runtime::Builder::new_current_thread().build().unwrap();
        runtime
            .block_on(access.authenticate_username_identity_token(
                &secure(),
                name,
                &Password::new(password.to_string()),
            ))
            .map_err(|e| e.status())
    }

    #[test]
    fn user_names_are_offered_only_with_a_users_file_and_a_secure_channel() {
        let none = ServerEndpoint::new_none("/", &[]);
        let named = Access::new(None, Some(users()));
        assert_eq!(kinds(&named, &secure()), [UserTokenType::UserName]);
        assert_eq!(kinds(&named, &none), []);
        let open = Access::new(Some(Role::Viewer), None);
        assert_eq!(kinds(&open, &secure()), [UserTokenType::Anonymous]);
        assert_eq!(kinds(&open, &none), [UserTokenType::Anonymous]);
        assert_eq!(kinds(&Access::new(None, None), &secure()), []);
    }

    #[test]
    fn a_user_of_the_file_logs_in_and_a_wrong_password_or_name_does_not() {
        let access = Access::new(None, Some(users()));
        assert_eq!(login(&access, "alice", "correct horse"), Ok(UserToken("user:alice".into())));
        assert_eq!(login(&access, "alice", "wrong"), Err(StatusCode::BadUserAccessDenied));
        assert_eq!(login(&access, "bob", "correct horse"), Err(StatusCode::BadUserAccessDenied));
        let without = Access::new(None, None);
        assert_eq!(
            login(&without, "alice", "correct horse"),
            Err(StatusCode::BadIdentityTokenRejected)
        );
    }

    #[test]
    fn roles_decide_writes_and_methods() {
        let access = Access::new(Some(Role::Viewer), Some(users()));
        let alice = UserToken("user:alice".into());
        let anonymous = UserToken(opcua::server::ANONYMOUS_USER_TOKEN_ID.into());
        let node = NodeId::new(2, "main.setpoint");
        let rw = AccessLevel::CURRENT_READ | AccessLevel::CURRENT_WRITE;
        let level = |token: &UserToken| access.effective_user_access_level(token, rw, &node).bits();
        assert_eq!(level(&alice), rw.bits(), "an operator");
        assert_eq!(level(&anonymous), AccessLevel::CURRENT_READ.bits(), "an anonymous viewer");
        let run = NodeId::new(2, "PLC.Run");
        assert!(access.is_user_executable(&alice, &run));
        assert!(access.is_user_executable(&alice, &NodeId::new(2, "PLC.Reset")));
        assert!(!access.is_user_executable(&anonymous, &run));
        assert!(!access.is_user_executable(&alice, &NodeId::new(2, "PLC.Load")), "not a method");
        // A token of no user of the file, and a user name that spells the anonymous token.
        assert_eq!(access.role(&UserToken("user:mallory".into())), None);
        assert_eq!(access.role(&UserToken("alice".into())), None);
        let open = Access::new(Some(Role::Operator), None);
        assert!(open.is_user_executable(&anonymous, &NodeId::new(2, "PLC.Stop")));
        assert_eq!(Access::caller(&alice), "opcua user \"alice\"");
        assert_eq!(Access::caller(&anonymous), "opcua anonymous session");
    }

    #[test]
    fn a_name_that_failed_three_times_waits_even_with_the_right_password() {
        let access = Access::new(None, Some(users()));
        for _ in 0..3 {
            assert_eq!(login(&access, "alice", "wrong"), Err(StatusCode::BadUserAccessDenied));
        }
        // The wait (1 s) has not passed: refused before the password is looked at, and the
        // attempt counts, so the wait grows.
        assert_eq!(login(&access, "alice", "correct horse"), Err(StatusCode::BadUserAccessDenied));
        let wait = access.throttle().check(&"alice".to_string(), access.started.elapsed());
        assert!(wait.is_err_and(|left| left > std::time::Duration::from_secs(1)), "{wait:?}");
    }
}

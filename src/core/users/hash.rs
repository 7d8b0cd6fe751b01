//! Password hashes: argon2id in the PHC string format, through RustCrypto's `argon2` crate (the
//! hashing, and the constant-time comparison of the result, are the crate's).

use argon2::password_hash::{PasswordHash, PasswordHasher, PasswordVerifier, SaltString};
use argon2::{Algorithm, Argon2, Params, Version};

use super::UsersError;

/// The bytes of a salt: 16, the length the PHC format recommends.
pub const SALT_LEN: usize = 16;

/// The costs of argon2id: memory, passes and lanes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct HashCosts {
    /// `m`: memory in KiB.
    pub memory_kib: u32,
    /// `t`: passes over the memory.
    pub passes: u32,
    /// `p`: lanes (the crate computes them one after the other: no threads in the core).
    pub lanes: u32,
}

impl HashCosts {
    /// The costs `plcd user` hashes with: 32 MiB, 3 passes, 1 lane. One verify takes about
    /// 65 ms on the 2-core x86-64 development machine (docs/USERS.md has the figures), a few
    /// times that on a Raspberry Pi 4, and needs 32 MiB while it runs; above the minimum OWASP
    /// recommends (19 MiB and 2 passes).
    pub const DEFAULT: HashCosts = HashCosts { memory_kib: 32 * 1024, passes: 3, lanes: 1 };

    /// The most a hash in the file may ask for: 256 MiB, 10 passes, 8 lanes. A dearer hash
    /// (made elsewhere for a bigger machine) would make every login a memory or time problem
    /// for the daemon, so the file refuses it rather than the login stalling.
    pub const MAX: HashCosts = HashCosts { memory_kib: 256 * 1024, passes: 10, lanes: 8 };

    fn params(self) -> Result<Params, UsersError> {
        Params::new(self.memory_kib, self.passes, self.lanes, None)
            .map_err(|e| UsersError::Hash(e.to_string()))
    }
}

/// A verify against this hash costs what a verify against a hash of [`HashCosts::DEFAULT`]
/// does: [`super::UsersFile::verify`] checks an unknown user's password against it, so that
/// the answer takes as long as for a known user with a wrong password and the time tells an
/// attacker nothing about which names exist. Its result is thrown away: no password opens a
/// login with it. (It is the hash of `secret`; a unit test checks that its costs are the
/// default ones.)
pub(super) const DUMMY: &str = "$argon2id$v=19$m=32768,t=3,p=1$BwcHBwcHBwcHBwcHBwcHBw$\
                                F9r++iKxX8tAKGz04Sxqt9sOeEoc6eMGuefbYC4h3R0";

/// The PHC string of `password` hashed with argon2id at `costs` and `salt` (the caller draws
/// it from a random source: the core has none). An empty password is refused.
pub fn hash_password(
    password: &[u8],
    salt: &[u8; SALT_LEN],
    costs: HashCosts,
) -> Result<String, UsersError> {
    if password.is_empty() {
        return Err(UsersError::EmptyPassword);
    }
    let salt = SaltString::encode_b64(salt).map_err(|e| UsersError::Hash(e.to_string()))?;
    let hasher = Argon2::new(Algorithm::Argon2id, Version::V0x13, costs.params()?);
    let hash =
        hasher.hash_password(password, &salt).map_err(|e| UsersError::Hash(e.to_string()))?;
    Ok(hash.to_string())
}

/// What is wrong with a PHC string as a hash of the users file, if anything. The message never
/// quotes the string: it holds the hash.
pub(super) fn check(phc: &str) -> Result<(), String> {
    let hash = PasswordHash::new(phc).map_err(|e| format!("not a PHC hash string: {e}"))?;
    if hash.algorithm != Algorithm::Argon2id.ident() {
        return Err(format!(
            "the hash is {}, plcd accepts argon2id only (make it with `plcd user add`)",
            hash.algorithm
        ));
    }
    if hash.version != Some(Version::V0x13.into()) {
        return Err("the hash is not of argon2 version 19 (`v=19`)".into());
    }
    let params = Params::try_from(&hash).map_err(|e| format!("bad argon2 parameters: {e}"))?;
    let costs =
        HashCosts { memory_kib: params.m_cost(), passes: params.t_cost(), lanes: params.p_cost() };
    let max = HashCosts::MAX;
    if costs.memory_kib > max.memory_kib || costs.passes > max.passes || costs.lanes > max.lanes {
        return Err(format!(
            "the hash costs m={},t={},p={}, more than plcd verifies (at most m={},t={},p={})",
            costs.memory_kib, costs.passes, costs.lanes, max.memory_kib, max.passes, max.lanes
        ));
    }
    if hash.salt.is_none() || hash.hash.is_none() {
        return Err("the hash string has no salt or no hash".into());
    }
    Ok(())
}

/// Whether `password` matches `phc`, a string [`check`] accepted. The comparison of the
/// computed hash with the stored one is the crate's, in constant time.
pub(super) fn matches(phc: &str, password: &[u8]) -> bool {
    let Ok(hash) = PasswordHash::new(phc) else { return false };
    // The parameters, salt and version are the hash's own: `Argon2::default()` only picks the
    // implementation.
    Argon2::default().verify_password(password, &hash).is_ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    const SALT: [u8; SALT_LEN] = [7; SALT_LEN];

    #[test]
    fn a_hash_is_argon2id_at_the_costs_and_salt_given_and_matches_its_password() {
        let costs = HashCosts { memory_kib: 64, passes: 1, lanes: 1 };
        let phc = hash_password(b"s3cret", &SALT, costs).unwrap();
        assert!(phc.starts_with("$argon2id$v=19$m=64,t=1,p=1$BwcHBwcHBwcHBwcHBwcHBw$"), "{phc}");
        assert_eq!(check(&phc), Ok(()));
        assert!(matches(&phc, b"s3cret"));
        assert!(!matches(&phc, b"s3cret "));
        assert!(!matches(&phc, b""));
        // Another salt, another hash.
        assert_ne!(hash_password(b"s3cret", &[8; SALT_LEN], costs).unwrap(), phc);
        assert_eq!(hash_password(b"", &SALT, costs), Err(UsersError::EmptyPassword));
    }

    #[test]
    fn the_dummy_hash_costs_what_a_default_hash_costs() {
        let dummy = PasswordHash::new(DUMMY).unwrap();
        let params = Params::try_from(&dummy).unwrap();
        let d = HashCosts::DEFAULT;
        assert_eq!(
            (params.m_cost(), params.t_cost(), params.p_cost()),
            (d.memory_kib, d.passes, d.lanes)
        );
        assert_eq!(check(DUMMY), Ok(()));
        assert_eq!(dummy.hash.map(|h| h.len()), Some(32), "the default output length");
    }

    #[test]
    fn only_argon2id_of_version_19_within_the_costs_is_accepted() {
        let cases = [
            ("$argon2i$v=19$m=64,t=1,p=1$BwcHBwcHBwcHBwcHBwcHBw$AAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAA", "argon2i, plcd accepts argon2id only"),
            ("$argon2id$v=16$m=64,t=1,p=1$BwcHBwcHBwcHBwcHBwcHBw$AAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAA", "version 19"),
            ("$argon2id$v=19$m=524288,t=1,p=1$BwcHBwcHBwcHBwcHBwcHBw$AAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAA", "more than plcd verifies"),
            ("$argon2id$v=19$m=64,t=1,p=1", "no salt or no hash"),
            ("hunter2", "not a PHC hash string"),
            ("$argon2id$v=19$m=1,t=1,p=1$BwcHBwcHBwcHBwcHBwcHBw$AAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAA", "bad argon2 parameters"),
        ];
        for (phc, wanted) in cases {
            let message = check(phc).unwrap_err();
            assert!(message.contains(wanted), "{phc}: {message}");
            assert!(!message.contains("hunter2") && !message.contains("AAAA"), "{message}");
        }
    }
}

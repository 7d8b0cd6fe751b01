//! A users file (`[users] file`, docs/USERS.md): parsed as `plcd check` and the services parse
//! it. Rejected, its diagnostics point into it and quote no hash; accepted, its users are what
//! its lines say, its text comes back byte for byte, and removing each user takes out exactly
//! that user's line. No password is verified: a hash of the file may ask for 256 MiB and ten
//! passes, a second of work per input, and verifying is the argon2 crate's.

use std::path::Path;

use plcd::users::{check_name, UsersFile};

use crate::assert_located;

pub fn run(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let path = Path::new("users");
    let file = match UsersFile::parse(text, path) {
        Ok(file) => file,
        Err(diags) => {
            assert_located(&diags, path, text);
            // The third field of a line is its hash: no message quotes one (a long one; a
            // short field may be a word any message holds).
            for line in text.lines() {
                let Some(hash) = line.trim().splitn(3, ':').nth(2) else { continue };
                if hash.len() >= 16 {
                    assert!(
                        diags.iter().all(|d| !d.message.contains(hash)),
                        "a diagnostic quotes the hash {hash:?}: {diags:?}"
                    );
                }
            }
            return;
        }
    };
    assert_eq!(file.text(), text, "the text as read");
    let lines: Vec<&str> = text.split_inclusive('\n').collect();
    for (n, user) in file.users().iter().enumerate() {
        assert_eq!(check_name(&user.name), Ok(()), "{user:?}");
        assert!(file.users()[..n].iter().all(|u| u.name != user.name), "{user:?} twice");
        let line = lines[user.line as usize - 1].trim();
        assert!(line.starts_with(&format!("{}:{}:", user.name, user.role)), "{user:?}: {line:?}");
        let mut without = file.clone();
        assert_eq!(without.remove(&user.name), Ok(user.role));
        let mut expected = lines.clone();
        expected.remove(user.line as usize - 1);
        assert_eq!(without.text(), expected.concat(), "removing {user:?}");
        assert_eq!(without.users().len(), file.users().len() - 1);
    }
}

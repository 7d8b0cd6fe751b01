//! Who may use the control socket: root, the daemon's user, and the members of one group
//! (`[control] group`, by default the daemon's), decided on each peer's `SO_PEERCRED`
//! credentials. The socket file's mode and group ([`super::socket`]) already keep others from
//! connecting; each peer is checked as well so that the rule does not rest on the file's
//! permissions alone.

use std::fs;

use super::Peer;

/// Who may connect: root, the daemon's user, and members of one group.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Policy {
    pub(super) daemon_uid: u32,
    pub(super) allowed_gid: u32,
}

impl Policy {
    /// Whether `peer` is admitted. `supplementary` gives the peer's supplementary groups; it is
    /// only called when the cheaper checks did not decide (it reads /proc).
    pub(super) fn admits(&self, peer: &Peer, supplementary: impl FnOnce() -> Vec<u32>) -> bool {
        peer.uid == 0
            || peer.uid == self.daemon_uid
            || peer.gid == self.allowed_gid
            || supplementary().contains(&self.allowed_gid)
    }
}

/// The `Groups:` line of a `/proc/<pid>/status`.
fn parse_groups(status: &str) -> Vec<u32> {
    status
        .lines()
        .find_map(|line| line.strip_prefix("Groups:"))
        .map(|list| list.split_whitespace().filter_map(|g| g.parse().ok()).collect())
        .unwrap_or_default()
}

/// The supplementary groups of process `pid`, empty when they cannot be read. SO_PEERCRED has
/// only the primary group; the pid is the one that connected, so a process that exited (and a
/// recycled pid) is possible but can only be refused: the answer then is "not a member".
pub(super) fn supplementary_groups(pid: i32) -> Vec<u32> {
    if pid <= 0 {
        return Vec::new();
    }
    fs::read_to_string(format!("/proc/{pid}/status")).map(|s| parse_groups(&s)).unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;

    const POLICY: Policy = Policy { daemon_uid: 990, allowed_gid: 985 };

    fn peer(uid: u32, gid: u32) -> Peer {
        Peer { pid: 4242, uid, gid }
    }

    #[test]
    fn root_the_daemons_user_and_the_group_are_admitted() {
        let none = Vec::new;
        assert!(POLICY.admits(&peer(0, 0), none));
        assert!(POLICY.admits(&peer(0, 1000), none));
        assert!(POLICY.admits(&peer(990, 1000), none));
        assert!(POLICY.admits(&peer(1000, 985), none));
        assert!(POLICY.admits(&peer(1000, 1000), || vec![4, 985, 27]));
    }

    #[test]
    fn others_are_refused() {
        assert!(!POLICY.admits(&peer(1000, 1000), Vec::new));
        assert!(!POLICY.admits(&peer(1000, 1000), || vec![4, 24, 27]));
        assert!(!POLICY.admits(&peer(65534, 65534), || vec![65534]));
        // The daemon's gid is not its uid.
        assert!(!POLICY.admits(&peer(985, 990), Vec::new));
    }

    #[test]
    fn supplementary_groups_are_read_only_when_needed() {
        let never = || -> Vec<u32> { panic!("read /proc although the uid decided") };
        assert!(POLICY.admits(&peer(0, 7), never));
        assert!(POLICY.admits(&peer(990, 7), never));
        assert!(POLICY.admits(&peer(7, 985), never));
    }

    #[test]
    fn the_groups_line_is_parsed() {
        let status = "Name:\tplcctl\nUid:\t1000\t1000\t1000\t1000\nGid:\t1000\t1000\t1000\t1000\n\
                      Groups:\t4 24 27 985 \nNStgid:\t1\n";
        assert_eq!(parse_groups(status), [4, 24, 27, 985]);
        assert_eq!(parse_groups("Name:\tx\nGroups:\t\nPid:\t3\n"), Vec::<u32>::new());
        assert_eq!(parse_groups("Name:\tx\n"), Vec::<u32>::new());
        assert_eq!(parse_groups("Groups:\t4 junk 5\n"), [4, 5]);
    }

    #[test]
    fn our_own_supplementary_groups_are_found() {
        let ours: Vec<u32> =
            nix::unistd::getgroups().unwrap().into_iter().map(|g| g.as_raw()).collect();
        let mut read = supplementary_groups(std::process::id() as i32);
        read.sort_unstable();
        let mut ours = ours;
        ours.sort_unstable();
        ours.dedup();
        assert_eq!(read, ours);
        assert!(supplementary_groups(0).is_empty());
        assert!(supplementary_groups(-1).is_empty());
    }
}

//! The names of the system libraries plcd ships (`[st] system_libraries`): which ones exist
//! and which a project uses. Their sources are [`crate::st::libraries`]'s.

use std::fmt;

/// One library plcd ships.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SystemLibrary {
    /// TwinCAT's `Tc2_System`: memory functions, CPU counter, task index, ADS log messages.
    Tc2System,
    /// TwinCAT's `Tc2_Utilities`: the string functions and the ring buffer public code uses.
    Tc2Utilities,
    /// TwinCAT's `Tc2_Standard`: the WSTRING function `WLEN` (its standard blocks are the
    /// prelude's).
    Tc2Standard,
    /// TwinCAT's `Tc2_Math`: rounding and modulo functions on `LREAL` (`FLOOR`, `MODABS` …).
    Tc2Math,
    /// CODESYS's `SysFile` (with its `SysTypes` and `SysDir`'s `CmpErrors`): declared so that
    /// code using files compiles; plcd gives programs no file system, every call fails.
    SysFile,
    /// TwinCAT's `Tc2_TcpIp` (TF6310's TCP/IP Connection Server): declared so that code using
    /// sockets compiles; plcd has no ADS router, every block answers error 6.
    Tc2TcpIp,
}

impl SystemLibrary {
    /// Every library, in the order their names are listed in messages.
    pub const ALL: [SystemLibrary; 6] = [
        SystemLibrary::Tc2System,
        SystemLibrary::Tc2Utilities,
        SystemLibrary::Tc2Standard,
        SystemLibrary::Tc2Math,
        SystemLibrary::SysFile,
        SystemLibrary::Tc2TcpIp,
    ];

    /// The name the config and the project's code write, as the vendor spells it.
    pub fn name(self) -> &'static str {
        match self {
            SystemLibrary::Tc2System => "Tc2_System",
            SystemLibrary::Tc2Utilities => "Tc2_Utilities",
            SystemLibrary::Tc2Standard => "Tc2_Standard",
            SystemLibrary::Tc2Math => "Tc2_Math",
            SystemLibrary::SysFile => "SysFile",
            SystemLibrary::Tc2TcpIp => "Tc2_TcpIp",
        }
    }

    /// The library named `name` (any case, as ST names are).
    pub fn from_name(name: &str) -> Option<SystemLibrary> {
        SystemLibrary::ALL.into_iter().find(|l| l.name().eq_ignore_ascii_case(name))
    }

    /// The set with this library alone.
    fn bit(self) -> u8 {
        1 << SystemLibrary::ALL.iter().position(|&l| l == self).unwrap_or(0)
    }
}

impl fmt::Display for SystemLibrary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A set of [`SystemLibrary`]s (`[st] system_libraries`); `Copy`, as the dialect that carries
/// it is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SystemLibraries(u8);

impl SystemLibraries {
    /// No library: the default.
    pub const NONE: SystemLibraries = SystemLibraries(0);

    /// The set with `library` added.
    pub fn with(self, library: SystemLibrary) -> SystemLibraries {
        SystemLibraries(self.0 | library.bit())
    }

    /// The set with the libraries its libraries use: `Tc2_Utilities` uses `Tc2_System`'s
    /// types and MEMCPY, `Tc2_TcpIp` its `T_AmsNetID` and `T_IPv4Addr`, as TwinCAT's do.
    pub fn with_dependencies(self) -> SystemLibraries {
        if self.contains(SystemLibrary::Tc2Utilities) || self.contains(SystemLibrary::Tc2TcpIp) {
            self.with(SystemLibrary::Tc2System)
        } else {
            self
        }
    }

    pub fn contains(self, library: SystemLibrary) -> bool {
        self.0 & library.bit() != 0
    }

    pub fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// The libraries of the set, in [`SystemLibrary::ALL`]'s order.
    pub fn iter(self) -> impl Iterator<Item = SystemLibrary> {
        SystemLibrary::ALL.into_iter().filter(move |&l| self.contains(l))
    }

    /// Every known name, for the message about an unknown one.
    pub fn known_names() -> String {
        let names: Vec<String> =
            SystemLibrary::ALL.iter().map(|l| format!("`{}`", l.name())).collect();
        names.join(", ")
    }
}

impl FromIterator<SystemLibrary> for SystemLibraries {
    fn from_iter<I: IntoIterator<Item = SystemLibrary>>(iter: I) -> SystemLibraries {
        iter.into_iter().fold(SystemLibraries::NONE, SystemLibraries::with)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_any_case_and_dependencies() {
        assert_eq!(SystemLibrary::from_name("tc2_tcpip"), Some(SystemLibrary::Tc2TcpIp));
        assert_eq!(
            SystemLibrary::from_name("Tc2_TcpIp").map(SystemLibrary::name),
            Some("Tc2_TcpIp")
        );
        assert_eq!(SystemLibrary::from_name("Tc3_EventLogger"), None);
        // Tc2_TcpIp and Tc2_Utilities bring Tc2_System; the others bring nothing.
        for lib in [SystemLibrary::Tc2TcpIp, SystemLibrary::Tc2Utilities] {
            let set = SystemLibraries::NONE.with(lib).with_dependencies();
            assert!(set.contains(SystemLibrary::Tc2System) && set.contains(lib));
        }
        let math = SystemLibraries::NONE.with(SystemLibrary::Tc2Math).with_dependencies();
        assert_eq!(math.iter().collect::<Vec<_>>(), vec![SystemLibrary::Tc2Math]);
        assert!(SystemLibraries::known_names().ends_with("`SysFile`, `Tc2_TcpIp`"));
    }
}

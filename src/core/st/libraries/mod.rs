//! The system libraries plcd ships (`[st] system_libraries`, docs/ST.md "System libraries"):
//! the declarations of TwinCAT's `Tc2_System` and `Tc2_Utilities` and of CODESYS's `SysFile`
//! that public TwinCAT code calls, written in Structured Text and embedded in the binary as the
//! prelude is.
//!
//! This folder owns those sources, one folder per library (`tc2_system/*.st`, …). Every line is
//! plcd's own, written from the interface each vendor documents (Beckhoff Infosys, "TwinCAT 3
//! PLC Lib: Tc2_System" and "Tc2_Utilities"; the CODESYS online help of `SysFile` and
//! `CmpErrors`); each file says which pages it follows.
//!
//! A library named in the config is compiled after the project's own files and before the
//! prelude ([`crate::st::compile`]): its TYPEs and VAR_GLOBALs are the project's, its POUs are
//! checked and compiled only when the project calls them ("what no program calls costs
//! nothing"). As TwinCAT resolves the project first, a project's declaration of a name the
//! library declares too replaces the library's; the library's name before a declaration
//! (`Tc2_System.MEMCPY`) names it as `[st] namespaces` do. A diagnostic inside a library names
//! its embedded file: `<Tc2_System>/mem.st:12:5`.

use std::fmt;

/// One library plcd ships.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SystemLibrary {
    /// TwinCAT's `Tc2_System`: memory functions, CPU counter, task index, ADS log messages.
    Tc2System,
    /// TwinCAT's `Tc2_Utilities`: the string functions and the ring buffer public code uses.
    Tc2Utilities,
    /// CODESYS's `SysFile` (with its `SysTypes` and `SysDir`'s `CmpErrors`): declared so that
    /// code using files compiles; plcd gives programs no file system, every call fails.
    SysFile,
}

/// An embedded source: its name in diagnostics (`<Tc2_System>/mem.st`) and its text.
pub type Source = (&'static str, &'static str);

impl SystemLibrary {
    /// Every library, in the order their names are listed in messages.
    pub const ALL: [SystemLibrary; 3] =
        [SystemLibrary::Tc2System, SystemLibrary::Tc2Utilities, SystemLibrary::SysFile];

    /// The name the config and the project's code write, as the vendor spells it.
    pub fn name(self) -> &'static str {
        match self {
            SystemLibrary::Tc2System => "Tc2_System",
            SystemLibrary::Tc2Utilities => "Tc2_Utilities",
            SystemLibrary::SysFile => "SysFile",
        }
    }

    /// The library named `name` (any case, as ST names are).
    pub fn from_name(name: &str) -> Option<SystemLibrary> {
        SystemLibrary::ALL.into_iter().find(|l| l.name().eq_ignore_ascii_case(name))
    }

    /// The names that qualify a declaration of the library (`Tc2_System.MEMCPY`,
    /// `SysFile.SysTypes.RTS_IEC_RESULT`, `SysDir.CmpErrors.Errors.ERR_OK`).
    pub fn namespaces(self) -> &'static [&'static str] {
        match self {
            SystemLibrary::Tc2System => &["Tc2_System"],
            SystemLibrary::Tc2Utilities => &["Tc2_Utilities"],
            SystemLibrary::SysFile => &["SysFile", "SysTypes", "SysDir", "CmpErrors"],
        }
    }

    /// The library's sources.
    pub fn sources(self) -> &'static [Source] {
        match self {
            SystemLibrary::Tc2System => &[
                ("<Tc2_System>/types.st", include_str!("tc2_system/types.st")),
                ("<Tc2_System>/mem.st", include_str!("tc2_system/mem.st")),
                ("<Tc2_System>/time.st", include_str!("tc2_system/time.st")),
                ("<Tc2_System>/adslog.st", include_str!("tc2_system/adslog.st")),
            ],
            SystemLibrary::Tc2Utilities => &[
                ("<Tc2_Utilities>/strings.st", include_str!("tc2_utilities/strings.st")),
                ("<Tc2_Utilities>/ringbuffer.st", include_str!("tc2_utilities/ringbuffer.st")),
            ],
            SystemLibrary::SysFile => &[
                ("<SysFile>/Errors.st", include_str!("sysfile/Errors.st")),
                ("<SysFile>/sysfile.st", include_str!("sysfile/sysfile.st")),
            ],
        }
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
    /// types and MEMCPY, as TwinCAT's does.
    pub fn with_dependencies(self) -> SystemLibraries {
        if self.contains(SystemLibrary::Tc2Utilities) {
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

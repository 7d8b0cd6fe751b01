//! The system libraries plcd ships (`[st] system_libraries`, docs/ST.md "System libraries"):
//! the declarations of TwinCAT's `Tc2_System`, `Tc2_Utilities`, `Tc2_Standard`, `Tc2_Math` and `Tc2_TcpIp` and of
//! CODESYS's `SysFile` that public TwinCAT code calls, written in Structured Text and embedded in the binary as the
//! prelude is.
//!
//! This folder owns those sources, one folder per library (`tc2_system/*.st`, …). Every line is
//! plcd's own, written from the interface each vendor documents (Beckhoff Infosys, "TwinCAT 3
//! PLC Lib: Tc2_System", "Tc2_Utilities", "Tc2_Standard" and "Tc2_Math", "TF6310 TC3 TCP/IP"; the CODESYS online help of `SysFile` and
//! `CmpErrors`); each file says which pages it follows.
//!
//! A library named in the config is compiled after the project's own files and before the
//! prelude ([`compile`](mod@crate::st::compile)): its TYPEs and VAR_GLOBALs are the project's, its POUs are
//! checked and compiled only when the project calls them ("what no program calls costs
//! nothing"). As TwinCAT resolves the project first, a project's declaration of a name the
//! library declares too replaces the library's; the library's name before a declaration
//! (`Tc2_System.MEMCPY`) names it as `[st] namespaces` do. A diagnostic inside a library names
//! its embedded file: `<Tc2_System>/mem.st:12:5`.

pub use crate::config::{SystemLibraries, SystemLibrary};

/// An embedded source: its name in diagnostics (`<Tc2_System>/mem.st`) and its text.
pub type Source = (&'static str, &'static str);

/// The names that qualify a declaration of the library (`Tc2_System.MEMCPY`,
/// `SysFile.SysTypes.RTS_IEC_RESULT`, `SysDir.CmpErrors.Errors.ERR_OK`).
pub fn namespaces(library: SystemLibrary) -> &'static [&'static str] {
    match library {
        SystemLibrary::Tc2System => &["Tc2_System"],
        SystemLibrary::Tc2Utilities => &["Tc2_Utilities"],
        SystemLibrary::Tc2Standard => &["Tc2_Standard"],
        SystemLibrary::Tc2Math => &["Tc2_Math"],
        SystemLibrary::SysFile => &["SysFile", "SysTypes", "SysDir", "CmpErrors"],
        SystemLibrary::Tc2TcpIp => &["Tc2_TcpIp"],
    }
}

/// The library's sources.
pub fn sources(library: SystemLibrary) -> &'static [Source] {
    match library {
        SystemLibrary::Tc2System => &[
            ("<Tc2_System>/types.st", include_str!("tc2_system/types.st")),
            ("<Tc2_System>/mem.st", include_str!("tc2_system/mem.st")),
            ("<Tc2_System>/time.st", include_str!("tc2_system/time.st")),
            (
                "<Tc2_System>/TwinCAT_SystemInfoVarList.st",
                include_str!("tc2_system/TwinCAT_SystemInfoVarList.st"),
            ),
            ("<Tc2_System>/task.st", include_str!("tc2_system/task.st")),
            ("<Tc2_System>/adslog.st", include_str!("tc2_system/adslog.st")),
            ("<Tc2_System>/file.st", include_str!("tc2_system/file.st")),
            ("<Tc2_System>/ads.st", include_str!("tc2_system/ads.st")),
        ],
        SystemLibrary::Tc2Utilities => &[
            ("<Tc2_Utilities>/strings.st", include_str!("tc2_utilities/strings.st")),
            ("<Tc2_Utilities>/ringbuffer.st", include_str!("tc2_utilities/ringbuffer.st")),
            ("<Tc2_Utilities>/hexstr.st", include_str!("tc2_utilities/hexstr.st")),
            ("<Tc2_Utilities>/format.st", include_str!("tc2_utilities/format.st")),
            ("<Tc2_Utilities>/fmtstr.st", include_str!("tc2_utilities/fmtstr.st")),
            ("<Tc2_Utilities>/time.st", include_str!("tc2_utilities/time.st")),
            ("<Tc2_Utilities>/syminfo.st", include_str!("tc2_utilities/syminfo.st")),
        ],
        SystemLibrary::Tc2Standard => {
            &[("<Tc2_Standard>/wstring.st", include_str!("tc2_standard/wstring.st"))]
        }
        SystemLibrary::Tc2Math => &[("<Tc2_Math>/math.st", include_str!("tc2_math/math.st"))],
        SystemLibrary::SysFile => &[
            ("<SysFile>/Errors.st", include_str!("sysfile/Errors.st")),
            ("<SysFile>/sysfile.st", include_str!("sysfile/sysfile.st")),
        ],
        SystemLibrary::Tc2TcpIp => &[("<Tc2_TcpIp>/tcpip.st", include_str!("tc2_tcpip/tcpip.st"))],
    }
}

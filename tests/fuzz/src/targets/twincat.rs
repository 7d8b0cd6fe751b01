//! A TwinCAT 3 source file (`.TcPOU`): its XML read for the Structured Text in its CDATA
//! sections, compiled as the scan program of a project and, if accepted, run for a few scans in
//! virtual time. A rejected file's diagnostics point into the XML file itself (its lines, and
//! the line after the last for a POU's end); an accepted one runs twice the same way.

pub const CONFIG: &str = r#"
[plc]
watchdog_ms = 10
[[program]]
name = "main"
file = "MAIN.TcPOU"
task = "scan"
"#;

pub fn run(data: &[u8]) {
    super::program(CONFIG, "MAIN.TcPOU", &[], super::st::STIMULUS, data);
}

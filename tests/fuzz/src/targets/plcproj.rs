//! A TwinCAT PLC project file (`.plcproj`, MSBuild XML): the namespaces it names, read by
//! `st::plcproj::namespaces` alone and then as two files of one project, the library's
//! `lib/Lib.plcproj` (in the `[st] library` folder beside its block `FB_X`) and the program's
//! `App/App.plcproj` (the nearest one above `App/POUs/MAIN.TcPOU`, which names the block
//! `MyLib.FB_X`).
//!
//! Alone: every namespace returned is a name, at a line of the text; every error is at a line
//! of it. In the project: rejected, its diagnostics point into the file; and the project
//! compiles exactly when the file parses and names `MyLib` (the program and the block are
//! valid, so nothing else decides), and then runs twice the same way.

use std::path::{Path, PathBuf};

use plcd::project;

use crate::assert_located;

const CONFIG: &str = r#"
[plc]
watchdog_ms = 10
[[program]]
name = "main"
file = "App/POUs/MAIN.TcPOU"
task = "scan"
[st]
library = ["lib/"]
"#;

const MAIN: &str = r#"<?xml version="1.0" encoding="utf-8"?>
<TcPlcObject Version="1.1.0.1">
  <POU Name="MAIN" Id="{1}" SpecialFunc="None">
    <Declaration><![CDATA[PROGRAM MAIN
VAR
	fbX : MyLib.FB_X;
	n : INT;
END_VAR]]></Declaration>
    <Implementation>
      <ST><![CDATA[fbX();
n := fbX.nCount;]]></ST>
    </Implementation>
  </POU>
</TcPlcObject>
"#;

const FB_X: &str = r#"<?xml version="1.0" encoding="utf-8"?>
<TcPlcObject Version="1.1.0.1">
  <POU Name="FB_X" Id="{2}" SpecialFunc="None">
    <Declaration><![CDATA[FUNCTION_BLOCK FB_X
VAR_OUTPUT
	nCount : INT;
END_VAR]]></Declaration>
    <Implementation>
      <ST><![CDATA[nCount := nCount + 1;]]></ST>
    </Implementation>
  </POU>
</TcPlcObject>
"#;

const LIBRARY: &str = "lib/Lib.plcproj";
const APP: &str = "App/App.plcproj";

pub fn run(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let lines = text.split('\n').count() as u32;
    // a place in the text: a line of it (an error may stand at the end, on the line after the
    // last, as `assert_located` allows) and a column from 1
    let within = |line: u32, col: u32| line >= 1 && line <= lines + 1 && col >= 1;
    let names = match plcd::st::plcproj::namespaces(text) {
        Ok(found) => {
            for ns in &found {
                assert!(plcd::config::is_namespace(&ns.name), "not a name: {ns:?}");
                assert!(within(ns.span.line, ns.span.col), "outside the text: {ns:?}");
            }
            Some(found)
        }
        Err(errors) => {
            assert!(!errors.is_empty(), "an error without a diagnostic");
            for e in &errors {
                assert!(!e.message.trim().is_empty(), "an error without a message: {e:?}");
                assert!(within(e.span.line, e.span.col), "outside the text: {e:?}");
            }
            None
        }
    };
    let names_mylib = names
        .as_ref()
        .is_some_and(|found| found.iter().any(|ns| ns.name.eq_ignore_ascii_case("MyLib")));

    let config = plcd::config::parse(CONFIG, Path::new("plcd.toml")).expect("the target's config");
    let read = |path: &Path| {
        Ok(match path.to_str().unwrap_or_default() {
            "App/POUs/MAIN.TcPOU" => MAIN.to_string(),
            "lib/FB_X.TcPOU" => FB_X.to_string(),
            _ => text.to_string(),
        })
    };
    let list = |_: &Path| Ok(vec![PathBuf::from(LIBRARY), PathBuf::from("lib/FB_X.TcPOU")]);
    let files_in = |dir: &Path| {
        Ok(match dir.to_str().unwrap_or_default() {
            "App" => vec![PathBuf::from(APP)],
            _ => Vec::new(),
        })
    };
    match project::from_config_with(config, read, list, files_in) {
        Err(diags) => {
            assert!(!names_mylib, "names MyLib, yet refused:\n{diags}");
            assert_located(&diags, Path::new(LIBRARY), text);
            assert_located(&diags, Path::new(APP), text);
        }
        Ok(project) => {
            assert!(names_mylib, "accepted without naming MyLib: {names:?}");
            super::run_twice(&project, &[]);
        }
    }
}

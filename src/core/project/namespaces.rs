//! The namespaces a project learns from TwinCAT's `.plcproj` files (docs/ST.md, "Qualified
//! names"), beside those `[st] namespaces` lists: which files are read, and what `plcd check`
//! says of them. The files' XML is `st::plcproj`'s to read.
//!
//! Two kinds of `.plcproj` are read, as a TwinCAT tree copied whole holds them:
//!
//! - every one in an `[st] library` folder, at any depth the folder's walk reaches (a library
//!   project's `<DefaultNamespace>`, TcUnit's `TcUnit/TcUnit/TcUnit.plcproj`);
//! - the one nearest a `[[program]]`'s TwinCAT file (the project the program belongs to, whose
//!   references name the libraries it uses): in the file's folder, else in the nearest parent
//!   folder holding one, up to the config file's folder (a file outside it: its own folder
//!   only). Every `.plcproj` of that folder is read; TwinCAT writes one per project folder.
//!
//! A `[[program]]`'s `.st` file is no TwinCAT project's and looks for none, and neither does an
//! `[st] library` entry that is a file: a plain ST project keeps the namespaces its config
//! lists. An `[st] library` folder that holds no `.plcproj` and is in none (a library's sources
//! copied without their project) is a namespace named after the folder, where its name is one a
//! namespace may have: TwinCAT's `<DefaultNamespace>` is the project's name, and its folder has
//! that name (`TcUnit/`).

use std::path::{Component, Path, PathBuf};

use super::Reader;
use crate::config::{SystemLibraries, SystemLibrary};
use crate::diag::Diagnostic;
use crate::st::plcproj::{self, Origin};

/// What the project's `.plcproj` files named so far.
#[derive(Debug, Default)]
pub(super) struct Learnt {
    /// Each namespace in the order first named, with every place naming it.
    names: Vec<(String, Vec<Place>)>,
    /// The files read, so that one reached twice is read once.
    read: Vec<PathBuf>,
}

/// Where a namespace was named: an element of a `.plcproj`, or a library folder's name.
#[derive(Debug)]
struct Place {
    /// The `.plcproj`, or the folder.
    file: PathBuf,
    /// The element of the `.plcproj` and its line; `None` for a folder.
    element: Option<(u32, Origin)>,
}

impl Learnt {
    /// Reads the `.plcproj` at `path` (once), `line` and `col` the config entry that led to it
    /// (`what`, for a file that cannot be read). False after an error (in `reader.diags`).
    pub(super) fn read<R, L, F>(
        &mut self,
        reader: &mut Reader<'_, R, L, F>,
        path: &Path,
        (line, col): (u32, u32),
        what: &str,
    ) -> bool
    where
        R: Fn(&Path) -> std::io::Result<String>,
        L: Fn(&Path) -> std::io::Result<Vec<PathBuf>>,
        F: Fn(&Path) -> std::io::Result<Vec<PathBuf>>,
    {
        if self.read.iter().any(|p| p == path) {
            return true;
        }
        self.read.push(path.to_path_buf());
        let Some(text) = reader.read(path, line, col, what) else { return false };
        match plcproj::namespaces(&text) {
            Ok(found) => {
                for ns in found {
                    let element = Some((ns.span.line, ns.origin));
                    self.add(ns.name, Place { file: path.to_path_buf(), element });
                }
                true
            }
            Err(errors) => {
                for e in errors {
                    reader.diags.push(Diagnostic::new(path, e.span.line, e.span.col, e.message));
                }
                false
            }
        }
    }

    /// The library folder `dir`, which holds no `.plcproj`: its name is a namespace, if it is one
    /// a namespace may have and no folder above it up to the config file's (`base`) holds a
    /// `.plcproj` (then it is a part of that project, `App/Tests/`, and no library of its own;
    /// a folder that cannot be listed counts as one that does). The module's doc says why.
    pub(super) fn folder<R, L, F>(&mut self, reader: &Reader<'_, R, L, F>, dir: &Path, base: &Path)
    where
        R: Fn(&Path) -> std::io::Result<String>,
        L: Fn(&Path) -> std::io::Result<Vec<PathBuf>>,
        F: Fn(&Path) -> std::io::Result<Vec<PathBuf>>,
    {
        let name = dir.file_name().and_then(|n| n.to_str()).unwrap_or_default();
        if !crate::config::is_namespace(name) {
            return;
        }
        let mut above = dir.parent();
        while let Some(folder) = above.filter(|f| inside(f, base)) {
            match (reader.files_in)(folder) {
                Ok(files) if !files.iter().any(|f| crate::config::is_plcproj(f)) => {}
                _ => return,
            }
            above = folder.parent();
        }
        self.add(name.to_string(), Place { file: dir.to_path_buf(), element: None });
    }

    fn add(&mut self, name: String, place: Place) {
        match self.names.iter_mut().find(|(n, _)| n.eq_ignore_ascii_case(&name)) {
            Some((_, places)) => places.push(place),
            None => self.names.push((name, vec![place])),
        }
    }

    /// Reads the `.plcproj` files nearest the program file `file` (the module's doc says
    /// which), `base` the config file's folder. False after an error.
    pub(super) fn nearest<R, L, F>(
        &mut self,
        reader: &mut Reader<'_, R, L, F>,
        file: &Path,
        base: &Path,
        at: (u32, u32),
        what: &str,
    ) -> bool
    where
        R: Fn(&Path) -> std::io::Result<String>,
        L: Fn(&Path) -> std::io::Result<Vec<PathBuf>>,
        F: Fn(&Path) -> std::io::Result<Vec<PathBuf>>,
    {
        let mut dir = file.parent();
        while let Some(folder) = dir {
            let projects = match (reader.files_in)(folder) {
                Ok(files) => {
                    let mut projects: Vec<PathBuf> =
                        files.into_iter().filter(|f| crate::config::is_plcproj(f)).collect();
                    projects.sort();
                    projects
                }
                Err(e) => {
                    let shown = if folder.as_os_str().is_empty() { Path::new(".") } else { folder };
                    let msg = format!(
                        "{what}: cannot list folder `{}` for the program's `.plcproj`: {e}",
                        shown.display()
                    );
                    reader.diags.push(Diagnostic::new(&reader.config.path, at.0, at.1, msg));
                    return false;
                }
            };
            if !projects.is_empty() {
                let mut ok = true;
                for project in projects {
                    ok &= self.read(reader, &project, at, what);
                }
                return ok;
            }
            if folder == base || !inside(folder, base) {
                break;
            }
            dir = folder.parent();
        }
        true
    }

    /// `[st] namespaces` (`listed`) followed by the names learnt that they do not hold (a name
    /// given twice is one namespace, whatever its case).
    pub(super) fn with(&self, listed: &[String]) -> Vec<String> {
        let mut all = listed.to_vec();
        for (name, _) in &self.names {
            if !all.iter().any(|n| n.eq_ignore_ascii_case(name)) {
                all.push(name.clone());
            }
        }
        all
    }

    /// What `plcd check` shows: a line a namespace, with each place that names it (`shown`,
    /// the file as the config's folder sees it), and for a library plcd ships that the config
    /// does not compile, how to have it.
    pub(super) fn notes(
        &self,
        shown: impl Fn(&Path) -> String,
        shipped: SystemLibraries,
    ) -> Vec<String> {
        self.names
            .iter()
            .map(|(name, places)| {
                let from: Vec<String> = places
                    .iter()
                    .map(|p| match &p.element {
                        Some((line, origin)) => format!("{}:{line} {origin}", shown(&p.file)),
                        None => format!(
                            "{}/ (the library folder's name: it holds no .plcproj)",
                            shown(&p.file)
                        ),
                    })
                    .collect();
                let hint = match SystemLibrary::from_name(name) {
                    Some(library) if !shipped.contains(library) => format!(
                        " (a library plcd ships: `[st] system_libraries = [\"{}\"]` compiles it)",
                        library.name()
                    ),
                    _ => String::new(),
                };
                format!("namespace {name}, from {}{hint}", from.join(", "))
            })
            .collect()
    }
}

/// Whether `dir` is `base` or a folder under it, by their names (the core sees no file
/// system): `base` joined with names alone, no `..`.
fn inside(dir: &Path, base: &Path) -> bool {
    dir.strip_prefix(base).is_ok_and(|rest| {
        rest.components().all(|c| matches!(c, Component::Normal(_) | Component::CurDir))
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::project::{from_config_with, Project};
    use std::cell::RefCell;
    use std::collections::BTreeMap;

    /// A TcUnit-shaped tree under `/p`: the library folder `Lib/` with its `.plcproj`
    /// (`DefaultNamespace` `MyLib`) and block, and the program `App/POUs/MAIN.TcPOU`, whose
    /// project `App/App.plcproj` references `MyLib`.
    fn tree() -> BTreeMap<PathBuf, String> {
        let pou = |decl: &str, body: &str| {
            format!("<TcPlcObject>\n<POU Name=\"P\"><Declaration><![CDATA[{decl}]]></Declaration>\n<Implementation><ST><![CDATA[{body}]]></ST></Implementation></POU>\n</TcPlcObject>")
        };
        let mut files = BTreeMap::new();
        let mut add = |path: &str, text: String| files.insert(PathBuf::from(path), text);
        add(
            "/p/plcd.toml",
            "[[program]]\nname = \"main\"\nfile = \"App/POUs/MAIN.TcPOU\"\n\n[st]\nlibrary = [\"Lib/\"]\n".into(),
        );
        add(
            "/p/Lib/MyLib.plcproj",
            "<Project>\n  <PropertyGroup>\n    <DefaultNamespace>MyLib</DefaultNamespace>\n  </PropertyGroup>\n</Project>\n".into(),
        );
        add(
            "/p/Lib/POUs/FB_X.TcPOU",
            pou("FUNCTION_BLOCK FB_X\nVAR_OUTPUT n : INT; END_VAR", "n := n + 1;"),
        );
        add(
            "/p/App/App.plcproj",
            "<Project>\n<ItemGroup>\n  <PlaceholderReference Include=\"MyLib\">\n    <Namespace>MyLib</Namespace>\n  </PlaceholderReference>\n</ItemGroup>\n</Project>\n".into(),
        );
        add(
            "/p/App/POUs/MAIN.TcPOU",
            pou("PROGRAM MAIN\nVAR x : MyLib.FB_X; n : INT; END_VAR", "x(); n := x.n;"),
        );
        files
    }

    /// Loads the project of `files`, recording every folder the loader listed for a program's
    /// `.plcproj`; a folder in `unlistable` cannot be listed.
    fn load(
        files: &BTreeMap<PathBuf, String>,
        unlistable: &[&str],
    ) -> (Result<Project, String>, Vec<String>) {
        let config =
            crate::config::parse(&files[Path::new("/p/plcd.toml")], Path::new("/p/plcd.toml"))
                .unwrap();
        let listed = RefCell::new(Vec::new());
        let read = |path: &Path| {
            files.get(path).cloned().ok_or_else(|| std::io::Error::other("no such file"))
        };
        let list = |dir: &Path| Ok(files.keys().filter(|f| f.starts_with(dir)).cloned().collect());
        let files_in = |dir: &Path| {
            listed.borrow_mut().push(dir.display().to_string());
            if unlistable.iter().any(|u| Path::new(u) == dir) {
                return Err(std::io::Error::other("permission denied"));
            }
            Ok(files.keys().filter(|f| f.parent() == Some(dir)).cloned().collect())
        };
        let project = from_config_with(config, read, list, files_in).map_err(|d| d.to_string());
        (project, listed.into_inner())
    }

    #[test]
    fn a_library_folders_and_a_programs_plcproj_name_the_namespaces() {
        let (project, listed) = load(&tree(), &[]);
        let project = project.unwrap();
        assert_eq!(
            project.notes,
            ["namespace MyLib, from Lib/MyLib.plcproj:3 <DefaultNamespace>, App/App.plcproj:4 <PlaceholderReference Include=\"MyLib\">"]
        );
        // the program's folder, then its parent, where the `.plcproj` is
        assert_eq!(listed, ["/p/App/POUs", "/p/App"]);
    }

    #[test]
    fn either_plcproj_alone_is_enough_and_without_both_the_name_is_unknown() {
        let mut without_app = tree();
        without_app.remove(Path::new("/p/App/App.plcproj"));
        let (project, listed) = load(&without_app, &[]);
        assert!(project.is_ok(), "{project:?}");
        // up to the config file's folder, never above it
        assert_eq!(listed, ["/p/App/POUs", "/p/App", "/p"]);
        let mut without_lib = tree();
        without_lib.remove(Path::new("/p/Lib/MyLib.plcproj"));
        assert!(load(&without_lib, &[]).0.is_ok());
        without_app.remove(Path::new("/p/Lib/MyLib.plcproj"));
        let error = load(&without_app, &[]).0.unwrap_err();
        assert_eq!(error, "/p/App/POUs/MAIN.TcPOU:3:9: error: unknown type `MyLib.FB_X`\n");
    }

    #[test]
    fn a_library_folder_without_a_plcproj_is_a_namespace_of_its_name() {
        // TcUnit's sources copied without their project: `MyLib/` is the namespace `MyLib`.
        let mut files: BTreeMap<PathBuf, String> = tree()
            .into_iter()
            .filter(|(path, _)| !crate::config::is_plcproj(path))
            .map(|(path, text)| match path.strip_prefix("/p/Lib") {
                Ok(rest) => (Path::new("/p/MyLib").join(rest), text),
                Err(_) => (path, text),
            })
            .collect();
        let config = files.get_mut(Path::new("/p/plcd.toml")).unwrap();
        *config = config.replace("\"Lib/\"", "\"MyLib/\"");
        let project = load(&files, &[]).0.unwrap();
        assert_eq!(
            project.notes,
            ["namespace MyLib, from MyLib/ (the library folder's name: it holds no .plcproj)"]
        );
        // A name no namespace may have is none (and the qualified type stays unknown).
        let renamed: BTreeMap<PathBuf, String> = files
            .into_iter()
            .map(|(path, text)| match path.strip_prefix("/p/MyLib") {
                Ok(rest) => (Path::new("/p/My-Lib").join(rest), text),
                Err(_) => (path, text.replace("\"MyLib/\"", "\"My-Lib/\"")),
            })
            .collect();
        let error = load(&renamed, &[]).0.unwrap_err();
        assert_eq!(error, "/p/App/POUs/MAIN.TcPOU:3:9: error: unknown type `MyLib.FB_X`\n");
    }

    #[test]
    fn the_config_lists_namespaces_beside_those_learnt_and_twice_is_no_error() {
        let mut files = tree();
        let config = files.get_mut(Path::new("/p/plcd.toml")).unwrap();
        config.push_str("namespaces = [\"mylib\", \"Other\"]\n");
        assert!(load(&files, &[]).0.is_ok());
    }

    #[test]
    fn a_folder_that_cannot_be_listed_or_a_plcproj_that_cannot_be_read_is_an_error_at_the_entry() {
        let error = load(&tree(), &["/p/App"]).0.unwrap_err();
        assert_eq!(
            error,
            "/p/plcd.toml:3:8: error: program \"main\": cannot list folder `/p/App` for the program's `.plcproj`: permission denied\n"
        );
        // a `.plcproj` listed but gone when read
        let mut files = tree();
        let config =
            crate::config::parse(&files[Path::new("/p/plcd.toml")], Path::new("/p/plcd.toml"))
                .unwrap();
        files.remove(Path::new("/p/Lib/MyLib.plcproj"));
        let read = |path: &Path| {
            files.get(path).cloned().ok_or_else(|| std::io::Error::other("no such file"))
        };
        let list = |_: &Path| {
            Ok(vec![PathBuf::from("/p/Lib/MyLib.plcproj"), PathBuf::from("/p/Lib/POUs/FB_X.TcPOU")])
        };
        let files_in =
            |dir: &Path| Ok(files.keys().filter(|f| f.parent() == Some(dir)).cloned().collect());
        let error = from_config_with(config, read, list, files_in).unwrap_err().to_string();
        assert_eq!(
            error,
            "/p/plcd.toml:6:12: error: st.library: cannot read `/p/Lib/MyLib.plcproj`: no such file\n"
        );
    }

    #[test]
    fn a_broken_plcproj_is_reported_in_it_and_stops_the_compile() {
        let mut files = tree();
        files.insert(
            PathBuf::from("/p/App/App.plcproj"),
            "<Project>\n<PropertyGroup><DefaultNamespace>My-App</DefaultNamespace></PropertyGroup>\n</Project>".into(),
        );
        let error = load(&files, &[]).0.unwrap_err();
        assert_eq!(
            error,
            "/p/App/App.plcproj:2:34: error: the `<DefaultNamespace>` `My-App` is not a name (letters, digits and `_`)\n"
        );
    }

    #[test]
    fn a_st_program_looks_for_no_plcproj() {
        let mut files = tree();
        files.insert(
            PathBuf::from("/p/plcd.toml"),
            "[[program]]\nname = \"main\"\nfile = \"main.st\"\n".into(),
        );
        files.insert(
            PathBuf::from("/p/main.st"),
            "PROGRAM Main\nVAR n : INT; END_VAR\nn := n + 1;\nEND_PROGRAM\n".into(),
        );
        let (project, listed) = load(&files, &[]);
        assert!(project.unwrap().notes.is_empty());
        assert!(listed.is_empty(), "{listed:?}");
    }

    #[test]
    fn a_folder_is_inside_the_configs_by_its_names() {
        assert!(inside(Path::new("a/b"), Path::new("")));
        assert!(inside(Path::new("/p/a"), Path::new("/p")));
        assert!(inside(Path::new("/p"), Path::new("/p")));
        assert!(!inside(Path::new("/q/a"), Path::new("/p")));
        assert!(!inside(Path::new("../a"), Path::new("")));
        assert!(!inside(Path::new("/p/../q"), Path::new("/p")));
        assert!(!inside(Path::new("/abs"), Path::new("")));
    }
}

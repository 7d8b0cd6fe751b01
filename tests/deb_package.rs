//! The Debian package as Cargo.toml describes it (`[package.metadata.deb]`, built by
//! `systemd/deb/build` with cargo-deb), held against the other install path, `systemd/install`:
//! the package must hold every file the script installs, from the same source and with the same
//! mode, at the place a package puts it (`/usr/lib/…` where the script writes `/etc/…`), so the
//! two cannot drift apart. Also: the unit the package installs (`systemd/plcd.service` through
//! `systemd/deb/unit.sed`) and the maintainer scripts of `systemd/deb/`.
//!
//! Building the package takes cargo-deb and installing it a VM: `tests/qemu/run-deb` does both.
//! Where `systemd-analyze` is missing, the verify of the packaged unit is skipped (a failure with
//! `PLCD_REQUIRE_SYSTEMD=1`, as in tests/systemd_unit.rs).

mod harness;

use std::collections::BTreeMap;
use std::fs;
use std::os::unix::fs::PermissionsExt;
use std::path::{Path, PathBuf};
use std::process::Command;

use harness::tempdir::TempDir;

fn repo() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn read(relative: &str) -> String {
    fs::read_to_string(repo().join(relative)).unwrap_or_else(|e| panic!("{relative}: {e}"))
}

/// `[package.metadata.deb]` of the root Cargo.toml.
fn deb_metadata() -> toml::Table {
    let manifest: toml::Table = read("Cargo.toml").parse().expect("Cargo.toml parses");
    manifest["package"]["metadata"]["deb"].as_table().expect("[package.metadata.deb]").clone()
}

/// One file of the package: where it comes from (relative to the repository; `target/release/`
/// stands for cargo's output directory, as cargo-deb reads it) and its mode.
#[derive(Debug, Clone, PartialEq)]
struct Asset {
    source: String,
    mode: String,
}

/// The files matching `pattern`, relative to the repository: a plain path, or one `*` in its
/// last component (as the assets use them; cargo-deb expands them the same way).
fn expand(pattern: &str) -> Vec<String> {
    let Some((dir, last)) = pattern.rsplit_once('/').filter(|(_, last)| last.contains('*')) else {
        return vec![pattern.to_string()];
    };
    let (prefix, suffix) = last.split_once('*').unwrap();
    let mut names: Vec<String> = fs::read_dir(repo().join(dir))
        .unwrap_or_else(|e| panic!("asset {pattern}: {e}"))
        .map(|entry| entry.unwrap().file_name().into_string().unwrap())
        .filter(|name| name.starts_with(prefix) && name.ends_with(suffix))
        .collect();
    names.sort();
    assert!(!names.is_empty(), "asset {pattern} matches no file");
    names.into_iter().map(|name| format!("{dir}/{name}")).collect()
}

/// Every file of the package by its absolute path on the target, the assets' globs expanded.
fn package_files() -> BTreeMap<String, Asset> {
    let mut files = BTreeMap::new();
    let metadata = deb_metadata();
    let assets = metadata["assets"].as_array().expect("assets is an array");
    for asset in assets {
        let fields: Vec<&str> = asset
            .as_array()
            .unwrap_or_else(|| panic!("asset {asset} is not [source, dest, mode]"))
            .iter()
            .map(|field| field.as_str().expect("asset fields are strings"))
            .collect();
        let [source, dest, mode] = fields[..] else {
            panic!("asset {fields:?} is not [source, dest, mode]");
        };
        assert!(!dest.starts_with('/'), "asset dest {dest} must be relative, as cargo-deb wants");
        for file in expand(source) {
            let path = match dest.strip_suffix('/') {
                Some(dir) => format!("/{dir}/{}", file.rsplit('/').next().unwrap()),
                None => format!("/{dest}"),
            };
            let previous =
                files.insert(path.clone(), Asset { source: file, mode: mode.to_string() });
            assert!(previous.is_none(), "two assets install {path}");
        }
    }
    files
}

/// Where the package puts what `systemd/install` writes to `path` (with `--prefix /usr`):
/// vendor files under /usr/lib, where /etc stays the admin's.
fn package_path(path: &str) -> String {
    for (script, package) in [
        ("/etc/systemd/system/", "/usr/lib/systemd/system/"),
        ("/etc/sysusers.d/", "/usr/lib/sysusers.d/"),
        ("/etc/udev/rules.d/", "/usr/lib/udev/rules.d/"),
    ] {
        if let Some(name) = path.strip_prefix(script) {
            return format!("{package}{name}");
        }
    }
    path.to_string()
}

/// What `systemd/install --dry-run --prefix /usr` says it would install into an empty root:
/// (path, mode, origin) of each file.
fn script_files() -> Vec<(String, String, String)> {
    let root = TempDir::new("deb-dry-run");
    let root_arg = root.path().to_str().unwrap();
    let out = Command::new("bash")
        .arg(repo().join("systemd/install"))
        .args(["--dry-run", "--root", root_arg, "--prefix", "/usr"])
        .args(["--binary", "/nonexistent/release/plcd"])
        .env_remove("CARGO_TARGET_DIR")
        .output()
        .expect("bash systemd/install");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "systemd/install --dry-run failed:\n{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut files = Vec::new();
    for line in stdout.lines() {
        // "  would install ROOT/PATH  (mode 0644[, group plcd], from ORIGIN)"
        let Some(rest) = line.trim_start().strip_prefix("would install ") else {
            continue;
        };
        let (target, details) = rest.split_once("  (").expect(line);
        let path = target.strip_prefix(root_arg).expect(line).to_string();
        let details = details.strip_suffix(')').expect(line);
        let mode = details.strip_prefix("mode ").and_then(|d| d.split(',').next()).expect(line);
        let origin = details.split_once(", from ").expect(line).1;
        files.push((path, mode.to_string(), origin.to_string()));
    }
    files
}

#[test]
fn the_package_holds_every_file_systemd_install_installs() {
    let package = package_files();
    let script = script_files();
    // Not vacuous: the dry run was understood.
    for path in ["/usr/bin/plcd", "/usr/bin/plcctl", "/etc/plcd/plcd.toml"] {
        assert!(script.iter().any(|(p, _, _)| p == path), "the dry run did not name {path}");
    }
    let mut problems = Vec::new();
    for (path, mode, origin) in &script {
        let deb_path = package_path(path);
        let Some(asset) = package.get(&deb_path) else {
            problems.push(format!("{deb_path} (systemd/install's {path}) is not in the package"));
            continue;
        };
        // The script's binaries come from --binary's directory, its unit from
        // systemd/plcd.service with the paths of the prefix: the package's from target/release.
        let source = if let Some(binary) = origin.strip_prefix("/nonexistent/release/") {
            format!("target/release/{binary}")
        } else if origin.starts_with("systemd/plcd.service, ") {
            "target/release/deb/plcd.service".to_string()
        } else {
            origin.clone()
        };
        if asset.source != source {
            problems.push(format!(
                "{deb_path}: from {} in the package, {source} by the script",
                asset.source
            ));
        }
        if format!("0{}", asset.mode) != *mode {
            problems.push(format!(
                "{deb_path}: mode {} in the package, {mode} by the script",
                asset.mode
            ));
        }
    }
    assert!(
        problems.is_empty(),
        "the package and systemd/install differ:\n{}",
        problems.join("\n")
    );
}

#[test]
fn the_package_holds_the_drop_ins_and_all_the_docs() {
    let package = package_files();
    let mut wanted: Vec<(String, String)> = expand("systemd/drop-ins/*.conf")
        .into_iter()
        .map(|f| (format!("/usr/share/plcd/drop-ins/{}", &f["systemd/drop-ins/".len()..]), f))
        .collect();
    wanted.extend(
        expand("docs/*.md")
            .into_iter()
            .map(|f| (format!("/usr/share/doc/plcd/{}", &f["docs/".len()..]), f)),
    );
    wanted.push(("/usr/share/doc/plcd/README.md".into(), "README.md".into()));
    for (path, source) in wanted {
        let asset = package.get(&path).unwrap_or_else(|| panic!("{path} is not in the package"));
        assert_eq!(asset, &Asset { source, mode: "644".into() }, "{path}");
    }
}

#[test]
fn everything_the_package_puts_under_etc_is_the_example_project() {
    // cargo-deb makes every file under /etc a conffile: dpkg keeps an admin's change on upgrade.
    // The project is root:plcd 0640 once installed (the postinst sets the group).
    let package = package_files();
    for (path, asset) in &package {
        if path.starts_with("/etc/") {
            assert!(path.starts_with("/etc/plcd/"), "{path}: only the project goes under /etc");
            assert_eq!(asset.mode, "640", "{path}");
            assert_eq!(path["/etc/plcd/".len()..], asset.source["etc/".len()..], "{path}");
        } else {
            assert!(path.starts_with("/usr/"), "{path}: a package installs under /usr and /etc");
        }
        if !asset.source.starts_with("target/") {
            assert!(repo().join(&asset.source).is_file(), "{path}: no file {}", asset.source);
        }
    }
    let postinst = read("systemd/deb/postinst");
    assert!(postinst.contains("chgrp plcd"), "the postinst gives the project group plcd");
}

/// `systemd/plcd.service` as the package installs it: through `systemd/deb/unit.sed`.
fn packaged_unit() -> String {
    let out = Command::new("sed")
        .arg("-f")
        .arg(repo().join("systemd/deb/unit.sed"))
        .arg(repo().join("systemd/plcd.service"))
        .output()
        .expect("sed");
    assert!(
        out.status.success(),
        "sed -f systemd/deb/unit.sed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

#[test]
fn the_packaged_unit_is_the_unit_with_its_paths_under_usr() {
    let unit = packaged_unit();
    let expected = read("systemd/plcd.service")
        .replace("/usr/local/bin/plcd", "/usr/bin/plcd")
        .replace("/usr/local/share/doc/plcd", "/usr/share/doc/plcd");
    let header = unit.strip_suffix(&expected).expect("the packaged unit ends with the unit, moved");
    assert!(
        !header.is_empty() && header.lines().all(|l| l.starts_with('#')),
        "only comment lines come before the unit:\n{header}"
    );
    assert!(!unit.contains("/usr/local"), "a path under /usr/local is left:\n{unit}");

    // What the unit names, the package holds.
    let package = package_files();
    for (key, path) in [
        ("ExecStart=", "/usr/bin/plcd"),
        ("ExecReload=", "/usr/bin/plcd"),
        ("Documentation=file:", "/usr/share/doc/plcd/DEPLOY.md"),
    ] {
        assert!(unit.lines().any(|l| l.starts_with(&format!("{key}{path}"))), "{key}{path}");
        assert!(package.contains_key(path), "the unit names {path}, not in the package");
    }
    // The postrm's purge deletes the state directory the unit has systemd create.
    assert!(unit.lines().any(|l| l == "StateDirectory=plcd"));
    assert!(read("systemd/deb/postrm").contains("rm -rf /var/lib/plcd"));
}

#[test]
fn the_packaged_unit_passes_systemd_analyze_verify() {
    match Command::new("systemd-analyze").arg("--version").output() {
        Ok(out) if out.status.success() => {}
        _ => {
            harness::skip::skip(Some("PLCD_REQUIRE_SYSTEMD"), "systemd-analyze not available");
            return;
        }
    }
    let root = TempDir::new("deb-verify");
    root.write("usr/lib/systemd/system/plcd.service", packaged_unit());
    root.write("usr/lib/systemd/system/sysinit.target", "[Unit]\nDescription=stub\n");
    root.write("bin/kill", "#!/bin/sh\nexit 0\n");
    root.chmod("bin/kill", 0o755);
    fs::create_dir_all(root.join("usr/bin")).unwrap();
    let plcd: PathBuf = root.join("usr/bin/plcd");
    if fs::hard_link(env!("CARGO_BIN_EXE_plcd"), &plcd).is_err() {
        fs::copy(env!("CARGO_BIN_EXE_plcd"), &plcd).unwrap();
    }
    let verify = || {
        Command::new("systemd-analyze")
            .arg("verify")
            .arg(format!("--root={}", root.path().display()))
            .arg("plcd.service")
            .output()
            .expect("systemd-analyze verify")
    };
    let out = verify();
    assert!(
        out.status.success() && out.stdout.is_empty() && out.stderr.is_empty(),
        "systemd-analyze verify of the packaged unit is not clean:\n{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    // The check is real: without /usr/bin/plcd, verify complains.
    fs::remove_file(&plcd).unwrap();
    let out = verify();
    assert!(String::from_utf8_lossy(&out.stderr).contains("/usr/bin/plcd"), "verify missed it");
}

#[test]
fn the_maintainer_scripts_are_short_posix_sh() {
    let metadata = deb_metadata();
    let dir = metadata["maintainer-scripts"].as_str().expect("maintainer-scripts");
    assert_eq!(dir, "systemd/deb/");
    for name in ["postinst", "prerm", "postrm"] {
        let path = repo().join(dir).join(name);
        let text = read(&format!("{dir}{name}"));
        assert!(text.starts_with("#!/bin/sh\n"), "{name}: not #!/bin/sh");
        assert!(text.contains("\nset -e\n"), "{name}: no set -e");
        assert!(text.lines().count() <= 60, "{name}: keep it short");
        let mode = fs::metadata(&path).unwrap().permissions().mode();
        assert_eq!(mode & 0o111, 0o111, "{name}: not executable");
        // dash where it exists (Debian's /bin/sh): it knows no bash extension.
        let shell =
            if Command::new("dash").arg("-c").arg(":").status().is_ok() { "dash" } else { "sh" };
        let out = Command::new(shell).arg("-n").arg(&path).output().unwrap();
        assert!(
            out.status.success(),
            "{shell} -n {name}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    // The postinst creates the accounts from the sysusers file the package installs.
    let package = package_files();
    assert!(package.contains_key("/usr/lib/sysusers.d/plcd.conf"));
    assert!(read("systemd/deb/postinst").contains("systemd-sysusers plcd.conf"));
}

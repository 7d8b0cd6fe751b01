//! The binary AFL++ runs: `plcd-fuzz TARGET`, the input on stdin (persistent mode: one process
//! runs many inputs). Built by `tests/fuzz/run` with `cargo afl build --features afl`.

fn main() {
    let name = std::env::args().nth(1).unwrap_or_default();
    let Some(target) = plcd_fuzz::target(&name) else {
        let names: Vec<&str> = plcd_fuzz::TARGETS.iter().map(|t| t.name).collect();
        eprintln!("usage: plcd-fuzz TARGET (one of: {})", names.join(", "));
        std::process::exit(2);
    };
    plcd_fuzz::prepare(&name);
    afl::fuzz!(|data: &[u8]| (target.run)(data));
}

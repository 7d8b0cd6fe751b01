//! The Sparkplug B payload types in `src/services/mqtt/sparkplug_b.rs` are what prost-build
//! generates from `src/services/mqtt/sparkplug_b.proto` (parsed by protox: no protoc to
//! install). After a change of the schema, bless the generated file with
//! `PLCD_BLESS=1 cargo test -p plcd-sparkplug-schema`.

use std::path::Path;

#[test]
fn the_payload_types_are_generated_from_the_schema() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../src/services/mqtt");
    let schema = dir.join("sparkplug_b.proto");
    let descriptors = protox::compile([&schema], [&dir]).expect("the schema compiles");
    let out = std::env::temp_dir().join(format!("plcd-sparkplug-{}", std::process::id()));
    std::fs::create_dir_all(&out).unwrap();
    prost_build::Config::new().out_dir(&out).compile_fds(descriptors).expect("prost-build");
    let generated = std::fs::read_to_string(out.join("org.eclipse.tahu.protobuf.rs")).unwrap();
    let _ = std::fs::remove_dir_all(&out);
    let committed_path = dir.join("sparkplug_b.rs");
    if std::env::var_os("PLCD_BLESS").is_some() {
        std::fs::write(&committed_path, &generated).unwrap();
    }
    let committed = std::fs::read_to_string(&committed_path).unwrap();
    assert!(
        committed == generated,
        "src/services/mqtt/sparkplug_b.rs is not what prost-build makes of sparkplug_b.proto: \
         PLCD_BLESS=1 cargo test -p plcd-sparkplug-schema"
    );
}

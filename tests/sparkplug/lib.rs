//! Nothing but its test: `tests/schema.rs` (see Cargo.toml).

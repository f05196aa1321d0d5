//! No code: this crate only asks for dependency features, so that every build of the
//! workspace's crates compiles its shared dependencies alike (see `Cargo.toml`).

//! Empty: the build script exists so that the `syn` build dependency (host features, as
//! the proc-macros that use it) is part of every build (see `Cargo.toml`).

fn main() {}

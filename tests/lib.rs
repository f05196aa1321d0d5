//! gelrig's end-to-end tests live in the single test binary `e2e/` (ripgrep style:
//! `cargo test -p gelrig-tests`). This library is empty; it exists so the package builds.

//! Empty: it exists so that the host's `syn` is resolved with the features
//! every proc-macro of the workspace needs (Cargo.toml).
fn main() {}

//! Build script: whether the development logs are at hand (`$GREYBOX_SHARED_DATA`, else
//! `../shared/data` beside the repository), as the cfg `shared_data`, so that the tests
//! that read them are reported as ignored, not as passed, on a clone without them. A
//! folder added after the first build is seen once this script runs again (`touch build.rs`
//! or `cargo clean`).

use std::path::PathBuf;

fn main() {
    println!("cargo::rustc-check-cfg=cfg(shared_data)");
    println!("cargo::rerun-if-env-changed=GREYBOX_SHARED_DATA");
    println!("cargo::rerun-if-changed=build.rs");
    let dir = match std::env::var_os("GREYBOX_SHARED_DATA") {
        Some(dir) => PathBuf::from(dir),
        None => {
            PathBuf::from(std::env::var_os("CARGO_MANIFEST_DIR").unwrap_or_default()).join("../shared/data")
        }
    };
    if dir.is_dir() {
        println!("cargo::rustc-cfg=shared_data");
    }
}

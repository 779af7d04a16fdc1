//! `include/stepdamp.h` is what cbindgen generates from this crate today: fails on any
//! difference. `STEPDAMP_BLESS_HEADER=1 cargo test -p stepdamp-ffi --test header`
//! rewrites it.

use std::path::PathBuf;

#[test]
fn committed_header_equals_a_fresh_cbindgen_generation() {
    let crate_dir = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let config = cbindgen::Config::from_file(crate_dir.join("cbindgen.toml")).expect("read cbindgen.toml");
    let bindings = cbindgen::Builder::new()
        .with_crate(&crate_dir)
        .with_config(config)
        .generate()
        .expect("cbindgen generates the header");
    let mut fresh = Vec::new();
    bindings.write(&mut fresh);
    let fresh = String::from_utf8(fresh).expect("UTF-8 header");
    let path = crate_dir.join("../../include/stepdamp.h");
    if std::env::var_os("STEPDAMP_BLESS_HEADER").is_some() {
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(&path, &fresh).unwrap();
        return;
    }
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        committed == fresh,
        "{} is stale or missing: regenerate with STEPDAMP_BLESS_HEADER=1 cargo test -p stepdamp-ffi --test header",
        path.display()
    );
}

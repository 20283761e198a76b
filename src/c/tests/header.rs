//! The committed header include/spatial_dynamics.h is what cbindgen generates from the crate
//! now: a changed signature or doc comment without a regenerated header fails here. With
//! `SPATIAL_DYNAMICS_UPDATE_HEADER=1` the test writes the header instead.

use std::path::Path;

#[test]
fn committed_header_is_current() {
    let crate_dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let config = cbindgen::Config::from_file(crate_dir.join("cbindgen.toml")).unwrap();
    let bindings = cbindgen::generate_with_config(crate_dir, config).unwrap();
    let mut generated = Vec::new();
    bindings.write(&mut generated);
    let generated = String::from_utf8(generated).unwrap();
    let path = crate_dir.join("include/spatial_dynamics.h");
    if std::env::var_os("SPATIAL_DYNAMICS_UPDATE_HEADER").is_some() {
        std::fs::write(&path, &generated).unwrap();
    }
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        committed == generated,
        "{} is stale: regenerate it with `SPATIAL_DYNAMICS_UPDATE_HEADER=1 cargo test --release -p spatial_dynamics_c --test header`",
        path.display()
    );
}

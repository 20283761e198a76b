//! The C++ header, compiled with g++ (C++20, warnings as errors) against include/ and the
//! static library this crate's build makes, then run on the default arm:
//! tests/programs/wrapper.cpp checks the header's moves (a moved-from model or workspace owns
//! nothing, assignment frees what the target owned) and its refusal of a path or URDF text
//! holding a NUL byte.

use spatial_dynamics_core::model::examples::DEFAULT_ARM_URDF;
use std::path::{Path, PathBuf};
use std::process::Command;

fn crate_dir() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// libspatial_dynamics_c.a, which cargo builds beside this test's binary (in target/<profile>/,
/// or its deps/) when it builds the crate for the test.
fn static_library() -> PathBuf {
    let exe = std::env::current_exe().unwrap();
    let deps = exe.parent().unwrap();
    let candidates = [deps.parent().unwrap(), deps].map(|d| d.join("libspatial_dynamics_c.a"));
    candidates
        .iter()
        .find(|path| path.is_file())
        .unwrap_or_else(|| panic!("no static library at {candidates:?}"))
        .clone()
}

fn scratch(name: &str) -> PathBuf {
    Path::new(env!("CARGO_TARGET_TMPDIR")).join(name)
}

/// Compiles `source` (relative to the crate) into the program `name`.
fn compile(source: &str, name: &str) -> PathBuf {
    let out = scratch(name);
    let done = Command::new("g++")
        .args([
            "-std=c++20",
            "-Wall",
            "-Wextra",
            "-pedantic",
            "-Werror",
            "-O1",
        ])
        .arg(format!("-I{}", crate_dir().join("include").display()))
        .arg(crate_dir().join(source))
        .arg("-o")
        .arg(&out)
        .arg(static_library())
        .args(["-lpthread", "-ldl", "-lm"])
        .output()
        .expect("g++, which compiles the C++ programs, did not start");
    assert!(
        done.status.success(),
        "g++ {source}:\n{}",
        String::from_utf8_lossy(&done.stderr)
    );
    out
}

/// The default arm's URDF, written to a file of its own for the test `name`.
fn arm_urdf(name: &str) -> PathBuf {
    let path = scratch(&format!("{name}.urdf"));
    std::fs::write(&path, DEFAULT_ARM_URDF).unwrap();
    path
}

fn text(output: &[u8]) -> String {
    String::from_utf8_lossy(output).into_owned()
}

#[test]
fn the_header_moves_and_refuses_nul_bytes() {
    let program = compile("tests/programs/wrapper.cpp", "wrapper");
    let done = Command::new(&program)
        .arg(arm_urdf("wrapper"))
        .output()
        .unwrap();
    assert!(
        done.status.success() && text(&done.stdout) == "ok\n",
        "{:?}\n{}{}",
        done.status,
        text(&done.stdout),
        text(&done.stderr)
    );
}

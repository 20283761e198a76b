//! The C++ header and the C++ example, compiled with g++ (C++20, warnings as errors) against
//! include/ and the static library this crate's build makes, then run on the default arm:
//! tests/programs/wrapper.cpp checks the header's moves (a moved-from model or workspace owns
//! nothing, assignment frees what the target owned) and its refusal of a path or URDF text
//! holding a NUL byte; examples/gravity_compensation.cpp must answer a bad SECONDS with its
//! usage (exit 2), an unreadable URDF with its message (exit 1), and run a short loop.

use spatial_dynamics_core::model::examples::DEFAULT_ARM_URDF;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

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

#[test]
fn the_example_checks_its_arguments_and_runs() {
    let program = compile("examples/gravity_compensation.cpp", "gravity_compensation");
    let urdf = arm_urdf("gravity_compensation");
    let run = |args: &[&str]| -> Output {
        Command::new(&program)
            .arg(&urdf)
            .args(args)
            .output()
            .unwrap()
    };
    for seconds in [
        "1e12", "3600.5", "nan", "inf", "-inf", "-1", "0", "-0", "abc", "2s", "",
    ] {
        let done = run(&[seconds]);
        let stderr = text(&done.stderr);
        assert_eq!(done.status.code(), Some(2), "SECONDS {seconds:?}: {stderr}");
        assert!(
            stderr.contains(&format!(
                "SECONDS '{seconds}' is not a number greater than 0 and at most 3600"
            )) && stderr.contains("usage: "),
            "SECONDS {seconds:?}: {stderr}"
        );
        assert!(done.stdout.is_empty(), "SECONDS {seconds:?}");
    }
    let done = run(&["1", "extra"]);
    assert_eq!(done.status.code(), Some(2));
    assert!(text(&done.stderr).starts_with("usage: "));

    let done = Command::new(&program)
        .arg(scratch("no_such_file.urdf"))
        .arg("0.01")
        .output()
        .unwrap();
    let stderr = text(&done.stderr);
    assert_eq!(done.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.starts_with("error: ") && stderr.contains("no_such_file.urdf"),
        "{stderr}"
    );

    let done = run(&["0.01"]);
    let stdout = text(&done.stdout);
    assert!(done.status.success(), "{}", text(&done.stderr));
    let lines: Vec<&str> = stdout.lines().collect();
    let nv = lines.len() - 1;
    assert!(
        lines[0].starts_with(&format!(
            "10 calls of g(q) at 1 kHz on {nv} coordinates: per call min"
        )),
        "{stdout}"
    );
    assert!(
        lines[1..]
            .iter()
            .all(|line| line.starts_with("g[") && line.contains("] = ")),
        "{stdout}"
    );
}

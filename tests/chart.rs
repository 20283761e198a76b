//! `spatial_dynamics chart --quick`: the three SVGs parse as XML, the CSVs have their documented
//! columns, finite numbers and points for every algorithm, Pinocchio's bench is run on every
//! model with the right flags, and the integrators' reference is converged (Richardson).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::Command;

const BIN: &str = env!("CARGO_BIN_EXE_spatial_dynamics");
const KERNELS: [&str; 6] = [
    "rnea",
    "crba",
    "fd_aba",
    "fd_crba",
    "fd_rnea_columns",
    "gravity",
];

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("sd_chart_{name}_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// (header, rows as column → cell maps), from our simple CSV (quoted cells may hold commas).
fn read_csv(path: &Path) -> (Vec<String>, Vec<BTreeMap<String, String>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let split = |line: &str| -> Vec<String> {
        let mut cells = vec![String::new()];
        let mut quoted = false;
        let mut chars = line.chars().peekable();
        while let Some(c) = chars.next() {
            match c {
                '"' if quoted && chars.peek() == Some(&'"') => {
                    chars.next();
                    cells.last_mut().unwrap().push('"');
                }
                '"' => quoted = !quoted,
                ',' if !quoted => cells.push(String::new()),
                _ => cells.last_mut().unwrap().push(c),
            }
        }
        cells
    };
    let mut lines = text.lines();
    let header = split(lines.next().unwrap());
    let rows = lines
        .map(|line| {
            let cells = split(line);
            assert_eq!(cells.len(), header.len(), "{}: {line}", path.display());
            header.iter().cloned().zip(cells).collect()
        })
        .collect();
    (header, rows)
}

fn number(row: &BTreeMap<String, String>, column: &str) -> f64 {
    let cell = &row[column];
    let x: f64 = cell
        .parse()
        .unwrap_or_else(|_| panic!("{column} = '{cell}' is not a number in {row:?}"));
    assert!(x.is_finite(), "{column} = {x} in {row:?}");
    x
}

/// Parses the SVG as XML and checks the drawing has data in it: every coordinate finite.
fn check_svg(path: &Path) {
    let text = std::fs::read_to_string(path).unwrap();
    let root: xml::Element = text
        .parse()
        .unwrap_or_else(|e| panic!("{}: not XML: {e}", path.display()));
    assert_eq!(root.name, "svg");
    let mut counts: BTreeMap<String, usize> = BTreeMap::new();
    let mut stack = vec![&root];
    while let Some(e) = stack.pop() {
        *counts.entry(e.name.clone()).or_default() += 1;
        for (key, value) in [("points", "points"), ("cx", "cx"), ("cy", "cy"), ("d", "d")] {
            if let Some(v) = e.get_attribute(key, None) {
                for number in v
                    .split(|c: char| !(c.is_ascii_digit() || c == '.' || c == '-' || c == 'e'))
                    .filter(|s| !s.is_empty())
                {
                    let x: f64 = number.parse().unwrap_or_else(|_| {
                        panic!("{}: <{}> {value}='{v}'", path.display(), e.name)
                    });
                    assert!(x.is_finite(), "{}: {value}='{v}'", path.display());
                }
            }
        }
        stack.extend(e.children.iter().filter_map(|c| match c {
            xml::Xml::ElementNode(child) => Some(child),
            _ => None,
        }));
    }
    assert!(
        counts.get("polyline").copied().unwrap_or(0) >= 3,
        "{}: {counts:?}",
        path.display()
    );
    assert!(
        counts.get("text").copied().unwrap_or(0) >= 10,
        "{}: {counts:?}",
        path.display()
    );
}

/// A stand-in for Pinocchio's bench: logs its arguments, checks the URDF exists, prints the JSON.
fn fake_pinocchio(dir: &Path) -> (PathBuf, PathBuf) {
    let log = dir.join("pinocchio_args.log");
    let script = dir.join("fake_bench.sh");
    std::fs::write(
        &script,
        format!(
            "#!/bin/sh\necho \"$@\" >> '{}'\n[ -f \"$1\" ] || exit 3\n\
             echo '{{\"nv\": 0, \"ns_per_call\": {{\"rnea\": 11.5, \"crba\": 12.5, \"fd_aba\": 13.5, \
             \"fd_crba\": 14.5, \"fd_rnea_columns\": 15.5, \"gravity\": 16.5}}}}'\n",
            log.display()
        ),
    )
    .unwrap();
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&script, std::fs::Permissions::from_mode(0o755)).unwrap();
    }
    (script, log)
}

#[test]
fn quick_charts_are_well_formed_and_complete() {
    let dir = temp_dir("quick");
    let out = dir.join("charts");
    let (fake, log) = fake_pinocchio(&dir);
    let status = Command::new(BIN)
        .args(["chart", "--quick", "--out"])
        .arg(&out)
        .args([
            "--robot",
            "tree=src/core/tests/models/tree.urdf",
            "--robot",
            "arm=config/models/default_arm.urdf,floating",
            "--pinocchio-bench",
        ])
        .arg(&fake)
        .status()
        .unwrap();
    assert!(status.success());
    for name in ["timing", "accuracy", "work_precision"] {
        check_svg(&out.join(format!("{name}.svg")));
    }

    // Timing: every kernel, ours and Pinocchio's, chains and robots.
    let (header, rows) = read_csv(&out.join("timing.csv"));
    assert_eq!(
        header,
        [
            "model",
            "kind",
            "nv",
            "library",
            "algorithm",
            "ns_per_call",
            "states"
        ]
    );
    let mut seen = BTreeSet::new();
    for row in &rows {
        assert!(number(row, "ns_per_call") > 0.0);
        number(row, "nv");
        number(row, "states");
        seen.insert((
            row["kind"].clone(),
            row["library"].clone(),
            row["algorithm"].clone(),
        ));
        if row["library"] == "pinocchio" {
            let expected =
                11.5 + KERNELS.iter().position(|k| *k == row["algorithm"]).unwrap() as f64;
            assert_eq!(number(row, "ns_per_call"), expected, "{row:?}");
        }
    }
    for kind in ["chain", "robot"] {
        for library in ["ours", "pinocchio"] {
            for kernel in KERNELS {
                assert!(
                    seen.contains(&(kind.into(), library.into(), kernel.into())),
                    "no {kind} {library} {kernel}"
                );
            }
        }
    }
    let nv: BTreeMap<&str, f64> = rows
        .iter()
        .map(|r| (r["model"].as_str(), number(r, "nv")))
        .collect();
    assert_eq!(nv["pendulum8"], 8.0);
    assert_eq!(
        nv["arm"], 13.0,
        "the default arm's 7 joints and a floating base"
    );
    // Pinocchio ran once per model, on the URDF file, floating only for the floating robot.
    let log = std::fs::read_to_string(&log).unwrap();
    let calls: Vec<&str> = log.lines().collect();
    assert_eq!(calls.len(), nv.len(), "{log}");
    for call in calls {
        assert!(
            call.contains("--states") && call.contains("--repeats") && call.contains("--min-time"),
            "{call}"
        );
        assert_eq!(
            call.contains("--floating-base"),
            call.contains("default_arm.urdf"),
            "{call}"
        );
    }
    assert!(out.join("urdf/pendulum8.urdf").is_file());

    // Accuracy: the three methods on every chain, errors small on these short chains.
    let (header, rows) = read_csv(&out.join("accuracy.csv"));
    assert_eq!(
        header,
        [
            "n",
            "r",
            "method",
            "ns_per_call",
            "rel_err_max",
            "rel_err_median",
            "min_mass",
            "status"
        ]
    );
    let methods: BTreeSet<&str> = rows.iter().map(|r| r["method"].as_str()).collect();
    assert_eq!(methods, BTreeSet::from(["aba", "crba", "rnea_columns"]));
    for row in &rows {
        assert_eq!(row["status"], "ok", "{row:?}");
        assert!(number(row, "ns_per_call") > 0.0);
        let (max, median) = (number(row, "rel_err_max"), number(row, "rel_err_median"));
        assert!(median <= max && max < 1e-11, "{row:?}");
        number(row, "n");
        number(row, "r");
        number(row, "min_mass");
    }

    // Work-precision: every integrator has points on both problems; the reference is converged.
    let (header, rows) = read_csv(&out.join("work_precision.csv"));
    assert_eq!(
        header,
        [
            "problem",
            "integrator",
            "steps",
            "h",
            "error",
            "cpu_s_per_sim_s",
            "reference_change",
            "status"
        ]
    );
    let problems: BTreeSet<&str> = rows.iter().map(|r| r["problem"].as_str()).collect();
    assert_eq!(problems.len(), 2);
    for problem in &problems {
        let mine: Vec<_> = rows.iter().filter(|r| r["problem"] == *problem).collect();
        for integrator in [
            "explicit_euler",
            "semi_implicit_euler",
            "rk4",
            "implicit_euler",
        ] {
            let ok = mine
                .iter()
                .filter(|r| r["integrator"] == integrator && r["status"] == "ok")
                .count();
            assert!(ok >= 2, "{problem}, {integrator}: {ok} points");
        }
        let change = number(mine[0], "reference_change");
        let mut smallest = f64::INFINITY;
        for row in mine.iter().filter(|r| r["status"] == "ok") {
            assert!(number(row, "cpu_s_per_sim_s") > 0.0);
            assert_eq!(number(row, "h") * number(row, "steps"), 1.0);
            smallest = smallest.min(number(row, "error"));
        }
        assert!(
            smallest >= 100.0 * change,
            "{problem}: the reference moves by {change:e} when its step is halved, the smallest error is {smallest:e}"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_options_are_errors_naming_them() {
    let dir = temp_dir("bad");
    for (args, needle) in [
        (vec!["--robot", "noequals"], "noequals"),
        (
            vec!["--robot", "x=missing.urdf", "--only", "timing", "--quick"],
            "missing.urdf",
        ),
        (vec!["--only", "pie"], "pie"),
        (
            vec!["--pinocchio-bench", "/nonexistent/bench"],
            "/nonexistent/bench",
        ),
    ] {
        let out = Command::new(BIN)
            .args(["chart", "--out"])
            .arg(&dir)
            .args(&args)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?}");
        assert!(stderr.contains(needle), "{args:?}: {stderr}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The files of a staged run that did not end, or any file but the outputs.
fn leftovers(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|name| name.starts_with('.'))
        .collect()
}

/// A run that fails replaces none of the outputs and leaves nothing behind (the outputs are
/// staged and moved into place together); a `--robot` that cannot be loaded fails before
/// anything is timed or written.
#[test]
fn a_failed_run_changes_no_output() {
    let dir = temp_dir("atomic");
    let chart = |out: &Path, extra: &[&str]| {
        let output = Command::new(BIN)
            .args(["chart", "--out"])
            .arg(out)
            .args(["--quick", "--only", "timing"])
            .args(extra)
            .output()
            .unwrap();
        (
            output.status.success(),
            String::from_utf8_lossy(&output.stderr).into_owned(),
        )
    };
    let (ok, err) = chart(&dir, &[]);
    assert!(ok, "{err}");
    assert!(leftovers(&dir).is_empty(), "{:?}", leftovers(&dir));
    let svg = std::fs::read(dir.join("timing.svg")).unwrap();
    let urdf = std::fs::read(dir.join("urdf/pendulum8.urdf")).unwrap();
    std::fs::remove_file(dir.join("timing.csv")).unwrap();
    std::fs::create_dir(dir.join("timing.csv")).unwrap();
    let (ok, err) = chart(&dir, &[]);
    assert!(!ok && err.contains("timing.csv"), "{err}");
    assert_eq!(std::fs::read(dir.join("timing.svg")).unwrap(), svg);
    assert_eq!(
        std::fs::read(dir.join("urdf/pendulum8.urdf")).unwrap(),
        urdf
    );
    assert!(leftovers(&dir).is_empty(), "{:?}", leftovers(&dir));

    let fresh = dir.join("fresh");
    let start = std::time::Instant::now();
    let (ok, err) = chart(&fresh, &["--robot", "x=/nonexistent/x.urdf"]);
    assert!(
        !ok && err.contains("--robot x=/nonexistent/x.urdf"),
        "{err}"
    );
    assert!(
        !err.contains("chart timing:"),
        "timed before the robot was loaded: {err}"
    );
    assert!(start.elapsed().as_secs() < 10);
    assert!(!fresh.exists(), "the failed run left {}", fresh.display());
    std::fs::create_dir(&fresh).unwrap();
    let (ok, err) = chart(&fresh, &["--robot", "x=/nonexistent/x.urdf"]);
    assert!(!ok, "{err}");
    let left: Vec<_> = std::fs::read_dir(&fresh).unwrap().collect();
    assert!(left.is_empty(), "{left:?}");
    std::fs::remove_dir_all(&dir).unwrap();
}

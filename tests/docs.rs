//! The documentation against the repository: docs/tests.md names every test file (and only files
//! that exist), the README's box diagrams keep their right border, the README states the
//! `rust-version` of both manifests, and every relative link of the Markdown files reaches a file
//! and, with `#anchor`, one of its headings. (The README's and docs/library.md's Rust examples are
//! compiled as doctests of `spatial_dynamics_core`.)

use std::fs;
use std::path::{Path, PathBuf};

/// The repository root: this package's manifest directory.
fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn read(path: &str) -> String {
    fs::read_to_string(repo().join(path)).unwrap_or_else(|e| panic!("cannot read {path}: {e}"))
}

/// The folders that hold tests, from the repository root.
const TEST_DIRS: [&str; 3] = ["tests", "src/core/tests", "src/c/tests"];

/// Build output, fuzzing inputs and caches: not test files.
const NOT_TESTS: [&str; 5] = ["target", "corpus", "artifacts", "__pycache__", "coverage"];

/// Extensions of the files that make up the tests: code, and the models the tests load.
const TEST_EXTENSIONS: [&str; 6] = ["rs", "py", "urdf", "c", "cpp", "hpp"];

fn is_test_file(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| TEST_EXTENSIONS.contains(&e))
}

/// Every test file under `dir` (repository-relative, `/`-separated), hidden folders and
/// [`NOT_TESTS`] skipped.
fn test_files(dir: &str, out: &mut Vec<String>) {
    let entries =
        fs::read_dir(repo().join(dir)).unwrap_or_else(|e| panic!("cannot list {dir}: {e}"));
    for entry in entries {
        let entry = entry.unwrap();
        let name = entry.file_name().to_string_lossy().into_owned();
        let path = format!("{dir}/{name}");
        if entry.file_type().unwrap().is_dir() {
            if !name.starts_with('.') && !NOT_TESTS.contains(&name.as_str()) {
                test_files(&path, out);
            }
        } else if is_test_file(Path::new(&name)) {
            out.push(path);
        }
    }
}

/// The `code spans` of a Markdown text.
fn code_spans(text: &str) -> Vec<&str> {
    text.split('`').skip(1).step_by(2).collect()
}

#[test]
fn docs_tests_md_names_every_test_file() {
    let mut files = Vec::new();
    for dir in TEST_DIRS {
        test_files(dir, &mut files);
    }
    files.sort();
    assert!(
        files.len() > 50,
        "only {} test files found under {TEST_DIRS:?}: {files:?}",
        files.len()
    );
    let doc = read("docs/tests.md");
    let named = code_spans(&doc);
    let missing: Vec<&String> = files
        .iter()
        .filter(|f| !named.contains(&f.as_str()))
        .collect();
    assert!(
        missing.is_empty(),
        "docs/tests.md does not name these test files (as `path` from the repository root): {missing:#?}"
    );
}

#[test]
fn docs_tests_md_names_no_test_file_that_is_gone() {
    let doc = read("docs/tests.md");
    let gone: Vec<&str> = code_spans(&doc)
        .into_iter()
        .filter(|span| TEST_DIRS.iter().any(|d| span.starts_with(&format!("{d}/"))))
        .filter(|span| is_test_file(Path::new(span)) && !repo().join(span).is_file())
        .collect();
    assert!(
        gone.is_empty(),
        "docs/tests.md names files that do not exist: {gone:?}"
    );
}

/// Columns a line takes in a monospace font: combining marks (the dots of `q̇`, `q̈`) take none,
/// every other character (box drawing and arrows included) one.
fn columns(line: &str) -> usize {
    let combining = |c: char| matches!(c as u32, 0x0300..=0x036F | 0x1AB0..=0x1AFF | 0x1DC0..=0x1DFF | 0x20D0..=0x20FF | 0xFE20..=0xFE2F);
    line.chars().filter(|&c| !combining(c)).count()
}

/// The fenced blocks of a Markdown text that draw a box (`┌`), as lists of lines.
fn box_drawings(text: &str) -> Vec<Vec<&str>> {
    let mut blocks = Vec::new();
    let mut lines = text.lines();
    while let Some(line) = lines.next() {
        if line.starts_with("```") {
            let block: Vec<&str> = lines
                .by_ref()
                .take_while(|l| !l.starts_with("```"))
                .collect();
            if block.iter().any(|l| l.contains('┌')) {
                blocks.push(block);
            }
        }
    }
    blocks
}

#[test]
fn readme_box_drawings_keep_their_right_border() {
    let readme = read("README.md");
    let drawings = box_drawings(&readme);
    assert!(
        !drawings.is_empty(),
        "the README's node diagram was not found"
    );
    for block in drawings {
        let width = columns(block[0]);
        for line in &block {
            assert_eq!(
                columns(line),
                width,
                "this line of a README diagram ends at column {} where its first line ends at {width}:\n{line}",
                columns(line)
            );
            let last = line.chars().last();
            assert!(
                matches!(last, Some('┐' | '│' | '┘')),
                "a README diagram line does not end on the box's border:\n{line}"
            );
        }
    }
}

/// The `rust-version` a manifest declares.
fn rust_version(manifest: &str) -> String {
    let text = read(manifest);
    let line = text
        .lines()
        .find(|l| l.starts_with("rust-version"))
        .unwrap_or_else(|| panic!("{manifest} declares no rust-version"));
    line.split('"')
        .nth(1)
        .expect("rust-version = \"X.Y\"")
        .to_string()
}

#[test]
fn readme_states_the_manifests_rust_versions() {
    let readme = read("README.md");
    let program = rust_version("Cargo.toml");
    let library = rust_version("src/core/Cargo.toml");
    let lines = [
        format!("Rust ≥ {program}"),
        format!("the library alone builds with {library}"),
    ];
    for line in lines {
        let found = readme.replace('\n', " ").contains(&line);
        assert!(found, "README.md does not say \"{line}\"");
    }
}

/// The Markdown files a user reads.
fn markdown_files() -> Vec<String> {
    let mut files = vec![
        "README.md".to_string(),
        "config/models/README.md".to_string(),
    ];
    for entry in fs::read_dir(repo().join("docs")).unwrap() {
        let name = entry.unwrap().file_name().to_string_lossy().into_owned();
        if name.ends_with(".md") {
            files.push(format!("docs/{name}"));
        }
    }
    files
}

/// GitHub's anchor of a heading: lower case, punctuation dropped, spaces turned into `-`.
fn anchor(heading: &str) -> String {
    heading
        .trim()
        .to_lowercase()
        .chars()
        .filter(|c| c.is_alphanumeric() || matches!(c, '-' | '_' | ' '))
        .map(|c| if c == ' ' { '-' } else { c })
        .collect()
}

/// The anchors of a Markdown file's headings (outside fenced blocks).
fn anchors(text: &str) -> Vec<String> {
    let mut fenced = false;
    let mut out = Vec::new();
    for line in text.lines() {
        if line.starts_with("```") {
            fenced = !fenced;
        } else if !fenced && line.starts_with('#') {
            out.push(anchor(line.trim_start_matches('#')));
        }
    }
    out
}

/// The targets of a Markdown text's inline links, `[text](target)`.
fn link_targets(text: &str) -> Vec<&str> {
    text.split("](")
        .skip(1)
        .filter_map(|rest| rest.split_once(')').map(|(target, _)| target))
        .collect()
}

#[test]
fn relative_links_in_the_docs_resolve() {
    let mut broken = Vec::new();
    for file in markdown_files() {
        let text = read(&file);
        let dir = Path::new(&file).parent().unwrap();
        for target in link_targets(&text) {
            if target.contains("://") || target.starts_with("mailto:") {
                continue;
            }
            let (path, fragment) = target.split_once('#').unwrap_or((target, ""));
            let linked = if path.is_empty() {
                PathBuf::from(&file)
            } else {
                dir.join(path)
            };
            let full = repo().join(&linked);
            if !full.exists() {
                broken.push(format!("{file}: {target} (no such file)"));
            } else if !fragment.is_empty() && linked.extension().is_some_and(|e| e == "md") {
                let headings = anchors(&fs::read_to_string(&full).unwrap());
                if !headings.iter().any(|a| a == fragment) {
                    broken.push(format!("{file}: {target} (no such heading)"));
                }
            }
        }
    }
    assert!(broken.is_empty(), "broken links: {broken:#?}");
}

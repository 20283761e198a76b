//! What a URDF is checked for before it becomes a model: the file it is read from, its XML, its
//! joints' limits, axes and dynamics, its links' inertias, the locks asked for; every refusal
//! names the file, element, joint, link or attribute at fault.

use spatial_dynamics_core::{urdf, Model, ModelError, ModelOptions};
use std::path::{Path, PathBuf};

fn model(text: &str) -> Result<Model, ModelError> {
    urdf::model_from_str(text, &ModelOptions::default())
}

fn error(text: &str) -> String {
    model(text).unwrap_err().to_string()
}

/// A scratch directory of this test binary's own (removed at the end of each test that makes
/// one).
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("sd_urdf_checks_{}_{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

// ---- the file -----------------------------------------------------------------------------------

#[test]
fn a_file_that_is_not_regular_is_refused_with_its_path() {
    for path in ["/dev/zero", "/tmp"] {
        let err = urdf::model_from_file(Path::new(path), &ModelOptions::default())
            .unwrap_err()
            .to_string();
        assert!(
            err.contains(&format!("{path}: not a regular file")) && err.contains("67108864"),
            "{err}"
        );
    }
}

#[test]
fn a_file_over_the_size_limit_is_refused_with_its_path_and_the_limit() {
    let dir = scratch("big");
    let path = dir.join("big.urdf");
    // Sparse: no disk is written.
    let file = std::fs::File::create(&path).unwrap();
    file.set_len(urdf::MAX_FILE_BYTES + 1).unwrap();
    let err = urdf::model_from_file(&path, &ModelOptions::default())
        .unwrap_err()
        .to_string();
    std::fs::remove_dir_all(&dir).unwrap();
    assert!(
        err.contains(&format!(
            "{}: the file is bigger than 67108864 bytes",
            path.display()
        )),
        "{err}"
    );
}

#[test]
fn a_file_at_the_size_limit_is_read() {
    let dir = scratch("limit");
    let path = dir.join("limit.urdf");
    let head = r#"<robot name="r"><link name="a"/></robot>"#;
    let text = format!(
        "{head}{}",
        " ".repeat(urdf::MAX_FILE_BYTES as usize - head.len())
    );
    std::fs::write(&path, text).unwrap();
    let result = urdf::model_from_file(&path, &ModelOptions::default());
    std::fs::remove_dir_all(&dir).unwrap();
    assert_eq!(result.unwrap().links().len(), 1);
}

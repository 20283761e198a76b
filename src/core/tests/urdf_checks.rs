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

/// A named pipe is refused at once: opened, it would wait for a writer that never comes.
#[cfg(unix)]
#[test]
fn a_named_pipe_is_refused_without_waiting_for_a_writer() {
    let dir = scratch("fifo");
    let path = dir.join("robot.urdf");
    let made = std::process::Command::new("mkfifo").arg(&path).status();
    assert!(made.is_ok_and(|s| s.success()), "mkfifo failed");
    let (send, receive) = std::sync::mpsc::channel();
    let reading = path.clone();
    std::thread::spawn(move || {
        let result = urdf::model_from_file(&reading, &ModelOptions::default());
        let _ = send.send(result.map(|_| ()).map_err(|e| e.to_string()));
    });
    let answer = receive.recv_timeout(std::time::Duration::from_secs(10));
    if answer.is_err() {
        // Let the blocked reader go before failing, so the test binary can exit.
        let _ = std::fs::OpenOptions::new().write(true).open(&path);
    }
    std::fs::remove_dir_all(&dir).unwrap();
    let err = answer.expect("still waiting after 10 s").unwrap_err();
    assert!(err.contains("not a regular file"), "{err}");
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

// ---- joints -------------------------------------------------------------------------------------

/// A one-joint robot whose joint `j` carries `extra` (a `<limit>`, `<dynamics>`, `<axis>`…).
fn one_joint(kind: &str, extra: &str) -> String {
    format!(
        r#"<robot name="r"><link name="a"/>
  <link name="b"><inertial><mass value="1"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial></link>
  <joint name="j" type="{kind}"><parent link="a"/><child link="b"/>{extra}</joint></robot>"#
    )
}

#[test]
fn bad_limits_and_dynamics_are_refused_naming_the_joint_and_attribute() {
    let limit = r#"<limit lower="-1" upper="1" effort="5" velocity="2"/>"#;
    let cases = [
        (
            limit.replace("-1", "nan"),
            "<limit lower> is NaN, not a finite number",
        ),
        (
            limit.replace("\"1\"", "\"inf\""),
            "<limit upper> is inf, not a finite number",
        ),
        (
            limit.replace("5", "-5"),
            "<limit effort> is -5e0, it must not be negative",
        ),
        (
            limit.replace("2", "-2"),
            "<limit velocity> is -2e0, it must not be negative",
        ),
        (
            r#"<limit lower="1" upper="-1" effort="5" velocity="2"/>"#.to_string(),
            "<limit lower> 1e0 is above <limit upper> -1e0",
        ),
        (
            format!(r#"{limit}<dynamics damping="-0.5"/>"#),
            "<dynamics damping> is -5e-1, it must not be negative",
        ),
        (
            format!(r#"{limit}<dynamics damping="NaN"/>"#),
            "<dynamics damping> is NaN, not a finite number",
        ),
        (
            format!(r#"{limit}<dynamics friction="-1"/>"#),
            "<dynamics friction> is -1e0, it must not be negative",
        ),
        (
            format!(r#"{limit}<dynamics friction="inf"/>"#),
            "<dynamics friction> is inf, not a finite number",
        ),
    ];
    for kind in ["revolute", "prismatic"] {
        for (extra, expected) in &cases {
            let err = error(&one_joint(kind, extra));
            assert!(
                err.contains(&format!("joint 'j': {expected}")),
                "{kind} {extra}: {err}"
            );
        }
    }
    // Sound limits and dynamics load, and a missing <limit> is no limit.
    let ok = model(&one_joint(
        "revolute",
        &format!(r#"{limit}<dynamics damping="0.5" friction="0.1"/>"#),
    ))
    .unwrap();
    assert_eq!(ok.nv(), 1);
    assert_eq!(model(&one_joint("continuous", "")).unwrap().nv(), 1);
}

// ---- links and locks ----------------------------------------------------------------------------

const INERTIAL: &str = r#"<inertial><mass value="1"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial>"#;

/// A base, a revolute `j1` to `a` and a prismatic `p` (limits ±1) to `b`.
fn slide() -> String {
    format!(
        r#"<robot name="r"><link name="base">{INERTIAL}</link><link name="a">{INERTIAL}</link><link name="b">{INERTIAL}</link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="a"/><origin xyz="0 0 0.5"/><axis xyz="0 1 0"/><limit lower="-1" upper="1" effort="10" velocity="1"/></joint>
  <joint name="p" type="prismatic"><parent link="a"/><child link="b"/><origin xyz="0 0 0.5"/><axis xyz="1 0 0"/><limit lower="-1" upper="1" effort="10" velocity="1"/></joint>
</robot>"#
    )
}

fn with_locks(text: &str, locks: &[(&str, f64)]) -> Result<Model, ModelError> {
    let options = ModelOptions {
        locked: locks.iter().map(|(n, v)| (n.to_string(), *v)).collect(),
        ..Default::default()
    };
    urdf::model_from_str(text, &options)
}

#[test]
fn a_fused_inertia_that_overflows_is_refused_naming_the_link() {
    // A 1e10 kg link fixed 1e200 m away: its inertia about the body's origin is m d² = inf.
    let text = slide()
        .replace(r#"type="prismatic""#, r#"type="fixed""#)
        .replace(
            r#"<origin xyz="0 0 0.5"/><axis xyz="1 0 0"/>"#,
            r#"<origin xyz="1e200 0 0"/>"#,
        )
        .replace(
            r#"<link name="b"><inertial><mass value="1"/>"#,
            r#"<link name="b"><inertial><mass value="1e10"/>"#,
        );
    let err = model(&text).unwrap_err().to_string();
    assert!(
        err.contains("link 'b': fused through fixed joint 'p' into body 'a', it makes that body's inertia overflow (its mass 1e10 kg at (1e200, 0e0, 0e0) m)"),
        "{err}"
    );
}

#[test]
fn a_lock_outside_the_joint_limits_is_refused_naming_the_joint_value_and_limits() {
    for (joint, value) in [("p", 1e200), ("p", 1.5), ("j1", -1.0 - 1e-9)] {
        let err = with_locks(&slide(), &[(joint, value)])
            .unwrap_err()
            .to_string();
        assert!(
            err.contains(&format!(
                "cannot lock joint '{joint}' at {value:e}: outside its limits [-1e0, 1e0]"
            )),
            "{err}"
        );
    }
    // At a limit is within; a continuous joint, or a revolute joint without <limit>, has no range.
    assert_eq!(
        with_locks(&slide(), &[("p", 1.0), ("j1", -1.0)])
            .unwrap()
            .nv(),
        0
    );
    let continuous = slide().replace(r#"type="revolute""#, r#"type="continuous""#);
    assert_eq!(with_locks(&continuous, &[("j1", 7.0)]).unwrap().nv(), 1);
    let no_limit = slide().replace(
        r#"<axis xyz="0 1 0"/><limit lower="-1" upper="1" effort="10" velocity="1"/>"#,
        r#"<axis xyz="0 1 0"/>"#,
    );
    assert_eq!(with_locks(&no_limit, &[("j1", 2.0)]).unwrap().nv(), 1);
}

#[test]
fn a_joint_locked_twice_is_refused_by_name() {
    let err = with_locks(&slide(), &[("j1", 0.1), ("p", 0.2), ("j1", 0.3)])
        .unwrap_err()
        .to_string();
    assert!(err.contains("joint 'j1' is locked twice"), "{err}");
}

#[test]
fn a_massless_link_with_a_doubtful_inertia_warns_as_a_massive_one() {
    let text = |inertia: &str| {
        format!(
            r#"<robot name="r"><link name="a"/><link name="b"><inertial><mass value="0"/><inertia {inertia}/></inertial></link>
  <joint name="j" type="continuous"><parent link="a"/><child link="b"/></joint></robot>"#
        )
    };
    let warnings = |inertia: &str| model(&text(inertia)).unwrap().warnings().to_vec();
    let not_psd = warnings(r#"ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="-1""#);
    assert!(
        not_psd.len() == 1
            && not_psd[0]
                .contains("link 'b': its rotational inertia is not positive semi-definite"),
        "{not_psd:?}"
    );
    let triangle = warnings(r#"ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="5""#);
    assert!(
        triangle.len() == 1 && triangle[0].contains("link 'b': its principal moments"),
        "{triangle:?}"
    );
    for fine in [
        r#"ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0""#,
        r#"ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1.5""#,
    ] {
        assert!(warnings(fine).is_empty(), "{fine}: {:?}", warnings(fine));
    }
}

// ---- the XML ------------------------------------------------------------------------------------

const ONE_LINK: &str = r#"<robot name="r"><link name="a"/></robot>"#;

#[test]
fn an_empty_robot_is_said_to_have_no_links() {
    for text in [
        r#"<robot name="r"></robot>"#,
        r#"<robot name="r"><group><link name="a"/></group></robot>"#,
    ] {
        let err = error(text);
        assert!(
            err.contains("robot 'r' has no links: a URDF needs at least one <link> element"),
            "{err}"
        );
    }
}

#[test]
fn content_outside_the_root_element_is_refused_naming_it() {
    let cases = [
        (
            format!("{ONE_LINK}<robot name=\"s\"><link name=\"z\"/></robot>"),
            "element <robot> after the root element's end </robot>",
        ),
        (
            format!(
                r#"{ONE_LINK}<joint name="j2" type="fixed"><parent link="a"/><child link="b"/></joint>"#
            ),
            "element <joint> after the root element's end </robot>",
        ),
        (
            format!("{ONE_LINK} garbage"),
            "text 'garbage' after the root element's end </robot>",
        ),
        (
            format!("{ONE_LINK}</robot>"),
            "after the root element's end </robot>",
        ),
        (
            format!("garbage {ONE_LINK}"),
            "text 'garbage' before the root <robot> element",
        ),
        (
            format!("<!DOCTYPE robot [<!ENTITY m \"2.5\">]>{ONE_LINK}"),
            "a <!DOCTYPE> with an internal subset ([…]) is not supported",
        ),
    ];
    for (text, expected) in &cases {
        let Err(err) = model(text).map(|_| ()) else {
            panic!("{text}: loaded");
        };
        let err = err.to_string();
        assert!(err.contains(expected), "{text}: {err}");
    }
    // White space, comments and declarations around the root, and a byte-order mark, are fine.
    for text in [
        format!("\n<?xml version=\"1.0\"?>\n<!-- a -->\n{ONE_LINK}\n<!-- b -->\n"),
        format!("\u{feff}{ONE_LINK}"),
    ] {
        assert_eq!(model(&text).unwrap().links().len(), 1, "{text}");
    }
}

#[test]
fn an_unexpected_end_of_the_text_says_so() {
    let err = error(r#"<robot name="r"><link name="a"/>"#);
    assert!(
        err.contains("unexpected end of the text: <robot> still open"),
        "{err}"
    );
    let err = error("<robot name=\"r\"><link name=\"a\"><inertial>\n");
    assert!(
        err.contains(r#"unexpected end of the text: <robot> <link> <inertial> still open (in <link name="a">)"#),
        "{err}"
    );
    for empty in ["", "  \n", "<!-- only a comment -->"] {
        let err = error(empty);
        assert!(err.contains("no XML element"), "{empty:?}: {err}");
    }
}

#[test]
fn a_huge_axis_is_a_direction_and_errors_print_numbers_short() {
    for (xyz, unit) in [("1e200 0 0", "1 0 0"), ("1e200 1e200 0", "1 1 0")] {
        let axis = |xyz: &str| {
            let m = model(&one_joint("continuous", &format!(r#"<axis xyz="{xyz}"/>"#))).unwrap();
            let joint = &m.bodies()[0].joint;
            (joint.kind, joint.coords)
        };
        assert_eq!(axis(xyz), axis(unit), "{xyz}");
    }
    let err = error(&one_joint("continuous", r#"<axis xyz="0 0 1e-300"/>"#));
    assert!(
        err.contains("joint 'j': <axis xyz> (0e0, 0e0, 1e-300) is not a usable direction"),
        "{err}"
    );
    let err = error(
        r#"<robot name="r"><link name="a"><inertial><mass value="-1e200"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link></robot>"#,
    );
    assert!(
        err.contains("link 'a': mass must be finite and not negative, got -1e200"),
        "{err}"
    );
}

#[test]
fn parse_errors_name_the_element_and_the_file() {
    let inertial = |body: &str| {
        format!(
            r#"<robot name="r"><link name="a"/><link name="b"><inertial>{body}</inertial></link>
  <joint name="j" type="continuous"><parent link="a"/><child link="b"/></joint></robot>"#
        )
    };
    let cases = [
        (inertial(r#"<mass value="1"/>"#), r#"<link name="b">: "#),
        (
            inertial(
                r#"<mass value="heavy"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/>"#,
            ),
            r#"<link name="b">: "#,
        ),
        (
            one_joint("revolute", r#"<axis xyz="0 0 1"/><axis xyz="1 0 0"/>"#),
            r#"<joint name="j">: "#,
        ),
        (
            r#"<robot name="r"><link name="a"><inertial></inertia></link></robot>"#.to_string(),
            r#"the end tag </inertia> does not close <inertial> (in <link name="a">)"#,
        ),
    ];
    for (text, expected) in &cases {
        let err = error(text);
        assert!(err.contains(expected), "{text}: {err}");
    }
    let dir = scratch("errors");
    let path = dir.join("bad.urdf");
    std::fs::write(&path, &cases[0].0).unwrap();
    let err = urdf::model_from_file(&path, &ModelOptions::default())
        .unwrap_err()
        .to_string();
    std::fs::write(
        &path,
        one_joint(
            "revolute",
            r#"<limit lower="1" upper="0" effort="1" velocity="1"/>"#,
        ),
    )
    .unwrap();
    let invalid = urdf::model_from_file(&path, &ModelOptions::default())
        .unwrap_err()
        .to_string();
    std::fs::remove_dir_all(&dir).unwrap();
    let prefix = format!(r#"{}: <link name="b">: "#, path.display());
    assert!(err.contains(&prefix), "{err}");
    let prefix = format!("{}: joint 'j': <limit lower>", path.display());
    assert!(invalid.contains(&prefix), "{invalid}");
}

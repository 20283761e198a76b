//! URDF → [`Model`], through `urdf-rs`.
//!
//! Dynamics needs links, joints and inertias only: `<visual>`, `<collision>`, `<material>`,
//! `<gazebo>` and `<transmission>` are removed before parsing, so a description is never refused
//! for a drawing detail (a `<texture/>` without a file name, an odd mesh tag).
//!
//! Conventions: `<origin rpy>` is roll about x, then pitch about y, then yaw about z (fixed axes:
//! `R = Rz(yaw) Ry(pitch) Rx(roll)`); an `<inertial>`'s tensor is given in the frame of its
//! `<origin>`; a link with no `<inertial>` is massless.

use crate::error::ModelError;
use crate::model::{
    BodySpec, JointKind, JointLimits, JointSpec, Model, ModelBuilder, ModelOptions,
};
use crate::spatial::{Inertia, Matrix3, Transform, Vector3};
use nalgebra::Rotation3;
use std::path::Path;

/// Elements that only matter for drawing or simulation plugins.
const IGNORED_ELEMENTS: [&str; 5] = ["visual", "collision", "material", "gazebo", "transmission"];

/// Builds a model from URDF text.
pub fn model_from_str(text: &str, options: &ModelOptions) -> Result<Model, ModelError> {
    builder_from_str(text)?.build(options)
}

/// The links and joints of URDF text, ready to build.
pub(crate) fn builder_from_str(text: &str) -> Result<ModelBuilder, ModelError> {
    let robot = parse(text)?;
    let mut builder = ModelBuilder::new(&robot.name);
    for link in &robot.links {
        builder.link(BodySpec {
            name: link.name.clone(),
            inertia: link_inertia(link)?,
        });
    }
    for joint in &robot.joints {
        builder.joint(joint_spec(joint)?);
    }
    Ok(builder)
}

/// Builds a model from a URDF file: a regular file of at most [`MAX_FILE_BYTES`] of UTF-8.
/// Errors start with the file's path.
pub fn model_from_file(path: &Path, options: &ModelOptions) -> Result<Model, ModelError> {
    let text = read_file(path)?;
    model_from_str(&text, options).map_err(|e| {
        let at = |m: String| format!("{}: {m}", path.display());
        match e {
            ModelError::Parse(m) => ModelError::Parse(at(m)),
            ModelError::Invalid(m) => ModelError::Invalid(at(m)),
            io => io,
        }
    })
}

/// The largest URDF file read: 64 MiB (TALOS's URDF, a full humanoid, is 0.2 MB). A bigger file,
/// or one that is not a regular file (`/dev/zero`, a pipe, a directory), is refused before it is
/// read.
pub const MAX_FILE_BYTES: u64 = 64 << 20;

/// The text of the file at `path`, read through a bound of [`MAX_FILE_BYTES`] (the file may grow
/// while it is read).
fn read_file(path: &Path) -> Result<String, ModelError> {
    use std::io::Read;
    let io = |e: std::io::Error| ModelError::Io(format!("{}: {e}", path.display()));
    let too_big = || {
        Err(ModelError::Io(format!(
            "{}: the file is bigger than {MAX_FILE_BYTES} bytes (64 MiB), the most a URDF may have",
            path.display()
        )))
    };
    let not_regular = || {
        Err(ModelError::Io(format!(
            "{}: not a regular file (a URDF is read from a file of at most {MAX_FILE_BYTES} bytes)",
            path.display()
        )))
    };
    // Checked before opening too: opening a named pipe waits for a writer.
    if !std::fs::metadata(path).map_err(io)?.is_file() {
        return not_regular();
    }
    let file = std::fs::File::open(path).map_err(io)?;
    let meta = file.metadata().map_err(io)?;
    if !meta.is_file() {
        return not_regular();
    }
    if meta.len() > MAX_FILE_BYTES {
        return too_big();
    }
    let mut bytes = Vec::new();
    file.take(MAX_FILE_BYTES + 1)
        .read_to_end(&mut bytes)
        .map_err(io)?;
    if bytes.len() as u64 > MAX_FILE_BYTES {
        return too_big();
    }
    String::from_utf8(bytes).map_err(|e| {
        ModelError::Io(format!(
            "{}: not UTF-8 text (invalid byte at offset {})",
            path.display(),
            e.utf8_error().valid_up_to()
        ))
    })
}

/// Limits no real robot description comes near (TALOS, a full humanoid, has about 2 000 XML
/// elements nested 6 deep, 50 coordinates), so that a huge or hostile text is refused with a
/// reason instead of exhausting the stack (the XML tree is walked recursively) or memory.
/// Memory is bounded by the model itself: the builder refuses a model whose workspace would
/// take more than [`Workspace::MAX_BYTES`](crate::Workspace::MAX_BYTES) (2 GiB: ten `nv × nv`
/// matrices, and lists of ancestors that grow as the square of a chain's length), which a
/// revolute chain reaches at about 4 800 links.
pub const MAX_DEPTH: usize = 100;
/// See [`MAX_DEPTH`]: XML elements in the whole description.
pub const MAX_ELEMENTS: usize = 1_000_000;
/// See [`MAX_DEPTH`]: `<link>` elements, and `<joint>` elements, each (fixed joints fuse their
/// links into one body, so many links need not make a big model).
pub const MAX_LINKS: usize = 20_000;

/// Parses the text with the elements dynamics does not need removed. The XML is read as a
/// stream first, so that nesting, element and link counts are checked before any of it is
/// walked recursively.
fn parse(text: &str) -> Result<urdf_rs::Robot, ModelError> {
    let too_big = |what: String| {
        Err(ModelError::Parse(format!(
            "{what}: not a robot description this library can use"
        )))
    };
    let mut parser = xml::Parser::new();
    // A byte-order mark is no content.
    parser.feed_str(text.strip_prefix('\u{feff}').unwrap_or(text));
    let mut builder = xml::ElementBuilder::new();
    let (mut depth, mut elements, mut links, mut joints) = (0usize, 0usize, 0usize, 0usize);
    let mut root = None;
    // The open elements' names (at most MAX_DEPTH), and the <link> or <joint> being read, for
    // the errors.
    let mut open: Vec<String> = Vec::new();
    let mut within = String::new();
    for event in parser.by_ref() {
        match &event {
            Ok(xml::Event::Characters(t) | xml::Event::CDATA(t))
                if depth == 0 && !t.trim().is_empty() =>
            {
                // The XML reader ends a declaration at its first '>'.
                return Err(ModelError::Parse(if t.trim_start().starts_with(']') {
                    "a <!DOCTYPE> with an internal subset ([…]) is not supported".into()
                } else {
                    format!("text {} before the root <robot> element", snippet(t))
                }));
            }
            Ok(xml::Event::ElementStart(tag)) => {
                depth += 1;
                elements += 1;
                if depth > MAX_DEPTH {
                    return too_big(format!(
                        "elements are nested more than {MAX_DEPTH} deep (at <{}>)",
                        tag.name
                    ));
                }
                if elements > MAX_ELEMENTS {
                    return too_big(format!("more than {MAX_ELEMENTS} XML elements"));
                }
                match (depth, tag.name.as_str()) {
                    (2, "link") => links += 1,
                    (2, "joint") => joints += 1,
                    _ => {}
                }
                if links.max(joints) > MAX_LINKS {
                    return too_big(format!("more than {MAX_LINKS} links or joints"));
                }
                open.push(tag.name.clone());
                if depth == 2 {
                    within = match tag.attributes.get(&("name".to_string(), None)) {
                        Some(name) => format!(" (in <{} name=\"{name}\">)", tag.name),
                        None => format!(" (in a <{}> without a name)", tag.name),
                    };
                }
            }
            Ok(xml::Event::ElementEnd(tag)) => {
                if let Some(top) = open.pop().filter(|top| *top != tag.name) {
                    return Err(ModelError::Parse(format!(
                        "the end tag </{}> does not close <{top}>{within}",
                        tag.name
                    )));
                }
                depth = depth.saturating_sub(1);
                if depth < 2 {
                    within.clear();
                }
            }
            _ => {}
        }
        if let Some(element) = builder.handle_event(event) {
            root = Some(element.map_err(|e| ModelError::Parse(format!("{e}{within}")))?);
            break;
        }
    }
    let mut root = root.ok_or_else(|| {
        ModelError::Parse(if open.is_empty() {
            "no XML element: the text is empty, or only comments and declarations".into()
        } else {
            format!(
                "unexpected end of the text: <{}> still open{within}",
                open.join("> <")
            )
        })
    })?;
    // Nothing but comments, declarations and white space may follow the root element.
    for event in parser {
        let after = |what: String| {
            Err(ModelError::Parse(format!(
                "{what} after the root element's end </{}>: a URDF is one <robot> element",
                root.name
            )))
        };
        match event {
            Ok(xml::Event::ElementStart(tag)) => return after(format!("element <{}>", tag.name)),
            Ok(xml::Event::ElementEnd(tag)) => return after(format!("end tag </{}>", tag.name)),
            Ok(xml::Event::Characters(t) | xml::Event::CDATA(t)) if !t.trim().is_empty() => {
                return after(format!("text {}", snippet(&t)))
            }
            Err(e) => return after(format!("malformed XML ({e})")),
            _ => {}
        }
    }
    // Text after the last tag is never emitted as an event (it may go on in a later feed).
    let tail = &text[text.rfind('>').map_or(0, |i| i + 1)..];
    if !tail.trim().is_empty() {
        return Err(ModelError::Parse(format!(
            "text {} after the root element's end </{}>: a URDF is one <robot> element",
            snippet(tail),
            root.name
        )));
    }
    if root.name != "robot" {
        return Err(ModelError::Parse(format!(
            "the root element is <{}>, not <robot>",
            root.name
        )));
    }
    strip(&mut root);
    urdf_rs::read_from_string(&root.to_string()).map_err(|e| {
        ModelError::Parse(match culprit(&root) {
            Some(element) => format!("{element}: {e}"),
            None => e.to_string(),
        })
    })
}

/// The first `<link>` or `<joint>` that `urdf-rs` refuses on its own, as `<link name="…">`: the
/// element a whole-robot error comes from (it names none).
fn culprit(root: &xml::Element) -> Option<String> {
    root.children.iter().find_map(|child| match child {
        xml::Xml::ElementNode(e) if e.name == "link" || e.name == "joint" => {
            let alone = format!(r#"<robot name="r">{e}</robot>"#);
            urdf_rs::read_from_string(&alone).is_err().then(|| {
                match e.get_attribute("name", None) {
                    Some(name) => format!(r#"<{} name="{name}">"#, e.name),
                    None => format!("a <{}> without a name", e.name),
                }
            })
        }
        _ => None,
    })
}

/// `text`, trimmed and quoted, its first 40 characters at most.
fn snippet(text: &str) -> String {
    let text = text.trim();
    match text.char_indices().nth(40) {
        Some((end, _)) => format!("'{}…'", &text[..end]),
        None => format!("'{text}'"),
    }
}

fn strip(element: &mut xml::Element) {
    element.children.retain(
        |c| !matches!(c, xml::Xml::ElementNode(e) if IGNORED_ELEMENTS.contains(&e.name.as_str())),
    );
    for child in &mut element.children {
        if let xml::Xml::ElementNode(e) = child {
            strip(e);
        }
    }
}

fn rotation(rpy: &[f64; 3]) -> Matrix3 {
    Rotation3::from_euler_angles(rpy[0], rpy[1], rpy[2]).into_inner()
}

fn vector(v: &[f64; 3]) -> Vector3 {
    Vector3::new(v[0], v[1], v[2])
}

fn all_finite(values: &[f64]) -> bool {
    values.iter().all(|x| x.is_finite())
}

/// `<origin>` as the transform from the parent frame into the child frame.
fn pose(origin: &urdf_rs::Pose, context: &str) -> Result<Transform, ModelError> {
    if !all_finite(&origin.xyz.0) || !all_finite(&origin.rpy.0) {
        return Err(ModelError::Invalid(format!(
            "{context}: <origin> has a value that is not a finite number"
        )));
    }
    Ok(Transform::from_pose(
        &rotation(&origin.rpy),
        &vector(&origin.xyz),
    ))
}

/// The link's spatial inertia in the link frame.
fn link_inertia(link: &urdf_rs::Link) -> Result<Inertia, ModelError> {
    let inertial = &link.inertial;
    let t = &inertial.inertia;
    let tensor = Matrix3::new(
        t.ixx, t.ixy, t.ixz, t.ixy, t.iyy, t.iyz, t.ixz, t.iyz, t.izz,
    );
    let context = format!("link '{}'", link.name);
    pose(&inertial.origin, &context)?;
    if !all_finite(tensor.as_slice()) || !inertial.mass.value.is_finite() {
        return Err(ModelError::Invalid(format!(
            "{context}: <inertial> has a value that is not a finite number"
        )));
    }
    let r = rotation(&inertial.origin.rpy);
    Ok(Inertia::from_com(
        inertial.mass.value,
        &vector(&inertial.origin.xyz),
        &(r * tensor * r.transpose()),
    ))
}

fn joint_spec(joint: &urdf_rs::Joint) -> Result<JointSpec, ModelError> {
    use urdf_rs::JointType as T;
    let context = format!("joint '{}'", joint.name);
    let axis = vector(&joint.axis.xyz);
    let unit_axis = || {
        // Scaled by its largest component first, so that no square overflows or underflows.
        let largest = axis.amax();
        let scaled = axis / largest;
        let norm = scaled.norm();
        if largest.is_finite() && largest * norm > 1e-9 && norm.is_finite() {
            Ok(scaled / norm)
        } else {
            Err(ModelError::Invalid(format!(
                "{context}: <axis xyz> ({:e}, {:e}, {:e}) is not a usable direction",
                axis.x, axis.y, axis.z
            )))
        }
    };
    let kind = match joint.joint_type {
        T::Fixed => None,
        T::Revolute => Some(JointKind::Revolute { axis: unit_axis()? }),
        T::Continuous => Some(JointKind::Continuous { axis: unit_axis()? }),
        T::Prismatic => Some(JointKind::Prismatic { axis: unit_axis()? }),
        T::Planar => Some(JointKind::planar(unit_axis()?)),
        T::Floating => Some(JointKind::Floating),
        T::Spherical => {
            return Err(ModelError::Invalid(format!(
                "{context}: joint type 'spherical' is not supported"
            )))
        }
    };
    let l = &joint.limit;
    check_limits(joint, &context)?;
    let unbounded = matches!(joint.joint_type, T::Continuous | T::Floating | T::Planar);
    let limits = JointLimits {
        lower: if unbounded {
            f64::NEG_INFINITY
        } else {
            l.lower
        },
        upper: if unbounded { f64::INFINITY } else { l.upper },
        // A missing <limit> (or a zero, which no real joint has) means no limit.
        velocity: if l.velocity > 0.0 {
            l.velocity
        } else {
            f64::INFINITY
        },
        effort: if l.effort > 0.0 {
            l.effort
        } else {
            f64::INFINITY
        },
        damping: joint.dynamics.as_ref().map_or(0.0, |d| d.damping),
        friction: joint.dynamics.as_ref().map_or(0.0, |d| d.friction),
    };
    Ok(JointSpec {
        name: joint.name.clone(),
        parent: joint.parent.link.clone(),
        child: joint.child.link.clone(),
        origin: pose(&joint.origin, &context)?,
        kind,
        mimic: joint.mimic.as_ref().map(|m| {
            (
                m.joint.clone(),
                m.multiplier.unwrap_or(1.0),
                m.offset.unwrap_or(0.0),
            )
        }),
        limits,
    })
}

/// `<limit>` and `<dynamics>` must be finite, `lower ≤ upper`, effort, velocity, damping and
/// friction not negative.
fn check_limits(joint: &urdf_rs::Joint, context: &str) -> Result<(), ModelError> {
    let l = &joint.limit;
    let d = joint.dynamics.as_ref();
    let values = [
        ("<limit lower>", l.lower),
        ("<limit upper>", l.upper),
        ("<limit effort>", l.effort),
        ("<limit velocity>", l.velocity),
        ("<dynamics damping>", d.map_or(0.0, |d| d.damping)),
        ("<dynamics friction>", d.map_or(0.0, |d| d.friction)),
    ];
    for (attribute, value) in values {
        if !value.is_finite() {
            return Err(ModelError::Invalid(format!(
                "{context}: {attribute} is {value}, not a finite number"
            )));
        }
    }
    for (attribute, value) in &values[2..] {
        if *value < 0.0 {
            return Err(ModelError::Invalid(format!(
                "{context}: {attribute} is {value:e}, it must not be negative"
            )));
        }
    }
    if l.lower > l.upper {
        return Err(ModelError::Invalid(format!(
            "{context}: <limit lower> {:e} is above <limit upper> {:e}",
            l.lower, l.upper
        )));
    }
    Ok(())
}

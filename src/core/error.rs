//! Errors, each naming what went wrong and where (which joint, link, coordinate or value).

use std::fmt;

/// A robot description that cannot be turned into a model.
#[derive(Debug, Clone, PartialEq)]
pub enum ModelError {
    /// The file could not be read.
    Io(String),
    /// The text is not a URDF the parser understands.
    Parse(String),
    /// The description parses but does not make a valid tree of rigid bodies.
    Invalid(String),
}

impl fmt::Display for ModelError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ModelError::Io(m) => write!(f, "cannot read the robot description: {m}"),
            ModelError::Parse(m) => write!(f, "cannot parse the URDF: {m}"),
            ModelError::Invalid(m) => write!(f, "invalid robot model: {m}"),
        }
    }
}

impl std::error::Error for ModelError {}

/// An algorithm call that cannot give a trustworthy answer. Never returned as NaN.
#[derive(Debug, Clone, PartialEq)]
pub enum DynamicsError {
    /// An input vector has the wrong length.
    Length {
        vector: &'static str,
        expected: usize,
        got: usize,
    },
    /// An input value is NaN or infinite.
    NonFinite {
        vector: &'static str,
        index: usize,
        coordinate: String,
        value: f64,
    },
    /// A floating joint's quaternion has (nearly) zero norm.
    BadQuaternion { joint: String, norm: f64 },
    /// An external wrench is NaN or infinite.
    NonFiniteWrench { body: String },
    /// The mass matrix is singular or not positive definite at this coordinate.
    SingularMassMatrix { coordinate: String, pivot: f64 },
    /// The articulated inertia seen by a joint is singular (ABA): the Cholesky pivot of
    /// `D = Sᵀ I^A S` that failed, at velocity `coordinate` of `joint` (carrying `body`).
    SingularArticulatedInertia {
        joint: String,
        body: String,
        coordinate: String,
        pivot: f64,
    },
    /// The method cannot handle this model.
    Unsupported {
        method: &'static str,
        reason: String,
    },
    /// The computation overflowed to a non-finite value.
    NonFiniteResult {
        quantity: &'static str,
        coordinate: String,
    },
    /// A frame was asked of a link the model does not have: never in the description, or
    /// `pruned` with a massless subtree (then nothing places it). `known` lists the first
    /// [`NAMES_SHOWN`] links that are frames, of `links` in all.
    UnknownLink {
        link: String,
        pruned: bool,
        known: Vec<String>,
        links: usize,
    },
    /// The workspace was made ([`Workspace::new`](crate::Workspace::new)) for another model
    /// than the one given: its buffers and plan belong to that model. Each model is named by
    /// its robot name and its identity (every model built or reduced gets its own; a clone
    /// keeps it).
    ForeignWorkspace {
        workspace_model: String,
        workspace_model_id: u64,
        model: String,
        model_id: u64,
    },
    /// A [`Frame`](crate::algorithms::Frame) found in another model than the one given: its link
    /// index and the identities of both models.
    ForeignFrame {
        link: usize,
        frame_model_id: u64,
        model: String,
        model_id: u64,
    },
    /// A time step that is negative or not finite (a linearisation's `dt`).
    BadStep { dt: f64 },
}

impl fmt::Display for DynamicsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DynamicsError::Length { vector, expected, got } => {
                write!(f, "{vector} has {got} values, the model needs {expected}")
            }
            DynamicsError::NonFinite { vector, index, coordinate, value } => {
                write!(f, "{vector}[{index}] ({coordinate}) is {value}, not a finite number")
            }
            DynamicsError::BadQuaternion { joint, norm } => write!(
                f,
                "the quaternion of floating joint '{joint}' has norm {}: it must be a unit quaternion (x, y, z, w)",
                short(*norm)
            ),
            DynamicsError::NonFiniteWrench { body } => {
                write!(f, "the external wrench on '{body}' is not finite")
            }
            // A pivot that overflowed is not a singularity of the model but of the numbers.
            DynamicsError::SingularMassMatrix { coordinate, pivot } if !pivot.is_finite() => write!(
                f,
                "the mass matrix at coordinate '{coordinate}' overflowed to a non-finite value (pivot {pivot}): the state is too extreme to compute with"
            ),
            DynamicsError::SingularArticulatedInertia { joint, body, coordinate, pivot } if !pivot.is_finite() => write!(
                f,
                "the articulated inertia at joint '{joint}' (body '{body}') overflowed to a non-finite value (pivot of coordinate '{coordinate}': {pivot}): the state is too extreme to compute with"
            ),
            DynamicsError::SingularMassMatrix { coordinate, pivot } => write!(
                f,
                "the mass matrix is singular or not positive definite at coordinate '{coordinate}' (pivot {pivot:e}): a massless body or one that cannot move along this joint"
            ),
            DynamicsError::SingularArticulatedInertia { joint, body, coordinate, pivot } => write!(
                f,
                "the articulated inertia at joint '{joint}' (body '{body}') is singular: the pivot of coordinate '{coordinate}' is {pivot:e}: nothing with mass moves when this joint moves"
            ),
            DynamicsError::Unsupported { method, reason } => write!(f, "method '{method}' cannot be used: {reason}"),
            DynamicsError::NonFiniteResult { quantity, coordinate } => {
                write!(f, "{quantity} at '{coordinate}' overflowed to a non-finite value")
            }
            DynamicsError::UnknownLink { link, pruned: true, known, links } => write!(
                f,
                "link {} was pruned with a massless subtree, so no body carries its frame; the model's links are: {}",
                quoted(link),
                name_list(known, *links)
            ),
            DynamicsError::UnknownLink { link, pruned: false, known, links } => write!(
                f,
                "the model has no link named {}; its links are: {}",
                quoted(link),
                name_list(known, *links)
            ),
            DynamicsError::ForeignWorkspace { workspace_model, workspace_model_id, model, model_id } => write!(
                f,
                "the workspace was made for model '{workspace_model}' (#{workspace_model_id}), not for the model given, '{model}' (#{model_id}): make one with Workspace::new for each model"
            ),
            DynamicsError::ForeignFrame { link, frame_model_id, model, model_id } => write!(
                f,
                "the frame (link #{link}) was found in model #{frame_model_id}, not in the model given, '{model}' (#{model_id}): find it in this model with find_frame"
            ),
            DynamicsError::BadStep { dt } => {
                write!(f, "dt is {dt}: a time step must be finite and at least zero (0: continuous time)")
            }
        }
    }
}

impl std::error::Error for DynamicsError {}

/// `Ok` when a vector has the `expected` length, else the `Length` error naming it.
pub(crate) fn check_len(
    vector: &'static str,
    expected: usize,
    got: usize,
) -> Result<(), DynamicsError> {
    if expected == got {
        Ok(())
    } else {
        Err(DynamicsError::Length {
            vector,
            expected,
            got,
        })
    }
}

/// How many names a message lists before it says how many more there are ([`name_list`]).
pub const NAMES_SHOWN: usize = 12;

/// The longest name a message repeats whole ([`quoted`]), in bytes.
pub const NAME_SHOWN_BYTES: usize = 64;

/// `'name'`; a name longer than [`NAME_SHOWN_BYTES`] is cut (at a character boundary) and its
/// length given: a message is a sentence, not a copy of the request that caused it.
pub fn quoted(name: &str) -> String {
    match cut(name) {
        Some((start, bytes)) => format!("'{start}…' ({bytes} bytes)"),
        None => format!("'{name}'"),
    }
}

/// `a, b, c` for the first [`NAMES_SHOWN`] of `names` (of `total` in all), then `… (N more)`;
/// long names cut as [`quoted`] cuts them.
pub fn name_list<S: AsRef<str>>(names: &[S], total: usize) -> String {
    let shown = names
        .iter()
        .take(NAMES_SHOWN)
        .map(|n| match cut(n.as_ref()) {
            Some((start, bytes)) => format!("{start}… ({bytes} bytes)"),
            None => n.as_ref().to_string(),
        });
    let mut list = shown.collect::<Vec<_>>().join(", ");
    let more = total.saturating_sub(names.len().min(NAMES_SHOWN));
    if more > 0 {
        list.push_str(&format!(", … ({more} more)"));
    }
    list
}

/// The start of a name longer than [`NAME_SHOWN_BYTES`], and its length; `None` if it is short.
fn cut(name: &str) -> Option<(&str, usize)> {
    if name.len() <= NAME_SHOWN_BYTES {
        return None;
    }
    let mut end = NAME_SHOWN_BYTES - 16;
    while !name.is_char_boundary(end) {
        end -= 1;
    }
    Some((&name[..end], name.len()))
}

/// `x` as a reader would write it: plainly between 10⁻⁴ and 10⁶ (and 0), in exponent form
/// otherwise (`1e200`, not two hundred digits).
fn short(x: f64) -> String {
    if x == 0.0 || (1e-4..1e6).contains(&x.abs()) || !x.is_finite() {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn long_names_and_long_lists_are_cut() {
        assert_eq!(quoted("elbow"), "'elbow'");
        let long = "é".repeat(500_000);
        let q = quoted(&long);
        assert!(q.len() < 80 && q.ends_with("…' (1000000 bytes)"), "{q}");
        let names: Vec<String> = (0..4000).map(|i| format!("link_{i:04}")).collect();
        let list = name_list(&names, names.len());
        assert!(
            list.starts_with("link_0000, link_0001, ") && list.len() < 200,
            "{list}"
        );
        assert!(list.ends_with("link_0011, … (3988 more)"), "{list}");
        assert_eq!(name_list(&names[..3], 3), "link_0000, link_0001, link_0002");
        // A list of the first names of many, as UnknownLink carries it.
        assert!(name_list(&names[..NAMES_SHOWN], 4000).ends_with("(3988 more)"));
    }
}

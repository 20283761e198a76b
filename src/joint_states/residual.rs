//! The effort residual of a measured joint state (all vectors `nv` long, model order, joint
//! space):
//!
//! ```text
//! r = τ_measured − RNEA(q, q̇, q̈_measured)
//! ```
//!
//! `τ_measured` is the message's `effort[]`, `q̈_measured` the finite-difference estimate of
//! [`differences`](super::differences) (the acceleration of `~/measured_dynamics`), so
//! `RNEA(…)` is the effort the rigid-body model needs for the measured motion (base at rest in
//! an inertial frame, no external wrenches) and `r` what it does not explain: contact wrenches
//! mapped to the joints (`Jᵀ f`), friction, unmodelled payload, the error of the q̈ estimate.
//!
//! [`Lagged`] is the live node's form: the central difference at sample `i` needs sample
//! `i + 1`, so the residual of a joint state comes out when the next one arrives. Replay has
//! every neighbour at hand and calls [`read_effort`] and [`effort_residual`] directly.

use super::differences::{joins, velocity_derivative};
use super::joint_map::{JointMap, Target};
use super::Rejection;
use spatial_dynamics_core::algorithms::rnea;
use spatial_dynamics_core::{Model, Workspace};

/// The measured effort of a message whose names `map` has just matched
/// ([`JointMap::match_names`]) into `out` (model order; coordinates without a name keep their
/// value). `Ok(false)`: the message carries no effort (an empty array), so no residual;
/// an array of the wrong length or with a non-finite value is refused, naming the joint.
pub fn read_effort(map: &JointMap, effort: &[f64], out: &mut [f64]) -> Result<bool, Rejection> {
    if effort.is_empty() {
        return Ok(false);
    }
    map.scatter("effort", effort, Target::Rate, false, out)
        .map_err(|e| ("bad effort", e))?;
    Ok(true)
}

/// `r = τ_measured − τ_model`, element by element, into `out` (all the same length); refused
/// when a difference overflows (finite inputs of opposite sign near `f64::MAX`).
pub fn effort_residual(
    measured: &[f64],
    explained: &[f64],
    out: &mut [f64],
) -> Result<(), Rejection> {
    let mut finite = true;
    for ((r, m), e) in out.iter_mut().zip(measured).zip(explained) {
        *r = m - e;
        finite &= r.is_finite();
    }
    match finite {
        true => Ok(()),
        false => {
            let k = out.iter().position(|r| !r.is_finite()).unwrap_or(0);
            Err((
                "residual not finite",
                format!(
                    "coordinate {k}: effort {} minus the model's {} overflows",
                    measured[k], explained[k]
                ),
            ))
        }
    }
}

/// One joint state kept for the finite differences.
#[derive(Clone, Debug)]
struct Sample<T> {
    /// Time base of the differences, ns.
    t: i64,
    has_velocity: bool,
    /// This sample and the one before it are one segment ([`joins`]).
    joins_prev: bool,
    has_effort: bool,
    q: Vec<f64>,
    v: Vec<f64>,
    effort: Vec<f64>,
    tag: T,
}

/// `(h, q̇)` of a neighbour of the joint state at `t` ns: its distance in seconds, its velocities.
fn neighbour<T>(s: &Sample<T>, t: i64) -> (f64, &[f64]) {
    (s.t.abs_diff(t) as f64 * 1e-9, &s.v)
}

/// The residual of the joint state before the newest, as [`Lagged::push`] gives it.
#[derive(Debug)]
pub struct Delayed<'a, T> {
    /// What the caller pushed with that joint state (its header, names, …).
    pub tag: &'a T,
    /// Its `q`, `q̇` (model order).
    pub q: &'a [f64],
    pub v: &'a [f64],
    /// `r` (model order), or why it could not be estimated.
    pub residual: Result<&'a [f64], Rejection>,
}

/// The live node's residual: the last three joint states (`i − 1`, `i`, `i + 1`), and the
/// residual of joint state `i` once `i + 1` has arrived (one sample late). Sized once for a
/// model: buffers are reused, a push allocates nothing (the caller's tag aside).
#[derive(Clone, Debug)]
pub struct Lagged<T> {
    max_gap_ns: i64,
    /// Joint states `i − 1`, `i`, `i + 1`, oldest first (`None` until pushed).
    window: [Option<Sample<T>>; 3],
    nq: usize,
    nv: usize,
    a: Vec<f64>,
    r: Vec<f64>,
}

impl<T> Lagged<T> {
    /// Nothing held yet; joint states further apart than `max_gap_ns` (or not later) are not
    /// differenced across.
    pub fn new(model: &Model, max_gap_ns: i64) -> Lagged<T> {
        Lagged {
            max_gap_ns,
            window: [None, None, None],
            nq: model.nq(),
            nv: model.nv(),
            a: vec![0.0; model.nv()],
            r: vec![0.0; model.nv()],
        }
    }

    /// What the newest joint state was pushed with, if it carried effort: its residual waits
    /// for the next joint state (and is lost if none comes).
    pub fn pending(&self) -> Option<&T> {
        self.window[2]
            .as_ref()
            .filter(|s| s.has_effort)
            .map(|s| &s.tag)
    }

    /// Takes joint state `i + 1` (time `t` in ns, `q` and `q̇` in model order, `has_velocity`:
    /// whether the message carried velocities, `effort`: its measured effort in model order,
    /// if any) and returns joint state `i`'s residual when joint state `i` carried effort:
    /// `q̈_i` by [`velocity_derivative`] from its neighbours in its segment, then
    /// `r_i = τ_i − RNEA(q_i, q̇_i, q̈_i)` ([`effort_residual`]).
    #[allow(clippy::too_many_arguments)]
    pub fn push(
        &mut self,
        model: &Model,
        ws: &mut Workspace,
        t: i64,
        q: &[f64],
        v: &[f64],
        has_velocity: bool,
        effort: Option<&[f64]>,
        tag: T,
    ) -> Option<Delayed<'_, T>> {
        let newest = self.window[2].as_ref().map(|s| (s.t, s.has_velocity));
        let joins_prev = joins(newest, t, has_velocity, self.max_gap_ns);
        // The oldest sample's buffers take the new one.
        let (nq, nv) = (self.nq, self.nv);
        let mut sample = match self.window[0].take() {
            Some(s) => Sample { tag, ..s },
            None => Sample {
                t,
                has_velocity,
                joins_prev,
                has_effort: false,
                q: vec![0.0; nq],
                v: vec![0.0; nv],
                effort: vec![0.0; nv],
                tag,
            },
        };
        sample.t = t;
        sample.has_velocity = has_velocity;
        sample.joins_prev = joins_prev;
        sample.q.copy_from_slice(q);
        sample.v.copy_from_slice(v);
        sample.has_effort = effort.is_some();
        if let Some(e) = effort {
            sample.effort.copy_from_slice(e);
        }
        self.window.rotate_left(1);
        self.window[2] = Some(sample);

        let [older, Some(current), Some(next)] = &self.window else {
            return None;
        };
        if !current.has_effort {
            return None;
        }
        let (a, r) = (&mut self.a, &mut self.r);
        let residual = if !current.has_velocity {
            Err(("no velocities in the message", "velocity[] is empty".into()))
        } else {
            let t = current.t;
            let before = older
                .as_ref()
                .filter(|_| current.joins_prev)
                .map(|s| neighbour(s, t));
            let after = next.joins_prev.then(|| neighbour(next, t));
            if velocity_derivative(before, &current.v, after, a) {
                rnea(model, ws, &current.q, &current.v, a)
                    .map_err(|e| ("inverse dynamics failed", e.to_string()))
                    .and_then(|tau| effort_residual(&current.effort, tau, r))
            } else {
                Err((
                    "no neighbour in its segment",
                    "an isolated joint state: no difference can be taken".into(),
                ))
            }
        };
        Some(Delayed {
            tag: &current.tag,
            q: &current.q,
            v: &current.v,
            residual: residual.map(|()| r.as_slice()),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use spatial_dynamics_core::model::examples::DEFAULT_ARM_URDF;
    use spatial_dynamics_core::{urdf, ModelOptions};

    /// Velocities quadratic in time (positions cubic): the three-point difference is exact, so
    /// an effort made of `RNEA(q, q̇, q̈_exact)` plus a known torque leaves exactly that torque
    /// at every joint state inside a segment; one sample late, with the caller's tag.
    #[test]
    fn lagged_residual_recovers_an_added_torque_one_sample_late() {
        let model = urdf::model_from_str(DEFAULT_ARM_URDF, &ModelOptions::default()).unwrap();
        assert_eq!(model.nq(), model.nv());
        let nv = model.nv();
        let mut ws = Workspace::new(&model);
        let c: Vec<[f64; 3]> = (0..nv)
            .map(|k| {
                [
                    0.3 - 0.1 * k as f64,
                    0.5 + 0.2 * k as f64,
                    -0.4 + 0.15 * k as f64,
                ]
            })
            .collect();
        let state = |t: f64| {
            let q: Vec<f64> = c
                .iter()
                .map(|c| 0.1 + c[0] * t + c[1] * t * t / 2.0 + c[2] * t * t * t / 3.0)
                .collect();
            let v: Vec<f64> = c.iter().map(|c| c[0] + c[1] * t + c[2] * t * t).collect();
            let a: Vec<f64> = c.iter().map(|c| c[1] + 2.0 * c[2] * t).collect();
            (q, v, a)
        };
        let external = |k: usize| if k >= 5 { 3.0 } else { 0.0 };
        let mut lagged = Lagged::new(&model, 100_000_000);
        // Uneven steps of about 2 ms; sample 3 has no effort.
        let times_ns: Vec<i64> = (0..12)
            .map(|i| i * 2_000_000 + (i * i) % 5 * 100_000)
            .collect();
        let mut got = Vec::new();
        for (i, &t_ns) in times_ns.iter().enumerate() {
            let (q, v, a) = state(t_ns as f64 * 1e-9);
            let mut effort = rnea(&model, &mut ws, &q, &v, &a).unwrap().to_vec();
            effort[2] += external(i);
            let effort = (i != 3).then_some(effort.as_slice());
            if let Some(d) = lagged.push(&model, &mut ws, t_ns, &q, &v, true, effort, i) {
                got.push((*d.tag, d.residual.map(|r| r.to_vec())));
                assert_eq!(d.q, state(times_ns[*d.tag] as f64 * 1e-9).0);
            }
        }
        // Joint state 0 (the first of its segment) is differenced one-sided: not exact, but
        // reported; 3 carries no effort; 11 waits for a twelfth.
        let tags: Vec<usize> = got.iter().map(|(i, _)| *i).collect();
        assert_eq!(tags, [0, 1, 2, 4, 5, 6, 7, 8, 9, 10]);
        for (i, r) in &got[1..] {
            let r = r.as_ref().unwrap();
            for (k, x) in r.iter().enumerate() {
                let want = if k == 2 { external(*i) } else { 0.0 };
                assert!(
                    (x - want).abs() < 1e-7,
                    "joint state {i}, joint {k}: {x} vs {want}"
                );
            }
        }
    }

    /// A gap starts a new segment; a joint state alone in its segment, or without velocities,
    /// gets no residual, and says why.
    #[test]
    fn isolated_or_velocityless_joint_states_say_why() {
        let model = urdf::model_from_str(DEFAULT_ARM_URDF, &ModelOptions::default()).unwrap();
        let mut ws = Workspace::new(&model);
        let (q, v, e) = (
            vec![0.1; model.nq()],
            vec![0.2; model.nv()],
            vec![1.0; model.nv()],
        );
        let mut lagged = Lagged::new(&model, 10);
        let mut push = |t: i64, has_v: bool| {
            lagged
                .push(&model, &mut ws, t, &q, &v, has_v, Some(&e), t)
                .map(|d| (*d.tag, d.residual.map(|_| ()).map_err(|(kind, _)| kind)))
        };
        assert_eq!(push(0, true), None);
        assert_eq!(
            push(100, true),
            Some((0, Err("no neighbour in its segment")))
        );
        assert_eq!(push(105, true), Some((100, Ok(())))); // forward: the first after the gap
        assert_eq!(push(110, false), Some((105, Ok(())))); // backward: 110 has no velocities
        assert_eq!(
            push(115, true),
            Some((110, Err("no velocities in the message")))
        );
        assert_eq!(push(120, true), Some((115, Ok(()))));
    }

    #[test]
    fn effort_is_optional_but_never_short_or_non_finite() {
        let model = urdf::model_from_str(DEFAULT_ARM_URDF, &ModelOptions::default()).unwrap();
        let mut map = JointMap::for_model(&model).unwrap();
        let names = map.names().to_vec();
        map.match_names(&names, "name").unwrap();
        let mut out = vec![0.0; model.nv()];
        assert_eq!(read_effort(&map, &[], &mut out), Ok(false));
        let mut r = [0.0; 2];
        assert!(effort_residual(&[1.0, 2.0], &[0.5, -1.0], &mut r).is_ok() && r == [0.5, 3.0]);
        let err = effort_residual(&[1.0, 1e308], &[0.5, -1e308], &mut r).unwrap_err();
        assert_eq!(err.0, "residual not finite");
        let mut effort: Vec<f64> = (0..names.len()).map(|k| k as f64).collect();
        assert_eq!(read_effort(&map, &effort, &mut out), Ok(true));
        assert_eq!(out, effort);
        assert_eq!(
            read_effort(&map, &effort[1..], &mut out).unwrap_err().0,
            "bad effort"
        );
        effort[4] = f64::INFINITY;
        let (kind, message) = read_effort(&map, &effort, &mut out).unwrap_err();
        assert_eq!(kind, "bad effort");
        assert!(
            message.contains("effort[4]") && message.contains(&names[4]),
            "{message}"
        );
    }
}

//! `q ⊕ v·dt` for the integrators, with the model's joints sorted once: the coordinates of
//! every joint but a floating one are Euclidean (`q + v·dt`, as [`JointKind::integrate`] does
//! for them), merged into contiguous runs of `(q, v)` indices and added without a call per
//! joint; each floating joint moves on SE(3) by [`JointKind::integrate`]. Same results, bit
//! for bit, as [`Model::integrate`].

use crate::error::{check_len, DynamicsError};
use crate::model::JointKind;
use crate::Model;

/// The model's coordinates, split as [`Model::integrate`] treats them.
#[derive(Clone, Debug)]
pub(crate) struct Configuration {
    nq: usize,
    nv: usize,
    /// `(q start, v start, length)` of each run of Euclidean coordinates.
    euclidean: Vec<(usize, usize, usize)>,
    /// `(q start, v start)` of each floating joint (7 position and 6 velocity coordinates).
    floating: Vec<(usize, usize)>,
}

impl Configuration {
    pub(crate) fn new(model: &Model) -> Configuration {
        let mut euclidean: Vec<(usize, usize, usize)> = Vec::new();
        let mut floating = Vec::new();
        for j in model.coordinate_joints() {
            if *j.kind == JointKind::Floating {
                floating.push((j.q_index, j.v_index));
                continue;
            }
            match euclidean.last_mut() {
                Some((q0, v0, len)) if *q0 + *len == j.q_index && *v0 + *len == j.v_index => {
                    *len += j.nq;
                }
                _ => euclidean.push((j.q_index, j.v_index, j.nq)),
            }
        }
        Configuration {
            nq: model.nq,
            nv: model.nv,
            euclidean,
            floating,
        }
    }

    /// `out = q ⊕ v·dt` ([`Model::integrate`], with its length errors).
    pub(crate) fn integrate(
        &self,
        q: &[f64],
        v: &[f64],
        dt: f64,
        out: &mut [f64],
    ) -> Result<(), DynamicsError> {
        self.check(q.len(), v.len())?;
        check_len("out", self.nq, out.len())?;
        for &(q0, v0, len) in &self.euclidean {
            let (o, q, v) = (&mut out[q0..q0 + len], &q[q0..q0 + len], &v[v0..v0 + len]);
            for ((o, x), r) in o.iter_mut().zip(q).zip(v) {
                *o = x + r * dt;
            }
        }
        for &(q0, v0) in &self.floating {
            JointKind::Floating.integrate(&q[q0..q0 + 7], &v[v0..v0 + 6], dt, &mut out[q0..q0 + 7]);
        }
        Ok(())
    }

    /// `q ← q ⊕ v·dt` in place.
    pub(crate) fn integrate_in_place(
        &self,
        q: &mut [f64],
        v: &[f64],
        dt: f64,
    ) -> Result<(), DynamicsError> {
        self.check(q.len(), v.len())?;
        for &(q0, v0, len) in &self.euclidean {
            for (x, r) in q[q0..q0 + len].iter_mut().zip(&v[v0..v0 + len]) {
                *x += r * dt;
            }
        }
        for &(q0, v0) in &self.floating {
            let mut moved = [0.0; 7];
            JointKind::Floating.integrate(&q[q0..q0 + 7], &v[v0..v0 + 6], dt, &mut moved);
            q[q0..q0 + 7].copy_from_slice(&moved);
        }
        Ok(())
    }

    /// The first velocity coordinate of each floating joint.
    pub(crate) fn floating_velocities(&self) -> impl Iterator<Item = usize> + '_ {
        self.floating.iter().map(|&(_, v0)| v0)
    }

    fn check(&self, nq: usize, nv: usize) -> Result<(), DynamicsError> {
        check_len("q", self.nq, nq)?;
        check_len("v", self.nv, nv)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::{random_q, Rng};
    use crate::urdf::model_from_str;
    use crate::ModelOptions;

    /// A floating base, then revolute, prismatic, continuous and planar joints and a mimic
    /// follower (no coordinates of its own): the runs and the floating joint reproduce
    /// `Model::integrate` exactly, out of place and in place, and refuse the same lengths.
    #[test]
    fn matches_model_integrate_bit_for_bit() {
        let link = |n: &str| {
            format!(
                r#"<link name="{n}"><inertial><mass value="1"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial></link>"#
            )
        };
        let joint = |n: &str, kind: &str, parent: &str, child: &str, extra: &str| {
            format!(
                r#"<joint name="{n}" type="{kind}"><parent link="{parent}"/><child link="{child}"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/>{extra}</joint>"#
            )
        };
        let urdf = format!(
            r#"<robot name="mix">{}{}{}{}{}{}</robot>"#,
            link("base") + &link("a") + &link("b") + &link("c") + &link("d") + &link("e"),
            joint("rev", "revolute", "base", "a", ""),
            joint("pri", "prismatic", "a", "b", ""),
            joint("cont", "continuous", "b", "c", ""),
            joint("plan", "planar", "c", "d", ""),
            joint(
                "mim",
                "revolute",
                "d",
                "e",
                r#"<mimic joint="rev" multiplier="2"/>"#
            ),
        );
        let model = model_from_str(
            &urdf,
            &ModelOptions {
                floating_base: true,
                ..Default::default()
            },
        )
        .unwrap();
        let config = Configuration::new(&model);
        assert_eq!(config.floating.len(), 1);
        let mut rng = Rng::new(7);
        for _ in 0..20 {
            let q = random_q(&model, &mut rng);
            let v = rng.vector(model.nv, 2.0);
            let (mut expected, mut got) = (vec![0.0; model.nq], vec![0.0; model.nq]);
            model.integrate(&q, &v, 0.013, &mut expected).unwrap();
            config.integrate(&q, &v, 0.013, &mut got).unwrap();
            assert_eq!(got, expected);
            let mut in_place = q.clone();
            config.integrate_in_place(&mut in_place, &v, 0.013).unwrap();
            assert_eq!(in_place, expected);
        }
        let (q, v) = (model.neutral(), vec![0.0; model.nv]);
        let mut out = vec![0.0; model.nq];
        assert_eq!(
            config.integrate(&q[1..], &v, 0.1, &mut out),
            model.integrate(&q[1..], &v, 0.1, &mut out)
        );
        assert_eq!(
            config.integrate(&q, &v[1..], 0.1, &mut out),
            model.integrate(&q, &v[1..], 0.1, &mut out)
        );
        assert_eq!(
            config.integrate(&q, &v, 0.1, &mut out[1..]),
            model.integrate(&q, &v, 0.1, &mut out[1..])
        );
    }
}

//! Joint names ↔ the model's coordinate vectors. Messages name their joints in any order
//! (`/joint_states` is often alphabetical); every coordinate joint must be named exactly once.
//!
//! Rules (services and topics alike):
//! - a name that is not a joint of the model is refused; names of joints without a coordinate
//!   (mimic followers, fixed and locked joints) are accepted and ignored;
//! - a duplicate name, a missing coordinate joint, an array whose length is neither the number
//!   of names nor zero (zero means "all zero" where a field is optional), or a non-finite value
//!   is refused; every message names the joint, the field and the value.
//! - an empty list of names means every coordinate joint, in model order;
//! - answers list their joints in the request's order (model order for an empty list);
//! - a planar joint `J` is named by its components `J/x`, `J/y`, `J/theta`; a floating base is not
//!   named here (it has fields of its own).

use spatial_dynamics_core::error::{name_list, quoted};
use spatial_dynamics_core::model::JointKind;
use spatial_dynamics_core::Model;
use std::collections::HashMap;

/// Which vector a field fills.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Target {
    /// Position coordinates (`q`).
    Position,
    /// Velocity-like coordinates (`v`, `a`, `τ`).
    Rate,
}

/// The index of the model's named coordinates.
#[derive(Clone, Debug)]
pub struct JointMap {
    /// Coordinate names in model order (what answers list in `name[]`).
    names: Vec<String>,
    /// `(q index, v index)` of each named coordinate, same order.
    slots: Vec<(usize, usize)>,
    lookup: HashMap<String, usize>,
    /// Joints without a coordinate: accepted and ignored.
    passive: HashMap<String, ()>,
    /// `(q index, v index)` of the floating base, if the model has one at its root.
    base: Option<(usize, usize)>,
    /// For the message being read: the slot of each name (`None` for passive names).
    order: Vec<Option<usize>>,
    seen: Vec<bool>,
}

impl JointMap {
    /// The map of `model` accepting (and ignoring) the names of its locked and fixed joints,
    /// as the node's topics and services do.
    pub fn for_model(model: &Model) -> Result<JointMap, String> {
        let passive: Vec<String> = model
            .locked_joints()
            .iter()
            .map(|(n, _)| n.clone())
            .chain(model.fixed_joints().iter().cloned())
            .chain(model.reduction().frozen_joint_names())
            .chain(model.reduction().pruned_joints.iter().cloned())
            .collect();
        JointMap::new(model, &passive)
    }

    /// The map of `model`; refuses floating joints anywhere but at the root.
    pub fn new(model: &Model, passive: &[String]) -> Result<JointMap, String> {
        let mut map = JointMap {
            names: Vec::new(),
            slots: Vec::new(),
            lookup: HashMap::new(),
            passive: passive.iter().map(|n| (n.clone(), ())).collect(),
            base: None,
            order: Vec::new(),
            seen: Vec::new(),
        };
        for body in model.bodies().iter() {
            let joint = &body.joint;
            if joint.is_mimic() {
                map.passive.insert(joint.name.clone(), ());
                continue;
            }
            let c = joint.coords;
            match joint.kind {
                JointKind::Floating if body.parent.is_none() && map.base.is_none() => {
                    map.base = Some((c.q_index, c.v_index))
                }
                JointKind::Floating => {
                    return Err(format!(
                        "joint '{}': a floating joint is only supported as the base of the tree",
                        joint.name
                    ))
                }
                JointKind::Planar { .. } => {
                    for (k, part) in ["x", "y", "theta"].iter().enumerate() {
                        map.push(
                            format!("{}/{part}", joint.name),
                            c.q_index + k,
                            c.v_index + k,
                        );
                    }
                }
                _ => map.push(joint.name.clone(), c.q_index, c.v_index),
            }
        }
        map.seen = vec![false; map.names.len()];
        Ok(map)
    }

    fn push(&mut self, name: String, q: usize, v: usize) {
        self.lookup.insert(name.clone(), self.names.len());
        self.names.push(name);
        self.slots.push((q, v));
    }

    /// Coordinate names in model order.
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// `(q index, v index)` of the floating base.
    pub fn base(&self) -> Option<(usize, usize)> {
        self.base
    }

    /// Index of a named coordinate in [`names`](Self::names).
    pub fn index(&self, name: &str) -> Option<usize> {
        self.lookup.get(name).copied()
    }

    /// `(q index, v index)` of the named coordinate at `index` in [`names`](Self::names).
    pub fn slot(&self, index: usize) -> (usize, usize) {
        self.slots[index]
    }

    /// Matches `names` (from a message's `field` array of names) against the model: every
    /// coordinate joint once, nothing unknown. Must precede [`scatter`](Self::scatter).
    pub fn match_names(&mut self, names: &[String], field: &str) -> Result<(), String> {
        self.order.clear();
        if names.is_empty() {
            self.order.extend((0..self.names.len()).map(Some));
            return Ok(());
        }
        self.seen.iter_mut().for_each(|s| *s = false);
        for name in names {
            match self.lookup.get(name.as_str()) {
                Some(&slot) if self.seen[slot] => {
                    return Err(format!("joint {} appears twice in {field}", quoted(name)))
                }
                Some(&slot) => {
                    self.seen[slot] = true;
                    self.order.push(Some(slot));
                }
                None if self.passive.contains_key(name.as_str()) => self.order.push(None),
                None => {
                    return Err(format!(
                        "unknown joint {} in {field} (the model's joints: {})",
                        quoted(name),
                        name_list(&self.names, self.names.len())
                    ))
                }
            }
        }
        if self.seen.iter().any(|s| !s) {
            let missing: Vec<&str> = self
                .names
                .iter()
                .zip(&self.seen)
                .filter(|(_, s)| !**s)
                .map(|(n, _)| n.as_str())
                .collect();
            return Err(format!(
                "{field} lacks joints ({})",
                name_list(&missing, missing.len())
            ));
        }
        Ok(())
    }

    /// Writes `values` (one per name of the last [`match_names`](Self::match_names)) into `out`
    /// at each joint's position or velocity index. An empty array writes zeros when `optional`.
    pub fn scatter(
        &self,
        field: &str,
        values: &[f64],
        target: Target,
        optional: bool,
        out: &mut [f64],
    ) -> Result<(), String> {
        if values.is_empty() && optional {
            for &(q, v) in &self.slots {
                out[if target == Target::Position { q } else { v }] = 0.0;
            }
            return Ok(());
        }
        if values.len() != self.order.len() {
            return Err(format!(
                "{field} has {} values for {} names",
                values.len(),
                self.order.len()
            ));
        }
        for (i, (value, slot)) in values.iter().zip(&self.order).enumerate() {
            let Some(slot) = slot else { continue };
            if !value.is_finite() {
                return Err(format!(
                    "{field}[{i}] (joint '{}') is {value}",
                    self.names[*slot]
                ));
            }
            let (q, v) = self.slots[*slot];
            out[if target == Target::Position { q } else { v }] = *value;
        }
        Ok(())
    }

    /// Positions and velocities of a message matched by [`match_names`](Self::match_names)
    /// into `q` and `v` (model order); `velocity` may be empty (zero velocities). Returns
    /// whether the message carried velocities.
    pub fn scatter_state(
        &self,
        position: &[f64],
        velocity: &[f64],
        q: &mut [f64],
        v: &mut [f64],
    ) -> Result<bool, super::Rejection> {
        self.scatter("position", position, Target::Position, false, q)
            .map_err(|e| ("bad position", e))?;
        self.scatter("velocity", velocity, Target::Rate, true, v)
            .map_err(|e| ("bad velocity", e))?;
        Ok(!velocity.is_empty())
    }

    /// The coordinates named by the last [`match_names`](Self::match_names), in its order
    /// (indices into [`names`](Self::names)); joints without a coordinate are left out.
    pub fn answer_order(&self) -> impl Iterator<Item = usize> + '_ {
        self.order.iter().flatten().copied()
    }

    /// The names of [`answer_order`](Self::answer_order).
    pub fn answer_names(&self) -> Vec<String> {
        self.answer_order().map(|s| self.names[s].clone()).collect()
    }

    /// The values of `from` (a `q`- or `v`-sized vector) at every named coordinate, in model order.
    pub fn gather_all(&self, from: &[f64], target: Target, out: &mut Vec<f64>) {
        out.clear();
        out.extend(
            self.slots
                .iter()
                .map(|&(q, v)| from[if target == Target::Position { q } else { v }]),
        );
    }

    /// The values of `from` (a `q`- or `v`-sized vector) in [`answer_order`](Self::answer_order).
    pub fn gather(&self, from: &[f64], target: Target, out: &mut Vec<f64>) {
        self.gather_in(self.answer_order(), from, target, out);
    }

    /// The values of `from` (a `q`- or `v`-sized vector) at the named coordinates `order`
    /// (indices into [`names`](Self::names)), in that order.
    pub fn gather_in(
        &self,
        order: impl Iterator<Item = usize>,
        from: &[f64],
        target: Target,
        out: &mut Vec<f64>,
    ) {
        out.clear();
        out.extend(order.map(|s| {
            let (q, v) = self.slots[s];
            from[if target == Target::Position { q } else { v }]
        }));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use spatial_dynamics_core::{urdf, ModelOptions};

    fn strings(a: &[&str]) -> Vec<String> {
        a.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn matches_by_name_in_any_order_and_names_every_problem() {
        let model = urdf::model_from_str(
            spatial_dynamics_core::model::examples::MIMIC_GRIPPER_URDF,
            &ModelOptions::default(),
        )
        .unwrap();
        let mut map = JointMap::new(&model, &[]).unwrap();
        assert_eq!(map.names(), ["wrist", "finger_left"]);
        let mut q = vec![9.0; 2];
        map.match_names(&strings(&["thumb", "finger_left", "wrist"]), "name")
            .unwrap();
        map.scatter(
            "position",
            &[123.0, 0.02, 0.5],
            Target::Position,
            false,
            &mut q,
        )
        .unwrap();
        assert_eq!(q, [0.5, 0.02]);
        assert_eq!(map.answer_names(), ["finger_left", "wrist"]);
        let mut out = Vec::new();
        map.gather(&q, Target::Position, &mut out);
        assert_eq!(out, [0.02, 0.5]);
        map.match_names(&[], "name").unwrap();
        assert_eq!(map.answer_names(), ["wrist", "finger_left"]);
        map.scatter("velocity", &[], Target::Rate, true, &mut q)
            .unwrap();
        assert_eq!(q, [0.0, 0.0]);
        assert_eq!(
            map.scatter("velocity", &[], Target::Rate, false, &mut q)
                .unwrap_err(),
            "velocity has 0 values for 2 names"
        );
        assert_eq!(
            map.scatter(
                "position",
                &[0.0, f64::NAN],
                Target::Position,
                false,
                &mut q
            )
            .unwrap_err(),
            "position[1] (joint 'finger_left') is NaN"
        );
        assert!(map
            .match_names(&strings(&["wrist", "wrist", "finger_left"]), "name")
            .unwrap_err()
            .contains("'wrist' appears twice"));
        assert!(map
            .match_names(&strings(&["wrist"]), "name")
            .unwrap_err()
            .contains("lacks joints (finger_left)"));
        assert!(map
            .match_names(&strings(&["wrist", "finger_left", "elbow"]), "name")
            .unwrap_err()
            .contains("unknown joint 'elbow'"));
    }
}

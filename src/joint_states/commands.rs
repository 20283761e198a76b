//! The commanded effort `τ_cmd` (`nv` values, model order) under which forward dynamics runs:
//! zero until a command arrives, then the latest one, from either input the node reads:
//!
//! - `~/effort_command` (sensor_msgs/JointState): every coordinate joint named, `effort[]` one
//!   value per name;
//! - `~/commands` (std_msgs/Float64MultiArray): one value per `command_joints` entry, in that
//!   order; coordinates not listed get zero.
//!
//! A floating base is never commanded (its six entries stay zero).

use super::joint_map::{JointMap, Target};
use super::Rejection;
use spatial_dynamics_core::error::{name_list, quoted};

/// The latest command, and the joint order of `~/commands`.
#[derive(Clone, Debug)]
pub struct Commands {
    map: JointMap,
    /// For each `command_joints` entry, its index in the map's names.
    slots: Vec<usize>,
    effort: Vec<f64>,
    scratch: Vec<f64>,
}

impl Commands {
    /// Commands for the coordinates of `map` (`nv` values); `command_joints` orders
    /// `~/commands` (empty: every coordinate joint, in model order).
    pub fn new(map: &JointMap, nv: usize, command_joints: &[String]) -> Result<Commands, String> {
        let slots = if command_joints.is_empty() {
            (0..map.names().len()).collect()
        } else {
            command_joints
                .iter()
                .map(|n| {
                    map.index(n).ok_or_else(|| {
                        format!(
                            "command_joints: unknown joint {} (the model's joints: {})",
                            quoted(n),
                            name_list(map.names(), map.names().len())
                        )
                    })
                })
                .collect::<Result<Vec<_>, _>>()?
        };
        let mut entry_of = vec![None; map.names().len()];
        for (k, &slot) in slots.iter().enumerate() {
            if let Some(first) = entry_of[slot].replace(k) {
                return Err(format!(
                    "command_joints: joint '{}' is named twice (entries {first} and {k})",
                    command_joints[k]
                ));
            }
        }
        Ok(Commands {
            map: map.clone(),
            slots,
            effort: vec![0.0; nv],
            scratch: vec![0.0; nv],
        })
    }

    /// `τ_cmd`, model order.
    pub fn effort(&self) -> &[f64] {
        &self.effort
    }

    /// Back to zero effort.
    pub fn clear(&mut self) {
        self.effort.fill(0.0);
    }

    /// The efforts of `old` (commands for another model) on the coordinates of the same name;
    /// coordinates `old` does not know get zero. Returns the names of the coordinates whose
    /// non-zero effort this model has no place for.
    pub fn carry_from(&mut self, old: &Commands) -> Vec<String> {
        self.effort.fill(0.0);
        let mut lost = Vec::new();
        for (index, name) in old.map.names().iter().enumerate() {
            let value = old.effort[old.map.slot(index).1];
            match self.map.index(name) {
                Some(here) => self.effort[self.map.slot(here).1] = value,
                None if value != 0.0 => lost.push(name.clone()),
                None => {}
            }
        }
        lost
    }

    /// Names of `command_joints`, in command order.
    pub fn names(&self) -> Vec<String> {
        self.slots
            .iter()
            .map(|&i| self.map.names()[i].clone())
            .collect()
    }

    /// The values of `x` (an `nv`-sized vector) in `command_joints` order.
    pub fn gather(&self, x: &[f64]) -> Vec<f64> {
        self.slots.iter().map(|&s| x[self.map.slot(s).1]).collect()
    }

    /// `~/effort_command`: `effort[k]` for joint `names[k]`. A refused message changes nothing.
    pub fn set_effort_command(
        &mut self,
        names: &[String],
        effort: &[f64],
    ) -> Result<(), Rejection> {
        self.map
            .match_names(names, "name")
            .map_err(|e| ("bad joint names", e))?;
        self.scratch.fill(0.0);
        self.map
            .scatter("effort", effort, Target::Rate, false, &mut self.scratch)
            .map_err(|e| ("bad effort", e))?;
        self.effort.copy_from_slice(&self.scratch);
        Ok(())
    }

    /// `~/commands`: `data[k]` for `command_joints[k]`. A refused message changes nothing.
    pub fn set_commands(&mut self, data: &[f64]) -> Result<(), Rejection> {
        if data.len() != self.slots.len() {
            return Err((
                "wrong length",
                format!(
                    "commands has {} values, command_joints has {} joints ({})",
                    data.len(),
                    self.slots.len(),
                    name_list(&self.names(), self.slots.len())
                ),
            ));
        }
        if let Some(i) = data.iter().position(|x| !x.is_finite()) {
            return Err((
                "bad value",
                format!(
                    "commands[{i}] (joint '{}') is {}",
                    self.map.names()[self.slots[i]],
                    data[i]
                ),
            ));
        }
        self.effort.fill(0.0);
        for (&slot, value) in self.slots.iter().zip(data) {
            self.effort[self.map.slot(slot).1] = *value;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use spatial_dynamics_core::{urdf, ModelOptions};

    #[test]
    fn a_command_joint_named_twice_is_refused() {
        let model = urdf::model_from_str(
            spatial_dynamics_core::model::examples::MIMIC_GRIPPER_URDF,
            &ModelOptions::default(),
        )
        .unwrap();
        let map = JointMap::new(&model, &[]).unwrap();
        let names = |a: &[&str]| a.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        assert!(Commands::new(&map, model.nv(), &names(&["finger_left", "wrist"])).is_ok());
        let e = Commands::new(&map, model.nv(), &names(&["wrist", "finger_left", "wrist"]))
            .unwrap_err();
        assert_eq!(
            e,
            "command_joints: joint 'wrist' is named twice (entries 0 and 2)"
        );
    }
}

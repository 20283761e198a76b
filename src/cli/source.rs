//! Where the model comes from: a URDF file or a built-in example, and the model options.

use clap::Args;
use spatial_dynamics_core::model::{examples, joint_position};
use spatial_dynamics_core::spatial::Vector3;
use spatial_dynamics_core::{urdf, Model, ModelOptions};
use std::path::PathBuf;

/// Model selection and options shared by every subcommand.
#[derive(Args, Debug, Clone)]
pub struct ModelArgs {
    /// URDF file of the robot.
    #[arg(long, value_name = "FILE", conflicts_with = "builtin")]
    pub urdf: Option<PathBuf>,
    /// A built-in model (or scene): default_arm (the default), particle, lamp, mimic_gripper, pendulum:N.
    #[arg(long, value_name = "NAME", alias = "scene")]
    pub builtin: Option<String>,
    /// Add a floating joint between the world and the root link.
    #[arg(long)]
    pub floating_base: bool,
    /// Treat <mimic> joints as independent joints.
    #[arg(long)]
    pub ignore_mimic: bool,
    /// Lock a joint at a position, NAME=VALUE (repeatable): it becomes fixed and its child fuses
    /// into the parent body.
    #[arg(long = "lock", value_name = "NAME=VALUE")]
    pub locks: Vec<String>,
    /// Keep only this link's subtree; it becomes the fixed base (joints above and beside it
    /// freeze at their --lock value or zero).
    #[arg(long, value_name = "LINK")]
    pub root: Option<String>,
    /// Keep only the joints from the root to this link (repeatable); the bodies past it become
    /// a payload lumped onto it, side branches freeze.
    #[arg(long = "tip", value_name = "LINK")]
    pub tips: Vec<String>,
    /// Remove moving joints whose whole subtree is massless (and their coordinates).
    #[arg(long)]
    pub prune_massless: bool,
    /// Gravity in the world frame, m/s² (default 0,0,-9.81).
    #[arg(long, value_name = "X,Y,Z", allow_hyphen_values = true)]
    pub gravity: Option<String>,
}

impl ModelArgs {
    /// True when any reduction (locks, root, tips, pruning) is asked for.
    pub fn reduces(&self) -> bool {
        !self.locks.is_empty()
            || self.root.is_some()
            || !self.tips.is_empty()
            || self.prune_massless
    }

    /// The same model source and options without the reductions.
    pub fn without_reductions(&self) -> ModelArgs {
        ModelArgs {
            locks: Vec::new(),
            root: None,
            tips: Vec::new(),
            prune_massless: false,
            ..self.clone()
        }
    }

    /// Loads the model; the error names the problem.
    pub fn load(&self) -> Result<Model, String> {
        let options = self.options()?;
        let result = match (&self.urdf, &self.builtin) {
            (Some(path), _) => urdf::model_from_file(path, &options),
            (None, Some(name)) => urdf::model_from_str(&builtin_urdf(name)?, &options),
            (None, None) => urdf::model_from_str(examples::DEFAULT_ARM_URDF, &options),
        };
        let model = result.map_err(|e| e.to_string())?;
        for warning in model.warnings() {
            eprintln!("spatial_dynamics: warning: {warning}");
        }
        Ok(model)
    }

    /// The model options these arguments ask for.
    pub fn options(&self) -> Result<ModelOptions, String> {
        let mut options = ModelOptions {
            floating_base: self.floating_base,
            ignore_mimic: self.ignore_mimic,
            root: self.root.clone(),
            tips: self.tips.clone(),
            prune_massless: self.prune_massless,
            ..ModelOptions::default()
        };
        if let Some(g) = &self.gravity {
            options.gravity = parse_gravity(g)?;
        }
        for lock in &self.locks {
            options
                .locked
                .push(joint_position(lock).map_err(|e| format!("--lock {e}"))?);
        }
        Ok(options)
    }
}

fn builtin_urdf(name: &str) -> Result<String, String> {
    if let Some(n) = name.strip_prefix("pendulum:") {
        let n: usize = n.parse().map_err(|_| {
            format!("--builtin {name}: the number of links must be a positive integer")
        })?;
        // N rods and the world link: within the URDF's limit, checked before the text is made.
        if n == 0 || n >= urdf::MAX_LINKS {
            return Err(format!(
                "--builtin {name}: the number of links must be 1 to {}",
                urdf::MAX_LINKS - 1
            ));
        }
        return Ok(examples::pendulum_urdf(n, 1.0, 1.0));
    }
    Ok(match name {
        "default_arm" => examples::DEFAULT_ARM_URDF,
        "particle" => examples::PARTICLE_URDF,
        "lamp" => examples::LAMP_URDF,
        "mimic_gripper" => examples::MIMIC_GRIPPER_URDF,
        _ => return Err(format!("unknown built-in model '{name}' (default_arm, particle, lamp, mimic_gripper, pendulum:N)")),
    }
    .to_string())
}

fn parse_gravity(text: &str) -> Result<Vector3, String> {
    let parts: Result<Vec<f64>, _> = text.split(',').map(|s| s.trim().parse::<f64>()).collect();
    match parts {
        Ok(p) if p.len() == 3 && p.iter().all(|x| x.is_finite()) => {
            Ok(Vector3::new(p[0], p[1], p[2]))
        }
        _ => Err(format!(
            "--gravity '{text}': expected three finite numbers X,Y,Z"
        )),
    }
}

//! Joint servos: how a command becomes the effort the simulator integrates.
//!
//! A command reaches a joint through one of three interfaces (ros2_control's names):
//!
//! - effort: the command is the joint effort `τ` itself (N·m or N);
//! - position: a PD servo, `τ = kp (q_cmd − q) + kd (q̇_cmd − q̇)`;
//! - velocity: a damping servo, `τ = kd (q̇_cmd − q̇)`.
//!
//! The servo is evaluated at each integration step from the state of that step (not once per
//! command), so the loop it closes is the one a real joint controller closes. Gains are per
//! axis (one coordinate of a one-degree-of-freedom joint); `q` and `q̇` are the joint's own
//! coordinate and rate. The effort goes through the simulator's passive forces afterwards, so
//! with `effort_limits` on it is clamped to the URDF limit like any other command.

use std::fmt;
use std::str::FromStr;

/// What a command sets on a joint.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum CommandInterface {
    #[default]
    Effort,
    Position,
    Velocity,
}

impl CommandInterface {
    /// The name as ros2_control spells it (`effort`, `position`, `velocity`).
    pub fn name(self) -> &'static str {
        match self {
            CommandInterface::Effort => "effort",
            CommandInterface::Position => "position",
            CommandInterface::Velocity => "velocity",
        }
    }
}

impl fmt::Display for CommandInterface {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for CommandInterface {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "effort" => Ok(CommandInterface::Effort),
            "position" => Ok(CommandInterface::Position),
            "velocity" => Ok(CommandInterface::Velocity),
            _ => Err(format!(
                "unknown command interface '{s}' (known: effort, position, velocity)"
            )),
        }
    }
}

/// One servoed coordinate: where it sits in `q` and `v`, and its gains.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ServoAxis {
    pub q_index: usize,
    pub v_index: usize,
    /// Position gain (N·m/rad or N/m); unused by a velocity servo.
    pub kp: f64,
    /// Rate gain (N·m·s/rad or N·s/m).
    pub kd: f64,
}

/// PD (position) or damping (velocity) servos on a set of coordinates, with their targets.
#[derive(Clone, Debug, PartialEq)]
pub struct Servo {
    interface: CommandInterface,
    axes: Vec<ServoAxis>,
    /// `q_cmd` per axis (position servos).
    position: Vec<f64>,
    /// `q̇_cmd` per axis.
    velocity: Vec<f64>,
}

impl Servo {
    /// Servos of `interface` (position or velocity) on `axes`, targets zero. Gains must be
    /// finite and ≥ 0; the error names the axis (its index in `axes`).
    pub fn new(interface: CommandInterface, axes: Vec<ServoAxis>) -> Result<Servo, String> {
        if interface == CommandInterface::Effort {
            return Err("an effort command needs no servo".into());
        }
        for (k, a) in axes.iter().enumerate() {
            for (name, gain) in [("kp", a.kp), ("kd", a.kd)] {
                if !(gain.is_finite() && gain >= 0.0) {
                    return Err(format!(
                        "servo axis {k}: {name} = {gain} (must be finite and ≥ 0)"
                    ));
                }
            }
        }
        let n = axes.len();
        Ok(Servo {
            interface,
            axes,
            position: vec![0.0; n],
            velocity: vec![0.0; n],
        })
    }

    pub fn interface(&self) -> CommandInterface {
        self.interface
    }

    pub fn axes(&self) -> &[ServoAxis] {
        &self.axes
    }

    /// Every target back to zero, as [`new`](Self::new) makes them.
    pub fn clear_targets(&mut self) {
        self.position.fill(0.0);
        self.velocity.fill(0.0);
    }

    /// Sets the target of axis `k`: `q_cmd` (ignored by a velocity servo) and `q̇_cmd`.
    pub fn set_target(&mut self, k: usize, position: f64, velocity: f64) {
        self.position[k] = position;
        self.velocity[k] = velocity;
    }

    /// Adds the servo efforts at `(q, v)` to `tau` (`nv` values): each axis gets
    /// `kp (q_cmd − q) + kd (q̇_cmd − q̇)` (position) or `kd (q̇_cmd − q̇)` (velocity).
    /// Allocation-free.
    pub fn add_effort(&self, q: &[f64], v: &[f64], tau: &mut [f64]) {
        let position = self.interface == CommandInterface::Position;
        for (k, a) in self.axes.iter().enumerate() {
            let mut t = a.kd * (self.velocity[k] - v[a.v_index]);
            if position {
                t += a.kp * (self.position[k] - q[a.q_index]);
            }
            tau[a.v_index] += t;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::examples::PARTICLE_URDF;
    use crate::sim::{Passive, SimConfig, Simulator, State};
    use crate::{urdf, Model, ModelOptions};

    const G: f64 = 9.81;

    fn particle() -> Model {
        urdf::model_from_str(PARTICLE_URDF, &ModelOptions::default()).unwrap()
    }

    /// Steps the particle (1 kg, joints x then z) `n` times under `servo` plus `feedforward`.
    fn run(servo: &Servo, passive: Passive, n: usize) -> State {
        let model = particle();
        let config = SimConfig {
            passive,
            ..SimConfig::default()
        };
        let mut sim = Simulator::new(&model, config).unwrap();
        let mut state = State::at_rest(&model, vec![0.0, 0.0]);
        let mut tau = vec![0.0; 2];
        for _ in 0..n {
            tau.fill(0.0);
            servo.add_effort(&state.q, &state.v, &mut tau);
            sim.step(&model, &mut state, &tau).unwrap();
        }
        state
    }

    fn axis(v_index: usize, kp: f64, kd: f64) -> ServoAxis {
        ServoAxis {
            q_index: v_index,
            v_index,
            kp,
            kd,
        }
    }

    #[test]
    fn a_pd_holds_the_particle_against_gravity_short_by_m_g_over_kp() {
        // At rest the PD balances the weight: kp (z_cmd − z) = m g, so z = z_cmd − m g / kp.
        let (kp, kd, target) = (400.0, 40.0, 0.5);
        let mut servo = Servo::new(CommandInterface::Position, vec![axis(1, kp, kd)]).unwrap();
        servo.set_target(0, target, 0.0);
        let state = run(&servo, Passive::default(), 3000);
        let steady = target - 1.0 * G / kp;
        assert!(
            (state.q[1] - steady).abs() < 1e-9,
            "{} vs {steady}",
            state.q[1]
        );
        assert!(state.v[1].abs() < 1e-9);
        assert_eq!(state.q[0], 0.0, "the x joint has no servo");
    }

    #[test]
    fn a_velocity_servo_approaches_its_target_as_the_discrete_exponential() {
        // Semi-implicit Euler on m v̇ = kd (v_cmd − v) from rest: v_n = v_cmd (1 − (1 − h kd/m)^n).
        let (kd, target, h) = (5.0, 0.8, 1e-3);
        let mut servo = Servo::new(CommandInterface::Velocity, vec![axis(0, 1e6, kd)]).unwrap();
        servo.set_target(0, 123.0, target);
        for n in [1, 10, 200, 1000] {
            let state = run(&servo, Passive::default(), n);
            let expected = target * (1.0 - (1.0 - h * kd).powi(n as i32));
            assert!(
                (state.v[0] - expected).abs() < 1e-12,
                "n = {n}: {} vs {expected}",
                state.v[0]
            );
        }
    }

    #[test]
    fn with_effort_limits_the_servo_effort_is_clamped_to_the_urdf_limit() {
        // kp · 10 m = 1e4 N asked; the URDF limit is 100 N, so the particle accelerates at
        // (100 − m g) m/s² over the first step.
        let mut servo = Servo::new(CommandInterface::Position, vec![axis(1, 1e3, 0.0)]).unwrap();
        servo.set_target(0, 10.0, 0.0);
        let passive = Passive {
            effort_limits: true,
            ..Passive::default()
        };
        let state = run(&servo, passive, 1);
        assert!(
            (state.v[1] - (100.0 - G) * 1e-3).abs() < 1e-12,
            "{}",
            state.v[1]
        );
    }

    #[test]
    fn bad_gains_and_an_effort_servo_are_refused() {
        let nan = Servo::new(CommandInterface::Position, vec![axis(0, f64::NAN, 1.0)]);
        assert_eq!(
            nan.unwrap_err(),
            "servo axis 0: kp = NaN (must be finite and ≥ 0)"
        );
        assert!(Servo::new(CommandInterface::Velocity, vec![axis(0, 1.0, -1.0)]).is_err());
        assert!(Servo::new(CommandInterface::Effort, vec![]).is_err());
        assert_eq!("velocity".parse(), Ok(CommandInterface::Velocity));
        assert!("torque".parse::<CommandInterface>().is_err());
    }
}

//! The node's request → answer path, without DDS: the engine behind its services and topics
//! (`src/node/engine/`, compiled here from the node's own source files) driven by a sequence of
//! structured messages built from the fuzz input: joint names from the model's vocabulary and
//! outside it, arrays of right and wrong lengths, numbers from ordinary to NaN, ±inf and 1e300.
//!
//! Checked after each message: a service answers `success = true` with finite numbers, or
//! `success = false` with a reason and empty result arrays; a topic handler gives finite outputs
//! or a reason. Never a panic.
#![no_main]

use arbitrary::{Result, Unstructured};
use libfuzzer_sys::fuzz_target;
use spatial_dynamics_core::model::examples::{
    DEFAULT_ARM_URDF, LAMP_URDF, MIMIC_GRIPPER_URDF, PARTICLE_URDF,
};
use std::time::Instant;

// The node's engine and the modules it uses, from the node's sources (the DDS serving loop in
// `src/node/mod.rs` is left out): the engine, the joint-state code it shares with offline
// replay (`src/joint_states/`), the plain message types (`src/ros/msgs.rs`) and the parameters
// (`params` names ros2-client's `ParameterValue`; nothing else of ROS is compiled). The
// sources refer to `crate::node::…`, `crate::joint_states::…` and `crate::ros::…`.
#[allow(dead_code, unused_imports)]
#[path = "../../../src/node/engine/mod.rs"]
mod engine;
#[allow(dead_code)]
#[path = "../../../src/joint_states/mod.rs"]
mod joint_states;
#[allow(dead_code)]
#[path = "../../../src/node/params.rs"]
mod params;
#[allow(dead_code)]
#[path = "../../../src/ros/msgs.rs"]
mod ros_msgs;
mod ros {
    pub(crate) use super::ros_msgs as msgs;
}
mod node {
    pub(crate) use super::{engine, params};
}

use node::engine::Engine;
use ros::msgs::*;
use node::params::Settings;

const SPECIAL: [f64; 10] = [
    0.0,
    -0.0,
    1.0,
    -1.5,
    1e300,
    -1e300,
    1e-310,
    f64::NAN,
    f64::INFINITY,
    f64::NEG_INFINITY,
];

/// A number: mostly moderate, sometimes extreme or non-finite.
fn number(u: &mut Unstructured) -> Result<f64> {
    Ok(match u.int_in_range(0u8..=9)? {
        0..=5 => (u.int_in_range(-3000i32..=3000)? as f64) / 1000.0,
        6 | 7 => *u.choose(&SPECIAL)?,
        _ => f64::from_bits(u.arbitrary()?),
    })
}

fn numbers(u: &mut Unstructured, names: usize) -> Result<Vec<f64>> {
    let len = match u.int_in_range(0u8..=5)? {
        0 => 0,
        1 => names.saturating_sub(1),
        2 => names + 1,
        3 => u.int_in_range(0usize..=40)?,
        _ => names,
    };
    (0..len).map(|_| number(u)).collect()
}

/// `K` arrays of numbers for `names` names (of right and wrong lengths), drawn in order.
fn arrays<const K: usize>(u: &mut Unstructured, names: usize) -> Result<[Vec<f64>; K]> {
    let mut arrays: [Vec<f64>; K] = std::array::from_fn(|_| Vec::new());
    for array in &mut arrays {
        *array = numbers(u, names)?;
    }
    Ok(arrays)
}

fn vector(u: &mut Unstructured) -> Result<Vector3> {
    Ok(Vector3 {
        x: number(u)?,
        y: number(u)?,
        z: number(u)?,
    })
}

fn pose(u: &mut Unstructured) -> Result<Pose> {
    let p = vector(u)?;
    let q = if u.arbitrary()? {
        Quaternion {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            w: 1.0,
        }
    } else {
        Quaternion {
            x: number(u)?,
            y: number(u)?,
            z: number(u)?,
            w: number(u)?,
        }
    };
    Ok(Pose {
        position: Point {
            x: p.x,
            y: p.y,
            z: p.z,
        },
        orientation: q,
    })
}

/// A message of two vectors (`Twist { linear, angular }`, `Wrench { force, torque }`), each
/// drawn by [`vector`] in the order named.
macro_rules! two_vectors {
    ($u:expr, $message:ident { $first:ident, $second:ident }) => {
        $message {
            $first: vector($u)?,
            $second: vector($u)?,
        }
    };
}

/// Names to build messages from: the model's coordinates (usually all of them, shuffled), joints
/// without coordinates, links, and names the model does not have.
struct Vocabulary {
    coordinates: Vec<String>,
    others: Vec<String>,
}

impl Vocabulary {
    fn new(engine: &Engine) -> Self {
        let model = &engine.model;
        let mut others: Vec<String> = model.links().iter().map(|l| l.name.clone()).collect();
        others.extend(model.bodies().iter().map(|b| b.joint.name.clone()));
        others.extend(model.fixed_joints().iter().cloned());
        others
            .extend(["", "unknown", "root_joint", "world", "base/x", "joint1 "].map(String::from));
        Vocabulary {
            coordinates: engine.names().to_vec(),
            others,
        }
    }

    fn names(&self, u: &mut Unstructured) -> Result<Vec<String>> {
        let mut names = match u.int_in_range(0u8..=7)? {
            0 => Vec::new(),
            _ => self.coordinates.clone(),
        };
        // Shuffle, then maybe spoil: drop one, add one (a duplicate, a passive or an unknown name).
        for i in (1..names.len()).rev() {
            let j = u.int_in_range(0..=i)?;
            names.swap(i, j);
        }
        if u.ratio(1u8, 4)? && !names.is_empty() {
            let i = u.choose_index(names.len())?;
            names.remove(i);
        }
        if u.ratio(1u8, 3)? {
            let extra = match u.int_in_range(0u8..=2)? {
                0 if !self.coordinates.is_empty() => u.choose(&self.coordinates)?.clone(),
                1 => u.choose(&self.others)?.clone(),
                _ => u.arbitrary::<String>()?,
            };
            let at = u.int_in_range(0..=names.len())?;
            names.insert(at, extra);
        }
        Ok(names)
    }

    /// Names (as [`Self::names`]) and `K` arrays of numbers for them, drawn in order.
    fn named<const K: usize>(
        &self,
        u: &mut Unstructured,
    ) -> Result<(Vec<String>, [Vec<f64>; K])> {
        let names = self.names(u)?;
        let values = arrays(u, names.len())?;
        Ok((names, values))
    }

    fn link(&self, u: &mut Unstructured) -> Result<String> {
        if u.ratio(1u8, 8)? {
            u.arbitrary()
        } else {
            Ok(u.choose(&self.others)?.clone())
        }
    }
}

fn wrenches(u: &mut Unstructured, vocabulary: &Vocabulary) -> Result<Vec<LinkWrench>> {
    let n = u.int_in_range(0usize..=3)?;
    (0..n)
        .map(|_| {
            let link = vocabulary.link(u)?;
            let frame = match u.int_in_range(0u8..=3)? {
                0 => String::new(),
                1 => "world".to_string(),
                2 => link.clone(),
                _ => vocabulary.link(u)?,
            };
            Ok(LinkWrench {
                link,
                frame,
                wrench: two_vectors!(u, Wrench { force, torque }),
            })
        })
        .collect()
}

fn finite(x: &[f64]) -> bool {
    x.iter().all(|v| v.is_finite())
}

fn finite3(v: &Vector3) -> bool {
    v.x.is_finite() && v.y.is_finite() && v.z.is_finite()
}

fn service(what: &str, success: bool, message: &str, results: &[&[f64]], names: &[String]) {
    if success {
        assert!(
            results.iter().all(|r| finite(r)),
            "{what}: success with a non-finite number: {results:?}"
        );
    } else {
        assert!(!message.is_empty(), "{what}: failure without a reason");
        assert!(
            results.iter().all(|r| r.is_empty()) && names.is_empty(),
            "{what}: failure with results"
        );
    }
}

fn topic<T>(what: &str, result: std::result::Result<T, String>, outputs: impl Fn(&T) -> bool) {
    match result {
        Ok(out) => assert!(outputs(&out), "{what}: a non-finite output"),
        Err(reason) => assert!(!reason.is_empty(), "{what}: dropped without a reason"),
    }
}

fn js_finite(m: &JointState) -> bool {
    finite(&m.position) && finite(&m.velocity) && finite(&m.effort)
}

fn settings(u: &mut Unstructured) -> Result<Settings> {
    let mut s = Settings::default();
    s.robot_description = u
        .choose(&[
            DEFAULT_ARM_URDF,
            LAMP_URDF,
            MIMIC_GRIPPER_URDF,
            PARTICLE_URDF,
        ])?
        .to_string();
    let args: [&[&str]; 12] = [
        &["floating_base", "true"],
        &["ignore_mimic", "true"],
        &["method", "crba"],
        &["method", "rnea_columns"],
        &["command_joints", "[joint3, joint1]"],
        &["locked_joints", "[joint2=0.5]"],
        &["mode", "simulate"],
        &["gravity", "[0.0, 1e300, -9.81]"],
        &["command_interface", "position"],
        &["command_interface", "velocity"],
        &["step_mode", "on_command"],
        &["servo_kp", "[1e300]"],
    ];
    for arg in args {
        if u.ratio(1u8, 5)? {
            // Some combinations are refused (a joint this model lacks): that is an answer too.
            let _ = s.apply_arg(arg[0], arg[1]);
        }
    }
    Ok(s)
}

fn run(u: &mut Unstructured) -> Result<()> {
    let settings = settings(u)?;
    let mut engine = match Engine::from_settings(&settings, None) {
        Ok(engine) => engine,
        Err(reason) => {
            assert!(!reason.is_empty());
            return Ok(());
        }
    };
    let vocabulary = Vocabulary::new(&engine);
    for _ in 0..u.int_in_range(1u8..=12)? {
        match u.int_in_range(0u8..=15)? {
            0 => {
                let names = vocabulary.names(u)?;
                let nanosec = u.int_in_range(0u32..=999_999_999)?;
                let [position, velocity, effort] = arrays(u, names.len())?;
                let js = JointState {
                    header: Header {
                        stamp: Time { sec: 0, nanosec },
                        frame_id: String::new(),
                    },
                    name: names,
                    position,
                    velocity,
                    effort,
                };
                let stamp = js.header.stamp.clone();
                topic("joint_states", engine.joint_states(&js, stamp), |a| {
                    js_finite(&a.gravity)
                        && finite(&a.acceleration.position)
                        && finite(&a.acceleration.velocity)
                        && finite(&a.acceleration.acceleration)
                        && finite(&a.acceleration.effort)
                        && match &a.residual {
                            Some(Ok(r)) => js_finite(r),
                            Some(Err(reason)) => !reason.is_empty(),
                            None => true,
                        }
                });
            }
            1 => {
                let (names, [effort]) = vocabulary.named(u)?;
                let js = JointState {
                    name: names,
                    effort,
                    ..Default::default()
                };
                topic("effort_command", engine.set_effort_command(&js), |_| true);
            }
            2 => {
                let cmd = Float64MultiArray {
                    data: numbers(u, engine.command_names().len())?,
                    ..Default::default()
                };
                topic("commands", engine.set_commands(&cmd), |_| true);
            }
            3 => {
                let names = vocabulary.names(u)?;
                let points = (0..u.int_in_range(0u8..=2)?)
                    .map(|_| {
                        let [positions, velocities, accelerations] = arrays(u, names.len())?;
                        Ok(JointTrajectoryPoint {
                            positions,
                            velocities,
                            accelerations,
                            ..Default::default()
                        })
                    })
                    .collect::<Result<Vec<_>>>()?;
                let traj = JointTrajectory {
                    joint_names: names,
                    points,
                    ..Default::default()
                };
                topic("reference", engine.reference(&traj), |(e, c)| {
                    js_finite(e) && finite(&c.data)
                });
            }
            4 => {
                let mut odom = Odometry::default();
                odom.pose.pose = pose(u)?;
                odom.twist.twist = two_vectors!(u, Twist { linear, angular });
                topic("base_state", engine.set_base_state(&odom), |_| true);
            }
            5 => {
                let (names, [position, velocity, acceleration]) = vocabulary.named(u)?;
                let req = InverseDynamicsRequest {
                    name: names,
                    position,
                    velocity,
                    acceleration,
                    external_wrenches: wrenches(u, &vocabulary)?,
                    base_pose: pose(u)?,
                    base_twist: two_vectors!(u, Twist { linear, angular }),
                    base_accel: two_vectors!(u, Accel { linear, angular }),
                };
                let r = engine.inverse_dynamics(&req);
                let w = &r.base_wrench;
                assert!(
                    !r.success || (finite3(&w.force) && finite3(&w.torque)),
                    "base wrench {w:?}"
                );
                service(
                    "inverse_dynamics",
                    r.success,
                    &r.message,
                    &[&r.effort],
                    &r.name,
                );
            }
            6 => {
                let (names, [position, velocity, effort]) = vocabulary.named(u)?;
                let req = ForwardDynamicsRequest {
                    name: names,
                    position,
                    velocity,
                    effort,
                    external_wrenches: wrenches(u, &vocabulary)?,
                    method: u
                        .choose(&["", "aba", "crba", "rnea_columns", "ABA", "magic"])?
                        .to_string(),
                    base_pose: pose(u)?,
                    base_twist: two_vectors!(u, Twist { linear, angular }),
                    base_wrench: two_vectors!(u, Wrench { force, torque }),
                };
                let r = engine.forward_dynamics(&req);
                let b = &r.base_accel;
                assert!(
                    !r.success || (finite3(&b.linear) && finite3(&b.angular)),
                    "base accel {b:?}"
                );
                service(
                    "forward_dynamics",
                    r.success,
                    &r.message,
                    &[&r.acceleration],
                    &r.name,
                );
            }
            7 => {
                let (names, [position]) = vocabulary.named(u)?;
                let req = MassMatrixRequest {
                    name: names,
                    position,
                    base_pose: pose(u)?,
                };
                let r = engine.mass_matrix(&req);
                service("mass_matrix", r.success, &r.message, &[&r.matrix], &r.name);
                if r.success {
                    let n = r.matrix.len();
                    assert!(
                        (r.name.len()..=r.name.len() + 6).any(|k| k * k == n),
                        "matrix size {n}"
                    );
                }
            }
            8 => {
                let r = engine.describe();
                assert!(r.success && r.joint_names.len() == r.joint_types.len());
            }
            9 => {
                // A tick run on time or up to 255 ms after it was due (dropped past the lag bound).
                let lag = std::time::Duration::from_millis(u64::from(u.arbitrary::<u8>()?));
                let now = Instant::now();
                let due = now.checked_sub(lag).unwrap_or(now);
                if let Some(Ok((js, _))) = engine.simulation_tick(due, now) {
                    assert!(js_finite(&js), "simulated joint_states not finite: {js:?}");
                }
            }
            10 => {
                let _ = engine.simulation_pause(u.arbitrary()?);
                match engine.simulation_step(Instant::now()) {
                    Ok((js, _)) => {
                        assert!(js_finite(&js), "stepped joint_states not finite: {js:?}")
                    }
                    Err(reason) => assert!(!reason.is_empty()),
                }
            }
            11 => {
                let (names, [position, velocity]) = vocabulary.named(u)?;
                let req = ResetRequest {
                    name: names,
                    position,
                    velocity,
                    base_pose: pose(u)?,
                    base_twist: two_vectors!(u, Twist { linear, angular }),
                };
                let r = engine.simulation_reset(&req);
                assert!(r.success || !r.message.is_empty());
            }
            12 => {
                let names = vocabulary.names(u)?;
                let links = (0..u.int_in_range(0u8..=3)?)
                    .map(|_| vocabulary.link(u))
                    .collect::<Result<Vec<_>>>()?;
                let [position, velocity, acceleration] = arrays(u, names.len())?;
                let req = FrameKinematicsRequest {
                    name: names,
                    position,
                    velocity,
                    acceleration,
                    base_pose: pose(u)?,
                    base_twist: two_vectors!(u, Twist { linear, angular }),
                    base_accel: two_vectors!(u, Accel { linear, angular }),
                    links,
                    reference: u
                        .choose(&["", "world", "local", "local_world_aligned", "LOCAL"])?
                        .to_string(),
                };
                let r = engine.frame_kinematics(&req);
                let poses: Vec<f64> = r
                    .poses
                    .iter()
                    .flat_map(|p| {
                        let (x, o) = (&p.position, &p.orientation);
                        [x.x, x.y, x.z, o.x, o.y, o.z, o.w]
                    })
                    .chain(r.accelerations.iter().flat_map(|a| {
                        let (l, w) = (&a.linear, &a.angular);
                        [l.x, l.y, l.z, w.x, w.y, w.z]
                    }))
                    .collect();
                let com = [r.mass, r.center_of_mass.x, r.center_of_mass.y, r.center_of_mass.z];
                service(
                    "frame_kinematics",
                    r.success,
                    &r.message,
                    &[&r.jacobians, &r.center_of_mass_jacobian, &poses, &com[..(r.success as usize) * 4]],
                    &r.links,
                );
                if r.success {
                    let n = r.columns.len();
                    assert_eq!(r.jacobians.len(), r.links.len() * 6 * n);
                    assert_eq!(r.center_of_mass_jacobian.len(), 3 * n);
                    assert_eq!((r.poses.len(), r.accelerations.len()), (r.links.len(), r.links.len()));
                }
            }
            13 => {
                let (names, [position, velocity, effort]) = vocabulary.named(u)?;
                let req = LinearizeRequest {
                    name: names,
                    position,
                    velocity,
                    effort,
                    dt: if u.arbitrary()? {
                        number(u)?
                    } else {
                        *u.choose(&[0.0, 1e-3, 0.05])?
                    },
                    base_pose: pose(u)?,
                    base_twist: two_vectors!(u, Twist { linear, angular }),
                    base_wrench: two_vectors!(u, Wrench { force, torque }),
                };
                let r = engine.linearize(&req);
                service(
                    "linearize",
                    r.success,
                    &r.message,
                    &[&r.a, &r.b, &r.ddq_dq, &r.ddq_dv, &r.minv, &r.effort, &r.acceleration],
                    &r.columns,
                );
                if r.success {
                    let n = r.columns.len();
                    assert_eq!((r.a.len(), r.b.len(), r.minv.len()), (4 * n * n, 2 * n * n, n * n));
                    assert_eq!((r.effort.len(), r.acceleration.len()), (n, n));
                }
            }
            14 => {
                let (names, [position, velocity, effort]) = vocabulary.named(u)?;
                let js = JointState {
                    name: names,
                    position,
                    velocity,
                    effort,
                    ..Default::default()
                };
                topic("joint_commands", engine.set_joint_commands(&js), |_| true);
                if let Some(Ok((js, _))) = engine.command_step(Instant::now()) {
                    assert!(js_finite(&js), "lockstep joint_states not finite: {js:?}");
                }
            }
            _ => {
                let _ = engine.simulation_status();
            }
        }
    }
    Ok(())
}

fuzz_target!(|data: &[u8]| {
    let _ = run(&mut Unstructured::new(data));
});

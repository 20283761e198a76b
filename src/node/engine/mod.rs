//! The dynamics behind the node's services and topics, free of DDS: a model, its workspace,
//! the joint-name map, and the latest state and command received. Every entry point answers a
//! message with a message, or with an error text that names the joint, field or value.

pub mod clock;
mod frame_kinematics;
mod linearize;
pub(crate) mod requests;
pub(crate) mod simulation;

use super::params::Settings;
use crate::joint_states::commands::Commands;
use crate::joint_states::dynamics::JointStateDynamics;
use crate::joint_states::joint_map::{JointMap, Target};
use crate::joint_states::residual::{read_effort, Lagged};
use crate::ros::msgs::*;
use requests::Refused;
use simulation::Simulation;
use spatial_dynamics_core::algorithms::kinematics::body_placements;
use spatial_dynamics_core::algorithms::method_choice::AUTO_TOLERANCE;
use spatial_dynamics_core::algorithms::{
    choose_method, crba, forward_dynamics, rnea_with, JointStateInputs, Linearization,
};
use spatial_dynamics_core::error::{name_list, quoted};
use spatial_dynamics_core::model::examples::DEFAULT_ARM_URDF;
use spatial_dynamics_core::model::quaternion_is_usable;
use spatial_dynamics_core::sim::CommandInterface;
use spatial_dynamics_core::spatial::{Force, Transform};
use spatial_dynamics_core::{urdf, Externals, ForwardDynamicsMethod, Model, Workspace};
use std::time::{Duration, Instant};

/// Joint states further apart than this (ns, by header stamp) are not differenced across for
/// `~/effort_residual` (replay's default `--max-gap`).
pub const RESIDUAL_MAX_GAP_NS: i64 = 100_000_000;

/// What a `joint_states` message gives.
#[derive(Debug)]
pub struct JointStateAnswer {
    /// `~/gravity_effort`.
    pub gravity: JointState,
    /// `~/acceleration`.
    pub acceleration: JointDynamics,
    /// `~/effort_residual` of the joint state before this one (one sample late), or why that
    /// one, which carried effort, has none; `None` when it carried no effort.
    pub residual: Option<Result<JointState, String>>,
    /// Why this message's effort is refused (wrong length, non-finite): it will have no residual.
    pub bad_effort: Option<String>,
}

/// What a joint state keeps until its residual goes out: its header (with the output stamp)
/// and its names, as indices into the map's names.
#[derive(Clone, Debug)]
struct ResidualTag {
    header: Header,
    order: Vec<usize>,
}

/// Where the model came from (for diagnostics and DescribeModel).
#[derive(Clone, Debug, PartialEq)]
pub enum ModelSource {
    Parameter,
    File(String),
    Topic,
    Default,
}

/// A model and everything needed to answer with it.
pub struct Engine {
    pub model: Model,
    pub source: ModelSource,
    pub method: ForwardDynamicsMethod,
    /// How `method: auto` chose (`None` when the method was given).
    pub method_choice: Option<String>,
    ws: Workspace,
    /// Scratch for `joint_states`: gravity torques and accelerations computed together.
    dynamics: JointStateDynamics,
    map: JointMap,
    /// Latest commanded effort, zero until one arrives.
    commands: Commands,
    q: Vec<f64>,
    v: Vec<f64>,
    a: Vec<f64>,
    tau: Vec<f64>,
    out: Vec<f64>,
    wrenches: Vec<Force>,
    /// Measured effort of the latest joint state, model order.
    effort: Vec<f64>,
    /// The last joint states, for `~/effort_residual` (one sample late).
    residual: Lagged<ResidualTag>,
    /// When the latest command arrived.
    command_time: Option<Instant>,
    /// The simulated robot, in simulate mode.
    simulation: Option<Simulation>,
    /// Latest floating-base pose `[x y z qx qy qz qw]` and twist from `~/base_state`.
    base_q: [f64; 7],
    base_v: [f64; 6],
    /// `~/linearize`'s matrices and scratch (`4nv² + 2nv²` numbers), made by the first request:
    /// a model that is never linearised (a 10 000-link chain) never holds them.
    linearization: Option<Linearization>,
}

impl Engine {
    /// Builds the model the settings ask for: `robot_description`, else `urdf_file`, else the
    /// description received on the topic, else the embedded default arm.
    pub fn from_settings(
        settings: &Settings,
        topic_description: Option<&str>,
    ) -> Result<Engine, String> {
        let options = settings.model_options();
        let (model, source) = if !settings.robot_description.is_empty() {
            (
                urdf::model_from_str(&settings.robot_description, &options),
                ModelSource::Parameter,
            )
        } else if !settings.urdf_file.is_empty() {
            (
                urdf::model_from_file(settings.urdf_file.as_ref(), &options),
                ModelSource::File(settings.urdf_file.clone()),
            )
        } else if let Some(text) = topic_description {
            (urdf::model_from_str(text, &options), ModelSource::Topic)
        } else {
            (
                urdf::model_from_str(DEFAULT_ARM_URDF, &options),
                ModelSource::Default,
            )
        };
        let model = model.map_err(|e| e.to_string())?;
        let map = JointMap::for_model(&model)?;
        let commands = Commands::new(&map, model.nv(), &settings.command_joints)?;
        let (nq, nv, nb) = (model.nq(), model.nv(), model.nbodies());
        let mut engine = Engine {
            ws: Workspace::new(&model),
            dynamics: JointStateDynamics::new(&model),
            map,
            commands,
            q: vec![0.0; nq],
            v: vec![0.0; nv],
            a: vec![0.0; nv],
            tau: vec![0.0; nv],
            out: Vec::with_capacity(nv),
            effort: vec![0.0; nv],
            residual: Lagged::new(&model, RESIDUAL_MAX_GAP_NS),
            wrenches: vec![Force::zero(); nb],
            command_time: None,
            simulation: None,
            base_q: [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
            base_v: [0.0; 6],
            linearization: None,
            method: ForwardDynamicsMethod::Aba,
            method_choice: None,
            model,
            source,
        };
        engine.set_method(settings.method);
        engine.configure_simulation(settings)?;
        Ok(engine)
    }

    /// Takes over, by joint name, what `old` (the engine this one replaces) held from the
    /// topics in serve mode: the latest effort command, with its arrival time, and the floating
    /// base's pose and twist from `~/base_state`. Returns, described, what this model has no
    /// place for: commanded joints it lacks, a base state when it has no floating base. In
    /// simulate mode nothing is taken: the simulation starts again, with no command in force.
    /// The residual `old` still owes ([`Engine::pending_residual`]) is not carried.
    pub fn take_over(&mut self, old: &Engine) -> Vec<String> {
        if self.simulation.is_some() {
            return Vec::new();
        }
        let mut lost = Vec::new();
        let joints = self.commands.carry_from(&old.commands);
        if !joints.is_empty() {
            lost.push(format!(
                "the effort command of {} (not in the new model)",
                name_list(&joints, joints.len())
            ));
        }
        self.command_time = old.command_time;
        let base_set = old.base_q != [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0] || old.base_v != [0.0; 6];
        if self.map.base().is_some() {
            (self.base_q, self.base_v) = (old.base_q, old.base_v);
        } else if old.map.base().is_some() && base_set {
            lost.push("the base pose and twist from ~/base_state (no floating base now)".into());
        }
        lost
    }

    /// The stamp of the latest joint state whose effort residual waits for the next joint state
    /// (`~/effort_residual` is one sample late), if any.
    pub fn pending_residual(&self) -> Option<&Time> {
        self.residual.pending().map(|tag| &tag.header.stamp)
    }

    /// Uses `method`, or with `None` (`auto`) the method with the fewest FLOPs per call among
    /// those that agree with `aba` to [`AUTO_TOLERANCE`] on this model (checked now, timed for
    /// the summary within about 10 ms per method). If no method can
    /// run on the model (a singular mass matrix, say), `aba` stays and requests will say why.
    /// A running simulation steps with the new method from its next step on.
    pub fn set_method(&mut self, method: Option<ForwardDynamicsMethod>) {
        (self.method, self.method_choice) = match method {
            Some(m) => (m, None),
            None => match choose_method(&self.model, AUTO_TOLERANCE, Duration::from_millis(10)) {
                Ok(choice) => (choice.method, Some(format!("auto: {}", choice.summary()))),
                Err(e) => (
                    ForwardDynamicsMethod::Aba,
                    Some(format!("auto: aba (no method could be measured: {e})")),
                ),
            },
        };
        self.simulate_with_method();
    }

    /// Names of the joint coordinates, in model order.
    pub fn names(&self) -> &[String] {
        self.map.names()
    }

    /// Names of `command_joints`, in command order (the order of `~/commands`; the fuzz target
    /// sizes its commands by it).
    #[allow(dead_code)]
    pub fn command_names(&self) -> Vec<String> {
        self.commands.names()
    }

    // ---- services ------------------------------------------------------------------------------

    /// `~/inverse_dynamics`.
    pub fn inverse_dynamics(&mut self, req: &InverseDynamicsRequest) -> InverseDynamicsResponse {
        let result = self.read_request_state(req).and_then(|_| {
            self.read_acceleration(&req.acceleration, &req.base_accel)?;
            let n = self.external_wrenches(&req.external_wrenches)?;
            let ext = externals(&self.wrenches, n);
            let tau = rnea_with(&self.model, &mut self.ws, &self.q, &self.v, &self.a, &ext)
                .map_err(|e| e.to_string())?;
            self.tau.copy_from_slice(tau);
            Ok(())
        });
        match result {
            Ok(()) => {
                self.map.gather(&self.tau, Target::Rate, &mut self.out);
                InverseDynamicsResponse {
                    success: true,
                    message: String::new(),
                    name: self.map.answer_names(),
                    effort: self.out.clone(),
                    base_wrench: base_wrench(self.map.base(), &self.tau),
                }
            }
            Err(message) => InverseDynamicsResponse::refused(message),
        }
    }

    /// `~/forward_dynamics`.
    pub fn forward_dynamics(&mut self, req: &ForwardDynamicsRequest) -> ForwardDynamicsResponse {
        let result = self.read_request_state(req).and_then(|_| {
            let method = if req.method.is_empty() {
                self.method
            } else {
                req.method.parse()?
            };
            self.read_efforts(&req.effort, &req.base_wrench)?;
            let n = self.external_wrenches(&req.external_wrenches)?;
            let ext = externals(&self.wrenches, n);
            let qdd = forward_dynamics(
                &self.model,
                &mut self.ws,
                &self.q,
                &self.v,
                &self.tau,
                method,
                &ext,
            )
            .map_err(|e| e.to_string())?;
            self.a.copy_from_slice(qdd);
            Ok(())
        });
        match result {
            Ok(()) => {
                self.map.gather(&self.a, Target::Rate, &mut self.out);
                let base_accel = self.map.base().map_or_else(Accel::default, |(_, v)| Accel {
                    linear: vector(&self.a[v..v + 3]),
                    angular: vector(&self.a[v + 3..v + 6]),
                });
                ForwardDynamicsResponse {
                    success: true,
                    message: String::new(),
                    name: self.map.answer_names(),
                    acceleration: self.out.clone(),
                    base_accel,
                }
            }
            Err(message) => ForwardDynamicsResponse::refused(message),
        }
    }

    /// `~/mass_matrix`: the full `nv × nv` matrix, row-major; with a floating base its six
    /// coordinates come first, named `<base>/linear_x` … `<base>/angular_z`.
    pub fn mass_matrix(&mut self, req: &MassMatrixRequest) -> MassMatrixResponse {
        if let Err(message) =
            self.read_state(&req.name, &req.position, &[], Some(&req.base_pose), None)
        {
            return MassMatrixResponse::refused(message);
        }
        // Rows and columns: the base's six coordinates, then the joints in the request's order.
        let (index, _) = self.velocity_columns();
        let h = match crba(&self.model, &mut self.ws, &self.q) {
            Ok(h) => h,
            Err(e) => return MassMatrixResponse::refused(e.to_string()),
        };
        let matrix = linearize::permuted(h, &index, &index);
        MassMatrixResponse {
            success: true,
            message: String::new(),
            name: self.map.answer_names(),
            matrix,
        }
    }

    /// `~/describe_model`.
    pub fn describe(&self) -> DescribeModelResponse {
        let mut r = DescribeModelResponse {
            success: true,
            nq: self.model.nq() as u32,
            nv: self.model.nv() as u32,
            floating_base: self.map.base().is_some(),
            gravity: self.model.gravity().into(),
            method: self.method.name().into(),
            ..Default::default()
        };
        // The names requests take (a planar joint J as J/x, J/y, J/theta), each with the type
        // and limits of the joint it belongs to.
        for (index, name) in self.map.names().iter().enumerate() {
            let (q, _) = self.map.slot(index);
            let joint = self
                .model
                .joint_of_q(q)
                .and_then(|(joint, _)| self.model.bodies().iter().find(|b| b.joint.name == joint))
                .map(|b| &b.joint)
                .expect("a named coordinate belongs to a joint");
            let limits = &joint.limits;
            r.joint_names.push(name.clone());
            r.joint_types.push(joint.kind.type_name().to_string());
            r.position_lower.push(limits.lower);
            r.position_upper.push(limits.upper);
            r.velocity_limit.push(limits.velocity);
            r.effort_limit.push(limits.effort);
        }
        r.link_names = self.model.links().iter().map(|l| l.name.clone()).collect();
        r.locked_joints =
            self.model
                .locked_joints()
                .iter()
                .map(|(n, v)| format!("{n}={v:?}"))
                .chain(self.model.reduction().frozen_joints.iter().map(
                    |(n, q)| match q.as_slice() {
                        [v] => format!("{n}={v:?}"),
                        q => format!("{n}={q:?}"),
                    },
                ))
                .collect();
        r.fused_links = self.model.fused_links().to_vec();
        r.message = format!(
            "robot '{}' from {}",
            self.model.name(),
            match &self.source {
                ModelSource::Parameter => "the robot_description parameter".to_string(),
                ModelSource::File(f) => format!("file {f}"),
                ModelSource::Topic => "the robot_description topic".to_string(),
                ModelSource::Default => "the embedded default (sd_arm7)".to_string(),
            }
        );
        if let Some(choice) = &self.method_choice {
            r.message += "; method ";
            r.message += choice;
        }
        for line in self.model.reduction().summary() {
            r.message += "; ";
            r.message += &line;
        }
        r
    }

    // ---- topics --------------------------------------------------------------------------------

    /// `~/base_state` (nav_msgs/Odometry): the floating base's pose and twist for topic inputs.
    pub fn set_base_state(&mut self, odom: &Odometry) -> Result<(), String> {
        let Some(_) = self.map.base() else {
            return Err("the model has no floating base".into());
        };
        let (mut q, mut v) = ([0.0; 7], [0.0; 6]);
        write_pose(&mut q, 0, &odom.pose.pose, "pose")?;
        write_base(
            Some((0, 0)),
            &mut v,
            [
                ("linear", &odom.twist.twist.linear),
                ("angular", &odom.twist.twist.angular),
            ],
            "twist",
        )?;
        self.base_q = q;
        self.base_v = v;
        Ok(())
    }

    /// `~/effort_command` (by name).
    pub fn set_effort_command(&mut self, js: &JointState) -> Result<(), String> {
        self.commands
            .set_effort_command(&js.name, &js.effort)
            .map_err(|(_, e)| e)?;
        self.command_time = Some(Instant::now());
        Ok(())
    }

    /// `~/commands` (in `command_joints` order): efforts (joints left out get zero), or the
    /// servos' targets with `command_interface` position or velocity.
    pub fn set_commands(&mut self, cmd: &Float64MultiArray) -> Result<(), String> {
        if self.command_interface() == CommandInterface::Effort {
            self.commands.set_commands(&cmd.data).map_err(|(_, e)| e)?;
        } else {
            let names = self.commands.names();
            let slots: Vec<usize> = (0..names.len()).collect();
            let what = format!(
                "one per command joint: {} targets",
                self.command_interface().name()
            );
            check_command_field("data", &cmd.data, &names, &what)?;
            self.set_servo_targets(&slots, &cmd.data, &[]);
        }
        self.command_time = Some(Instant::now());
        Ok(())
    }

    /// `~/joint_commands` (sensor_msgs/JointState, as topic_based_ros2_control sends commands):
    /// command joints by name, any subset in any order, the field of the command interface
    /// (`effort`, `position`, `velocity`) one finite value per name; with position servos a
    /// `velocity` field of the same length is the rate target (empty: zero). Joints not named
    /// keep their command. A refused message changes nothing.
    pub fn set_joint_commands(&mut self, js: &JointState) -> Result<(), String> {
        let interface = self.command_interface();
        if js.name.is_empty() {
            return Err("the message names no joint: name the joints it commands".into());
        }
        let names = self.commands.names();
        let mut slots = Vec::with_capacity(js.name.len());
        for name in &js.name {
            let k = names.iter().position(|c| c == name).ok_or_else(|| {
                format!(
                    "unknown joint {} (the command joints: {})",
                    quoted(name),
                    name_list(&names, names.len())
                )
            })?;
            if slots.contains(&k) {
                return Err(format!("joint {} is named twice", quoted(name)));
            }
            slots.push(k);
        }
        let values = match interface {
            CommandInterface::Effort => &js.effort,
            CommandInterface::Position => &js.position,
            CommandInterface::Velocity => &js.velocity,
        };
        let what = format!("one per name: command_interface is {}", interface.name());
        check_command_field(interface.name(), values, &js.name, &what)?;
        if interface == CommandInterface::Effort {
            let mut data = self.commands.gather(self.commands.effort());
            for (&k, &x) in slots.iter().zip(values) {
                data[k] = x;
            }
            self.commands.set_commands(&data).map_err(|(_, e)| e)?;
        } else {
            let rates = if interface == CommandInterface::Position && !js.velocity.is_empty() {
                let what = "one per name, or none: the position servos' rate targets";
                check_command_field("velocity", &js.velocity, &js.name, what)?;
                &js.velocity[..]
            } else {
                &[]
            };
            self.set_servo_targets(&slots, values, rates);
        }
        self.command_time = Some(Instant::now());
        Ok(())
    }

    /// `joint_states` → `~/gravity_effort`, `~/acceleration` under the latest command, and the
    /// previous joint state's `~/effort_residual`; outputs stamped `stamp`. A message the
    /// dynamics refuse is not kept for the residual's finite differences (time base: its
    /// header stamp).
    pub fn joint_states(
        &mut self,
        js: &JointState,
        stamp: Time,
    ) -> Result<JointStateAnswer, String> {
        self.read_state(&js.name, &js.position, &js.velocity, None, None)?;
        let effort = read_effort(&self.map, &js.effort, &mut self.effort);
        // g(q) and q̈ = FD(q, q̇, τ_cmd) on one set of joint transforms.
        let input = JointStateInputs {
            q: &self.q,
            v: &self.v,
            effort_command: self.commands.effort(),
            measured_acceleration: None,
        };
        self.dynamics
            .evaluate(&self.model, &mut self.ws, self.method, &input)
            .node?;
        self.tau.copy_from_slice(self.dynamics.gravity());
        self.a.copy_from_slice(self.dynamics.acceleration());
        let header = Header {
            stamp,
            frame_id: js.header.frame_id.clone(),
        };
        let names = self.map.answer_names();
        let mut position = Vec::new();
        self.map.gather(&self.q, Target::Position, &mut position);
        self.map.gather(&self.tau, Target::Rate, &mut self.out);
        let gravity = JointState {
            header: header.clone(),
            name: names.clone(),
            position: position.clone(),
            velocity: Vec::new(),
            effort: self.out.clone(),
        };
        let mut velocity = Vec::new();
        let mut acceleration = Vec::new();
        let mut command = Vec::new();
        self.map.gather(&self.v, Target::Rate, &mut velocity);
        self.map.gather(&self.a, Target::Rate, &mut acceleration);
        self.map
            .gather(self.commands.effort(), Target::Rate, &mut command);
        let acceleration = JointDynamics {
            header: header.clone(),
            name: names,
            position,
            velocity,
            acceleration,
            effort: command,
        };

        let t = i64::from(js.header.stamp.sec) * 1_000_000_000 + i64::from(js.header.stamp.nanosec);
        let tag = ResidualTag {
            header,
            order: self.map.answer_order().collect(),
        };
        let has_effort = matches!(effort, Ok(true));
        let measured = has_effort.then_some(self.effort.as_slice());
        let has_velocity = !js.velocity.is_empty();
        let delayed = self.residual.push(
            &self.model,
            &mut self.ws,
            t,
            &self.q,
            &self.v,
            has_velocity,
            measured,
            tag,
        );
        let map = &self.map;
        let residual = delayed.map(|d| {
            let r = d.residual.map_err(|(_, e)| e)?;
            let order = || d.tag.order.iter().copied();
            let mut msg = JointState {
                header: d.tag.header.clone(),
                name: order().map(|s| map.names()[s].clone()).collect(),
                ..Default::default()
            };
            map.gather_in(order(), d.q, Target::Position, &mut msg.position);
            map.gather_in(order(), d.v, Target::Rate, &mut msg.velocity);
            map.gather_in(order(), r, Target::Rate, &mut msg.effort);
            Ok(msg)
        });
        Ok(JointStateAnswer {
            gravity,
            acceleration,
            residual,
            bad_effort: effort.err().map(|(_, e)| e),
        })
    }

    /// `~/reference` (first point) → (`~/feedforward_effort`, `~/feedforward_commands`).
    pub fn reference(
        &mut self,
        traj: &JointTrajectory,
    ) -> Result<(JointState, Float64MultiArray), String> {
        let point = traj
            .points
            .first()
            .ok_or("the reference trajectory has no points")?;
        self.read_state(
            &traj.joint_names,
            &point.positions,
            &point.velocities,
            None,
            None,
        )?;
        self.map.scatter(
            "points[0].accelerations",
            &point.accelerations,
            Target::Rate,
            true,
            &mut self.a,
        )?;
        if let Some((_, v)) = self.map.base() {
            self.a[v..v + 6].iter_mut().for_each(|x| *x = 0.0);
        }
        let tau = rnea_with(
            &self.model,
            &mut self.ws,
            &self.q,
            &self.v,
            &self.a,
            &Externals::none(),
        )
        .map_err(|e| e.to_string())?;
        self.tau.copy_from_slice(tau);
        self.map.gather(&self.tau, Target::Rate, &mut self.out);
        let mut position = Vec::new();
        self.map.gather(&self.q, Target::Position, &mut position);
        let effort_msg = JointState {
            header: traj.header.clone(),
            name: self.map.answer_names(),
            position,
            velocity: Vec::new(),
            effort: self.out.clone(),
        };
        let data = self.commands.gather(&self.tau);
        let dim = MultiArrayDimension {
            label: "joints".into(),
            size: data.len() as u32,
            stride: data.len() as u32,
        };
        Ok((
            effort_msg,
            Float64MultiArray {
                layout: MultiArrayLayout {
                    dim: vec![dim],
                    data_offset: 0,
                },
                data,
            },
        ))
    }

    // ---- shared --------------------------------------------------------------------------------

    /// A request's `acceleration` (by its names, as [`Self::read_state`] matched them) and
    /// `base_accel` into `self.a`.
    fn read_acceleration(
        &mut self,
        acceleration: &[f64],
        base_accel: &Accel,
    ) -> Result<(), String> {
        scatter_rates(
            &self.map,
            ("acceleration", acceleration),
            (
                "base_accel",
                [
                    ("linear", &base_accel.linear),
                    ("angular", &base_accel.angular),
                ],
            ),
            &mut self.a,
        )
    }

    /// A request's `effort` (by its names, as [`Self::read_state`] matched them) and
    /// `base_wrench` into `self.tau`.
    fn read_efforts(&mut self, effort: &[f64], base_wrench: &Wrench) -> Result<(), String> {
        scatter_rates(
            &self.map,
            ("effort", effort),
            (
                "base_wrench",
                [
                    ("force", &base_wrench.force),
                    ("torque", &base_wrench.torque),
                ],
            ),
            &mut self.tau,
        )
    }

    /// Fills `q` and `v` from named joint arrays and the base (explicit fields for services, the
    /// latest `~/base_state` for topics).
    fn read_state(
        &mut self,
        names: &[String],
        position: &[f64],
        velocity: &[f64],
        base_pose: Option<&Pose>,
        base_twist: Option<&Twist>,
    ) -> Result<(), String> {
        self.map.match_names(names, "name")?;
        self.map
            .scatter_state(position, velocity, &mut self.q, &mut self.v)
            .map_err(|(_, e)| e)?;
        if let Some((qi, vi)) = self.map.base() {
            match base_pose {
                Some(pose) => write_pose(&mut self.q, qi, pose, "base_pose")?,
                None => self.q[qi..qi + 7].copy_from_slice(&self.base_q),
            }
            match (base_pose, base_twist) {
                (_, Some(t)) => write_base(
                    Some((qi, vi)),
                    &mut self.v,
                    [("linear", &t.linear), ("angular", &t.angular)],
                    "base_twist",
                )?,
                (Some(_), None) => self.v[vi..vi + 6].iter_mut().for_each(|x| *x = 0.0),
                (None, None) => self.v[vi..vi + 6].copy_from_slice(&self.base_v),
            }
        }
        Ok(())
    }

    /// Converts the requested link wrenches into body-frame forces; returns how many there were.
    fn external_wrenches(&mut self, wrenches: &[LinkWrench]) -> Result<usize, String> {
        self.wrenches.iter_mut().for_each(|w| *w = Force::zero());
        if wrenches.is_empty() {
            return Ok(0);
        }
        // World → body rotations, when a wrench is given in world axes.
        let mut placements: &[Transform] = &[];
        if wrenches.iter().any(|w| w.frame == "world") {
            placements =
                body_placements(&self.model, &mut self.ws, &self.q).map_err(|e| e.to_string())?;
        }
        for (i, w) in wrenches.iter().enumerate() {
            let link = self
                .model
                .link(&w.link)
                .ok_or_else(|| format!("external_wrenches[{i}]: unknown link '{}'", w.link))?;
            let values = [
                w.wrench.force.x,
                w.wrench.force.y,
                w.wrench.force.z,
                w.wrench.torque.x,
                w.wrench.torque.y,
                w.wrench.torque.z,
            ];
            if values.iter().any(|x| !x.is_finite()) {
                return Err(format!(
                    "external_wrenches[{i}] on link '{}' is not finite",
                    w.link
                ));
            }
            let f = Force::new((&w.wrench.torque).into(), (&w.wrench.force).into());
            let Some(body) = link.body else { continue }; // on the fixed world: no effect
                                                          // Torque about the link origin; "world" only turns the axes (world → link axes).
            let in_link = match w.frame.as_str() {
                "" => f,
                frame if frame == w.link => f,
                "world" => {
                    let world_to_link = link.x_body_link.rot * placements[body].rot;
                    Force::new(world_to_link * f.ang, world_to_link * f.lin)
                }
                other => return Err(format!("external_wrenches[{i}]: frame '{other}' must be the link's own name (or empty) or 'world'")),
            };
            self.wrenches[body] += link.x_body_link.transpose_apply_force(&in_link);
        }
        Ok(wrenches.len())
    }
}

/// The external forces of a request whose `n` wrenches [`Engine::external_wrenches`] turned
/// into the body-frame `wrenches`: none when it gave none.
fn externals(wrenches: &[Force], n: usize) -> Externals<'_> {
    Externals {
        wrenches: (n > 0).then_some(wrenches),
        ..Default::default()
    }
}

fn vector(x: &[f64]) -> Vector3 {
    Vector3 {
        x: x[0],
        y: x[1],
        z: x[2],
    }
}

fn base_wrench(base: Option<(usize, usize)>, tau: &[f64]) -> Wrench {
    base.map_or_else(Wrench::default, |(_, v)| Wrench {
        force: vector(&tau[v..v + 3]),
        torque: vector(&tau[v + 3..v + 6]),
    })
}

/// Writes a `[linear; angular]` pair into the base's six velocity-like coordinates.
/// A per-coordinate request field (optional: empty means zero) and the base's six entries of
/// the same quantity (linear, angular), into `out` in model order.
fn scatter_rates(
    map: &JointMap,
    (field, values): (&str, &[f64]),
    (base_field, base_parts): (&str, [(&str, &Vector3); 2]),
    out: &mut [f64],
) -> Result<(), String> {
    map.scatter(field, values, Target::Rate, true, out)?;
    write_base(map.base(), out, base_parts, base_field)
}

/// The base's six entries of a twist, acceleration or wrench: `parts` are its two vectors,
/// each with its field's name (`linear`, `angular`; `force`, `torque`), linear first.
fn write_base(
    base: Option<(usize, usize)>,
    out: &mut [f64],
    parts: [(&str, &Vector3); 2],
    field: &str,
) -> Result<(), String> {
    let Some((_, v)) = base else { return Ok(()) };
    let [(first, a), (second, b)] = parts;
    let values = [a.x, a.y, a.z, b.x, b.y, b.z];
    if let Some(i) = values.iter().position(|x| !x.is_finite()) {
        let part = if i < 3 { first } else { second };
        let axis = ["x", "y", "z"][i % 3];
        return Err(format!("{field}.{part}.{axis} is {}", values[i]));
    }
    out[v..v + 6].copy_from_slice(&values);
    Ok(())
}

fn write_pose(q: &mut [f64], at: usize, pose: &Pose, field: &str) -> Result<(), String> {
    let (p, o) = (&pose.position, &pose.orientation);
    let values = [p.x, p.y, p.z, o.x, o.y, o.z, o.w];
    if let Some(i) = values.iter().position(|x| !x.is_finite()) {
        return Err(format!(
            "{field}.{} is {}",
            [
                "position.x",
                "position.y",
                "position.z",
                "orientation.x",
                "orientation.y",
                "orientation.z",
                "orientation.w"
            ][i],
            values[i]
        ));
    }
    if !quaternion_is_usable(&values[3..]) {
        return Err(format!(
            "{field}.orientation is (nearly) zero or too large to normalise: give a unit \
             quaternion (w = 1 for none)"
        ));
    }
    q[at..at + 7].copy_from_slice(&values);
    Ok(())
}

/// A command's `field`: one finite value per joint of `names` (the interface's field of
/// `~/joint_commands`, or `~/commands` in command-joint order); `what` says what it holds.
fn check_command_field(
    field: &str,
    values: &[f64],
    names: &[String],
    what: &str,
) -> Result<(), String> {
    if values.len() != names.len() {
        return Err(format!(
            "{field} has {} values for {} joints ({what})",
            values.len(),
            names.len()
        ));
    }
    match values.iter().position(|x| !x.is_finite()) {
        Some(i) => Err(format!(
            "{field}[{i}] (joint '{}') is {}",
            names[i], values[i]
        )),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_example_parameter_file_gives_a_working_node() {
        for entry in std::fs::read_dir("config").unwrap() {
            let path = entry.unwrap().path();
            if path.extension().is_some_and(|e| e == "yaml") {
                let mut settings = Settings::default();
                settings
                    .apply_file(&path, "/", "spatial_dynamics")
                    .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
                let engine = Engine::from_settings(&settings, None)
                    .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
                assert!(!engine.names().is_empty(), "{}", path.display());
            }
        }
    }

    /// A base pose whose quaternion names no rotation (zero, or too small or too large to
    /// normalise, as the library refuses it) is refused where it arrives, naming the field,
    /// and nothing is kept.
    #[test]
    fn a_base_orientation_of_nearly_zero_norm_is_refused() {
        for w in [0.0, 1e-10, -5e-10, 1e200] {
            let mut pose = Pose::default();
            pose.orientation.w = w;
            let mut q = [0.0; 7];
            let e = write_pose(&mut q, 0, &pose, "base_pose").unwrap_err();
            assert!(
                e.contains("base_pose.orientation is (nearly) zero"),
                "{w}: {e}"
            );
            assert_eq!(q, [0.0; 7]);
        }
        let mut pose = Pose::default();
        pose.orientation.w = 2e-9; // normalised by the library
        let mut q = [0.0; 7];
        write_pose(&mut q, 0, &pose, "base_pose").unwrap();
        assert_eq!(q[6], 2e-9);
    }

    /// The residual of a joint state comes with the next one, stamped as the earlier one was;
    /// a bad effort costs the residual only.
    #[test]
    fn effort_residual_is_one_joint_state_late_and_bad_effort_costs_only_it() {
        let mut engine = Engine::from_settings(&Settings::default(), None).unwrap();
        let names: Vec<String> = engine.names().iter().rev().cloned().collect();
        let n = names.len();
        let state = |k: u32, effort: Vec<f64>| JointState {
            header: Header {
                stamp: Time {
                    sec: 7,
                    nanosec: 1_000_000 * k,
                },
                frame_id: "f".into(),
            },
            name: names.clone(),
            position: (0..n).map(|j| 0.1 * j as f64 + 0.01 * k as f64).collect(),
            velocity: vec![0.2; n],
            effort,
        };
        let stamp = |k: u32| Time {
            sec: 100,
            nanosec: k,
        };
        let first = engine
            .joint_states(&state(0, vec![1.0; n]), stamp(0))
            .unwrap();
        assert!(first.residual.is_none() && first.bad_effort.is_none());
        let bad = engine
            .joint_states(&state(1, vec![1.0; n - 1]), stamp(1))
            .unwrap();
        assert!(bad.bad_effort.unwrap().contains("effort has"));
        assert_eq!(bad.gravity.header.stamp, stamp(1));
        // Joint state 0's residual (a forward difference: constant velocities, q̈ = 0).
        let r = bad.residual.unwrap().unwrap();
        assert_eq!(
            (r.header.stamp, r.header.frame_id.as_str()),
            (stamp(0), "f")
        );
        assert_eq!(r.name, names);
        assert_eq!(r.position, state(0, vec![]).position);
        let mut ws = Workspace::new(&engine.model);
        let q: Vec<f64> = state(0, vec![]).position.into_iter().rev().collect();
        let tau = rnea_with(
            &engine.model,
            &mut ws,
            &q,
            &vec![0.2; n],
            &vec![0.0; n],
            &Externals::none(),
        )
        .unwrap()
        .to_vec();
        for (j, x) in r.effort.iter().enumerate() {
            assert!(
                (x - (1.0 - tau[n - 1 - j])).abs() < 1e-9,
                "{:?} vs {tau:?}",
                r.effort
            );
        }
        // Joint state 1's effort was refused: nothing for it when joint state 2 arrives.
        let third = engine.joint_states(&state(2, vec![]), stamp(2)).unwrap();
        assert!(third.residual.is_none() && third.bad_effort.is_none());
    }

    #[test]
    fn world_frame_wrench_turns_axes_but_stays_at_the_link_origin() {
        // A weight on tool0 given in world axes must equal the same force given in tool0's own
        // axes once rotated: compare the two answers at a bent configuration.
        let mut engine = Engine::from_settings(&Settings::default(), None).unwrap();
        let names: Vec<String> = engine.names().to_vec();
        let position = vec![0.3, -0.7, 0.5, 1.1, -0.4, 0.9, 0.2];
        let request = |frame: &str, force: Vector3| InverseDynamicsRequest {
            name: names.clone(),
            position: position.clone(),
            external_wrenches: vec![LinkWrench {
                link: "tool0".into(),
                frame: frame.into(),
                wrench: Wrench {
                    force,
                    torque: Vector3::default(),
                },
            }],
            ..Default::default()
        };
        let world = engine.inverse_dynamics(&request(
            "world",
            Vector3 {
                x: 0.0,
                y: 0.0,
                z: -20.0,
            },
        ));
        assert!(world.success, "{}", world.message);
        // tool0's orientation: the product of the joint rotations (all fixed origins are unrotated).
        let placements = body_placements(&engine.model, &mut engine.ws, &position)
            .unwrap()
            .to_vec();
        let link = engine.model.link("tool0").unwrap().clone();
        let world_to_tool = link.x_body_link.rot * placements[link.body.unwrap()].rot;
        let local = world_to_tool * nalgebra::Vector3::new(0.0, 0.0, -20.0);
        let own = engine.inverse_dynamics(&request("tool0", local.into()));
        let diff: f64 = world
            .effort
            .iter()
            .zip(&own.effort)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(diff < 1e-12, "{:?} vs {:?}", world.effort, own.effort);
        let none = engine.inverse_dynamics(&InverseDynamicsRequest {
            name: names.clone(),
            position: position.clone(),
            ..Default::default()
        });
        assert!(
            world
                .effort
                .iter()
                .zip(&none.effort)
                .any(|(a, b)| (a - b).abs() > 1.0),
            "the wrench must change the effort"
        );
        let bad = engine.inverse_dynamics(&request("elbow_frame", Vector3::default()));
        assert!(
            !bad.success && bad.message.contains("frame 'elbow_frame'"),
            "{}",
            bad.message
        );
    }
}

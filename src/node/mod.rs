//! `spatial_dynamics node`: the dynamics served over ROS 2 (ros2-client on RustDDS).
//!
//! Inputs: `joint_states`, `~/effort_command`, `~/commands`, `~/reference`, `~/base_state`,
//! `robot_description` (latched). Outputs: `~/gravity_effort`, `~/acceleration`,
//! `~/effort_residual` (one joint state late), `~/feedforward_effort`, `~/feedforward_commands`, `/diagnostics`, `/rosout`. Services:
//! `~/inverse_dynamics`, `~/forward_dynamics`, `~/mass_matrix`, `~/describe_model`,
//! `~/frame_kinematics`, and the standard parameter services. In simulate mode (`mode: simulate`)
//! the node also publishes
//! `joint_states`, a floating base's `~/base_state` (and `/clock` if `publish_clock`) from its
//! own integrated state, with ground contact at `ground_contacts` if given, and serves
//! `~/reset`, `~/pause` (std_srvs/SetBool) and `~/step` (std_srvs/Trigger); serve mode creates
//! none of those three publishers. With `use_sim_time`
//! (serve mode) the node reads `/clock` and stamps its outputs with it; the rules are in
//! [`engine::clock`]. QoS (chosen on purpose):
//!
//! | what | reliability | durability | depth |
//! |---|---|---|---|
//! | `joint_states`, `~/base_state` | best effort (matches reliable and best-effort publishers) | volatile | 10 (the `joint_states` reader keeps 1000) |
//! | commands, reference | reliable | volatile | 10 |
//! | outputs, `/diagnostics` | reliable | volatile | 10 |
//! | `robot_description` | reliable | transient local | 1 |
//! | `joint_states`, `~/base_state` (simulate), `/clock` | reliable (matches best-effort readers too) | volatile | 10, 1 |
//! | `/clock` read (`use_sim_time`) | best effort (rclcpp's ClockQoS: matches any publisher) | volatile | 1 |
//! | `/rosout` ([`logging`]) | reliable | transient local, lifespan 10 s | 1000 |
//! | services | reliable | volatile | 10 |

mod engine;
mod health;
pub(crate) mod logging;
mod messages;
mod parameter_descriptors;
mod params;
mod ros_args;

use crate::ros::msgs::*;
use crate::ros::names::NameResolver;
use engine::clock::{self, NodeClock};
use engine::Engine;
use futures::StreamExt;
use health::Health;
use logging::{log, Logger};
use params::Settings;
use ros2_client::dds::rustdds::{DomainParticipantBuilder, Topic};
use ros2_client::qos::{Durability, History, WhenFull};
use ros2_client::{
    Context, Message, MessageTypeName, Name, Node, NodeName, NodeOptions, ParameterValue,
    QosProfile, ROSTime, ServiceMapping, ServiceTypeName, Subscription,
};
use ros_args::RosArgs;
use std::collections::VecDeque;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant, SystemTime};

/// Runs the node until it is stopped. Configuration errors at start-up are returned (and the
/// process exits non-zero); after that, bad input is answered or dropped, never fatal.
pub fn run(args: &[String]) -> Result<(), String> {
    let ros_args = RosArgs::parse(args)?;
    let node_name = ros_args
        .node_name
        .clone()
        .unwrap_or_else(|| "spatial_dynamics".to_string());
    let resolver = NameResolver::new(
        ros_args.namespace.as_deref().unwrap_or("/"),
        &node_name,
        &ros_args.remaps,
    );
    let logger_name = logging::logger_name(resolver.namespace(), &node_name);
    let logger = Logger::new(
        &logger_name,
        logging::level_for(&logger_name, &ros_args.log_levels),
    );
    let mut settings = Settings::default();
    for file in &ros_args.params_files {
        let ignored = settings.apply_file(file, resolver.namespace(), &node_name)?;
        if !ignored.is_empty() {
            // rclcpp ignores overrides of parameters a node does not declare.
            log!(
                logger,
                Warn,
                "--params-file {}: ignoring parameters this node does not have: {} (its parameters: {})",
                file.display(),
                ignored.join(", "),
                params::NAMES.join(", ")
            );
        }
    }
    for (name, value) in &ros_args.params {
        settings.apply_arg(name, value)?;
    }
    let engine = Engine::from_settings(&settings, None)?;
    for warning in engine.model.warnings() {
        log!(logger, Warn, "{warning}");
    }
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .map_err(|e| e.to_string())?;
    runtime.block_on(serve(settings, engine, resolver, node_name, logger))
}

/// The DDS context: `ROS_DOMAIN_ID`, and discovery on loopback only when
/// `ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST` or `ROS_LOCALHOST_ONLY=1`.
fn context() -> Result<Context, String> {
    let domain = match std::env::var("ROS_DOMAIN_ID") {
        Ok(s) if !s.trim().is_empty() => s
            .trim()
            .parse::<u16>()
            .ok()
            .filter(|d| *d <= 232)
            .ok_or_else(|| format!("ROS_DOMAIN_ID '{s}' is not a domain id (0…232)"))?,
        _ => 0,
    };
    let localhost = std::env::var("ROS_AUTOMATIC_DISCOVERY_RANGE").is_ok_and(|v| v == "LOCALHOST")
        || std::env::var("ROS_LOCALHOST_ONLY").is_ok_and(|v| v == "1");
    let mut builder = DomainParticipantBuilder::new(domain);
    if localhost {
        builder = builder.with_only_networks([std::net::Ipv4Addr::LOCALHOST]);
    }
    let participant = builder
        .build()
        .map_err(|e| format!("cannot start DDS on domain {domain}: {e}"))?;
    Context::from_domain_participant(participant)
        .map_err(|e| format!("cannot start ROS 2 context: {e}"))
}

fn qos(reliable: bool, durability: Durability, depth: usize) -> QosProfile {
    let base = QosProfile::publisher_default()
        .durability(durability)
        .history(History::KeepLast { depth });
    if reliable {
        base.reliability_reliable(WhenFull::Wait(Duration::from_millis(100)))
    } else {
        base.reliability_best_effort()
    }
}

/// Messages that leave the node: none may carry a non-finite number.
trait Finite {
    fn all_finite(&self) -> bool;
}

fn finite(x: &[f64]) -> bool {
    x.iter().all(|v| v.is_finite())
}

impl Finite for JointState {
    fn all_finite(&self) -> bool {
        finite(&self.position) && finite(&self.velocity) && finite(&self.effort)
    }
}
impl Finite for JointDynamics {
    fn all_finite(&self) -> bool {
        finite(&self.position)
            && finite(&self.velocity)
            && finite(&self.acceleration)
            && finite(&self.effort)
    }
}
impl Finite for Odometry {
    fn all_finite(&self) -> bool {
        let (p, o, t) = (
            &self.pose.pose.position,
            &self.pose.pose.orientation,
            &self.twist.twist,
        );
        finite(&[p.x, p.y, p.z, o.x, o.y, o.z, o.w])
            && [&t.linear, &t.angular]
                .iter()
                .all(|v| finite(&[v.x, v.y, v.z]))
    }
}
impl Finite for Float64MultiArray {
    fn all_finite(&self) -> bool {
        finite(&self.data)
    }
}

struct Endpoints {
    resolver: NameResolver,
}

/// The node's clock fed from DDS: `use_sim_time` as ros2-client's parameter store holds it (the
/// store keeps that parameter to itself, so it is read before each use), and a `/clock`
/// subscription that exists while simulated time is read from it.
///
/// The node's time for an input is its clock when the input arrived (DDS receive time), not
/// when the node gets to it, so stamps and stamp checks do not depend on how far behind the
/// node is: the wall clock at arrival, or the latest `/clock` received before the input
/// (`/clock` messages received later wait in `pending` for the next input), or in simulate mode
/// the simulated time reached before it (`ticks`: when, by the wall clock, the simulation
/// reached which time).
struct TimeSource {
    clock: NodeClock,
    topic: Topic,
    name: String,
    /// The `/clock` subscription and when it was made (RustDDS may hand a new reader samples
    /// its participant received before, for an earlier reader: those are ignored).
    subscription: Option<(Subscription<Clock>, ROSTime)>,
    /// `/clock` messages read but not yet in effect: (received, time).
    pending: VecDeque<(ROSTime, Time)>,
    /// Simulate mode: (wall clock, simulated time in s) of the latest steps, oldest first.
    ticks: VecDeque<(ROSTime, f64)>,
    shared: Arc<Mutex<Settings>>,
    logger: Logger,
}

/// `/clock` messages the reader keeps between two reads (more than any input gap at 1 kHz).
const CLOCK_READER_DEPTH: usize = 100;

/// `joint_states` messages the reader keeps until the node takes them: 100 ms at 10 kHz.
const JOINT_STATES_READER_DEPTH: usize = 1000;

impl TimeSource {
    /// Simulate mode: the simulation has reached `t` (s) at wall time `at`.
    fn simulated(&mut self, at: ROSTime, t: Option<f64>) {
        if let Some(t) = t {
            if self.ticks.len() == CLOCK_READER_DEPTH {
                self.ticks.pop_front();
            }
            self.ticks.push_back((at, t));
        }
    }

    /// Follows `use_sim_time`, applies the `/clock` messages that arrived before `arrived` (all of
    /// them if `None`), and returns the node's time (ns; `None` while simulated time has not
    /// arrived).
    fn now(
        &mut self,
        node: &mut Node,
        engine: &Engine,
        health: &mut Health,
        arrived: Option<ROSTime>,
    ) -> Option<i64> {
        let wanted = matches!(
            node.get_parameter("use_sim_time"),
            Some(ParameterValue::Boolean(true))
        );
        if wanted != self.clock.use_sim_time() {
            self.clock.set_use_sim_time(wanted);
            if let Ok(mut settings) = self.shared.lock() {
                settings.use_sim_time = wanted;
            }
            log!(
                self.logger,
                Info,
                "parameter 'use_sim_time' now in effect: {wanted}; the node's clock is the {}",
                clock::source_name(wanted, engine.simulated_time().is_some())
            );
        }
        if !self.clock.reads_clock(engine.simulated_time().is_some()) {
            self.subscription = None;
            self.pending.clear();
        } else if self.subscription.is_none() {
            // rclcpp's ClockQoS is best effort, keep last 1; the reader keeps more (a local
            // choice, no effect on matching) so that none is lost between two inputs.
            match node.create_subscription::<Clock>(
                &self.topic,
                Some(qos(false, Durability::Volatile, CLOCK_READER_DEPTH)),
            ) {
                Ok(sub) => self.subscription = Some((sub, node.time_now_not_simulated())),
                Err(e) => health.dropped(&self.name, &format!("cannot subscribe: {e:?}")),
            }
        }
        if let Some((sub, since)) = &self.subscription {
            loop {
                match sub.take() {
                    Ok(Some((message, info))) => {
                        let received = info.received_timestamp().unwrap_or(ROSTime::ZERO);
                        if received >= *since || received == ROSTime::ZERO {
                            health.received(&self.name);
                            self.pending.push_back((received, message.clock));
                        }
                    }
                    Ok(None) => break,
                    Err(e) => {
                        health.dropped(&self.name, &format!("unreadable message: {e:?}"));
                        break;
                    }
                }
            }
        }
        while let Some((received, _)) = self.pending.front() {
            if arrived.is_some_and(|a| *received > a) {
                break;
            }
            let (_, t) = self.pending.pop_front().expect("front exists");
            if let Some(note) = self.clock.clock_received(&t) {
                log!(self.logger, Info, "{note}");
            }
        }
        // Simulate mode: the simulated time reached before the input arrived.
        let simulated = engine.simulated_time().map(|now| {
            arrived
                .and_then(|a| self.ticks.iter().rev().find(|(at, _)| *at <= a))
                .map_or(now, |(_, t)| *t)
        });
        // Wall clock: the input's DDS receive time.
        let wall = arrived
            .and_then(|a| u64::try_from(a.to_nanos()).ok())
            .map_or_else(SystemTime::now, |n| {
                SystemTime::UNIX_EPOCH + Duration::from_nanos(n)
            });
        self.clock.now(wall, simulated)
    }
}

impl Endpoints {
    fn name(&self, name: &str) -> Result<(String, Name), String> {
        let full = self.resolver.resolve(name);
        let parsed = Name::parse(&full).map_err(|e| format!("bad ROS name '{full}': {e:?}"))?;
        Ok((full, parsed))
    }
}

async fn serve(
    settings: Settings,
    engine: Engine,
    resolver: NameResolver,
    node_name: String,
    logger: Logger,
) -> Result<(), String> {
    let context = context()?;
    let shared = Arc::new(Mutex::new(settings));
    let topic_description: Arc<Mutex<Option<String>>> = Arc::new(Mutex::new(None));
    let (changes_tx, mut changes_rx) = tokio::sync::mpsc::unbounded_channel::<String>();

    // The node's own /rosout publisher (below) has rcl's rosout QoS; ros2-client's keeps 1 line.
    let mut options = NodeOptions::new()
        .enable_rosout(false)
        .start_parameter_services(true);
    for (name, value) in shared.lock().expect("settings lock").values() {
        options = options
            .describe_parameter(parameter_descriptors::descriptor(name, &value))
            .declare_parameter(name, value);
    }
    let (validator_settings, validator_description) = (shared.clone(), topic_description.clone());
    options = options.parameter_validator(Box::new(move |name, value| {
        if !params::NAMES.contains(&name) {
            return Ok(());
        }
        let mut candidate = validator_settings
            .lock()
            .map_err(|e| e.to_string())?
            .clone();
        candidate.set(name, value)?;
        if params::MODEL_PARAMETERS.contains(&name) || name == "command_joints" {
            let description = validator_description
                .lock()
                .map_err(|e| e.to_string())?
                .clone();
            // Choosing a method never fails (auto falls back to aba), so the candidate skips
            // auto's measurements: the set action that follows measures once, for real.
            candidate.method = Some(spatial_dynamics_core::ForwardDynamicsMethod::Aba);
            Engine::from_settings(&candidate, description.as_deref())?;
        }
        Ok(())
    }));
    let action_settings = shared.clone();
    options = options.parameter_set_action(Box::new(move |name, value| {
        if params::NAMES.contains(&name) {
            let mut settings = action_settings.lock().map_err(|e| e.to_string())?;
            if settings.get(name).as_ref() != Some(value) {
                settings.set(name, value)?;
                let _ = changes_tx.send(name.to_string());
            }
        }
        Ok(())
    }));
    let ns = resolver.namespace().to_string();
    let mut node: Node = context
        .new_node(
            NodeName::new(&ns, &node_name)
                .map_err(|e| format!("bad node name '{ns}/{node_name}': {e:?}"))?,
            options,
        )
        .map_err(|e| format!("cannot create node: {e:?}"))?;
    let ends = Endpoints { resolver };
    let rosout_qos = QosProfile {
        lifespan: Some(Duration::from_secs(10)),
        ..qos(true, Durability::TransientLocal, logging::ROSOUT_DEPTH)
    };
    logger.attach(
        node.create_publisher::<Log>(&context.get_rosout_topic(), Some(rosout_qos))
            .map_err(|e| format!("publisher /rosout: {e:?}"))?,
    );

    macro_rules! topic {
        ($name:expr, $pkg:expr, $ty:expr, $qos:expr) => {{
            let (full, name) = ends.name($name)?;
            let topic = node
                .create_topic(&name, MessageTypeName::new($pkg, $ty), &$qos)
                .map_err(|e| format!("topic {full}: {e:?}"))?;
            (full, topic)
        }};
    }
    macro_rules! subscription {
        ($t:ty, $name:expr, $pkg:expr, $ty:expr, $qos:expr) => {{
            let (full, topic) = topic!($name, $pkg, $ty, $qos);
            let sub = node
                .create_subscription::<$t>(&topic, None)
                .map_err(|e| format!("subscription {full}: {e:?}"))?;
            (full, sub)
        }};
    }
    macro_rules! publisher {
        ($t:ty, $name:expr, $pkg:expr, $ty:expr, $qos:expr) => {{
            let (full, topic) = topic!($name, $pkg, $ty, $qos);
            let publisher = node
                .create_publisher::<$t>(&topic, None)
                .map_err(|e| format!("publisher {full}: {e:?}"))?;
            (full, publisher)
        }};
    }
    macro_rules! service_in {
        ($pkg:expr, $req:ty, $resp:ty, $name:expr, $ty:expr) => {{
            let (full, name) = ends.name($name)?;
            let q = qos(true, Durability::Volatile, 10);
            let server = node
                .create_server::<$req, $resp>(
                    ServiceMapping::Enhanced,
                    &name,
                    &ServiceTypeName::new($pkg, $ty),
                    q.clone(),
                    q,
                )
                .map_err(|e| format!("service {full}: {e:?}"))?;
            (full, server)
        }};
    }
    macro_rules! server {
        ($req:ty, $resp:ty, $name:expr, $ty:expr) => {
            service_in!("spatial_dynamics_msgs", $req, $resp, $name, $ty)
        };
    }
    macro_rules! std_server {
        ($req:ty, $resp:ty, $name:expr, $ty:expr) => {
            service_in!("std_srvs", $req, $resp, $name, $ty)
        };
    }

    let sensor = qos(false, Durability::Volatile, 10);
    let reliable = qos(true, Durability::Volatile, 10);
    let latched = qos(true, Durability::TransientLocal, 1);
    let (js_name, js_topic) = topic!("joint_states", "sensor_msgs", "JointState", sensor);
    // The reader keeps more than the topic's depth (a local choice, no effect on matching): at
    // 10 kHz a reader that keeps 64 loses every input that arrives while the node is held up for
    // more than ~6 ms, as it is on a loaded machine (README, "Soak").
    let js_sub = node
        .create_subscription::<JointState>(
            &js_topic,
            Some(qos(false, Durability::Volatile, JOINT_STATES_READER_DEPTH)),
        )
        .map_err(|e| format!("subscription {js_name}: {e:?}"))?;
    let (effort_name, effort_sub) = subscription!(
        JointState,
        "~/effort_command",
        "sensor_msgs",
        "JointState",
        reliable
    );
    let (commands_name, commands_sub) = subscription!(
        Float64MultiArray,
        "~/commands",
        "std_msgs",
        "Float64MultiArray",
        reliable
    );
    let (reference_name, reference_sub) = subscription!(
        JointTrajectory,
        "~/reference",
        "trajectory_msgs",
        "JointTrajectory",
        reliable
    );
    let (base_name, base_sub) =
        subscription!(Odometry, "~/base_state", "nav_msgs", "Odometry", sensor);
    let (description_name, description_sub) = subscription!(
        StringMsg,
        "robot_description",
        "std_msgs",
        "String",
        latched
    );
    let (gravity_name, gravity_pub) = publisher!(
        JointState,
        "~/gravity_effort",
        "sensor_msgs",
        "JointState",
        reliable
    );
    let (accel_name, accel_pub) = publisher!(
        JointDynamics,
        "~/acceleration",
        "spatial_dynamics_msgs",
        "JointDynamics",
        reliable
    );
    let (residual_name, residual_pub) = publisher!(
        JointState,
        "~/effort_residual",
        "sensor_msgs",
        "JointState",
        reliable
    );
    let (ff_name, ff_pub) = publisher!(
        JointState,
        "~/feedforward_effort",
        "sensor_msgs",
        "JointState",
        reliable
    );
    let (ffc_name, ffc_pub) = publisher!(
        Float64MultiArray,
        "~/feedforward_commands",
        "std_msgs",
        "Float64MultiArray",
        reliable
    );
    let (_, diag_pub) = publisher!(
        DiagnosticArray,
        "/diagnostics",
        "diagnostic_msgs",
        "DiagnosticArray",
        reliable
    );
    let (id_name, id_server) = server!(
        InverseDynamicsRequest,
        InverseDynamicsResponse,
        "~/inverse_dynamics",
        "InverseDynamics"
    );
    let (fd_name, fd_server) = server!(
        ForwardDynamicsRequest,
        ForwardDynamicsResponse,
        "~/forward_dynamics",
        "ForwardDynamics"
    );
    let (mm_name, mm_server) = server!(
        MassMatrixRequest,
        MassMatrixResponse,
        "~/mass_matrix",
        "MassMatrix"
    );
    let (dm_name, dm_server) = server!(
        DescribeModelRequest,
        DescribeModelResponse,
        "~/describe_model",
        "DescribeModel"
    );
    let (fk_name, fk_server) = server!(
        FrameKinematicsRequest,
        FrameKinematicsResponse,
        "~/frame_kinematics",
        "FrameKinematics"
    );
    let (clock_name, clock_topic) = topic!(
        "/clock",
        "rosgraph_msgs",
        "Clock",
        qos(true, Durability::Volatile, 1)
    );
    // Only simulate mode publishes joint_states, /clock and ~/base_state (`mode` is read-only):
    // a serve-mode node must not look like a second source of them in the graph.
    let sim_out = if shared.lock().map_err(|e| e.to_string())?.simulate {
        let (sim_js_name, sim_js_pub) = publisher!(
            JointState,
            "joint_states",
            "sensor_msgs",
            "JointState",
            reliable
        );
        let clock_pub = node
            .create_publisher::<Clock>(&clock_topic, None)
            .map_err(|e| format!("publisher {clock_name}: {e:?}"))?;
        let (sim_base_name, sim_base_pub) =
            publisher!(Odometry, "~/base_state", "nav_msgs", "Odometry", reliable);
        Some(SimPublishers {
            joint_states: (sim_js_name, sim_js_pub),
            base: (sim_base_name, sim_base_pub),
            clock: clock_pub,
            logger: logger.clone(),
        })
    } else {
        None
    };
    let (reset_name, reset_server) = server!(ResetRequest, ResetResponse, "~/reset", "Reset");
    let (pause_name, pause_server) =
        std_server!(SetBoolRequest, SetBoolResponse, "~/pause", "SetBool");
    let (step_name, step_server) =
        std_server!(TriggerRequest, TriggerResponse, "~/step", "Trigger");

    let spinner = node
        .spinner()
        .map_err(|e| format!("cannot start the spinner: {e:?}"))?;
    tokio::spawn(spinner.spin());

    let mut engine = engine;
    // Why the latest robot description from the topic was ignored, once logged.
    let mut ignored_description: Option<String> = None;
    let mut health = Health::new(logger.clone());
    let mut time = TimeSource {
        clock: NodeClock::new(&*shared.lock().map_err(|e| e.to_string())?),
        topic: clock_topic,
        name: clock_name,
        subscription: None,
        pending: VecDeque::with_capacity(CLOCK_READER_DEPTH),
        ticks: VecDeque::with_capacity(CLOCK_READER_DEPTH),
        shared: shared.clone(),
        logger: logger.clone(),
    };
    // Subscribes to /clock now if simulated time is on, so that discovery starts at once.
    time.now(&mut node, &engine, &mut health, None);
    // diagnostic_updater's status name: the node's name (no namespace, no slash), ": ", the task.
    let diagnostics_name = format!("{node_name}: dynamics");
    log!(
        logger,
        Info,
        "{} serving robot '{}' ({} joints, nv = {}), method {}{}",
        node.fully_qualified_name(),
        engine.model.name(),
        engine.names().len(),
        engine.model.nv(),
        engine.method,
        engine.method_choice.as_ref().map_or(String::new(), |c| format!(
            ", chosen by FLOP count among the methods agreeing with aba; timings for information only ({c})"
        ))
    );

    let js_stream = js_sub.async_stream();
    let effort_stream = effort_sub.async_stream();
    let commands_stream = commands_sub.async_stream();
    let reference_stream = reference_sub.async_stream();
    let base_stream = base_sub.async_stream();
    let description_stream = description_sub.async_stream();
    let id_stream = id_server.receive_request_stream();
    let fd_stream = fd_server.receive_request_stream();
    let mm_stream = mm_server.receive_request_stream();
    let dm_stream = dm_server.receive_request_stream();
    let fk_stream = fk_server.receive_request_stream();
    let reset_stream = reset_server.receive_request_stream();
    let pause_stream = pause_server.receive_request_stream();
    let step_stream = step_server.receive_request_stream();
    futures::pin_mut!(
        js_stream,
        effort_stream,
        commands_stream,
        reference_stream,
        base_stream,
        description_stream,
        id_stream,
        fd_stream,
        mm_stream,
        dm_stream,
        fk_stream,
        reset_stream,
        pause_stream,
        step_stream
    );
    let mut diagnostics = tokio::time::interval(Duration::from_secs(1));
    let publish_clock =
        |settings: &Arc<Mutex<Settings>>| settings.lock().map(|s| s.publish_clock).unwrap_or(false);
    let mut sim_timer = simulation_timer(&engine);

    // SIGINT and SIGTERM end the loop; dropping the node then leaves the DDS graph cleanly.
    let mut terminate = tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate())
        .map_err(|e| e.to_string())?;
    loop {
        tokio::select! {
            _ = tokio::signal::ctrl_c() => break,
            _ = terminate.recv() => break,
            Some(item) = js_stream.next() => {
                health.received(&js_name);
                let arrived = item.as_ref().ok().and_then(|(_, info)| info.received_timestamp());
                let now = time.now(&mut node, &engine, &mut health, arrived);
                let started = Instant::now();
                match item.map_err(|e| format!("unreadable message: {e:?}")).and_then(|(js, _)| {
                    let stamp = time.clock.admit(&js.header.stamp, now)?;
                    engine.joint_states(&js, stamp)
                }) {
                    Ok(answer) => {
                        health.computed(started.elapsed());
                        send(&gravity_pub, answer.gravity, &gravity_name, &mut health);
                        send(&accel_pub, answer.acceleration, &accel_name, &mut health);
                        match answer.residual {
                            Some(Ok(r)) => send(&residual_pub, r, &residual_name, &mut health),
                            Some(Err(e)) => health.dropped(&residual_name, &e),
                            None => {}
                        }
                        if let Some(e) = answer.bad_effort {
                            health.dropped(&residual_name, &e);
                        }
                    }
                    Err(e) => health.dropped(&js_name, &e),
                }
            }
            Some(item) = effort_stream.next() => {
                health.received(&effort_name);
                if let Err(e) = item.map_err(|e| format!("unreadable message: {e:?}")).and_then(|(m, _)| engine.set_effort_command(&m)) {
                    health.dropped(&effort_name, &e);
                }
            }
            Some(item) = commands_stream.next() => {
                health.received(&commands_name);
                if let Err(e) = item.map_err(|e| format!("unreadable message: {e:?}")).and_then(|(m, _)| engine.set_commands(&m)) {
                    health.dropped(&commands_name, &e);
                }
            }
            Some(item) = reference_stream.next() => {
                health.received(&reference_name);
                let arrived = item.as_ref().ok().and_then(|(_, info)| info.received_timestamp());
                let now = time.now(&mut node, &engine, &mut health, arrived);
                let started = Instant::now();
                match item.map_err(|e| format!("unreadable message: {e:?}")).and_then(|(m, _)| {
                    let stamp = time.clock.output_stamp(&m.header.stamp, now)?;
                    let (mut effort, commands) = engine.reference(&m)?;
                    effort.header.stamp = stamp;
                    Ok((effort, commands))
                }) {
                    Ok((effort, commands)) => {
                        health.computed(started.elapsed());
                        send(&ff_pub, effort, &ff_name, &mut health);
                        send(&ffc_pub, commands, &ffc_name, &mut health);
                    }
                    Err(e) => health.dropped(&reference_name, &e),
                }
            }
            Some(item) = base_stream.next() => {
                health.received(&base_name);
                if let Err(e) = item.map_err(|e| format!("unreadable message: {e:?}")).and_then(|(m, _)| engine.set_base_state(&m)) {
                    health.dropped(&base_name, &e);
                }
            }
            Some(item) = description_stream.next() => {
                health.received(&description_name);
                match item {
                    Ok((m, _)) => {
                        let settings = shared.lock().map_err(|e| e.to_string())?.clone();
                        match Engine::from_settings(&settings, Some(&m.data)) {
                            Ok(new) => {
                                *topic_description.lock().map_err(|e| e.to_string())? = Some(m.data);
                                if new.source == engine::ModelSource::Topic {
                                    log!(logger, Info, "loaded robot '{}' from {description_name}", new.model.name());
                                    engine = new;
                                } else {
                                    let why = match &new.source {
                                        engine::ModelSource::Parameter => "the robot_description parameter is set".to_string(),
                                        engine::ModelSource::File(f) => format!("urdf_file is set ({f})"),
                                        _ => "another source is in use".to_string(),
                                    };
                                    if ignored_description.as_ref() != Some(&why) {
                                        log!(logger, Info, "ignoring the robot description on {description_name}: {why}, and it wins over the topic (the topic's description is used once neither robot_description nor urdf_file is set)");
                                        ignored_description = Some(why);
                                    }
                                }
                            }
                            Err(e) => health.dropped(&description_name, &format!("unusable robot description, keeping robot '{}': {e}", engine.model.name())),
                        }
                    }
                    Err(e) => health.dropped(&description_name, &format!("unreadable message: {e:?}")),
                }
            }
            Some(item) = id_stream.next() => {
                if let Ok((id, request)) = item {
                    let mut response = engine.inverse_dynamics(&request);
                    if !(finite(&response.effort) && [response.base_wrench.force.x, response.base_wrench.force.y, response.base_wrench.force.z, response.base_wrench.torque.x, response.base_wrench.torque.y, response.base_wrench.torque.z].iter().all(|x| x.is_finite())) {
                        response = InverseDynamicsResponse { message: "the result was not finite".into(), ..Default::default() };
                    }
                    if let Err(e) = id_server.send_response(id, response) { health.dropped(&id_name, &format!("response not sent: {e:?}")); }
                } else { health.dropped(&id_name, "unreadable request"); }
            }
            Some(item) = fd_stream.next() => {
                if let Ok((id, request)) = item {
                    let mut response = engine.forward_dynamics(&request);
                    if !finite(&response.acceleration) {
                        response = ForwardDynamicsResponse { message: "the result was not finite".into(), ..Default::default() };
                    }
                    if let Err(e) = fd_server.send_response(id, response) { health.dropped(&fd_name, &format!("response not sent: {e:?}")); }
                } else { health.dropped(&fd_name, "unreadable request"); }
            }
            Some(item) = mm_stream.next() => {
                if let Ok((id, request)) = item {
                    let mut response = engine.mass_matrix(&request);
                    if !finite(&response.matrix) {
                        response = MassMatrixResponse { message: "the result was not finite".into(), ..Default::default() };
                    }
                    if let Err(e) = mm_server.send_response(id, response) { health.dropped(&mm_name, &format!("response not sent: {e:?}")); }
                } else { health.dropped(&mm_name, "unreadable request"); }
            }
            Some(item) = fk_stream.next() => {
                if let Ok((id, request)) = item {
                    if let Err(e) = fk_server.send_response(id, engine.frame_kinematics(&request)) { health.dropped(&fk_name, &format!("response not sent: {e:?}")); }
                } else { health.dropped(&fk_name, "unreadable request"); }
            }
            Some(item) = dm_stream.next() => {
                if let Ok((id, _)) = item {
                    if let Err(e) = dm_server.send_response(id, engine.describe()) { health.dropped(&dm_name, &format!("response not sent: {e:?}")); }
                } else { health.dropped(&dm_name, "unreadable request"); }
            }
            _ = async { sim_timer.as_mut().expect("guarded").tick().await }, if sim_timer.is_some() => {
                let tick = engine.simulation_tick(Instant::now());
                time.simulated(node.time_now_not_simulated(), engine.simulated_time());
                if let Some(out) = &sim_out {
                    out.publish(tick, engine.simulated_base_state(), publish_clock(&shared), &mut health);
                }
            }
            Some(item) = reset_stream.next() => {
                if let Ok((id, request)) = item {
                    if let Err(e) = reset_server.send_response(id, engine.simulation_reset(&request)) { health.dropped(&reset_name, &format!("response not sent: {e:?}")); }
                } else { health.dropped(&reset_name, "unreadable request"); }
            }
            Some(item) = pause_stream.next() => {
                if let Ok((id, request)) = item {
                    let response = match engine.simulation_pause(request.data) {
                        Ok(message) => SetBoolResponse { success: true, message },
                        Err(message) => SetBoolResponse { success: false, message },
                    };
                    if let Err(e) = pause_server.send_response(id, response) { health.dropped(&pause_name, &format!("response not sent: {e:?}")); }
                } else { health.dropped(&pause_name, "unreadable request"); }
            }
            Some(item) = step_stream.next() => {
                if let Ok((id, _)) = item {
                    let stepped = engine.simulation_step(Instant::now());
                    time.simulated(node.time_now_not_simulated(), engine.simulated_time());
                    let response = match &stepped {
                        Ok((_, stamp)) => TriggerResponse { success: true, message: format!("t = {}.{:09} s", stamp.sec, stamp.nanosec) },
                        Err(message) => TriggerResponse { success: false, message: message.clone() },
                    };
                    if let (true, Some(out)) = (stepped.is_ok(), &sim_out) {
                        out.publish(Some(stepped), engine.simulated_base_state(), publish_clock(&shared), &mut health);
                    }
                    if let Err(e) = step_server.send_response(id, response) { health.dropped(&step_name, &format!("response not sent: {e:?}")); }
                } else { health.dropped(&step_name, "unreadable request"); }
            }
            Some(name) = changes_rx.recv() => {
                let settings = shared.lock().map_err(|e| e.to_string())?.clone();
                if name == "method" {
                    engine.set_method(settings.method);
                } else if name == "publish_clock" {
                    // Read at each simulation tick.
                } else if params::TIME_PARAMETERS.contains(&name.as_str()) {
                    time.clock.configure(&settings);
                } else {
                    let description = topic_description.lock().map_err(|e| e.to_string())?.clone();
                    match Engine::from_settings(&settings, description.as_deref()) {
                        Ok(new) => engine = new,
                        Err(e) => log!(logger, Error, "parameter '{name}' was accepted but the model could not be rebuilt, keeping robot '{}': {e}", engine.model.name()),
                    }
                }
                sim_timer = simulation_timer(&engine);
                time.ticks.clear();
                log!(logger, Info, "parameter '{name}' now in effect");
            }
            _ = diagnostics.tick() => {
                let now = time.now(&mut node, &engine, &mut health, None);
                let stamp = NodeClock::stamp(now);
                let mut status = health.report(&diagnostics_name, engine.model.name(), true);
                status.values.push(KeyValue { key: "clock".into(), value: clock::source_name(time.clock.use_sim_time(), engine.simulated_time().is_some()).into() });
                status.values.push(KeyValue { key: "clock time (s)".into(), value: now.map_or_else(|| "none yet".into(), |n| format!("{:.9}", n as f64 * 1e-9)) });
                if let Some((t, rtf, paused, diverged, clamped)) = engine.simulation_status() {
                    status.values.push(KeyValue { key: "simulated time (s)".into(), value: format!("{t:.6}") });
                    status.values.push(KeyValue { key: "real-time factor".into(), value: format!("{rtf:.3}") });
                    status.values.push(KeyValue { key: "paused".into(), value: paused.to_string() });
                    status.values.push(KeyValue { key: "efforts clamped".into(), value: clamped.to_string() });
                    if let Some(depth) = engine.simulated_penetration() {
                        status.values.push(KeyValue { key: "deepest ground penetration (m)".into(), value: format!("{depth:.6}") });
                    }
                    if let Some(why) = diverged {
                        status.level = 2;
                        status.message = why;
                    }
                }
                let _ = diag_pub.publish(DiagnosticArray { header: Header { stamp, frame_id: String::new() }, status: vec![status] });
            }
        }
    }
    log!(logger, Info, "shutting down");
    Ok(())
}

/// Publishes a message if every number in it is finite; counts what happened.
fn send<M: Message + Finite + std::fmt::Debug>(
    publisher: &ros2_client::Publisher<M>,
    message: M,
    topic: &str,
    health: &mut Health,
) {
    if !message.all_finite() {
        health.dropped(topic, "output held back: it contained a non-finite number");
    } else if let Err(e) = publisher.publish(message) {
        health.dropped(topic, &format!("publish failed: {e:?}"));
    } else {
        health.published(topic);
    }
}

/// The publish timer of simulate mode (none in serve mode).
fn simulation_timer(engine: &Engine) -> Option<tokio::time::Interval> {
    engine.simulation_period().map(|period| {
        let mut timer = tokio::time::interval(period);
        timer.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        timer
    })
}

/// Simulate mode's outputs: `joint_states`, the floating base on `~/base_state`, `/clock`.
struct SimPublishers {
    joint_states: (String, ros2_client::Publisher<JointState>),
    base: (String, ros2_client::Publisher<Odometry>),
    clock: ros2_client::Publisher<Clock>,
    logger: Logger,
}

impl SimPublishers {
    /// Publishes a tick's `joint_states` (with the base's state, and `/clock` when asked), or
    /// reports why the simulation stopped.
    fn publish(
        &self,
        tick: Option<Result<(JointState, Time), String>>,
        base: Option<Odometry>,
        publish_clock: bool,
        health: &mut Health,
    ) {
        match tick {
            None => {}
            Some(Ok((js, stamp))) => {
                if publish_clock {
                    let _ = self.clock.publish(Clock { clock: stamp });
                }
                send(&self.joint_states.1, js, &self.joint_states.0, health);
                if let Some(odometry) = base {
                    send(&self.base.1, odometry, &self.base.0, health);
                }
            }
            Some(Err(why)) => log!(self.logger, Error, "{why}"),
        }
    }
}

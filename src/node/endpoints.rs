//! The node's ROS plumbing: the DDS context, the QoS of each endpoint, the topics, publishers,
//! subscriptions and service servers, and the sending of what the handlers
//! ([`super::handlers`]) return. No dynamics here.

use super::handlers::{Names, NodeState, Outputs};
use super::health::Health;
use super::logging;
use crate::ros::msgs::*;
use ros2_client::dds::rustdds::{DomainParticipantBuilder, Topic};
use ros2_client::qos::{Durability, History, WhenFull};
use ros2_client::{
    Context, Message, MessageInfo, MessageTypeName, Name, Node, Publisher, QosProfile, ROSTime,
    RmwRequestId, Server, ServiceMapping, ServiceTypeName, Subscription,
};
use std::fmt::Debug;
use std::time::Duration;

/// `/clock` messages the reader keeps between two reads (more than any input gap at 1 kHz).
pub const CLOCK_READER_DEPTH: usize = 100;

/// `joint_states` messages the reader keeps until the node takes them: 100 ms at 10 kHz.
const JOINT_STATES_READER_DEPTH: usize = 1000;

/// Commands (`~/commands`, `~/joint_commands`, `~/effort_command`) the readers keep until the
/// node takes them.
const COMMAND_READER_DEPTH: usize = 1000;

/// The DDS context: `ROS_DOMAIN_ID`, and discovery on loopback only when
/// `ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST` or `ROS_LOCALHOST_ONLY=1`.
pub fn context() -> Result<Context, String> {
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

/// A QoS profile: reliable (a writer waits up to 100 ms when the reader's history is full) or
/// best effort, with this durability, keeping the last `depth` messages.
pub fn qos(reliable: bool, durability: Durability, depth: usize) -> QosProfile {
    let base = QosProfile::publisher_default()
        .durability(durability)
        .history(History::KeepLast { depth });
    if reliable {
        base.reliability_reliable(WhenFull::Wait(Duration::from_millis(100)))
    } else {
        base.reliability_best_effort()
    }
}

/// rcl's rosout QoS: reliable, transient local, keep last [`logging::ROSOUT_DEPTH`], lifespan 10 s.
pub fn rosout_qos() -> QosProfile {
    QosProfile {
        lifespan: Some(Duration::from_secs(10)),
        ..qos(true, Durability::TransientLocal, logging::ROSOUT_DEPTH)
    }
}

/// A message type: its package and name (`("sensor_msgs", "JointState")`).
type TypeName = (&'static str, &'static str);

const JOINT_STATE: TypeName = ("sensor_msgs", "JointState");
const ODOMETRY: TypeName = ("nav_msgs", "Odometry");
const MULTI_ARRAY: TypeName = ("std_msgs", "Float64MultiArray");

/// A topic of the node's, by full name.
pub fn topic(
    node: &Node,
    full: &str,
    (package, ty): TypeName,
    qos: &QosProfile,
) -> Result<Topic, String> {
    let name = Name::parse(full).map_err(|e| format!("bad ROS name '{full}': {e:?}"))?;
    node.create_topic(&name, MessageTypeName::new(package, ty), qos)
        .map_err(|e| format!("topic {full}: {e:?}"))
}

/// A subscription to a new topic; the reader takes the topic's QoS unless `reader` is given.
fn subscription<M: 'static>(
    node: &mut Node,
    full: &str,
    ty: TypeName,
    qos: &QosProfile,
    reader: Option<QosProfile>,
) -> Result<Subscription<M>, String> {
    let topic = topic(node, full, ty, qos)?;
    node.create_subscription::<M>(&topic, reader)
        .map_err(|e| format!("subscription {full}: {e:?}"))
}

/// A publisher on a new topic, with the topic's QoS.
fn publisher<M: serde::Serialize>(
    node: &mut Node,
    full: &str,
    ty: TypeName,
    qos: &QosProfile,
) -> Result<Publisher<M>, String> {
    let topic = topic(node, full, ty, qos)?;
    publisher_on(node, &topic, full)
}

fn publisher_on<M: serde::Serialize>(
    node: &mut Node,
    topic: &Topic,
    full: &str,
) -> Result<Publisher<M>, String> {
    node.create_publisher::<M>(topic, None)
        .map_err(|e| format!("publisher {full}: {e:?}"))
}

/// A service server (reliable, volatile, depth 10 both ways) of type `package/srv/ty`.
fn server<Req: Message + Clone + 'static, Resp: Message + 'static>(
    node: &mut Node,
    full: &str,
    (package, ty): TypeName,
) -> Result<Server<Req, Resp>, String> {
    let name = Name::parse(full).map_err(|e| format!("bad ROS name '{full}': {e:?}"))?;
    let q = qos(true, Durability::Volatile, 10);
    node.create_server::<Req, Resp>(
        ServiceMapping::Enhanced,
        &name,
        &ServiceTypeName::new(package, ty),
        q.clone(),
        q,
    )
    .map_err(|e| format!("service {full}: {e:?}"))
}

/// The node's topics and services.
pub struct Endpoints {
    pub joint_states: Subscription<JointState>,
    pub effort_command: Subscription<JointState>,
    pub commands: Subscription<Float64MultiArray>,
    pub joint_commands: Subscription<JointState>,
    pub reference: Subscription<JointTrajectory>,
    pub base_state: Subscription<Odometry>,
    pub robot_description: Subscription<StringMsg>,
    gravity: Publisher<JointState>,
    acceleration: Publisher<JointDynamics>,
    residual: Publisher<JointState>,
    feedforward_effort: Publisher<JointState>,
    feedforward_commands: Publisher<Float64MultiArray>,
    diagnostics: Publisher<DiagnosticArray>,
    /// Simulate mode's outputs (none in serve mode).
    simulation: Option<SimulationPublishers>,
    pub inverse_dynamics: Server<InverseDynamicsRequest, InverseDynamicsResponse>,
    pub forward_dynamics: Server<ForwardDynamicsRequest, ForwardDynamicsResponse>,
    pub mass_matrix: Server<MassMatrixRequest, MassMatrixResponse>,
    pub describe_model: Server<DescribeModelRequest, DescribeModelResponse>,
    pub frame_kinematics: Server<FrameKinematicsRequest, FrameKinematicsResponse>,
    pub linearize: Server<LinearizeRequest, LinearizeResponse>,
    pub reset: Server<ResetRequest, ResetResponse>,
    pub pause: Server<SetBoolRequest, SetBoolResponse>,
    pub step: Server<TriggerRequest, TriggerResponse>,
    /// `/clock`: read with `use_sim_time` ([`super::time_source`]), published in simulate mode.
    pub clock_topic: Topic,
}

/// Simulate mode's outputs: `joint_states`, the floating base on `~/base_state` and `/tf`,
/// `/clock`.
struct SimulationPublishers {
    joint_states: Publisher<JointState>,
    base_state: Publisher<Odometry>,
    clock: Publisher<Clock>,
    /// `/tf`, QoS as tf2's broadcaster: reliable, volatile, depth 100.
    tf: Publisher<TFMessage>,
}

impl Endpoints {
    /// Creates the node's topics and services under `names`; `simulate`: also simulate mode's
    /// publishers of `joint_states`, `~/base_state` and `/clock` (a serve-mode node must not
    /// look like a second source of them in the graph).
    pub fn create(node: &mut Node, names: &Names, simulate: bool) -> Result<Endpoints, String> {
        let sensor = qos(false, Durability::Volatile, 10);
        let reliable = qos(true, Durability::Volatile, 10);
        let latched = qos(true, Durability::TransientLocal, 1);
        let dynamics = |ty| ("spatial_dynamics_msgs", ty);
        // The joint_states reader keeps more than the topic's depth (a local choice, no effect
        // on matching): at 10 kHz a reader that keeps 64 loses every input that arrives while
        // the node is held up for more than ~6 ms, as it is on a loaded machine (docs/node.md, "Soak").
        let joint_states = subscription(
            node,
            &names.joint_states,
            JOINT_STATE,
            &sensor,
            Some(qos(false, Durability::Volatile, JOINT_STATES_READER_DEPTH)),
        )?;
        // So do the command readers: in lockstep every command is a step, and a burst of them
        // (a controller running faster than the node reads) must not lose any to the depth.
        let commands_reader = Some(qos(true, Durability::Volatile, COMMAND_READER_DEPTH));
        let effort_command = subscription(
            node,
            &names.effort_command,
            JOINT_STATE,
            &reliable,
            commands_reader.clone(),
        )?;
        let commands = subscription(
            node,
            &names.commands,
            MULTI_ARRAY,
            &reliable,
            commands_reader.clone(),
        )?;
        let joint_commands = subscription(
            node,
            &names.joint_commands,
            JOINT_STATE,
            &reliable,
            commands_reader,
        )?;
        let reference = subscription(
            node,
            &names.reference,
            ("trajectory_msgs", "JointTrajectory"),
            &reliable,
            None,
        )?;
        let base_state = subscription(node, &names.base_state, ODOMETRY, &sensor, None)?;
        let robot_description = subscription(
            node,
            &names.robot_description,
            ("std_msgs", "String"),
            &latched,
            None,
        )?;
        let gravity = publisher(node, &names.gravity, JOINT_STATE, &reliable)?;
        let acceleration = publisher(
            node,
            &names.acceleration,
            dynamics("JointDynamics"),
            &reliable,
        )?;
        let residual = publisher(node, &names.residual, JOINT_STATE, &reliable)?;
        let feedforward_effort =
            publisher(node, &names.feedforward_effort, JOINT_STATE, &reliable)?;
        let feedforward_commands =
            publisher(node, &names.feedforward_commands, MULTI_ARRAY, &reliable)?;
        let diagnostics = publisher(
            node,
            &names.diagnostics,
            ("diagnostic_msgs", "DiagnosticArray"),
            &reliable,
        )?;
        let inverse_dynamics = server(node, &names.inverse_dynamics, dynamics("InverseDynamics"))?;
        let forward_dynamics = server(node, &names.forward_dynamics, dynamics("ForwardDynamics"))?;
        let mass_matrix = server(node, &names.mass_matrix, dynamics("MassMatrix"))?;
        let describe_model = server(node, &names.describe_model, dynamics("DescribeModel"))?;
        let frame_kinematics = server(node, &names.frame_kinematics, dynamics("FrameKinematics"))?;
        let linearize = server(node, &names.linearize, dynamics("Linearize"))?;
        let clock_topic = topic(
            node,
            &names.clock,
            ("rosgraph_msgs", "Clock"),
            &qos(true, Durability::Volatile, 1),
        )?;
        let simulation = if simulate {
            Some(SimulationPublishers {
                joint_states: publisher(node, &names.joint_states, JOINT_STATE, &reliable)?,
                clock: publisher_on(node, &clock_topic, &names.clock)?,
                base_state: publisher(node, &names.base_state, ODOMETRY, &reliable)?,
                tf: publisher(
                    node,
                    &names.tf,
                    ("tf2_msgs", "TFMessage"),
                    &qos(true, Durability::Volatile, 100),
                )?,
            })
        } else {
            None
        };
        Ok(Endpoints {
            joint_states,
            effort_command,
            commands,
            joint_commands,
            reference,
            base_state,
            robot_description,
            gravity,
            acceleration,
            residual,
            feedforward_effort,
            feedforward_commands,
            diagnostics,
            simulation,
            inverse_dynamics,
            forward_dynamics,
            mass_matrix,
            describe_model,
            frame_kinematics,
            linearize,
            reset: server(node, &names.reset, dynamics("Reset"))?,
            pause: server(node, &names.pause, ("std_srvs", "SetBool"))?,
            step: server(node, &names.step, ("std_srvs", "Trigger"))?,
            clock_topic,
        })
    }

    /// Publishes what a handler returned, each message on its topic, counting each one
    /// published (or why not) in `health`. `/clock` and `/diagnostics` are not counted.
    pub fn publish(&self, out: Outputs, names: &Names, health: &mut Health) {
        send(&self.gravity, out.gravity, &names.gravity, health);
        send(
            &self.acceleration,
            out.acceleration,
            &names.acceleration,
            health,
        );
        send(&self.residual, out.residual, &names.residual, health);
        send(
            &self.feedforward_effort,
            out.feedforward_effort,
            &names.feedforward_effort,
            health,
        );
        send(
            &self.feedforward_commands,
            out.feedforward_commands,
            &names.feedforward_commands,
            health,
        );
        if let Some(sim) = &self.simulation {
            if let Some(clock) = out.clock {
                let _ = sim.clock.publish(clock);
            }
            send(
                &sim.joint_states,
                out.joint_states,
                &names.joint_states,
                health,
            );
            send(&sim.base_state, out.base_state, &names.base_state, health);
            send(&sim.tf, out.tf, &names.tf, health);
        }
        if let Some(diagnostics) = out.diagnostics {
            let _ = self.diagnostics.publish(diagnostics);
        }
    }
}

/// Publishes `message`, if any, counting it in `health` as published or failed on `topic`.
fn send<M: Message + Debug>(
    publisher: &Publisher<M>,
    message: Option<M>,
    topic: &str,
    health: &mut Health,
) {
    let Some(message) = message else { return };
    match publisher.publish(message) {
        Ok(()) => health.published(topic),
        Err(e) => health.dropped(topic, &format!("publish failed: {e:?}")),
    }
}

/// A message as it came off a subscription: the message, or why it could not be read; and its
/// DDS receive time.
pub fn decoded<M, E: Debug>(
    item: Result<(M, MessageInfo), E>,
) -> (Result<M, String>, Option<ROSTime>) {
    match item {
        Ok((message, info)) => (Ok(message), info.received_timestamp()),
        Err(e) => (Err(format!("unreadable message: {e:?}")), None),
    }
}

/// Answers a request with `handler`'s response; an unreadable request, or a response that
/// could not be sent, is counted on the service `name` picks from the node's names.
pub fn respond<Req: Message + 'static, Resp: Message + 'static, E>(
    server: &Server<Req, Resp>,
    item: Result<(RmwRequestId, Req), E>,
    state: &mut NodeState,
    name: fn(&Names) -> &String,
    handler: impl FnOnce(&mut NodeState, Req) -> Resp,
) {
    let Ok((id, request)) = item else {
        return state
            .health
            .dropped(name(&state.names), "unreadable request");
    };
    let response = handler(state, request);
    if let Err(e) = server.send_response(id, response) {
        state
            .health
            .dropped(name(&state.names), &format!("response not sent: {e:?}"));
    }
}

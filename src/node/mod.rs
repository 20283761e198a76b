//! `spatial_dynamics node`: the dynamics served over ROS 2 (ros2-client on RustDDS).
//!
//! Inputs: `joint_states`, `~/effort_command`, `~/commands`, `~/joint_commands`, `~/reference`, `~/base_state`,
//! `robot_description` (latched). Outputs: `~/gravity_effort`, `~/acceleration`,
//! `~/effort_residual` (one joint state late), `~/feedforward_effort`, `~/feedforward_commands`, `/diagnostics`, `/rosout`. Services:
//! `~/inverse_dynamics`, `~/forward_dynamics`, `~/mass_matrix`, `~/describe_model`,
//! `~/frame_kinematics`, `~/linearize`, and the standard parameter services. In simulate mode (`mode: simulate`)
//! the node also publishes
//! `joint_states`, a floating base's `~/base_state` and `/tf` (and `/clock` if `publish_clock`) from its
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

mod endpoints;
mod engine;
mod handlers;
mod health;
pub(crate) mod logging;
mod messages;
mod parameter_descriptors;
mod params;
mod ros_args;
mod time_source;

use crate::ros::msgs::Log;
use crate::ros::names::NameResolver;
use endpoints::{decoded, respond, Endpoints};
use engine::Engine;
use futures::StreamExt;
use handlers::{simulation_timer, Names, NodeState};
use logging::{log, Logger};
use params::Settings;
use ros2_client::{NodeName, NodeOptions};
use ros_args::RosArgs;
use std::time::{Duration, Instant};
use time_source::TimeSource;

/// Runs the node until it is stopped. Configuration errors at start-up are returned (and the
/// process exits non-zero); after that, bad input is answered or dropped, never fatal.
pub fn run(args: &[String]) -> Result<(), String> {
    let ros_args = RosArgs::parse(args)?;
    let remaps = ros_args.for_node("spatial_dynamics");
    let node_name = remaps.node_name.clone();
    let resolver = NameResolver::new(
        remaps.namespace.as_deref().unwrap_or("/"),
        &node_name,
        &remaps.remaps,
    );
    let logger_name = logging::logger_name(resolver.namespace(), &node_name);
    let logger = Logger::new(
        &logger_name,
        logging::level_for(&logger_name, &ros_args.log_levels),
    );
    if !remaps.other_nodes.is_empty() {
        log!(
            logger,
            Warn,
            "ignoring remapping rules for other nodes (this node is '{node_name}'): {}",
            remaps.other_nodes.join(", ")
        );
    }
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

/// Sets the node up (its parameters, topics, services and timers), then hands each input,
/// request and tick to its handler ([`handlers`]) and sends what the handler returns, until
/// SIGINT or SIGTERM.
async fn serve(
    settings: Settings,
    engine: Engine,
    resolver: NameResolver,
    node_name: String,
    logger: Logger,
) -> Result<(), String> {
    let context = endpoints::context()?;
    let simulate = settings.simulate;
    let names = Names::resolve(&resolver, &node_name);
    let mut state = NodeState::new(engine, settings, names.clone(), logger.clone());
    let (changes_tx, mut changes_rx) = tokio::sync::mpsc::unbounded_channel::<String>();

    // The node's own /rosout publisher (below) has rcl's rosout QoS; ros2-client's keeps 1 line.
    let mut options = NodeOptions::new()
        .enable_rosout(false)
        .start_parameter_services(true);
    let shared = state.settings();
    for (name, value) in shared.lock().map_err(|e| e.to_string())?.values() {
        options = options
            .describe_parameter(parameter_descriptors::descriptor(name, &value))
            .declare_parameter(name, value);
    }
    let description = state.topic_description();
    let (validated, batch_validated) = (shared.clone(), shared.clone());
    let batch_description = description.clone();
    options = options
        .parameter_validator(Box::new(move |name, value| {
            handlers::validate_parameter(&validated, &description, name, value)
        }))
        .parameter_batch_validator(Box::new(move |parameters| {
            let values = parameters.iter().map(|p| (p.name.as_str(), &p.value));
            handlers::validate_parameters(&batch_validated, &batch_description, values)
        }))
        .parameter_set_action(Box::new(move |name, value| {
            if handlers::apply_parameter(&shared, name, value)? {
                let _ = changes_tx.send(name.to_string());
            }
            Ok(())
        }));
    let ns = resolver.namespace().to_string();
    let mut node = context
        .new_node(
            NodeName::new(&ns, &node_name)
                .map_err(|e| format!("bad node name '{ns}/{node_name}': {e:?}"))?,
            options,
        )
        .map_err(|e| format!("cannot create node: {e:?}"))?;
    logger.attach(
        node.create_publisher::<Log>(&context.get_rosout_topic(), Some(endpoints::rosout_qos()))
            .map_err(|e| format!("publisher /rosout: {e:?}"))?,
    );
    let ends = Endpoints::create(&mut node, &names, simulate)?;
    let spinner = node
        .spinner()
        .map_err(|e| format!("cannot start the spinner: {e:?}"))?;
    tokio::spawn(spinner.spin());

    let mut time = TimeSource::new(ends.clock_topic.clone());
    // Subscribes to /clock now if simulated time is on, so that discovery starts at once.
    time.now(&mut node, &mut state, None);
    log!(
        logger,
        Info,
        "{} serving robot '{}' ({} joints, nv = {}), method {}{}",
        node.fully_qualified_name(),
        state.engine.model.name(),
        state.engine.names().len(),
        state.engine.model.nv(),
        state.engine.method,
        state
            .engine
            .method_choice
            .as_ref()
            .map_or(String::new(), |c| format!(
                ", chosen by FLOP count among the methods agreeing with aba; timings for information only ({c})"
            ))
    );

    let js_stream = ends.joint_states.async_stream();
    let effort_stream = ends.effort_command.async_stream();
    let commands_stream = ends.commands.async_stream();
    let joint_commands_stream = ends.joint_commands.async_stream();
    let reference_stream = ends.reference.async_stream();
    let base_stream = ends.base_state.async_stream();
    let description_stream = ends.robot_description.async_stream();
    let id_stream = ends.inverse_dynamics.receive_request_stream();
    let fd_stream = ends.forward_dynamics.receive_request_stream();
    let mm_stream = ends.mass_matrix.receive_request_stream();
    let dm_stream = ends.describe_model.receive_request_stream();
    let fk_stream = ends.frame_kinematics.receive_request_stream();
    let lin_stream = ends.linearize.receive_request_stream();
    let reset_stream = ends.reset.receive_request_stream();
    let pause_stream = ends.pause.receive_request_stream();
    let step_stream = ends.step.receive_request_stream();
    futures::pin_mut!(
        js_stream,
        effort_stream,
        commands_stream,
        joint_commands_stream,
        reference_stream,
        base_stream,
        description_stream,
        id_stream,
        fd_stream,
        mm_stream,
        dm_stream,
        fk_stream,
        lin_stream,
        reset_stream,
        pause_stream,
        step_stream
    );
    let mut diagnostics = tokio::time::interval(Duration::from_secs(1));
    let mut sim_timer = simulation_timer(&state.engine);

    // SIGINT and SIGTERM end the loop; dropping the node then leaves the DDS graph cleanly.
    let mut terminate = tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate())
        .map_err(|e| e.to_string())?;
    loop {
        tokio::select! {
            _ = tokio::signal::ctrl_c() => break,
            _ = terminate.recv() => break,
            Some(item) = js_stream.next() => {
                let (message, arrived) = decoded(item);
                let now = time.now(&mut node, &mut state, arrived);
                let out = state.joint_states(message, now);
                ends.publish(out, &names, &mut state.health);
            }
            Some(item) = effort_stream.next() => {
                let out = state.effort_command(decoded(item).0);
                ends.publish(out, &names, &mut state.health);
            }
            Some(item) = commands_stream.next() => {
                let out = state.commands(decoded(item).0);
                ends.publish(out, &names, &mut state.health);
            }
            Some(item) = joint_commands_stream.next() => {
                let out = state.joint_commands(decoded(item).0);
                ends.publish(out, &names, &mut state.health);
            }
            Some(item) = reference_stream.next() => {
                let (message, arrived) = decoded(item);
                let now = time.now(&mut node, &mut state, arrived);
                let out = state.reference(message, now);
                ends.publish(out, &names, &mut state.health);
            }
            Some(item) = base_stream.next() => state.base_state(decoded(item).0),
            Some(item) = description_stream.next() => state.robot_description(decoded(item).0)?,
            Some(item) = id_stream.next() => respond(&ends.inverse_dynamics, item, &mut state, |n| &n.inverse_dynamics, |s, r| s.inverse_dynamics(&r)),
            Some(item) = fd_stream.next() => respond(&ends.forward_dynamics, item, &mut state, |n| &n.forward_dynamics, |s, r| s.forward_dynamics(&r)),
            Some(item) = mm_stream.next() => respond(&ends.mass_matrix, item, &mut state, |n| &n.mass_matrix, |s, r| s.mass_matrix(&r)),
            Some(item) = fk_stream.next() => respond(&ends.frame_kinematics, item, &mut state, |n| &n.frame_kinematics, |s, r| s.frame_kinematics(&r)),
            Some(item) = lin_stream.next() => respond(&ends.linearize, item, &mut state, |n| &n.linearize, |s, r| s.linearize(&r)),
            Some(item) = dm_stream.next() => respond(&ends.describe_model, item, &mut state, |n| &n.describe_model, |s, _| s.describe_model()),
            due = async { sim_timer.as_mut().expect("guarded").tick().await }, if sim_timer.is_some() => {
                let out = state.simulation_tick(due.into_std(), Instant::now());
                time.simulated(node.time_now_not_simulated(), state.engine.simulated_time());
                ends.publish(out, &names, &mut state.health);
            }
            Some(item) = reset_stream.next() => respond(&ends.reset, item, &mut state, |n| &n.reset, |s, r| s.reset(&r)),
            Some(item) = pause_stream.next() => respond(&ends.pause, item, &mut state, |n| &n.pause, |s, r| s.pause(&r)),
            Some(item) = step_stream.next() => respond(&ends.step, item, &mut state, |n| &n.step, |s, _| {
                let (response, out) = s.step(Instant::now());
                time.simulated(node.time_now_not_simulated(), s.engine.simulated_time());
                ends.publish(out, &names, &mut s.health);
                response
            }),
            Some(name) = changes_rx.recv() => {
                state.parameter_changed(&name)?;
                // A new timer only for a new period: a timer's first tick comes one period
                // after it is made, and a change that keeps the period keeps the timer's pace.
                if sim_timer.as_ref().map(|t| t.period()) != state.engine.simulation_period() {
                    sim_timer = simulation_timer(&state.engine);
                }
                time.forget_ticks();
            }
            _ = diagnostics.tick() => {
                let now = time.now(&mut node, &mut state, None);
                let out = state.diagnostics(now);
                ends.publish(out, &names, &mut state.health);
            }
        }
    }
    log!(logger, Info, "shutting down");
    Ok(())
}

//! The instruction sets compute the same bits: every kernel whose passes are dispatched
//! (`spatial_dynamics_core::instruction_set`) gives exactly the same result in the baseline set
//! as in every other set the processor runs, on fixed, floating and branching models (long
//! enough for the AVX-512 copy of `aba_derivatives`' solve), and a simulation follows the same
//! trajectory bit for bit. On a processor with only the baseline set there is nothing to
//! compare; the test says which sets it compared on its output.

use spatial_dynamics_core::algorithms::{
    aba_derivatives, forward_dynamics, rnea, rnea_derivatives, Externals, ForwardDynamicsMethod,
};
use spatial_dynamics_core::model::examples::{self, pendulum_urdf};
use spatial_dynamics_core::sampling::{random_q, Rng};
use spatial_dynamics_core::sim::{Integrator, SimConfig, Simulator, State};
use spatial_dynamics_core::{urdf, InstructionSet, Model, ModelOptions, Workspace};

const TREE: &str = include_str!("models/tree.urdf");

fn load(text: &str, floating_base: bool) -> Model {
    let options = ModelOptions {
        floating_base,
        ..Default::default()
    };
    urdf::model_from_str(text, &options).unwrap()
}

/// The test tree without its world link and planar base joint: rooted at the torso.
fn tree_without_base() -> String {
    let start = TREE.find("<!-- base:").unwrap();
    let end = TREE.find("<!-- end of base -->").unwrap();
    format!("{}{}", &TREE[..start], &TREE[end..])
}

fn models() -> Vec<Model> {
    vec![
        load(examples::DEFAULT_ARM_URDF, false),
        load(TREE, false),
        load(&tree_without_base(), true),
        load(&pendulum_urdf(12, 0.4, 0.9), false),
        load(&pendulum_urdf(40, 0.3, 0.5), false),
        load(&chain_with_massive_root(40), true),
    ]
}

/// A chain of `n` links whose root link has mass, to float.
fn chain_with_massive_root(n: usize) -> String {
    let root = r#"<link name="world"><inertial><mass value="3"/>
        <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.2" iyz="0" izz="0.3"/></inertial></link>"#;
    pendulum_urdf(n, 0.3, 0.5).replacen(r#"<link name="world"/>"#, root, 1)
}

/// Workspaces for `model`, one in each set the processor runs, the baseline first.
fn workspaces(model: &Model) -> Vec<Workspace> {
    let sets = InstructionSet::available();
    eprintln!("instruction sets compared: {sets:?}");
    sets.into_iter()
        .map(|set| {
            let mut ws = Workspace::new(model);
            ws.set_instruction_set(set);
            ws
        })
        .collect()
}

/// The bits of every value, for exact comparison (NaN included).
fn bits<'a>(values: impl IntoIterator<Item = &'a f64>) -> Vec<u64> {
    values.into_iter().map(|x| x.to_bits()).collect()
}

#[test]
fn every_dispatched_kernel_gives_the_same_bits_in_every_set() {
    for model in models() {
        let mut workspaces = workspaces(&model);
        let mut rng = Rng::new(31);
        for _ in 0..8 {
            let q = random_q(&model, &mut rng);
            let v = rng.vector(model.nv(), 2.0);
            let tau = rng.vector(model.nv(), 20.0);
            let none = Externals::none();
            let mut results: Vec<Vec<u64>> = Vec::new();
            for ws in &mut workspaces {
                let mut out = Vec::new();
                let aba =
                    forward_dynamics(&model, ws, &q, &v, &tau, ForwardDynamicsMethod::Aba, &none);
                out.extend(bits(aba.unwrap()));
                out.extend(bits(rnea(&model, ws, &q, &v, &tau).unwrap()));
                let d = rnea_derivatives(&model, ws, &q, &v, &tau).unwrap();
                out.extend(bits(
                    d.dtau_dq
                        .iter()
                        .chain(d.dtau_dv.iter())
                        .chain(d.mass_matrix.iter()),
                ));
                let d = aba_derivatives(&model, ws, &q, &v, &tau, &none).unwrap();
                out.extend(bits(
                    d.ddq_dq.iter().chain(d.ddq_dv.iter()).chain(d.minv.iter()),
                ));
                results.push(out);
            }
            for (ws, result) in workspaces.iter().zip(&results).skip(1) {
                let set = ws.instruction_set().name();
                assert_eq!(&results[0], result, "{} in {set}", model.name());
            }
        }
    }
}

#[test]
fn a_simulation_follows_the_same_trajectory_in_every_set() {
    for model in models() {
        for integrator in [Integrator::SemiImplicitEuler, Integrator::Rk4] {
            let config = SimConfig {
                integrator,
                dt: 1e-3,
                ..SimConfig::default()
            };
            let mut rng = Rng::new(7);
            let start = State::at_rest(&model, random_q(&model, &mut rng));
            let tau = rng.vector(model.nv(), 1.0);
            let trajectories: Vec<Vec<u64>> = InstructionSet::available()
                .into_iter()
                .map(|set| {
                    let mut sim = Simulator::new(&model, config.clone()).unwrap();
                    sim.set_instruction_set(set);
                    let mut state = start.clone();
                    let mut trajectory = Vec::new();
                    for _ in 0..200 {
                        sim.step(&model, &mut state, &tau).unwrap();
                        trajectory.extend(bits(state.q.iter().chain(&state.v)));
                    }
                    trajectory
                })
                .collect();
            for (set, trajectory) in InstructionSet::available().iter().zip(&trajectories) {
                let name = set.name();
                assert_eq!(
                    &trajectories[0],
                    trajectory,
                    "{} {integrator} in {name}",
                    model.name()
                );
            }
        }
    }
}

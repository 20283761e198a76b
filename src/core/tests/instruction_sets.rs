//! The instruction sets agree: every kernel whose passes are dispatched
//! (`spatial_dynamics_core::instruction_set`) gives exactly the same bits in the sets with
//! fused multiply-adds (AVX2 and AVX-512), and in the baseline set the same values to within
//! rounding, on fixed, floating and branching models (long enough for the AVX-512 copy of
//! `aba_derivatives`' solve); a simulation follows the same trajectory, bit for bit in the
//! fused sets. On a processor with only the baseline set there is nothing to compare; the test
//! says which sets it compared on its output.

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
fn every_dispatched_kernel_agrees_in_every_set() {
    for model in models() {
        let mut workspaces = workspaces(&model);
        let mut rng = Rng::new(31);
        for _ in 0..8 {
            let q = random_q(&model, &mut rng);
            let v = rng.vector(model.nv(), 2.0);
            let tau = rng.vector(model.nv(), 20.0);
            let none = Externals::none();
            let mut results: Vec<Vec<Vec<u64>>> = Vec::new();
            for ws in &mut workspaces {
                let mut out = Vec::new();
                let aba =
                    forward_dynamics(&model, ws, &q, &v, &tau, ForwardDynamicsMethod::Aba, &none);
                out.push(bits(aba.unwrap()));
                out.push(bits(rnea(&model, ws, &q, &v, &tau).unwrap()));
                let d = rnea_derivatives(&model, ws, &q, &v, &tau).unwrap();
                out.extend([&d.dtau_dq, &d.dtau_dv, &d.mass_matrix].map(|m| bits(m.iter())));
                let d = aba_derivatives(&model, ws, &q, &v, &tau, &none).unwrap();
                out.extend([&d.ddq_dq, &d.ddq_dv, &d.minv].map(|m| bits(m.iter())));
                results.push(out);
            }
            let sets: Vec<_> = workspaces.iter().map(|ws| ws.instruction_set()).collect();
            agree(&sets, &results, model.name());
        }
    }
}

/// The bits of the kernels' results in each of `sets` (the baseline first): the fused sets
/// equal bit for bit; the baseline within rounding of them, an entry of a result to
/// [`WITHIN_ROUNDING`] of the largest entry of the same result (the fused multiply-adds round
/// once where the baseline rounds twice, each difference a rounding of a product, carried
/// through the solves by at most the conditioning of the mass matrix); and at least one entry
/// different, which shows the fused copies do fuse.
fn agree(sets: &[InstructionSet], results: &[Vec<Vec<u64>>], name: &str) {
    let Some((baseline, fused)) = results.split_first() else {
        return;
    };
    for (set, result) in sets.iter().zip(results).skip(2) {
        assert_eq!(
            &fused[0],
            result,
            "{name} in {} and {}",
            sets[1].name(),
            set.name()
        );
    }
    let Some(fused) = fused.first() else {
        return;
    };
    let mut any_different = false;
    for (k, (baseline, fused)) in baseline.iter().zip(fused).enumerate() {
        let values = |bits: &[u64]| bits.iter().map(|b| f64::from_bits(*b)).collect::<Vec<_>>();
        let (baseline, fused) = (values(baseline), values(fused));
        let scale = fused.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
        for (j, (b, f)) in baseline.iter().zip(&fused).enumerate() {
            assert!(
                (b - f).abs() <= WITHIN_ROUNDING * scale,
                "{name}: result {k} entry {j}, baseline {b:e} against {} {f:e}",
                sets[1].name()
            );
            any_different |= b.to_bits() != f.to_bits();
        }
    }
    assert!(
        any_different,
        "{name}: {} computes the baseline's bits",
        sets[1].name()
    );
}

/// How far the baseline's values may lie from the fused sets', relative to the largest entry
/// of the result: up to 3e-11 seen on the chains of 40 links, whose mass matrices are the
/// worst conditioned here (`∂q̈/∂q` goes through `H⁻¹` twice), 1e-13 and less on the others; a
/// term lost or misplaced in a sum moves an entry by its own size.
const WITHIN_ROUNDING: f64 = 1e-9;

#[test]
fn a_simulation_follows_one_trajectory_in_every_set() {
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
            let sets = InstructionSet::available();
            let trajectories: Vec<Vec<Vec<u64>>> = sets
                .iter()
                .copied()
                .map(|set| {
                    let mut sim = Simulator::new(&model, config.clone()).unwrap();
                    sim.set_instruction_set(set);
                    let mut state = start.clone();
                    let mut trajectory = Vec::new();
                    for _ in 0..200 {
                        sim.step(&model, &mut state, &tau).unwrap();
                        trajectory.push(bits(state.q.iter().chain(&state.v)));
                    }
                    trajectory
                })
                .collect();
            agree(
                &sets,
                &trajectories,
                &format!("{} {integrator}", model.name()),
            );
        }
    }
}

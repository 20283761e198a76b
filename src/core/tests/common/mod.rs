//! Helpers shared by the integration tests: a small deterministic random generator and random
//! states for a model.
#![allow(dead_code)]

#[allow(unused_imports)]
pub use spatial_dynamics_core::sampling::{random_q, Rng};
use spatial_dynamics_core::sim::{ContactPoint, Ground, Integrator, SimConfig};
use spatial_dynamics_core::spatial::Vector3;
use spatial_dynamics_core::{Model, ModelOptions};

/// Largest absolute difference.
pub fn max_diff(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

/// Euclidean norm.
pub fn norm(a: &[f64]) -> f64 {
    a.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// A global allocator that counts this thread's allocations and reallocations (tests run on
/// several threads); a test binary installs it with
/// `#[global_allocator] static GLOBAL: common::Counting = common::Counting;`.
pub struct Counting;

thread_local! {
    static ALLOCATIONS: std::cell::Cell<usize> = const { std::cell::Cell::new(0) };
}

unsafe impl std::alloc::GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: std::alloc::Layout) -> *mut u8 {
        ALLOCATIONS.with(|c| c.set(c.get() + 1));
        std::alloc::System.alloc(layout)
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: std::alloc::Layout) {
        std::alloc::System.dealloc(ptr, layout)
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: std::alloc::Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.with(|c| c.set(c.get() + 1));
        std::alloc::System.realloc(ptr, layout, new_size)
    }
}

/// Allocations this thread made while running `f` (with [`Counting`] installed).
pub fn allocations_during(f: impl FnOnce()) -> usize {
    let before = ALLOCATIONS.with(std::cell::Cell::get);
    f();
    ALLOCATIONS.with(std::cell::Cell::get) - before
}

/// An `n`-link pendulum hanging from a carriage on a 4 km rail (prismatic, ±2 km), the rail
/// from a short slide: the carriage is not a root, so only its joint's travel takes it far.
pub fn pendulum_on_a_rail(n: usize) -> String {
    spatial_dynamics_core::model::examples::pendulum_urdf(n, 0.5, 0.7)
        .replacen(
            r#"<parent link="world"/>"#,
            r#"<parent link="carriage"/>"#,
            1,
        )
        .replacen(
            "<link name=\"world\"/>\n",
            r#"<link name="world"/>
  <joint name="slide" type="prismatic"><parent link="world"/><child link="sled"/>
    <axis xyz="0 1 0"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <link name="sled"><inertial><mass value="2"/>
    <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.2" iyz="0" izz="0.3"/></inertial></link>
  <joint name="rail" type="prismatic"><parent link="sled"/><child link="carriage"/>
    <origin xyz="0.2 0 0"/><axis xyz="1 0 0"/>
    <limit lower="-2000" upper="2000" effort="1" velocity="1"/></joint>
  <link name="carriage"><inertial><mass value="3"/>
    <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.2" iyz="0" izz="0.3"/></inertial></link>
"#,
            1,
        )
}

/// The handout's lamp with penalty contacts at its foot's four corners, semi-implicit Euler at
/// 0.2 ms, `locked` joints held. The foot is a 0.20 × 0.10 m box whose bottom face is at z = 0
/// of its frame.
pub fn lamp(locked: &[(&str, f64)]) -> (Model, SimConfig) {
    let locked = locked.iter().map(|(n, v)| (n.to_string(), *v)).collect();
    let model = spatial_dynamics_core::urdf::model_from_str(
        spatial_dynamics_core::model::examples::LAMP_URDF,
        &ModelOptions {
            locked,
            ..Default::default()
        },
    )
    .unwrap();
    let points = [(0.1, 0.05), (0.1, -0.05), (-0.1, 0.05), (-0.1, -0.05)]
        .iter()
        .map(|&(x, y)| ContactPoint {
            link: "foot".into(),
            point: Vector3::new(x, y, 0.0),
        })
        .collect();
    let ground = Ground {
        points,
        ..Ground::default()
    };
    (
        model,
        SimConfig {
            integrator: Integrator::SemiImplicitEuler,
            dt: 2e-4,
            ground: Some(ground),
            ..Default::default()
        },
    )
}

//! Calls one kernel a given number of times, for counting the floating-point instructions it
//! executes under valgrind (`benches/count_flops.py`).
//!
//! ```text
//! flop_harness MODEL KERNEL CALLS
//! ```
//!
//! `MODEL` is a URDF path, `arm` (the embedded default arm), `pendulumN` (an N-link chain) or
//! `gripper` (mimic joints), with `+floating` appended for a floating base (and `+ignore_mimic`
//! to treat mimic joints as independent, as `bench --ignore-mimic` does); `KERNEL` is one of
//! `spatial_dynamics bench`'s kernels (`rnea`, `crba`, `fd_aba`, `fd_crba`, `fd_rnea_columns`,
//! `gravity`), called exactly as the bench calls it, or a calibration kernel whose count is
//! known exactly: `dot64` (a length-64 dot product, 64 m + 63 a) or `mat3` (a 3×3 matrix
//! product, 27 m + 18 a). Everything but the calls (model loading, the 8 random states) is the
//! same whatever `CALLS` is, so the difference of two runs' counts divided by the difference of
//! `CALLS` is the count of one call. The kernel's own count from the table
//! (`flop_table::kernel_flops`) is printed as JSON, so the script needs no other binary.

use nalgebra::{Matrix3, Rotation3, Vector6};
use spatial_dynamics_core::algorithms::cholesky::spd_inverse;
use spatial_dynamics_core::algorithms::{crba, forward_dynamics, gravity, rnea};
use spatial_dynamics_core::model::{examples, JointKind, MotionSubspace};
use spatial_dynamics_core::sampling::{random_q, Rng};
use spatial_dynamics_core::spatial::{
    AxisTransform, Force, Inertia, Matrix6, Motion, Transform, Translation, Vector3,
};
use spatial_dynamics_core::urdf::{model_from_file, model_from_str};
use spatial_dynamics_core::{flop_table, flops};
use spatial_dynamics_core::{Externals, ForwardDynamicsMethod, Model, ModelOptions, Workspace};
use std::hint::black_box;
use std::path::Path;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if let Err(e) = run(&args) {
        eprintln!("flop_harness: {e}");
        std::process::exit(2);
    }
}

fn run(args: &[String]) -> Result<(), String> {
    let [model_name, kernel, calls] = args else {
        return Err("usage: flop_harness MODEL KERNEL CALLS".into());
    };
    let calls: usize = calls
        .parse()
        .map_err(|_| format!("CALLS '{calls}' is not a count"))?;
    match kernel.as_str() {
        "dot64" => {
            calibrate_dot(calls);
            return Ok(());
        }
        "mat3" => {
            calibrate_mat3(calls);
            return Ok(());
        }
        _ => {}
    }
    if let Some(name) = kernel.strip_prefix("op:") {
        return operation(name, calls);
    }
    let model = load(model_name)?;
    let table = flop_table::kernel_flops(&model, kernel)
        .ok_or_else(|| format!("no FLOP count for kernel '{kernel}' on this model"))?;
    let states: Vec<State> = {
        let mut rng = Rng::new(1);
        (0..8).map(|_| State::random(&model, &mut rng)).collect()
    };
    let mut ws = Workspace::new(&model);
    for k in 0..calls {
        call(
            &model,
            &mut ws,
            kernel,
            black_box(&states[k % states.len()]),
        )?;
    }
    println!(
        "{{\"model\": \"{model_name}\", \"nv\": {}, \"kernel\": \"{kernel}\", \"mul\": {}, \"add\": {}, \"div\": {}, \"sqrt\": {}, \"sincos\": {}}}",
        model.nv(), table.mul, table.add, table.div, table.sqrt, table.sincos
    );
    Ok(())
}

/// `arm`, `gripper`, `pendulumN` or a URDF path, `+floating` for a floating base.
fn load(name: &str) -> Result<Model, String> {
    let mut parts = name.split('+');
    let base = parts.next().unwrap_or_default();
    let mut options = ModelOptions::default();
    for flag in parts {
        match flag {
            "floating" => options.floating_base = true,
            "ignore_mimic" => options.ignore_mimic = true,
            _ => return Err(format!("model '{name}': unknown flag '+{flag}'")),
        }
    }
    let model = if base == "arm" {
        model_from_str(examples::DEFAULT_ARM_URDF, &options)
    } else if base == "gripper" {
        model_from_str(examples::MIMIC_GRIPPER_URDF, &options)
    } else if let Some(n) = base.strip_prefix("pendulum") {
        let n: usize = n
            .parse()
            .map_err(|_| format!("model '{name}': pendulumN needs a number"))?;
        model_from_str(&examples::pendulum_urdf(n, 1.0, 1.0), &options)
    } else {
        model_from_file(Path::new(base), &options)
    };
    model.map_err(|e| format!("model '{name}': {e}"))
}

/// One call of `kernel`, as `spatial_dynamics bench` makes it; the result goes to `black_box`.
fn call(model: &Model, ws: &mut Workspace, kernel: &str, s: &State) -> Result<(), String> {
    use ForwardDynamicsMethod::{Aba, Crba, RneaColumns};
    let ext = Externals::none();
    let result = match kernel {
        "rnea" => rnea(model, ws, &s.q, &s.v, &s.a).map(|x| black_box(x.len())),
        "crba" => crba(model, ws, &s.q).map(|x| black_box(x.len())),
        "gravity" => gravity(model, ws, &s.q).map(|x| black_box(x.len())),
        "fd_aba" | "fd_crba" | "fd_rnea_columns" => {
            let method = match kernel {
                "fd_aba" => Aba,
                "fd_crba" => Crba,
                _ => RneaColumns,
            };
            forward_dynamics(model, ws, &s.q, &s.v, &s.a, method, &ext).map(|x| black_box(x.len()))
        }
        _ => return Err(format!("unknown kernel '{kernel}'")),
    };
    result.map(|_| ()).map_err(|e| format!("{kernel}: {e}"))
}

/// One spatial operation per call, on fixed operands (through `black_box`, so nothing is
/// folded or hoisted), and its cost from the table.
fn operation(name: &str, calls: usize) -> Result<(), String> {
    let e = *Rotation3::from_euler_angles(0.3, -0.7, 1.1).matrix();
    let x = Transform::from_pose(&e, &Vector3::new(0.2, -0.5, 0.9));
    let y = Transform::from_pose(&e.transpose(), &Vector3::new(-0.1, 0.4, 0.3));
    let a = Vector3::new(0.3, -1.2, 0.7);
    let b = Vector3::new(-0.5, 0.9, 1.1);
    let turn = AxisTransform::<1> {
        cos: 0.6,
        sin: 0.8,
        trans: b,
    };
    let m = Motion::new(a, b);
    let n = Motion::new(b, a);
    let f = Force::new(b, a);
    let inertia = Inertia::from_com(
        2.5,
        &a,
        &Matrix3::from_diagonal(&Vector3::new(0.3, 0.2, 0.25)),
    );
    let m6 = Matrix6::from_fn(|r, c| 0.1 * (r * 6 + c) as f64);
    let v6 = Vector6::from_fn(|r, _| 0.3 - r as f64);
    let mut s = MotionSubspace::default();
    let revolute_z = JointKind::Revolute { axis: Vector3::z() };
    let revolute_axis = JointKind::Revolute {
        axis: Vector3::new(1.0, 1.0, 0.0).normalize(),
    };
    let prismatic = JointKind::Prismatic {
        axis: b.normalize(),
    };
    let planar = JointKind::planar(a);
    let q = [0.4, -0.3, 0.8, 0.1, 0.2, 0.3, 0.9];
    macro_rules! repeat {
        ($e:expr) => {
            for _ in 0..calls {
                black_box($e);
            }
        };
    }
    let jcalc = |kind: &JointKind, calls: usize, s: &mut MotionSubspace| {
        let mut x_up = Transform::identity();
        for _ in 0..calls {
            black_box(kind).jcalc_up(black_box(&q[..kind.nq()]), black_box(&x), s, &mut x_up);
            black_box(&mut x_up);
        }
        flops::jcalc_up(kind)
    };
    let table = match name {
        "cross3" => {
            repeat!(black_box(&a).cross(black_box(&b)));
            flops::CROSS3
        }
        "mat3_vec3" => {
            repeat!(black_box(&e) * black_box(&a));
            flops::MAT3_VEC3
        }
        "mat3_tr_vec3" => {
            repeat!(black_box(&e).tr_mul(black_box(&a)));
            flops::MAT3_VEC3
        }
        "apply_motion" => {
            repeat!(black_box(&x).apply_motion(black_box(&m)));
            flops::TRANSFORM_VECTOR
        }
        "apply_force" => {
            repeat!(black_box(&x).apply_force(black_box(&f)));
            flops::TRANSFORM_VECTOR
        }
        "inverse_apply_motion" => {
            repeat!(black_box(&x).inverse_apply_motion(black_box(&m)));
            flops::TRANSFORM_VECTOR
        }
        "world_turn_axis" => {
            repeat!(black_box(&x).inverse_apply_axis(black_box(1), black_box(-1.0)));
            flops::WORLD_TURN_AXIS
        }
        "world_slide_axis" => {
            repeat!(black_box(&x).inverse_apply_axis(black_box(5), black_box(-1.0)));
            flops::WORLD_SLIDE_AXIS
        }
        "transpose_apply_force" => {
            repeat!(black_box(&x).transpose_apply_force(black_box(&f)));
            flops::TRANSFORM_VECTOR
        }
        "compose" => {
            repeat!(black_box(&x).compose(black_box(&y)));
            flops::COMPOSE
        }
        "transpose_apply_inertia" => {
            repeat!(black_box(&x).transpose_apply_inertia(black_box(&inertia)));
            flops::TRANSFORM_INERTIA
        }
        "translate_inertia" => {
            repeat!(Translation(*black_box(&a)).transpose_apply_inertia(black_box(&inertia)));
            flops::TRANSLATE_INERTIA
        }
        "axis_turn_motion" => {
            repeat!(black_box(&turn).apply_motion(black_box(&m)));
            flops::AXIS_TURN_VECTOR
        }
        "axis_turn_force" => {
            repeat!(black_box(&turn).transpose_apply_force(black_box(&f)));
            flops::AXIS_TURN_VECTOR
        }
        "axis_turn_compose" => {
            repeat!(black_box(&turn).compose(black_box(&y)));
            flops::AXIS_TURN_COMPOSE
        }
        "translate_compose" => {
            repeat!(Translation(*black_box(&a)).compose(black_box(&y)));
            flops::TRANSLATE_COMPOSE
        }
        "axis_turn_inertia" => {
            repeat!(black_box(&turn).transpose_apply_inertia(black_box(&inertia)));
            flops::AXIS_TURN_INERTIA
        }
        "inertia_apply" => {
            repeat!(black_box(&inertia).apply(black_box(&m)));
            flops::INERTIA_APPLY
        }
        "cross_motion" => {
            repeat!(black_box(&m).cross_motion(black_box(&n)));
            flops::CROSS6
        }
        "cross_force" => {
            repeat!(black_box(&m).cross_force(black_box(&f)));
            flops::CROSS6
        }
        "dot6" => {
            repeat!(black_box(&m).dot(black_box(&f)));
            flops::DOT6
        }
        "add6" => {
            repeat!(*black_box(&m) + *black_box(&n));
            flops::ADD6
        }
        "inertia_add" => {
            repeat!({
                let mut sum = *black_box(&inertia);
                sum += *black_box(&inertia);
                sum
            });
            flops::INERTIA_ADD
        }
        "mat6_vec6" => {
            repeat!(black_box(&m6) * black_box(&v6));
            flops::MAT6_VEC6
        }
        "subspace_column" => {
            prismatic.jcalc_up(&q[..1], &x, &mut s, &mut Transform::identity());
            repeat!(black_box(&s).apply(black_box(&q[..1]), black_box(0.5)));
            flops::SUBSPACE_COLUMN
        }
        "spd_inverse6" => {
            let spd = m6.transpose() * m6 + Matrix6::identity();
            let mut inv = Matrix6::zeros();
            repeat!(spd_inverse(black_box(&spd), 6, |p| p > 0.0, &mut inv).is_ok());
            flops::spd_inverse(6)
        }
        "inertia_to_matrix" => {
            repeat!(black_box(&inertia).to_matrix());
            flops::INERTIA_TO_MATRIX
        }
        "jcalc_revolute_z" => jcalc(&revolute_z, calls, &mut s),
        "jcalc_revolute_axis" => jcalc(&revolute_axis, calls, &mut s),
        "jcalc_prismatic" => jcalc(&prismatic, calls, &mut s),
        "jcalc_planar" => jcalc(&planar, calls, &mut s),
        "jcalc_floating" => jcalc(&JointKind::Floating, calls, &mut s),
        "bias_planar" => {
            repeat!(black_box(&planar).bias(black_box(&q[..3]), black_box(&q[3..6])));
            flops::joint_bias(&planar)
        }
        _ => return Err(format!("unknown operation '{name}'")),
    };
    println!(
        "{{\"kernel\": \"op:{name}\", \"mul\": {}, \"add\": {}, \"div\": {}, \"sqrt\": {}, \"sincos\": {}}}",
        table.mul, table.add, table.div, table.sqrt, table.sincos
    );
    Ok(())
}

/// A length-64 dot product per call: 64 multiplications, 63 additions (sequential, as IEEE
/// addition is not reassociated).
fn calibrate_dot(calls: usize) {
    let x: Vec<f64> = (0..64).map(|i| 0.5 + i as f64).collect();
    let y: Vec<f64> = (0..64).map(|i| 1.5 - i as f64).collect();
    for _ in 0..calls {
        let (x, y) = (black_box(&x), black_box(&y));
        let mut s = x[0] * y[0];
        for i in 1..64 {
            s += x[i] * y[i];
        }
        black_box(s);
    }
    println!("{{\"kernel\": \"dot64\", \"mul\": 64, \"add\": 63, \"div\": 0, \"sqrt\": 0, \"sincos\": 0}}");
}

/// A 3×3 matrix product per call (nalgebra): 27 multiplications, 18 additions.
fn calibrate_mat3(calls: usize) {
    let a = Matrix3::from_fn(|r, c| 0.3 + r as f64 - 0.7 * c as f64);
    let b = Matrix3::from_fn(|r, c| 1.1 - 0.2 * r as f64 + c as f64);
    for _ in 0..calls {
        black_box(black_box(&a) * black_box(&b));
    }
    println!("{{\"kernel\": \"mat3\", \"mul\": 27, \"add\": 18, \"div\": 0, \"sqrt\": 0, \"sincos\": 0}}");
}

/// Inputs of one call: `q` (unit quaternions for floating joints), `v`, and `a` (accelerations
/// for `rnea`, efforts for forward dynamics).
struct State {
    q: Vec<f64>,
    v: Vec<f64>,
    a: Vec<f64>,
}

impl State {
    fn random(model: &Model, rng: &mut Rng) -> Self {
        let q = random_q(model, rng);
        State {
            q,
            v: rng.vector(model.nv(), 1.0),
            a: rng.vector(model.nv(), 1.0),
        }
    }
}

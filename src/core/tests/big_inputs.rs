//! Big inputs: a 4 000-link chain and a 4 000-link tree load (no recursion over the tree, no
//! quadratic look-ups that take minutes) and every algorithm runs on them; a model whose
//! workspace would pass `Workspace::MAX_BYTES` (an 8 000-link chain) is refused before anything
//! is allocated for it, while 20 000 links fused by fixed joints load; a 50 MB description (a huge
//! comment, a giant attribute, deep nesting, very many links) is answered with a model or a clear
//! error, never a crash or an out-of-memory abort. Times are printed (`--nocapture`).

use spatial_dynamics_core::algorithms::kinematics::{body_motion, body_placements};
use spatial_dynamics_core::algorithms::{
    bias, crba, energy, forward_dynamics, gravity, rnea, rnea_with,
};
use spatial_dynamics_core::spatial::Force;
use spatial_dynamics_core::{
    urdf, Externals, ForwardDynamicsMethod, Model, ModelOptions, Workspace,
};
use std::time::{Duration, Instant};

const LINKS: usize = 4_000;

/// A link with a rod-like inertia (positive definite, mass 1 kg).
fn link(name: &str) -> String {
    format!(
        r#"<link name="{name}"><inertial><origin xyz="0 0 -0.05"/><mass value="1"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.001"/></inertial></link>"#
    )
}

/// A revolute joint about an axis that turns with `i` (so the tree is not planar).
fn joint(i: usize, parent: &str, child: &str) -> String {
    let axis = ["1 0 0", "0 1 0", "0 0 1"][i % 3];
    format!(
        r#"<joint name="j{i}" type="continuous"><parent link="{parent}"/><child link="{child}"/><origin xyz="0 0 -0.1" rpy="0.1 0 0"/><axis xyz="{axis}"/></joint>"#
    )
}

/// `n` moving links under a fixed `world` link; link `i` hangs from link `parent(i)`.
fn robot(n: usize, parent: impl Fn(usize) -> usize) -> String {
    let mut text = String::from("<robot name=\"big\"><link name=\"world\"/>");
    for i in 1..=n {
        let p = parent(i);
        let p = if p == 0 {
            "world".to_string()
        } else {
            format!("l{p}")
        };
        text += &link(&format!("l{i}"));
        text += &joint(i, &p, &format!("l{i}"));
    }
    text + "</robot>"
}

fn timed<T>(what: &str, f: impl FnOnce() -> T) -> (T, Duration) {
    let start = Instant::now();
    let out = f();
    let elapsed = start.elapsed();
    println!("{what}: {:.3} s", elapsed.as_secs_f64());
    (out, elapsed)
}

fn finite(x: &[f64]) -> bool {
    x.iter().all(|v| v.is_finite())
}

/// Runs every algorithm once on `model` at a bent, moving state; each must answer with finite
/// numbers, forward dynamics with `q̈` that inverse dynamics turns back into `τ`. ABA is always
/// run; `methods` are the other forward-dynamics methods to run (their factorisations are O(n³)
/// on a chain).
fn run_every_algorithm(label: &str, model: &Model, methods: &[ForwardDynamicsMethod]) {
    let n = model.nv();
    let q: Vec<f64> = (0..model.nq())
        .map(|i| 0.3 * ((i % 7) as f64 - 3.0))
        .collect();
    let v: Vec<f64> = (0..n).map(|i| 0.01 * ((i % 5) as f64 - 2.0)).collect();
    let a: Vec<f64> = (0..n).map(|i| 0.1 * ((i % 3) as f64 - 1.0)).collect();
    let mut ws = timed(&format!("{label}: workspace"), || Workspace::new(model)).0;
    let tau = timed(&format!("{label}: rnea"), || {
        rnea(model, &mut ws, &q, &v, &a).unwrap().to_vec()
    })
    .0;
    assert!(finite(&tau));
    let wrenches = vec![Force::zero(); model.nbodies()];
    let ext = Externals {
        wrenches: Some(&wrenches),
        ..Default::default()
    };
    let with = rnea_with(model, &mut ws, &q, &v, &a, &ext).unwrap();
    assert_eq!(with, tau.as_slice());
    assert!(finite(
        timed(&format!("{label}: bias"), || bias(
            model, &mut ws, &q, &v, &ext
        )
        .unwrap()
        .to_vec())
        .0
        .as_slice()
    ));
    assert!(finite(
        timed(&format!("{label}: gravity"), || gravity(model, &mut ws, &q)
            .unwrap()
            .to_vec())
        .0
        .as_slice()
    ));
    let (t, v_pot) = energy(model, &mut ws, &q, &v).unwrap();
    assert!(t.is_finite() && v_pot.is_finite());
    assert_eq!(
        body_placements(model, &mut ws, &q).unwrap().len(),
        model.nbodies()
    );
    body_motion(model, &mut ws, &q, &v).unwrap();
    let qdd = timed(&format!("{label}: forward dynamics (aba)"), || {
        forward_dynamics(
            model,
            &mut ws,
            &q,
            &v,
            &tau,
            ForwardDynamicsMethod::Aba,
            &Externals::none(),
        )
        .unwrap()
        .to_vec()
    })
    .0;
    check_residual(label, "aba", model, &mut ws, (&q, &v, &qdd), &tau);
    let h = timed(&format!("{label}: crba"), || {
        crba(model, &mut ws, &q).map(|h| h.nrows())
    })
    .0
    .unwrap();
    assert_eq!(h, n);
    for method in methods {
        let qdd = timed(&format!("{label}: forward dynamics ({method})"), || {
            forward_dynamics(model, &mut ws, &q, &v, &tau, *method, &Externals::none())
                .unwrap()
                .to_vec()
        })
        .0;
        check_residual(label, method.name(), model, &mut ws, (&q, &v, &qdd), &tau);
    }
}

/// The forward-dynamics answer is an answer: `‖RNEA(q, v, q̈) − τ‖ ≤ 1e-9 ‖τ‖` (the check
/// `benches/conditioning.py` uses; a 10 000-link chain's `H` is too badly conditioned for a
/// bound on `q̈` itself).
fn check_residual(
    label: &str,
    method: &str,
    model: &Model,
    ws: &mut Workspace,
    (q, v, qdd): (&[f64], &[f64], &[f64]),
    tau: &[f64],
) {
    let back = rnea(model, ws, q, v, qdd).unwrap();
    let norm = |x: &mut dyn Iterator<Item = f64>| x.map(|e| e * e).sum::<f64>().sqrt();
    let residual = norm(&mut back.iter().zip(tau).map(|(a, b)| a - b));
    let scale = norm(&mut tau.iter().copied());
    assert!(
        residual <= 1e-9 * scale,
        "{label}: {method}: ‖RNEA(q, v, q̈) − τ‖ = {residual:e}, ‖τ‖ = {scale:e}"
    );
}

fn load(label: &str, text: &str, links: usize) -> Model {
    let (model, took) = timed(&format!("{label}: load"), || {
        urdf::model_from_str(text, &ModelOptions::default()).unwrap()
    });
    assert_eq!((model.nbodies(), model.nv()), (links, links));
    assert!(
        took < Duration::from_secs(20),
        "{label}: loading took {took:?}"
    );
    model
}

#[test]
fn four_thousand_link_chain_loads_and_every_algorithm_runs() {
    let model = load("chain", &robot(LINKS, |i| i - 1), LINKS);
    // On a chain H is dense and its factorisation O(n³) (a minute at n = 4 000): the CRBA and
    // n+1-RNEA forward dynamics run on the 1 000-link chain below.
    run_every_algorithm("chain", &model, &[]);
}

#[test]
fn four_thousand_link_tree_loads_and_every_algorithm_runs() {
    // A binary tree: link i hangs from link i / 2 (depth 12): H is sparse, LᵀL cheap. The
    // n+1-RNEA method is O(n²) RNEA work plus a dense O(n³) Cholesky by design (it is the
    // reference method): it runs on the 1 000-link tree below.
    let model = load("tree", &robot(LINKS, |i| i / 2), LINKS);
    run_every_algorithm("tree", &model, &[ForwardDynamicsMethod::Crba]);
}

#[test]
fn thousand_link_chain_and_tree_run_every_forward_dynamics_method() {
    let all = [
        ForwardDynamicsMethod::Crba,
        ForwardDynamicsMethod::RneaColumns,
    ];
    let chain = load("chain 1000", &robot(1000, |i| i - 1), 1000);
    run_every_algorithm("chain 1000", &chain, &all);
    let tree = load("tree 1000", &robot(1000, |i| i / 2), 1000);
    run_every_algorithm("tree 1000", &tree, &all);
}

// ---- 50 MB descriptions ------------------------------------------------------------------------

const BIG: usize = 50 << 20;

/// A one-link robot with `filler` inside `<robot>`, after the link.
fn with_filler(filler: &str) -> String {
    format!(r#"<robot name="big">{}{filler}</robot>"#, link("only"))
}

/// Loads `text` (printing the time and size) and returns the result as text.
fn load_big(label: &str, text: &str) -> Result<Model, String> {
    let (result, took) = timed(&format!("{label} ({} MB)", text.len() >> 20), || {
        urdf::model_from_str(text, &ModelOptions::default())
    });
    assert!(took < Duration::from_secs(60), "{label}: took {took:?}");
    result.map_err(|e| {
        let message = e.to_string();
        println!("{label}: {}", &message[..message.len().min(200)]);
        message
    })
}

#[test]
fn fifty_megabyte_comment_loads() {
    let text = with_filler(&format!("<!--{}-->", "x".repeat(BIG)));
    let model = load_big("comment", &text).unwrap();
    assert_eq!(model.links().len(), 1);
}

#[test]
fn fifty_megabyte_link_name_loads() {
    let name = "n".repeat(BIG);
    let text = format!(r#"<robot name="big">{}</robot>"#, link(&name));
    let model = load_big("giant link name", &text).unwrap();
    assert_eq!(model.links()[0].name.len(), BIG);
}

#[test]
fn fifty_megabyte_number_loads() {
    let text = format!(
        r#"<robot name="big"><link name="a"><inertial><mass value="1.{}"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link></robot>"#,
        "0".repeat(BIG)
    );
    let model = load_big("giant number", &text).unwrap();
    assert_eq!(model.links().len(), 1);
}

#[test]
fn fifty_megabytes_of_nesting_is_refused() {
    let depth = BIG / 7;
    let text = with_filler(&format!("{}{}", "<a>".repeat(depth), "</a>".repeat(depth)));
    let err = load_big("deep nesting", &text).unwrap_err();
    assert!(err.contains("nested more than 100 deep (at <a>)"), "{err}");
}

#[test]
fn fifty_megabytes_of_elements_are_refused() {
    let text = with_filler(&"<a/>".repeat(BIG / 4));
    let err = load_big("many elements", &text).unwrap_err();
    assert!(err.contains("more than 1000000 XML elements"), "{err}");
}

#[test]
fn fifty_megabytes_of_links_are_refused() {
    let mut text = String::from("<robot name=\"big\"><link name=\"l0\"/>");
    let mut i = 0;
    while text.len() < BIG {
        i += 1;
        text += &link(&format!("l{i}"));
        text += &joint(i, &format!("l{}", i - 1), &format!("l{i}"));
    }
    text += "</robot>";
    println!("{i} links");
    let err = load_big("many links", &text).unwrap_err();
    assert!(err.contains("more than 20000 links or joints"), "{err}");
}

#[test]
fn too_many_coordinates_are_refused_with_the_memory_they_would_take() {
    // 4 000 floating joints: 24 000 coordinates, ten nv × nv matrices of 4.6 GB each.
    let text = robot(4000, |i| i - 1).replace("type=\"continuous\"", "type=\"floating\"");
    let err = load_big("24 000 coordinates", &text).unwrap_err();
    assert!(
        err.contains("4000 bodies and 24000 coordinates")
            && err.contains("about 48.5 GB")
            && err.contains("46.1 GB of nv × nv matrices")
            && err.contains("more than the 2.1 GB a model may need"),
        "{err}"
    );
}

/// An 8 000-link chain: its matrices (5.1 GB) and its lists of ancestors and supports (32 million
/// entries each, 0.5 GB) would exhaust a small machine's memory; refused before any is allocated.
#[test]
fn a_chain_whose_workspace_would_pass_the_budget_is_refused() {
    let text = robot(8000, |i| i - 1);
    let err = load_big("8 000-link chain", &text).unwrap_err();
    assert!(
        err.contains("8000 bodies and 8000 coordinates")
            && err.contains("5.1 GB of nv × nv matrices, 0.5 GB of ancestor and support lists")
            && err.contains("more than the 2.1 GB"),
        "{err}"
    );
    // At 4 800 links the chain still fits.
    let model = load("chain 4800", &robot(4800, |i| i - 1), 4800);
    assert!(Workspace::estimated_bytes(&model) <= Workspace::MAX_BYTES);
}

/// 20 000 links (the most `urdf::MAX_LINKS` lets through) joined by fixed joints make one body:
/// accepted, and small.
#[test]
fn twenty_thousand_fixed_links_load() {
    let text =
        robot(urdf::MAX_LINKS - 1, |i| i - 1).replace("type=\"continuous\"", "type=\"fixed\"");
    let model = load_big("20 000 fixed links", &text).unwrap();
    assert_eq!((model.links().len(), model.nv()), (urdf::MAX_LINKS, 0));
}

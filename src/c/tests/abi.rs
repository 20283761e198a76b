//! The `extern "C"` functions called from Rust: their answers are the library's, bit for bit;
//! their errors are non-zero codes with the library's message; NULL pointers, foreign
//! workspaces and bad arguments are refused, never answered.

use spatial_dynamics_c::derivatives::*;
use spatial_dynamics_c::dynamics::*;
use spatial_dynamics_c::frames::sd_reference_frame::*;
use spatial_dynamics_c::frames::*;
use spatial_dynamics_c::model::*;
use spatial_dynamics_c::status::*;
use spatial_dynamics_c::workspace::*;
use spatial_dynamics_core::algorithms::method_choice::AUTO_TOLERANCE;
use spatial_dynamics_core::algorithms::{
    aba_derivatives, choose_method, crba, find_frame, forward_dynamics, frame_jacobian, gravity,
    rnea, rnea_derivatives, ReferenceFrame,
};
use spatial_dynamics_core::model::examples::{DEFAULT_ARM_URDF, MIMIC_GRIPPER_URDF};
use spatial_dynamics_core::{urdf, Externals, Model, ModelOptions, Workspace};
use std::ffi::{c_int, CStr, CString};
use std::ptr;
use std::time::Duration;

const TREE: &str = include_str!("../../core/tests/models/tree.urdf");
const OK: c_int = sd_status::SD_OK as c_int;
const INPUT: c_int = sd_status::SD_ERROR_INPUT as c_int;
const USAGE: c_int = sd_status::SD_ERROR_USAGE as c_int;

/// A model and a workspace made through the C ABI, freed on drop, with the library's own
/// model built from the same text.
struct Handles {
    model: *mut sd_model,
    ws: *mut sd_workspace,
    library: Model,
}

/// An `extern "C"` function of a state: model, workspace, `q`, `v`, `a` or `tau`, one output.
type StateFn = unsafe extern "C" fn(
    *const sd_model,
    *mut sd_workspace,
    *const f64,
    *const f64,
    *const f64,
    *mut f64,
) -> c_int;

/// An `sd_*_derivatives` function: model, workspace, `q`, `v`, `a` or `tau`, three `nv × nv`
/// outputs.
type DerivativesFn = unsafe extern "C" fn(
    *const sd_model,
    *mut sd_workspace,
    *const f64,
    *const f64,
    *const f64,
    *mut f64,
    *mut f64,
    *mut f64,
) -> c_int;

impl Handles {
    fn new(text: &str, floating_base: bool) -> Self {
        let options = sd_model_options {
            floating_base: floating_base as c_int,
            ignore_mimic: 0,
        };
        let c_text = CString::new(text).unwrap();
        let model = unsafe { sd_model_from_urdf_string(c_text.as_ptr(), &options) };
        assert!(!model.is_null(), "{}", last_error());
        let library = urdf::model_from_str(
            text,
            &ModelOptions {
                floating_base,
                ..ModelOptions::default()
            },
        )
        .unwrap();
        Handles {
            model,
            ws: unsafe { sd_workspace_new(model) },
            library,
        }
    }

    /// A state: `q` on the joints' manifolds (a unit quaternion for a floating base), `v`, `a`.
    fn state(&self) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let (nq, nv) = (self.library.nq(), self.library.nv());
        let mut q: Vec<f64> = (0..nq).map(|i| 0.3 + 0.17 * i as f64).collect();
        if nq > nv {
            let norm = q[3..7].iter().map(|x| x * x).sum::<f64>().sqrt();
            q[3..7].iter_mut().for_each(|x| *x /= norm);
        }
        let v = (0..nv).map(|i| 0.5 - 0.11 * i as f64).collect();
        let a = (0..nv).map(|i| -0.2 + 0.23 * i as f64).collect();
        (q, v, a)
    }

    /// `f` of this model and workspace at `q`, `v`, `x` into `out`: its status.
    fn call(&self, f: StateFn, q: &[f64], v: &[f64], x: &[f64], out: &mut [f64]) -> c_int {
        let (model, ws) = (self.model, self.ws);
        unsafe {
            f(
                model,
                ws,
                q.as_ptr(),
                v.as_ptr(),
                x.as_ptr(),
                out.as_mut_ptr(),
            )
        }
    }

    /// `f` of this model and workspace at `q`, `v`, `x` into the three `outs`: its status.
    fn derivatives(
        &self,
        f: DerivativesFn,
        q: &[f64],
        v: &[f64],
        x: &[f64],
        outs: &mut [Vec<f64>; 3],
    ) -> c_int {
        let [d0, d1, d2] = outs;
        let (q, v, x) = (q.as_ptr(), v.as_ptr(), x.as_ptr());
        let outs = (d0.as_mut_ptr(), d1.as_mut_ptr(), d2.as_mut_ptr());
        unsafe { f(self.model, self.ws, q, v, x, outs.0, outs.1, outs.2) }
    }
}

impl Drop for Handles {
    fn drop(&mut self) {
        unsafe {
            sd_workspace_free(self.ws);
            sd_model_free(self.model);
        }
    }
}

fn last_error() -> String {
    let e = sd_last_error();
    assert!(!e.is_null(), "no error message");
    unsafe { CStr::from_ptr(e) }.to_str().unwrap().to_string()
}

/// Every model the tests use: a tree with a planar base, the same with a floating joint in the
/// description, a 7-DOF arm on a fixed and on a floating base, a gripper with mimic joints.
fn models() -> Vec<Handles> {
    let floating = TREE.replace(r#"type="planar""#, r#"type="floating""#);
    vec![
        Handles::new(TREE, false),
        Handles::new(&floating, false),
        Handles::new(DEFAULT_ARM_URDF, false),
        Handles::new(DEFAULT_ARM_URDF, true),
        Handles::new(MIMIC_GRIPPER_URDF, false),
    ]
}

#[test]
fn answers_are_the_librarys() {
    for h in models() {
        let m = &h.library;
        let (nq, nv) = (m.nq(), m.nv());
        assert_eq!(
            unsafe { (sd_model_nq(h.model), sd_model_nv(h.model)) },
            (nq, nv)
        );
        let mut ws = Workspace::new(m);
        let (q, v, a) = h.state();
        let mut out = vec![f64::NAN; nv];
        assert_eq!(h.call(sd_rnea, &q, &v, &a, &mut out), OK);
        assert_eq!(out, rnea(m, &mut ws, &q, &v, &a).unwrap(), "{}", m.name());
        unsafe { assert_eq!(sd_gravity(h.model, h.ws, q.as_ptr(), out.as_mut_ptr()), OK) };
        assert_eq!(out, gravity(m, &mut ws, &q).unwrap(), "{}", m.name());
        // The method `auto` picks, which handles the gripper's mimic joints (aba does not).
        let method = choose_method(m, AUTO_TOLERANCE, Duration::ZERO)
            .unwrap()
            .method;
        let name = unsafe { CStr::from_ptr(sd_model_forward_dynamics_method(h.model)) };
        assert_eq!(name.to_str().unwrap(), method.name());
        assert_eq!(h.call(sd_forward_dynamics, &q, &v, &a, &mut out), OK);
        let expected =
            forward_dynamics(m, &mut ws, &q, &v, &a, method, &Externals::none()).unwrap();
        assert_eq!(out, expected, "{}", m.name());
        let mut matrix = vec![f64::NAN; nv * nv];
        unsafe {
            assert_eq!(
                sd_mass_matrix(h.model, h.ws, q.as_ptr(), matrix.as_mut_ptr()),
                OK
            )
        };
        let expected = crba(m, &mut ws, &q).unwrap();
        for r in 0..nv {
            assert_eq!(
                &matrix[r * nv..(r + 1) * nv],
                expected.row(r).iter().copied().collect::<Vec<_>>()
            );
        }
        for i in 0..nv {
            let name = unsafe { CStr::from_ptr(sd_model_v_name(h.model, i)) };
            assert_eq!(name.to_str().unwrap(), m.v_name(i));
        }
        assert!(unsafe { sd_model_v_name(h.model, nv) }.is_null());
        assert!(last_error().contains(&format!("index {nv} is out of range")));
        let mut j = vec![f64::NAN; 6 * nv];
        let references = [
            (SD_WORLD, ReferenceFrame::World),
            (SD_LOCAL, ReferenceFrame::Local),
            (SD_LOCAL_WORLD_ALIGNED, ReferenceFrame::LocalWorldAligned),
        ];
        for link in m.links() {
            let c_link = CString::new(link.name.as_str()).unwrap();
            let frame = find_frame(m, &link.name).unwrap();
            for (c_reference, reference) in references {
                let status = unsafe {
                    sd_frame_jacobian(
                        h.model,
                        h.ws,
                        q.as_ptr(),
                        c_link.as_ptr(),
                        c_reference as c_int,
                        j.as_mut_ptr(),
                    )
                };
                assert_eq!(status, OK);
                let expected = frame_jacobian(m, &mut ws, &q, &frame, reference).unwrap();
                for r in 0..6 {
                    let row: Vec<f64> = expected.row(r).iter().copied().collect();
                    assert_eq!(
                        &j[r * nv..(r + 1) * nv],
                        row,
                        "{} {} {reference:?}",
                        m.name(),
                        link.name
                    );
                }
            }
        }
    }
}

#[test]
fn an_output_may_be_an_input() {
    let h = Handles::new(DEFAULT_ARM_URDF, false);
    let (q, v, a) = h.state();
    let mut tau = vec![0.0; h.library.nv()];
    let mut in_place = a.clone();
    assert_eq!(h.call(sd_rnea, &q, &v, &a, &mut tau), OK);
    unsafe {
        let a_ptr = in_place.as_mut_ptr();
        assert_eq!(
            sd_rnea(h.model, h.ws, q.as_ptr(), v.as_ptr(), a_ptr, a_ptr),
            OK
        );
    }
    assert_eq!(in_place, tau);
}

#[test]
fn bad_input_gives_the_librarys_error_and_leaves_outputs() {
    let h = Handles::new(DEFAULT_ARM_URDF, false);
    let m = &h.library;
    let mut ws = Workspace::new(m);
    let (mut q, v, a) = h.state();
    q[2] = f64::NAN;
    let mut out = vec![7.0; m.nv()];
    assert_eq!(h.call(sd_rnea, &q, &v, &a, &mut out), INPUT);
    let expected = rnea(m, &mut ws, &q, &v, &a).unwrap_err().to_string();
    assert_eq!(last_error(), format!("sd_rnea: {expected}"));
    assert!(
        expected.contains("q[2]") && expected.contains("NaN"),
        "{expected}"
    );
    assert_eq!(out, vec![7.0; m.nv()]);
    // The message stays through a successful call.
    unsafe {
        assert_eq!(
            sd_gravity(h.model, h.ws, h.state().0.as_ptr(), out.as_mut_ptr()),
            OK
        )
    };
    assert_eq!(last_error(), format!("sd_rnea: {expected}"));
    type Call<'a> = Box<dyn Fn(*mut f64) -> c_int + 'a>;
    let calls: [(&str, Call); 3] = [
        (
            "sd_gravity",
            Box::new(|o| unsafe { sd_gravity(h.model, h.ws, q.as_ptr(), o) }),
        ),
        (
            "sd_mass_matrix",
            Box::new(|o| unsafe { sd_mass_matrix(h.model, h.ws, q.as_ptr(), o) }),
        ),
        (
            "sd_forward_dynamics",
            Box::new(|o| unsafe {
                sd_forward_dynamics(h.model, h.ws, q.as_ptr(), v.as_ptr(), a.as_ptr(), o)
            }),
        ),
    ];
    let mut big = vec![7.0; m.nv() * m.nv()];
    for (function, call) in calls {
        assert_eq!(call(big.as_mut_ptr()), INPUT, "{function}");
        assert_eq!(last_error(), format!("{function}: {expected}"));
    }
    assert!(big.iter().all(|&x| x == 7.0));
}

#[test]
fn an_unknown_frame_is_named_with_the_links() {
    let h = Handles::new(DEFAULT_ARM_URDF, false);
    let (q, _, _) = h.state();
    let mut j = vec![0.0; 6 * h.library.nv()];
    let name = CString::new("no_such_link").unwrap();
    let status = unsafe {
        sd_frame_jacobian(
            h.model,
            h.ws,
            q.as_ptr(),
            name.as_ptr(),
            SD_WORLD as c_int,
            j.as_mut_ptr(),
        )
    };
    assert_eq!(status, INPUT);
    let expected = find_frame(&h.library, "no_such_link")
        .unwrap_err()
        .to_string();
    assert_eq!(last_error(), format!("sd_frame_jacobian: {expected}"));
    assert!(expected.contains("no_such_link") && expected.contains(&h.library.links()[1].name));
    // A reference that is none of the three.
    let link = CString::new(h.library.links()[1].name.as_str()).unwrap();
    let status =
        unsafe { sd_frame_jacobian(h.model, h.ws, q.as_ptr(), link.as_ptr(), 3, j.as_mut_ptr()) };
    assert_eq!(status, USAGE);
    assert!(
        last_error().contains("reference 3 is not SD_WORLD"),
        "{}",
        last_error()
    );
    // A name that is not UTF-8.
    let bad = CString::new(vec![b'l', 0xff]).unwrap();
    let status = unsafe {
        sd_frame_jacobian(
            h.model,
            h.ws,
            q.as_ptr(),
            bad.as_ptr(),
            SD_WORLD as c_int,
            j.as_mut_ptr(),
        )
    };
    assert_eq!(status, USAGE);
    assert!(
        last_error().contains("frame is not UTF-8"),
        "{}",
        last_error()
    );
}

#[test]
fn a_bad_description_gives_null_and_the_reason() {
    let text = CString::new("<robot name='r'><link name='a'/><joint name='j' type='revolute'><parent link='a'/><child link='missing'/></joint></robot>").unwrap();
    let model = unsafe { sd_model_from_urdf_string(text.as_ptr(), ptr::null()) };
    assert!(model.is_null());
    let expected =
        urdf::model_from_str(text.to_str().unwrap(), &ModelOptions::default()).unwrap_err();
    assert_eq!(
        last_error(),
        format!("sd_model_from_urdf_string: {expected}")
    );
    let text = CString::new("<robot").unwrap();
    assert!(unsafe { sd_model_from_urdf_string(text.as_ptr(), ptr::null()) }.is_null());
    assert!(
        last_error().contains("cannot parse the URDF"),
        "{}",
        last_error()
    );
    let path = CString::new("/no/such/robot.urdf").unwrap();
    assert!(unsafe { sd_model_from_urdf_file(path.as_ptr(), ptr::null()) }.is_null());
    let message = last_error();
    assert!(
        message.contains("/no/such/robot.urdf") && message.contains("cannot read"),
        "{message}"
    );
}

#[test]
fn a_file_gives_the_model_of_its_text() {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../core/tests/models/tree.urdf");
    let path = CString::new(path.to_str().unwrap()).unwrap();
    let options = sd_model_options {
        floating_base: 1,
        ignore_mimic: 0,
    };
    let model = unsafe { sd_model_from_urdf_file(path.as_ptr(), &options) };
    assert!(!model.is_null(), "{}", last_error());
    let library = urdf::model_from_str(
        TREE,
        &ModelOptions {
            floating_base: true,
            ..ModelOptions::default()
        },
    )
    .unwrap();
    assert_eq!(
        unsafe { (sd_model_nq(model), sd_model_nv(model)) },
        (library.nq(), library.nv())
    );
    unsafe { sd_model_free(model) };
}

#[test]
fn ignore_mimic_gives_the_followers_coordinates() {
    let text = CString::new(MIMIC_GRIPPER_URDF).unwrap();
    let nv = |ignore_mimic| unsafe {
        let model = sd_model_from_urdf_string(
            text.as_ptr(),
            &sd_model_options {
                floating_base: 0,
                ignore_mimic,
            },
        );
        let nv = sd_model_nv(model);
        sd_model_free(model);
        nv
    };
    let options = |ignore_mimic| ModelOptions {
        ignore_mimic,
        ..ModelOptions::default()
    };
    assert_eq!(
        nv(0),
        urdf::model_from_str(MIMIC_GRIPPER_URDF, &options(false))
            .unwrap()
            .nv()
    );
    assert_eq!(
        nv(1),
        urdf::model_from_str(MIMIC_GRIPPER_URDF, &options(true))
            .unwrap()
            .nv()
    );
    assert!(nv(1) > nv(0));
}

#[test]
fn null_pointers_are_refused_by_name() {
    let h = Handles::new(DEFAULT_ARM_URDF, false);
    let (q, v, a) = h.state();
    let mut out = vec![0.0; h.library.nv() * h.library.nv()];
    let (o, n) = (out.as_mut_ptr(), ptr::null_mut::<f64>());
    let (q, v, a, null) = (q.as_ptr(), v.as_ptr(), a.as_ptr(), ptr::null::<f64>());
    let frame = CString::new(h.library.links()[1].name.as_str()).unwrap();
    let f = frame.as_ptr();
    let (model, ws) = (h.model as *const sd_model, h.ws);
    // The call is refused with USAGE and the message names the function and the pointer.
    macro_rules! refused {
        ($expected:literal, $call:expr) => {
            assert_eq!(unsafe { $call }, USAGE, $expected);
            assert_eq!(last_error(), $expected);
        };
    }
    refused!(
        "sd_rnea: model is NULL",
        sd_rnea(ptr::null(), ws, q, v, a, o)
    );
    refused!(
        "sd_rnea: workspace is NULL",
        sd_rnea(model, ptr::null_mut(), q, v, a, o)
    );
    refused!("sd_rnea: q is NULL", sd_rnea(model, ws, null, v, a, o));
    refused!("sd_rnea: v is NULL", sd_rnea(model, ws, q, null, a, o));
    refused!("sd_rnea: a is NULL", sd_rnea(model, ws, q, v, null, o));
    refused!("sd_rnea: tau is NULL", sd_rnea(model, ws, q, v, a, n));
    refused!("sd_gravity: q is NULL", sd_gravity(model, ws, null, o));
    refused!("sd_gravity: g is NULL", sd_gravity(model, ws, q, n));
    refused!(
        "sd_forward_dynamics: tau is NULL",
        sd_forward_dynamics(model, ws, q, v, null, o)
    );
    refused!(
        "sd_forward_dynamics: qdd is NULL",
        sd_forward_dynamics(model, ws, q, v, a, n)
    );
    refused!(
        "sd_mass_matrix: q is NULL",
        sd_mass_matrix(model, ws, null, o)
    );
    refused!("sd_mass_matrix: m is NULL", sd_mass_matrix(model, ws, q, n));
    refused!(
        "sd_frame_jacobian: frame is NULL",
        sd_frame_jacobian(model, ws, q, ptr::null(), 0, o)
    );
    refused!(
        "sd_frame_jacobian: j is NULL",
        sd_frame_jacobian(model, ws, q, f, 0, n)
    );
    refused!(
        "sd_frame_jacobian: q is NULL",
        sd_frame_jacobian(model, ws, null, f, 0, o)
    );
    assert!(out.iter().all(|&x| x == 0.0));
    unsafe {
        assert!(sd_model_from_urdf_string(ptr::null(), ptr::null()).is_null());
        assert_eq!(last_error(), "sd_model_from_urdf_string: urdf is NULL");
        assert!(sd_model_from_urdf_file(ptr::null(), ptr::null()).is_null());
        assert_eq!(last_error(), "sd_model_from_urdf_file: path is NULL");
        assert!(sd_workspace_new(ptr::null()).is_null());
        assert_eq!(last_error(), "sd_workspace_new: model is NULL");
        assert_eq!((sd_model_nq(ptr::null()), sd_model_nv(ptr::null())), (0, 0));
        assert!(sd_model_v_name(ptr::null(), 0).is_null());
        assert_eq!(last_error(), "sd_model_v_name: model is NULL");
        assert!(sd_model_forward_dynamics_method(ptr::null()).is_null());
        sd_model_free(ptr::null_mut());
        sd_workspace_free(ptr::null_mut());
    }
}

#[test]
fn a_workspace_of_another_model_is_refused() {
    let arm = Handles::new(DEFAULT_ARM_URDF, false);
    // Same description, another model: still not the workspace's.
    let twin = Handles::new(DEFAULT_ARM_URDF, false);
    let (q, v, a) = arm.state();
    let mut out = vec![7.0; arm.library.nv() * arm.library.nv()];
    let o = out.as_mut_ptr();
    let (q, v, a) = (q.as_ptr(), v.as_ptr(), a.as_ptr());
    let frame = CString::new(arm.library.links()[1].name.as_str()).unwrap();
    let (model, ws) = (twin.model as *const sd_model, arm.ws);
    unsafe {
        let statuses = [
            ("sd_rnea", sd_rnea(model, ws, q, v, a, o)),
            ("sd_gravity", sd_gravity(model, ws, q, o)),
            (
                "sd_forward_dynamics",
                sd_forward_dynamics(model, ws, q, v, a, o),
            ),
            ("sd_mass_matrix", sd_mass_matrix(model, ws, q, o)),
            (
                "sd_rnea_derivatives",
                sd_rnea_derivatives(model, ws, q, v, a, o, o, o),
            ),
            (
                "sd_aba_derivatives",
                sd_aba_derivatives(model, ws, q, v, a, o, o, o),
            ),
            (
                "sd_frame_jacobian",
                sd_frame_jacobian(model, ws, q, frame.as_ptr(), 0, o),
            ),
        ];
        for (function, status) in statuses {
            assert_eq!(status, USAGE, "{function}");
        }
        assert!(
            last_error().starts_with("sd_frame_jacobian: the workspace was made for model"),
            "{}",
            last_error()
        );
        assert_eq!(sd_gravity(arm.model, arm.ws, q, o), OK);
    }
    assert!(out[arm.library.nv()..].iter().all(|&x| x == 7.0));
}

#[test]
fn a_model_without_coordinates_answers_with_empty_arrays() {
    let text = CString::new(
        "<robot name='block'><link name='base'><inertial><mass value='1'/>\
         <inertia ixx='1' iyy='1' izz='1' ixy='0' ixz='0' iyz='0'/></inertial></link></robot>",
    )
    .unwrap();
    unsafe {
        let model = sd_model_from_urdf_string(text.as_ptr(), ptr::null());
        assert!(!model.is_null(), "{}", last_error());
        assert_eq!((sd_model_nq(model), sd_model_nv(model)), (0, 0));
        let ws = sd_workspace_new(model);
        let (none, out) = (ptr::null::<f64>(), ptr::null_mut::<f64>());
        assert_eq!(sd_rnea(model, ws, none, none, none, out), OK);
        assert_eq!(sd_gravity(model, ws, none, out), OK);
        assert_eq!(sd_forward_dynamics(model, ws, none, none, none, out), OK);
        assert_eq!(sd_mass_matrix(model, ws, none, out), OK);
        let base = CString::new("base").unwrap();
        assert_eq!(
            sd_frame_jacobian(model, ws, none, base.as_ptr(), 0, out),
            OK
        );
        sd_workspace_free(ws);
        sd_model_free(model);
    }
}

/// `matrix` row by row.
fn row_major(matrix: &nalgebra::DMatrix<f64>) -> Vec<f64> {
    matrix.transpose().as_slice().to_vec()
}

#[test]
fn derivatives_are_the_library_s_row_major() {
    for h in models() {
        let m = &h.library;
        let nv = m.nv();
        let mut ws = Workspace::new(m);
        let (q, v, a) = h.state();
        let mut outs = [
            vec![f64::NAN; nv * nv],
            vec![f64::NAN; nv * nv],
            vec![f64::NAN; nv * nv],
        ];
        let status = h.derivatives(sd_rnea_derivatives, &q, &v, &a, &mut outs);
        assert_eq!(status, OK, "{}", m.name());
        let d = rnea_derivatives(m, &mut ws, &q, &v, &a).unwrap();
        let expected = [
            row_major(d.dtau_dq),
            row_major(d.dtau_dv),
            row_major(d.mass_matrix),
        ];
        assert_eq!(outs, expected, "{}", m.name());
        // The effort that the acceleration `a` needs, so that forward dynamics is well away from
        // anything singular.
        let tau = rnea(m, &mut ws, &q, &v, &a).unwrap().to_vec();
        let status = h.derivatives(sd_aba_derivatives, &q, &v, &tau, &mut outs);
        assert_eq!(status, OK, "{}", m.name());
        let d = aba_derivatives(m, &mut ws, &q, &v, &tau, &Externals::none()).unwrap();
        let expected = [row_major(d.ddq_dq), row_major(d.ddq_dv), row_major(d.minv)];
        assert_eq!(outs, expected, "{}", m.name());
    }
}

#[test]
fn derivatives_refuse_bad_input_and_null_outputs_untouched() {
    let h = Handles::new(DEFAULT_ARM_URDF, false);
    let nv = h.library.nv();
    let (mut q, v, a) = h.state();
    q[2] = f64::NAN;
    let mut out = vec![7.0; nv * nv];
    let o = out.as_mut_ptr();
    let (q, v, a) = (q.as_ptr(), v.as_ptr(), a.as_ptr());
    unsafe {
        let functions: [(&str, DerivativesFn); 2] = [
            ("sd_rnea_derivatives", sd_rnea_derivatives),
            ("sd_aba_derivatives", sd_aba_derivatives),
        ];
        for (function, f) in functions {
            assert_eq!(f(h.model, h.ws, q, v, a, o, o, o), INPUT, "{function}");
            let message = last_error();
            assert!(
                message.starts_with(&format!("{function}: ")) && message.contains("q[2]"),
                "{message}"
            );
        }
        let n = ptr::null_mut();
        assert_eq!(sd_rnea_derivatives(h.model, h.ws, q, v, a, o, n, o), USAGE);
        assert_eq!(last_error(), "sd_rnea_derivatives: dtau_dv is NULL");
        assert_eq!(sd_aba_derivatives(h.model, h.ws, q, v, a, o, o, n), USAGE);
        assert_eq!(last_error(), "sd_aba_derivatives: minv is NULL");
    }
    assert!(out.iter().all(|&x| x == 7.0));
}

/// A model or workspace used after it was freed, or freed twice, is a usage error naming it:
/// the handle stays allocated, empty.
#[test]
fn a_freed_handle_is_refused_by_name() {
    let h = Handles::new(DEFAULT_ARM_URDF, false);
    let (q, _, _) = h.state();
    let mut g = vec![7.0; h.library.nv()];
    unsafe {
        sd_workspace_free(h.ws);
        sd_workspace_free(h.ws);
        assert_eq!(sd_gravity(h.model, h.ws, q.as_ptr(), g.as_mut_ptr()), USAGE);
        assert!(
            last_error().contains("workspace was freed"),
            "{}",
            last_error()
        );
        let ws = sd_workspace_new(h.model);
        sd_model_free(h.model);
        assert_eq!(sd_gravity(h.model, ws, q.as_ptr(), g.as_mut_ptr()), USAGE);
        assert!(last_error().contains("model was freed"), "{}", last_error());
        assert_eq!(sd_model_nq(h.model), 0);
        assert!(sd_model_v_name(h.model, 0).is_null());
        assert!(sd_workspace_new(h.model).is_null());
        assert_eq!(sd_last_status(), USAGE);
        sd_workspace_free(ws);
    }
    assert!(g.iter().all(|&x| x == 7.0), "outputs untouched");
    // `Handles` frees both again on drop: nothing happens.
}

/// Two threads calling with one workspace never get a wrong answer: a call that finds the
/// workspace in use is refused (`SD_ERROR_USAGE`, naming it), the others answer exactly.
#[test]
fn a_workspace_in_use_is_refused_not_shared() {
    let h = Handles::new(DEFAULT_ARM_URDF, false);
    let (q, v, a) = h.state();
    let nv = h.library.nv();
    let mut want = vec![0.0; nv];
    assert_eq!(h.call(sd_rnea, &q, &v, &a, &mut want), OK);
    let (model, ws) = (h.model as usize, h.ws as usize);
    let run = |seed: f64| {
        let (q, v, a, want) = (q.clone(), v.clone(), a.clone(), want.clone());
        std::thread::spawn(move || {
            let (mut wrong, mut refused) = (0, 0);
            for k in 0..100_000 {
                let mut tau = vec![seed + k as f64; nv];
                let status = unsafe {
                    sd_rnea(
                        model as *const sd_model,
                        ws as *mut sd_workspace,
                        q.as_ptr(),
                        v.as_ptr(),
                        a.as_ptr(),
                        tau.as_mut_ptr(),
                    )
                };
                match status {
                    OK => wrong += usize::from(tau != want),
                    USAGE => {
                        assert!(last_error().contains("in use by another call"));
                        refused += 1;
                    }
                    other => panic!("status {other}: {}", last_error()),
                }
            }
            (wrong, refused)
        })
    };
    let (one, two) = (run(1.0), run(2.0));
    let (one, two) = (one.join().unwrap(), two.join().unwrap());
    assert_eq!(
        (one.0, two.0),
        (0, 0),
        "wrong answers with SD_OK (refused: {one:?} {two:?})"
    );
}

/// An array that is not aligned for `double` is refused naming it, input or output.
#[test]
fn a_misaligned_array_is_refused_by_name() {
    let h = Handles::new(DEFAULT_ARM_URDF, false);
    let (q, _, _) = h.state();
    let nq = q.len();
    let mut bytes = vec![0u8; 8 * nq + 8];
    let odd = unsafe { bytes.as_mut_ptr().add(1) } as *mut f64;
    unsafe { ptr::copy_nonoverlapping(q.as_ptr() as *const u8, odd as *mut u8, 8 * nq) };
    let mut g = vec![0.0; h.library.nv()];
    assert_eq!(
        unsafe { sd_gravity(h.model, h.ws, odd, g.as_mut_ptr()) },
        USAGE
    );
    assert!(
        last_error().contains("q is not aligned"),
        "{}",
        last_error()
    );
    assert_eq!(unsafe { sd_gravity(h.model, h.ws, q.as_ptr(), odd) }, USAGE);
    assert!(
        last_error().contains("g is not aligned"),
        "{}",
        last_error()
    );
}

/// `sd_last_status` gives the code of the last failed call on the thread: what a function
/// returning NULL failed with.
#[test]
fn the_last_status_is_the_last_failed_call_s_code() {
    std::thread::spawn(|| {
        assert_eq!(sd_last_status(), OK);
        let broken = CString::new("<robot name='a'><link").unwrap();
        assert!(unsafe { sd_model_from_urdf_string(broken.as_ptr(), ptr::null()) }.is_null());
        assert_eq!(sd_last_status(), INPUT);
        assert!(unsafe { sd_workspace_new(ptr::null()) }.is_null());
        assert_eq!(sd_last_status(), USAGE);
        let h = Handles::new(DEFAULT_ARM_URDF, false);
        assert_eq!(unsafe { sd_model_nq(h.model) }, 7);
        assert_eq!(sd_last_status(), USAGE, "a success leaves it");
    })
    .join()
    .unwrap();
}

/// A path is its bytes (Unix): a file whose name is not UTF-8 is read.
#[cfg(unix)]
#[test]
fn a_path_that_is_not_utf8_is_read() {
    use std::os::unix::ffi::OsStrExt;
    let dir = std::env::temp_dir().join(format!("sd_abi_path_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(std::ffi::OsStr::from_bytes(b"tree-\xff.urdf"));
    std::fs::write(&path, TREE).unwrap();
    let c_path = CString::new(path.as_os_str().as_bytes()).unwrap();
    let model = unsafe { sd_model_from_urdf_file(c_path.as_ptr(), ptr::null()) };
    std::fs::remove_dir_all(&dir).unwrap();
    assert!(!model.is_null(), "{}", last_error());
    unsafe { sd_model_free(model) };
}

/// A failing call from a thread-local destructor, after the library's own thread-local state
/// is gone, returns its code (without a message) instead of aborting the process.
#[test]
fn a_failing_call_during_thread_teardown_returns_its_code() {
    use std::sync::atomic::{AtomicI32, Ordering};
    static STATUS: AtomicI32 = AtomicI32::new(-1);
    struct CallsOnDrop;
    impl Drop for CallsOnDrop {
        fn drop(&mut self) {
            let status =
                unsafe { sd_gravity(ptr::null(), ptr::null_mut(), ptr::null(), ptr::null_mut()) };
            STATUS.store(status, Ordering::SeqCst);
        }
    }
    thread_local! {
        static LATE: CallsOnDrop = const { CallsOnDrop };
    }
    std::thread::spawn(|| {
        // Registered first, destroyed last: after the library's message of the call below.
        LATE.with(|_| {});
        assert_eq!(sd_last_status(), OK);
        let _ = unsafe { sd_gravity(ptr::null(), ptr::null_mut(), ptr::null(), ptr::null_mut()) };
    })
    .join()
    .unwrap();
    assert_eq!(STATUS.load(Ordering::SeqCst), USAGE);
}

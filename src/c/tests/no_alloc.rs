//! No call through the C ABI allocates once its model and workspace are made: every function,
//! on a warmed-up workspace, makes zero heap allocations (counted by a global allocator; this
//! file holds one test so nothing else runs in the process while it counts).

#[path = "../../core/tests/common/mod.rs"]
mod common;
use common::allocations_during;

use spatial_dynamics_c::derivatives::*;
use spatial_dynamics_c::dynamics::*;
use spatial_dynamics_c::frames::sd_reference_frame::*;
use spatial_dynamics_c::frames::*;
use spatial_dynamics_c::model::*;
use spatial_dynamics_c::workspace::*;
use std::ffi::{c_int, CString};
use std::ptr;

#[global_allocator]
static GLOBAL: common::Counting = common::Counting;

#[test]
fn calls_do_not_allocate() {
    // The counter does count: a fresh vector is one allocation.
    assert_eq!(
        allocations_during(|| drop(std::hint::black_box(vec![1u8; 16]))),
        1
    );
    let tree = include_str!("../../core/tests/models/tree.urdf");
    let floating = tree.replace(r#"type="planar""#, r#"type="floating""#);
    let gripper = spatial_dynamics_core::model::examples::MIMIC_GRIPPER_URDF;
    for (text, floating_base, link) in [
        (tree, 0, "right_hand"),
        (floating.as_str(), 0, "right_hand"),
        (
            spatial_dynamics_core::model::examples::DEFAULT_ARM_URDF,
            1,
            "link7",
        ),
        (gripper, 0, "thumb_link"),
    ] {
        let text = CString::new(text).unwrap();
        let options = sd_model_options {
            floating_base,
            ignore_mimic: 0,
        };
        let model = unsafe { sd_model_from_urdf_string(text.as_ptr(), &options) };
        assert!(!model.is_null());
        let ws = unsafe { sd_workspace_new(model) };
        let (nq, nv) = unsafe { (sd_model_nq(model), sd_model_nv(model)) };
        let mut q = vec![0.1; nq];
        if nq > nv {
            q[3..7].copy_from_slice(&[0.0, 0.0, 0.0, 1.0]);
        }
        let (v, a) = (vec![0.2; nv], vec![-0.3; nv]);
        let mut out = vec![0.0; 6 * nv.max(1) + nv * nv];
        let (mut o1, mut o2) = (vec![0.0; nv * nv], vec![0.0; nv * nv]);
        let (o, p1, p2) = (out.as_mut_ptr(), o1.as_mut_ptr(), o2.as_mut_ptr());
        let frame = CString::new(link).unwrap();
        let run_all = || unsafe {
            let mut status = 0;
            status |= sd_rnea(model, ws, q.as_ptr(), v.as_ptr(), a.as_ptr(), o);
            status |= sd_gravity(model, ws, q.as_ptr(), o);
            status |= sd_forward_dynamics(model, ws, q.as_ptr(), v.as_ptr(), a.as_ptr(), o);
            status |= sd_mass_matrix(model, ws, q.as_ptr(), o);
            status |= sd_rnea_derivatives(model, ws, q.as_ptr(), v.as_ptr(), a.as_ptr(), o, p1, p2);
            status |= sd_aba_derivatives(model, ws, q.as_ptr(), v.as_ptr(), a.as_ptr(), o, p1, p2);
            for reference in [SD_WORLD, SD_LOCAL, SD_LOCAL_WORLD_ALIGNED] {
                status |=
                    sd_frame_jacobian(model, ws, q.as_ptr(), frame.as_ptr(), reference as c_int, o);
            }
            status |= (sd_model_nq(model) == 0) as c_int;
            status |= sd_model_v_name(model, 0).is_null() as c_int;
            status |= sd_model_forward_dynamics_method(model).is_null() as c_int;
            assert_eq!(status, 0);
        };
        run_all();
        assert_eq!(
            allocations_during(run_all),
            0,
            "floating_base {floating_base}"
        );
        unsafe {
            sd_workspace_free(ws);
            sd_model_free(model);
        }
    }
    // And a failing call does allocate (its message), so the count above means something.
    assert!(
        allocations_during(|| unsafe {
            assert_ne!(
                sd_gravity(ptr::null(), ptr::null_mut(), ptr::null(), ptr::null_mut()),
                0
            );
        }) > 0
    );
}

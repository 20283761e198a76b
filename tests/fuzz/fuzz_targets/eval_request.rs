//! The `eval` command's request handling (`spatial_dynamics_core::requests`): any line of bytes is
//! answered with one JSON object, either `{"error": "<a reason>"}` alone or the result (one key,
//! or several for the derivative requests), whose numbers are all finite (JSON has no NaN: a NaN
//! would come out as `null`). Never a panic.
#![no_main]

use libfuzzer_sys::fuzz_target;
use serde_json::Value;
use spatial_dynamics_core::model::examples::{DEFAULT_ARM_URDF, LAMP_URDF, MIMIC_GRIPPER_URDF};
use spatial_dynamics_core::requests::answer_line;
use spatial_dynamics_core::{urdf, Model, ModelOptions, Workspace};
use std::sync::OnceLock;

/// A revolute joint carrying a prismatic one: the mass matrix holds `m x²`, so a finite
/// `x = 1e200` overflows it.
const TURN_SLIDE_URDF: &str = include_str!("../../../src/core/tests/models/turn_slide.urdf");

/// The robots the requests go to: a fixed-base arm, a planar-base model with a fused link, a
/// gripper with mimic joints, a turning slide, and the arm on a floating base.
fn models() -> &'static [Model] {
    static MODELS: OnceLock<Vec<Model>> = OnceLock::new();
    MODELS.get_or_init(|| {
        let floating = ModelOptions {
            floating_base: true,
            ..Default::default()
        };
        [
            (DEFAULT_ARM_URDF, ModelOptions::default()),
            (LAMP_URDF, ModelOptions::default()),
            (MIMIC_GRIPPER_URDF, ModelOptions::default()),
            (TURN_SLIDE_URDF, ModelOptions::default()),
            (DEFAULT_ARM_URDF, floating),
        ]
        .iter()
        .map(|(text, options)| urdf::model_from_str(text, options).expect("example model"))
        .collect()
    })
}

/// Every number in the answer is finite, and there is no `null` (a NaN or infinity turned into
/// JSON).
fn all_finite(value: &Value) -> bool {
    match value {
        Value::Null => false,
        Value::Number(n) => n.as_f64().is_some_and(f64::is_finite),
        Value::Array(items) => items.iter().all(all_finite),
        Value::Object(fields) => fields.values().all(all_finite),
        Value::Bool(_) | Value::String(_) => true,
    }
}

fuzz_target!(|data: &[u8]| {
    for model in models() {
        let mut ws = Workspace::new(model);
        let answer = answer_line(model, &mut ws, data);
        let object = answer.as_object().expect("an answer is a JSON object");
        assert!(!object.is_empty(), "an empty answer");
        match object.get("error") {
            Some(Value::String(reason)) => {
                assert!(!reason.is_empty(), "empty error");
                assert_eq!(object.len(), 1, "an error with a result: {answer}");
            }
            Some(other) => panic!("error is not a string: {other}"),
            None => assert!(
                all_finite(&answer),
                "non-finite answer to a good request: {answer}"
            ),
        }
        // The line printed parses back to the same answer.
        let printed = answer.to_string();
        assert_eq!(serde_json::from_str::<Value>(&printed).unwrap(), answer);
    }
});

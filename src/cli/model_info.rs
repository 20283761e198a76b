//! `spatial_dynamics model`: the model's coordinates, as JSON or as a table.

use super::ModelArgs;
use serde_json::json;
use std::fmt::Write as _;
use std::io::Write as _;

/// Prints the coordinate joints of the model. Output cut short by its reader (`| head`) ends
/// the command quietly, as it does any Unix tool.
pub fn run(args: &ModelArgs, as_json: bool) -> Result<(), String> {
    let text = describe(args, as_json)?;
    let mut out = std::io::stdout().lock();
    match out.write_all(text.as_bytes()).and_then(|_| out.flush()) {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => Err(format!("writing stdout: {e}")),
        _ => Ok(()),
    }
}

/// What [`run`] prints.
fn describe(args: &ModelArgs, as_json: bool) -> Result<String, String> {
    let model = args.load()?;
    let mut out = String::new();
    if as_json {
        let joints: Vec<_> = model
            .coordinate_joints()
            .map(|j| json!({"name": j.name, "type": j.kind.type_name(), "q_index": j.q_index, "nq": j.nq, "v_index": j.v_index, "nv": j.nv}))
            .collect();
        let r = model.reduction();
        let reduction = json!({
            "root": r.root, "tips": r.tips,
            "frozen_joints": r.frozen_joints, "payload_links": r.payload_links,
            "removed_links": r.removed_links, "pruned_joints": r.pruned_joints,
            "pruned_links": r.pruned_links,
        });
        let locked: Vec<_> = model
            .locked_joints()
            .iter()
            .map(|(n, v)| json!([n, v]))
            .collect();
        let _ = writeln!(
            out,
            "{}",
            json!({"nq": model.nq(), "nv": model.nv(), "nbodies": model.nbodies(), "joints": joints,
                   "locked_joints": locked, "fused_links": model.fused_links(), "reduction": reduction})
        );
        return Ok(out);
    }
    let _ = writeln!(
        out,
        "robot '{}': nq = {}, nv = {}, {} bodies, root link '{}'",
        model.name(),
        model.nq(),
        model.nv(),
        model.nbodies(),
        model.root_link()
    );
    let _ = writeln!(
        out,
        "{:<24} {:<11} {:>7} {:>4} {:>7} {:>4}",
        "joint", "type", "q_index", "nq", "v_index", "nv"
    );
    for j in model.coordinate_joints() {
        let _ = writeln!(
            out,
            "{:<24} {:<11} {:>7} {:>4} {:>7} {:>4}",
            j.name,
            j.kind.type_name(),
            j.q_index,
            j.nq,
            j.v_index,
            j.nv
        );
    }
    for b in model.bodies() {
        if let Some(m) = &b.joint.mimics {
            let _ = writeln!(
                out,
                "mimic: '{}' = {} × '{}' + {}",
                b.joint.name, m.multiplier, m.leader, m.offset
            );
        }
    }
    for (name, value) in model.locked_joints() {
        let _ = writeln!(out, "locked: '{name}' at {value}");
    }
    for line in model.reduction().summary() {
        let _ = writeln!(out, "reduced: {line}");
    }
    if !model.fused_links().is_empty() {
        let _ = writeln!(
            out,
            "fused (fixed joints): {}",
            model.fused_links().join(", ")
        );
    }
    Ok(out)
}

//! The bag readers (`src/bag/`, compiled here from their own source files) over arbitrary bytes:
//! the first byte chooses what the rest is read as: an MCAP file, an sqlite3 database (both
//! written to a scratch file and opened as a bag: topics listed, every message of two topics
//! read and its JointState, String or Float64MultiArray decoded), or one CDR
//! `sensor_msgs/JointState` or `std_msgs/Float64MultiArray`.
//!
//! Checked: never a panic, an abort or an allocation of a size the input claims (libFuzzer's
//! malloc limit); a failure is an `Err` with a message.
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::PathBuf;

#[allow(dead_code, unused_imports)]
#[path = "../../../src/bag/mod.rs"]
mod bag;

use bag::{cdr, Bag, Flow, Wanted};

const WANTED: [Wanted<'static>; 3] = [
    Wanted {
        topic: "/joint_states",
        type_name: "sensor_msgs/msg/JointState",
    },
    Wanted {
        topic: "/robot_description",
        type_name: "std_msgs/msg/String",
    },
    Wanted {
        topic: "/spatial_dynamics/commands",
        type_name: "std_msgs/msg/Float64MultiArray",
    },
];

fn joint_state(data: &[u8], names: &mut Vec<std::ops::Range<usize>>) -> Result<f64, String> {
    let view = cdr::parse_joint_state(data, names)?;
    let mut sum = 0.0;
    for r in names.iter() {
        sum += view.name_bytes(r).len() as f64;
    }
    for values in [&view.position, &view.velocity, &view.effort] {
        sum += values.iter().sum::<f64>();
    }
    Ok(sum)
}

fn multi_array(data: &[u8]) -> Result<f64, String> {
    Ok(cdr::parse_float64_multi_array(data)?.iter().sum())
}

fn scratch(ext: &str) -> PathBuf {
    let dir = if std::path::Path::new("/dev/shm").is_dir() {
        PathBuf::from("/dev/shm")
    } else {
        std::env::temp_dir()
    };
    dir.join(format!("sd_fuzz_bag_{}.{ext}", std::process::id()))
}

fn as_bag(bytes: &[u8], ext: &str) {
    let path = scratch(ext);
    std::fs::write(&path, bytes).expect("scratch file");
    if let Ok(bag) = Bag::open(&path, &Default::default()) {
        let _ = bag.topics();
        let mut names = Vec::new();
        let mut notes = Vec::new();
        let _ = bag.read_noting(
            &WANTED,
            &mut |m| {
                match m.topic {
                    0 => drop(joint_state(m.data, &mut names)),
                    1 => drop(cdr::parse_string(m.data)),
                    _ => drop(multi_array(m.data)),
                }
                Ok(Flow::Continue)
            },
            &mut notes,
        );
    }
    let _ = std::fs::remove_file(&path);
}

fuzz_target!(|data: &[u8]| {
    let Some((&kind, rest)) = data.split_first() else {
        return;
    };
    match kind % 4 {
        0 => as_bag(rest, "mcap"),
        1 => as_bag(rest, "db3"),
        2 => {
            let _ = joint_state(rest, &mut Vec::new());
        }
        _ => {
            let _ = multi_array(rest);
        }
    }
});

//! ROS-style command-line arguments (`--ros-args …`); names resolve by
//! [`NameResolver`](crate::ros::names::NameResolver).
//!
//! Understood: `-r/--remap FROM:=TO` (including `__node:=NAME` and `__ns:=/NS`),
//! `-p/--param NAME:=VALUE` (VALUE in YAML, as `ros2 run` reads it), `--params-file FILE`,
//! `--log-level LEVEL` and `--log-level LOGGER:=LEVEL` (see [`super::logging`]), and `--` or
//! `--ros-args` boundaries.

use super::logging::Level;
use std::path::PathBuf;

/// What the ROS arguments asked for.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RosArgs {
    /// `-r __node:=NAME`.
    pub node_name: Option<String>,
    /// `-r __ns:=/NS`.
    pub namespace: Option<String>,
    /// `-r FROM:=TO` topic and service remappings, in order.
    pub remaps: Vec<(String, String)>,
    /// `-p NAME:=VALUE` (VALUE as written, YAML).
    pub params: Vec<(String, String)>,
    /// `--params-file FILE`, in order (later files and `-p` override earlier ones).
    pub params_files: Vec<PathBuf>,
    /// `--log-level [LOGGER:=]LEVEL`, in order (`None`: every logger's default).
    pub log_levels: Vec<(Option<String>, Level)>,
}

impl RosArgs {
    /// Parses the arguments after the subcommand. Arguments outside `--ros-args … [--]` are
    /// refused with a message, like any unknown flag.
    pub fn parse(args: &[String]) -> Result<RosArgs, String> {
        let mut out = RosArgs::default();
        let mut in_ros_args = false;
        let mut it = args.iter();
        while let Some(arg) = it.next() {
            let mut value = |flag: &str| {
                it.next()
                    .cloned()
                    .ok_or_else(|| format!("{flag} needs a value"))
            };
            match arg.as_str() {
                "--ros-args" => in_ros_args = true,
                "--" => in_ros_args = false,
                "-r" | "--remap" if in_ros_args => {
                    let rule = value(arg)?;
                    let (from, to) = split_rule(&rule, arg)?;
                    match from {
                        "__node" | "__name" => out.node_name = Some(to.to_string()),
                        "__ns" => out.namespace = Some(to.to_string()),
                        _ => out.remaps.push((from.to_string(), to.to_string())),
                    }
                }
                "-p" | "--param" if in_ros_args => {
                    let rule = value(arg)?;
                    let (name, v) = split_rule(&rule, arg)?;
                    out.params.push((name.to_string(), v.to_string()));
                }
                "--params-file" if in_ros_args => out.params_files.push(PathBuf::from(value(arg)?)),
                "--log-level" if in_ros_args => {
                    let setting = value(arg)?;
                    out.log_levels.push(match setting.split_once(":=") {
                        Some((logger, level)) if !logger.is_empty() => {
                            (Some(logger.to_string()), Level::parse(level)?)
                        }
                        _ => (None, Level::parse(&setting)?),
                    });
                }
                other => return Err(format!("unexpected argument '{other}' (node arguments go after --ros-args: -r, -p, --params-file)")),
            }
        }
        Ok(out)
    }
}

fn split_rule<'a>(rule: &'a str, flag: &str) -> Result<(&'a str, &'a str), String> {
    rule.split_once(":=")
        .filter(|(a, b)| !a.is_empty() && !b.is_empty())
        .ok_or_else(|| format!("{flag} '{rule}': expected NAME:=VALUE"))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn strings(a: &[&str]) -> Vec<String> {
        a.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn parses_ros_args() {
        let args = RosArgs::parse(&strings(&[
            "--ros-args",
            "-r",
            "__node:=dyn",
            "-r",
            "__ns:=/robot",
            "-r",
            "joint_states:=/arm/joint_states",
            "--params-file",
            "a.yaml",
            "-p",
            "gravity:=[0.0, 0.0, -1.62]",
            "--log-level",
            "debug",
            "--log-level",
            "robot.dyn:=WARN",
        ]))
        .unwrap();
        assert_eq!(
            args.log_levels,
            vec![
                (None, Level::Debug),
                (Some("robot.dyn".to_string()), Level::Warn)
            ]
        );
        assert_eq!(args.node_name.as_deref(), Some("dyn"));
        assert_eq!(args.namespace.as_deref(), Some("/robot"));
        assert_eq!(
            args.remaps,
            vec![("joint_states".to_string(), "/arm/joint_states".to_string())]
        );
        assert_eq!(
            args.params,
            vec![("gravity".to_string(), "[0.0, 0.0, -1.62]".to_string())]
        );
        assert_eq!(args.params_files, vec![PathBuf::from("a.yaml")]);
        assert!(RosArgs::parse(&strings(&["-p", "x:=1"]))
            .unwrap_err()
            .contains("--ros-args"));
        assert!(RosArgs::parse(&strings(&["--ros-args", "-p", "x"]))
            .unwrap_err()
            .contains("NAME:=VALUE"));
        assert!(RosArgs::parse(&strings(&["--ros-args", "-r"]))
            .unwrap_err()
            .contains("needs a value"));
        assert!(
            RosArgs::parse(&strings(&["--ros-args", "--log-level", "loud"]))
                .unwrap_err()
                .contains("unknown severity 'loud'")
        );
    }
}

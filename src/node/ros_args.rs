//! ROS-style command-line arguments (`--ros-args …`); names resolve by
//! [`NameResolver`](crate::ros::names::NameResolver).
//!
//! Understood: `-r/--remap [NODE:]FROM:=TO` (including `__node:=NAME` and `__ns:=/NS`; a rule
//! prefixed `NODE:` applies only to the node of that name, as in rcl),
//! `-p/--param NAME:=VALUE` (VALUE in YAML, as `ros2 run` reads it), `--params-file FILE`,
//! `--log-level LEVEL` and `--log-level LOGGER:=LEVEL` (see [`super::logging`]), and `--` or
//! `--ros-args` boundaries.

use super::logging::Level;
use std::path::PathBuf;

/// What the ROS arguments asked for.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RosArgs {
    /// `-r [NODE:]FROM:=TO` rules, in order (`__node`, `__ns` and name remappings).
    pub rules: Vec<RemapRule>,
    /// `-p NAME:=VALUE` (VALUE as written, YAML).
    pub params: Vec<(String, String)>,
    /// `--params-file FILE`, in order (later files and `-p` override earlier ones).
    pub params_files: Vec<PathBuf>,
    /// `--log-level [LOGGER:=]LEVEL`, in order (`None`: every logger's default).
    pub log_levels: Vec<(Option<String>, Level)>,
}

/// One `-r [NODE:]FROM:=TO` rule.
#[derive(Clone, Debug, PartialEq)]
pub struct RemapRule {
    /// The node the rule is for (`None`: every node).
    pub node: Option<String>,
    pub from: String,
    pub to: String,
}

/// The remapping rules that apply to one node, as rcl applies them: the first matching rule
/// wins; `__node` and `__ns` rules are matched on the node's own name, name rules on its name
/// after `__node`.
#[derive(Clone, Debug, PartialEq)]
pub struct NodeRemaps {
    pub node_name: String,
    pub namespace: Option<String>,
    /// Topic and service remappings `(FROM, TO)`, in order.
    pub remaps: Vec<(String, String)>,
    /// The rules written for other nodes (`NODE:FROM:=TO`), which apply to none here.
    pub other_nodes: Vec<String>,
}

impl RosArgs {
    /// The rules for the node named `name` in the code (before `__node`).
    pub fn for_node(&self, name: &str) -> NodeRemaps {
        let applies = |rule: &RemapRule, to: &str| rule.node.as_deref().is_none_or(|n| n == to);
        let first = |keys: &[&str]| {
            self.rules
                .iter()
                .find(|r| keys.contains(&r.from.as_str()) && applies(r, name))
                .map(|r| r.to.clone())
        };
        let node_name = first(&["__node", "__name"]).unwrap_or_else(|| name.to_string());
        let namespace = first(&["__ns"]);
        let special = |r: &RemapRule| matches!(r.from.as_str(), "__node" | "__name" | "__ns");
        let remaps = self
            .rules
            .iter()
            .filter(|r| !special(r) && applies(r, &node_name));
        let other_nodes = self.rules.iter().filter(|r| {
            r.node.is_some() && !applies(r, if special(r) { name } else { &node_name })
        });
        NodeRemaps {
            remaps: remaps.map(|r| (r.from.clone(), r.to.clone())).collect(),
            other_nodes: other_nodes
                .map(|r| format!("{}:{}:={}", r.node.as_deref().unwrap_or(""), r.from, r.to))
                .collect(),
            node_name,
            namespace,
        }
    }

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
                    let (node, from) = match from.split_once(':') {
                        Some((node, from)) if !node.is_empty() && !from.is_empty() => {
                            (Some(node.to_string()), from)
                        }
                        Some(_) => return Err(format!("{arg} '{rule}': expected [NODE:]FROM:=TO")),
                        None => (None, from),
                    };
                    out.rules.push(RemapRule {
                        node,
                        from: from.to_string(),
                        to: to.to_string(),
                    });
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
    use crate::ros::names::NameResolver;

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
        let node = args.for_node("spatial_dynamics");
        assert_eq!(node.node_name, "dyn");
        assert_eq!(node.namespace.as_deref(), Some("/robot"));
        assert_eq!(
            node.remaps,
            vec![("joint_states".to_string(), "/arm/joint_states".to_string())]
        );
        assert!(node.other_nodes.is_empty());
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
        assert!(RosArgs::parse(&strings(&["--ros-args", "-r", ":a:=b"]))
            .unwrap_err()
            .contains("[NODE:]FROM:=TO"));
        assert!(RosArgs::parse(&strings(&["--ros-args", "-r"]))
            .unwrap_err()
            .contains("needs a value"));
        assert!(
            RosArgs::parse(&strings(&["--ros-args", "--log-level", "loud"]))
                .unwrap_err()
                .contains("unknown severity 'loud'")
        );
    }

    /// Rules prefixed `NODE:` apply to that node only, as in rcl: `__node` and `__ns` rules
    /// match the node's own name, name rules its name after `__node`; the first matching rule
    /// wins; rules for other nodes are reported.
    #[test]
    fn node_targeted_rules_apply_to_their_node_only() {
        let args = RosArgs::parse(&strings(&[
            "--ros-args",
            "-r",
            "other:__node:=x",
            "-r",
            "spatial_dynamics:__node:=dyn",
            "-r",
            "__node:=later",
            "-r",
            "spatial_dynamics:__ns:=/a",
            "-r",
            "dyn:joint_states:=/mine",
            "-r",
            "spatial_dynamics:gravity:=/not_after_the_rename",
            "-r",
            "joint_states:=/everyone",
            "-r",
            "talker:chatter:=/c",
        ]))
        .unwrap();
        let node = args.for_node("spatial_dynamics");
        assert_eq!(node.node_name, "dyn");
        assert_eq!(node.namespace.as_deref(), Some("/a"));
        let rule = |a: &str, b: &str| (a.to_string(), b.to_string());
        assert_eq!(
            node.remaps,
            [
                rule("joint_states", "/mine"),
                rule("joint_states", "/everyone")
            ]
        );
        assert_eq!(
            node.other_nodes,
            [
                "other:__node:=x",
                "spatial_dynamics:gravity:=/not_after_the_rename",
                "talker:chatter:=/c"
            ]
        );
        let resolver = NameResolver::new("/a", &node.node_name, &node.remaps);
        assert_eq!(resolver.resolve("joint_states"), "/mine");
    }
}

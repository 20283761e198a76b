//! ROS names: relative names under the namespace, `~/` names under the node, and remapping
//! rules matched on the resolved name. The node resolves every topic and service name with it;
//! offline replay resolves its topic arguments the same way.

/// Resolves ROS names for one node: relative names go under the namespace, `~/` names under
/// the node, and remapping rules (matched on the resolved name) replace them.
#[derive(Clone, Debug)]
pub struct NameResolver {
    namespace: String,
    node: String,
    remaps: Vec<(String, String)>,
}

impl NameResolver {
    /// A resolver for node `node` in namespace `namespace` (absolute, `/` for none).
    pub fn new(namespace: &str, node: &str, remaps: &[(String, String)]) -> Self {
        let mut r = NameResolver {
            namespace: normalise_namespace(namespace),
            node: node.to_string(),
            remaps: Vec::new(),
        };
        r.remaps = remaps
            .iter()
            .map(|(from, to)| (r.expand(from), r.expand(to)))
            .collect();
        r
    }

    /// A resolver without remapping for the node whose fully qualified name is `full`
    /// (`/NS/NAME`, or `NAME` for a node at the root; a trailing `/` is ignored).
    pub fn for_node(full: &str) -> Result<Self, String> {
        let trimmed = full.trim_end_matches('/');
        let (namespace, node) = match trimmed.rsplit_once('/') {
            Some((ns, node)) => (ns, node),
            None => ("", trimmed),
        };
        if node.is_empty() || trimmed.contains("//") {
            return Err(format!("'{full}' is not a node name"));
        }
        Ok(NameResolver::new(namespace, node, &[]))
    }

    /// The node's fully qualified name.
    pub fn node(&self) -> String {
        self.expand("~")
    }

    /// The namespace, absolute, `/` at the root.
    pub fn namespace(&self) -> &str {
        &self.namespace
    }

    /// The fully qualified, remapped name of `name`.
    pub fn resolve(&self, name: &str) -> String {
        let full = self.expand(name);
        self.remaps
            .iter()
            .find(|(from, _)| *from == full)
            .map_or(full, |(_, to)| to.clone())
    }

    fn expand(&self, name: &str) -> String {
        let base = self.namespace.trim_end_matches('/');
        if name.starts_with('/') {
            name.to_string()
        } else if let Some(private) = name.strip_prefix("~/") {
            format!("{base}/{}/{private}", self.node)
        } else if name == "~" {
            format!("{base}/{}", self.node)
        } else {
            format!("{base}/{name}")
        }
    }
}

fn normalise_namespace(ns: &str) -> String {
    let trimmed = ns.trim_matches('/');
    if trimmed.is_empty() {
        "/".to_string()
    } else {
        format!("/{trimmed}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resolves_and_remaps_names() {
        let remaps = vec![
            ("joint_states".to_string(), "/arm/joint_states".to_string()),
            ("~/acceleration".to_string(), "qdd".to_string()),
        ];
        let r = NameResolver::new("/robot", "dyn", &remaps);
        assert_eq!(r.resolve("joint_states"), "/arm/joint_states");
        assert_eq!(r.resolve("~/gravity_effort"), "/robot/dyn/gravity_effort");
        assert_eq!(r.resolve("~/acceleration"), "/robot/qdd");
        assert_eq!(r.resolve("/diagnostics"), "/diagnostics");
        assert_eq!(
            NameResolver::new("", "n", &[]).resolve("robot_description"),
            "/robot_description"
        );
        let r = NameResolver::for_node("/robot/dyn/").unwrap();
        assert_eq!(r.node(), "/robot/dyn");
        assert_eq!(r.resolve("~/effort_command"), "/robot/dyn/effort_command");
        assert_eq!(r.resolve("joint_states"), "/robot/joint_states");
        assert_eq!(
            NameResolver::for_node("spatial_dynamics").unwrap().node(),
            "/spatial_dynamics"
        );
        assert!(NameResolver::for_node("/").is_err());
        assert!(NameResolver::for_node("/a//b").is_err());
    }
}

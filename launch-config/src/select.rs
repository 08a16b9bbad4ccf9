//! Picks and merges the `ros__parameters` sections that apply to a node.

use serde_norway::{Mapping, Value};

use crate::error::{syntax_error, ConfigError};
use crate::locate::{Seg, SourceText};

/// The key under which ROS 2 parameter files keep a node's parameters.
pub(crate) const ROS_PARAMETERS: &str = "ros__parameters";

/// One parsed parameter file, reduced to what applies to one node.
#[derive(Debug)]
pub(crate) struct Selected<'a> {
    /// The merged parameter tree (dotted keys expanded).
    pub(crate) tree: Value,
    /// Where the tree came from, for mapping errors back to lines.
    pub(crate) origin: FileOrigin<'a>,
}

/// A file's text and the key paths (inside the file) of the sections that
/// were merged, lowest precedence first. A plain file has one empty prefix.
#[derive(Debug)]
pub(crate) struct FileOrigin<'a> {
    pub(crate) name: &'a str,
    pub(crate) source: SourceText<'a>,
    pub(crate) sections: Vec<Vec<String>>,
}

/// What [`select`] found in a file.
#[derive(Debug)]
pub(crate) enum Selection<'a> {
    /// Sections (or the whole plain file) that apply to the node.
    Found(Selected<'a>),
    /// A `ros__parameters` file without a section for the node.
    NotFound {
        /// The node sections the file does have.
        available: Vec<String>,
    },
}

/// A `ros__parameters` section found in a file.
#[derive(Debug)]
struct Section {
    /// Node name as written, namespace components joined with `/`.
    name: String,
    /// Key path inside the file, ending in `ros__parameters`.
    keys: Vec<String>,
    /// The section's parameters.
    params: Value,
}

/// Parses `text` and selects the parameters for `node`.
///
/// A file containing `ros__parameters` anywhere is treated as a ROS 2
/// parameter file: wildcard sections that match `node` are merged first (in
/// file order), then sections naming the node, so node keys override wildcard
/// keys recursively. A file without `ros__parameters` is taken whole.
pub(crate) fn select<'a>(
    text: &'a str,
    name: &'a str,
    node: &str,
) -> Result<Selection<'a>, ConfigError> {
    let source = SourceText::new(text);
    let mut doc: Value =
        serde_norway::from_str(text).map_err(|e| syntax_error(name, &e, &source))?;
    doc.apply_merge().map_err(|e| ConfigError::Structure {
        file: name.to_owned(),
        line: e.location().map(|l| l.line()),
        message: format!("invalid YAML merge key: {e}"),
    })?;

    if !mentions_ros_parameters(&doc) {
        let tree = match doc {
            Value::Null => Value::Mapping(Mapping::new()),
            other => expand_dotted(other),
        };
        return Ok(Selection::Found(Selected {
            tree,
            origin: FileOrigin {
                name,
                source,
                sections: vec![Vec::new()],
            },
        }));
    }

    let mut sections = Vec::new();
    let structure_error = |keys: &[String], message: String| ConfigError::Structure {
        file: name.to_owned(),
        line: source.locate(&to_segs(keys)).1,
        message,
    };
    collect_sections(doc, &mut Vec::new(), &mut sections, &structure_error)?;

    let wanted = NodeName::parse(node);
    let mut matched: Vec<(u8, Section)> = Vec::new();
    let mut available = Vec::new();
    for section in sections {
        let rank = if section.name.contains('*') {
            glob_match(&section.name, &wanted).then_some(0)
        } else {
            available.push(section.name.clone());
            wanted.matches(&NodeName::parse(&section.name)).then_some(1)
        };
        if let Some(rank) = rank {
            matched.push((rank, section));
        }
    }
    if matched.is_empty() {
        return Ok(Selection::NotFound { available });
    }
    // Stable: wildcards first, then named sections, each in file order.
    matched.sort_by_key(|(rank, _)| *rank);

    let mut tree = Value::Mapping(Mapping::new());
    let mut origins = Vec::new();
    for (_, section) in matched {
        deep_merge(&mut tree, expand_dotted(section.params));
        origins.push(section.keys);
    }
    Ok(Selection::Found(Selected {
        tree,
        origin: FileOrigin {
            name,
            source,
            sections: origins,
        },
    }))
}

fn to_segs(keys: &[String]) -> Vec<Seg> {
    keys.iter().cloned().map(Seg::Key).collect()
}

/// Is there a `ros__parameters` key anywhere in the mapping structure?
fn mentions_ros_parameters(value: &Value) -> bool {
    match value {
        Value::Mapping(map) => map.iter().any(|(key, value)| {
            key.as_str() == Some(ROS_PARAMETERS) || mentions_ros_parameters(value)
        }),
        _ => false,
    }
}

/// Walks the namespace/node keys down to each `ros__parameters` block.
fn collect_sections(
    value: Value,
    keys: &mut Vec<String>,
    out: &mut Vec<Section>,
    error: &dyn Fn(&[String], String) -> ConfigError,
) -> Result<(), ConfigError> {
    let Value::Mapping(map) = value else {
        let message = if keys.is_empty() {
            "expected a mapping of node names at the top level".to_owned()
        } else {
            format!("`{}` has no {ROS_PARAMETERS} section", keys.join("/"))
        };
        return Err(error(keys, message));
    };
    for (key, value) in map {
        let Some(key) = key.as_str().map(str::to_owned) else {
            let key = serde_norway::to_string(&key).unwrap_or_default();
            return Err(error(
                keys,
                format!("node names must be strings, found `{}`", key.trim_end()),
            ));
        };
        keys.push(key);
        if keys.len() > 1 && keys.last().map(String::as_str) == Some(ROS_PARAMETERS) {
            let params = match value {
                Value::Null => Value::Mapping(Mapping::new()),
                Value::Mapping(map) => Value::Mapping(map),
                _ => {
                    return Err(error(
                        keys,
                        format!("{ROS_PARAMETERS} must be a mapping of parameter names"),
                    ))
                }
            };
            let name_keys = &keys[..keys.len() - 1];
            out.push(Section {
                name: join_name(name_keys),
                keys: keys.clone(),
                params,
            });
        } else if keys.len() == 1 && keys[0] == ROS_PARAMETERS {
            return Err(error(
                keys,
                format!("{ROS_PARAMETERS} must be nested under a node name"),
            ));
        } else if !mentions_ros_parameters(&value) {
            return Err(error(
                keys,
                format!("`{}` has no {ROS_PARAMETERS} section", join_name(keys)),
            ));
        } else {
            collect_sections(value, keys, out, error)?;
        }
        keys.pop();
    }
    Ok(())
}

/// Joins nested namespace keys (`ns`, `node`) into `ns/node`.
fn join_name(keys: &[String]) -> String {
    let mut name = String::new();
    for (i, key) in keys.iter().enumerate() {
        if i == 0 {
            name.push_str(key.trim_end_matches('/'));
        } else {
            name.push('/');
            name.push_str(key.trim_matches('/'));
        }
    }
    name
}

/// A node name split into namespace tokens and base name.
#[derive(Debug)]
struct NodeName {
    /// `["ns", "node"]` for `/ns/node`, `["node"]` for `node` or `/node`.
    tokens: Vec<String>,
}

impl NodeName {
    fn parse(name: &str) -> Self {
        Self {
            tokens: name
                .split('/')
                .filter(|t| !t.is_empty())
                .map(str::to_owned)
                .collect(),
        }
    }

    /// Equal names, or equal base names when either side has no namespace.
    fn matches(&self, other: &NodeName) -> bool {
        if self.tokens == other.tokens {
            return true;
        }
        let unqualified = self.tokens.len() == 1 || other.tokens.len() == 1;
        unqualified && !self.tokens.is_empty() && self.tokens.last() == other.tokens.last()
    }
}

/// ROS 2 wildcard matching: `**` matches any number of name tokens, `*`
/// inside a token matches any characters of that token.
fn glob_match(pattern: &str, name: &NodeName) -> bool {
    let pattern: Vec<&str> = pattern.split('/').filter(|t| !t.is_empty()).collect();
    let name: Vec<&str> = name.tokens.iter().map(String::as_str).collect();
    tokens_match(&pattern, &name)
}

fn tokens_match(pattern: &[&str], name: &[&str]) -> bool {
    match pattern.split_first() {
        None => name.is_empty(),
        Some((&"**", rest)) => (0..=name.len()).any(|skip| tokens_match(rest, &name[skip..])),
        Some((token, rest)) => match name.split_first() {
            Some((first, name_rest)) => token_match(token, first) && tokens_match(rest, name_rest),
            None => false,
        },
    }
}

/// `*` matches any run of characters within one token.
fn token_match(pattern: &str, text: &str) -> bool {
    match pattern.split_once('*') {
        None => pattern == text,
        Some((head, tail)) => {
            let Some(rest) = text.strip_prefix(head) else {
                return false;
            };
            rest.char_indices()
                .map(|(i, _)| i)
                .chain(std::iter::once(rest.len()))
                .any(|i| token_match(tail, &rest[i..]))
        }
    }
}

/// Merges `over` into `base`: mappings recursively, anything else replaced.
pub(crate) fn deep_merge(base: &mut Value, over: Value) {
    match (base, over) {
        (Value::Mapping(base), Value::Mapping(over)) => {
            for (key, value) in over {
                match base.get_mut(&key) {
                    Some(existing) => deep_merge(existing, value),
                    None => {
                        base.insert(key, value);
                    }
                }
            }
        }
        (base, over) => *base = over,
    }
}

/// Expands ROS-style dotted keys: `{a.b: 1}` becomes `{a: {b: 1}}`, merged
/// with any sibling `a` mapping (later entries win on conflicts).
pub(crate) fn expand_dotted(value: Value) -> Value {
    match value {
        Value::Mapping(map) => {
            let mut out = Value::Mapping(Mapping::new());
            for (key, value) in map {
                let value = expand_dotted(value);
                let nested = match key.as_str() {
                    Some(dotted)
                        if dotted.contains('.') && !dotted.split('.').any(str::is_empty) =>
                    {
                        dotted.rsplit('.').fold(value, |inner, part| {
                            let mut map = Mapping::new();
                            map.insert(Value::String(part.to_owned()), inner);
                            Value::Mapping(map)
                        })
                    }
                    _ => {
                        let mut map = Mapping::new();
                        map.insert(key, value);
                        Value::Mapping(map)
                    }
                };
                deep_merge(&mut out, nested);
            }
            out
        }
        Value::Sequence(items) => Value::Sequence(items.into_iter().map(expand_dotted).collect()),
        other => other,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn yaml(text: &str) -> Value {
        serde_norway::from_str(text).expect("test YAML")
    }

    #[test]
    fn node_name_matching() {
        let m = |a: &str, b: &str| NodeName::parse(a).matches(&NodeName::parse(b));
        assert!(m("mrtwin_stand", "mrtwin_stand"));
        assert!(m("mrtwin_stand", "/mrtwin_stand"));
        assert!(m("/ns/mrtwin_stand", "mrtwin_stand"));
        assert!(m("mrtwin_stand", "/ns/mrtwin_stand"));
        assert!(m("/ns/mrtwin_stand", "ns/mrtwin_stand"));
        assert!(!m("/a/mrtwin_stand", "/b/mrtwin_stand"));
        assert!(!m("other", "mrtwin_stand"));
    }

    #[test]
    fn wildcards() {
        let g = |p: &str, n: &str| glob_match(p, &NodeName::parse(n));
        assert!(g("/**", "/node"));
        assert!(g("/**", "/ns/deep/node"));
        assert!(g("**", "node"));
        assert!(g("/**/node", "/node"));
        assert!(g("/**/node", "/a/b/node"));
        assert!(g("/ns/*", "/ns/node"));
        assert!(!g("/ns/*", "/ns/a/node"));
        assert!(g("/ns/mr*", "/ns/mrtwin"));
        assert!(g("/ns/*twin", "/ns/mrtwin"));
        assert!(!g("/ns/*x", "/ns/mrtwin"));
        assert!(!g("/other/**", "/ns/node"));
    }

    #[test]
    fn merge_is_recursive() {
        let mut base = yaml("a: {x: 1, y: 2}\nb: 3\n");
        deep_merge(&mut base, yaml("a: {y: 20, z: 30}\nc: 4\n"));
        assert_eq!(base, yaml("a: {x: 1, y: 20, z: 30}\nb: 3\nc: 4\n"));
    }

    #[test]
    fn dotted_keys_expand() {
        let v = expand_dotted(yaml("a.b: 1\na: {c: 2}\nx..y: 3\nl: [{p.q: 1}]\n"));
        assert_eq!(v, yaml("a: {b: 1, c: 2}\nx..y: 3\nl: [{p: {q: 1}}]\n"));
    }

    #[test]
    fn nested_namespace_sections() {
        let text = "ns:\n  node:\n    ros__parameters:\n      a: 1\n";
        let Selection::Found(sel) = select(text, "f.yaml", "/ns/node").expect("select") else {
            panic!("no section");
        };
        assert_eq!(sel.tree, yaml("a: 1"));
        assert_eq!(
            sel.origin.sections,
            vec![vec!["ns", "node", ROS_PARAMETERS]]
        );
    }
}

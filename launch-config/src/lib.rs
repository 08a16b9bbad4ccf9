//! mrtwin parameter files and ROS 2 command-line arguments, strictly
//! validated.
//!
//! Parameter files follow the ROS 2 `ros__parameters` convention:
//!
//! ```yaml
//! /**:                     # wildcard: applies to every node
//!   ros__parameters:
//!     model: two-chamber
//! mrtwin_stand:            # node name (or "/ns/node")
//!   ros__parameters:
//!     two_chamber:
//!       bulk_modulus_pa: 5.0e8
//! ```
//!
//! [`load_params`] / [`parse_params`] pick the sections for one node (wildcard
//! sections first, node sections overriding them key by key), and
//! deserialize them into a `#[serde(deny_unknown_fields, default)]` struct.
//! A file without any `ros__parameters` is taken whole, as plain YAML. Keys
//! with dots (`two_chamber.bulk_modulus_pa: 5.0e8`) are ROS-style nested
//! names and are expanded into nested mappings.
//!
//! Errors name the file, the dotted key path and the line in the original
//! file:
//!
//! ```
//! #[derive(Debug, Default, serde::Deserialize)]
//! #[serde(deny_unknown_fields, default)]
//! struct Params {
//!     gain: f64,
//! }
//!
//! let text = "stand:\n  ros__parameters:\n    gian: 2.0\n";
//! let err = launch_config::parse_params::<Params>(text, "params.yaml", "stand").unwrap_err();
//! assert_eq!(
//!     err.to_string(),
//!     "params.yaml line 3: unknown key gian (expected `gain`)"
//! );
//! ```
//!
//! [`parse_ros_args`] reads `--ros-args --params-file F -r __node:=N -p k:=v`
//! and [`load_node_params`] applies such arguments in one go.

mod error;
pub mod launch;
mod locate;
mod overrides;
mod ros_args;
mod select;

use std::path::Path;

use serde::de::DeserializeOwned;
use serde_norway::{Mapping, Value};

pub use error::ConfigError;
pub use launch::{load_launch, parse_launch, LaunchEntry, LaunchFile, NodeEntry};
pub use overrides::apply_param_overrides;
pub use ros_args::{parse_ros_args, RosArgs};

use error::io_error;
use locate::{display_path, Seg};
use overrides::param_path;
use select::{deep_merge, select, FileOrigin, Selection};

/// Reads the parameters for `node` from the ROS 2 parameter file at `path`.
///
/// `node` is a node name (`mrtwin_stand`) or fully qualified name
/// (`/lab/mrtwin_stand`). See [`parse_params`] for the rules.
///
/// # Errors
/// [`ConfigError::Io`] if the file cannot be read, otherwise as
/// [`parse_params`]; errors name the file as `path` is displayed.
pub fn load_params<T: DeserializeOwned>(path: &Path, node: &str) -> Result<T, ConfigError> {
    let name = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|e| io_error(&name, e))?;
    parse_params(&text, &name, node)
}

/// Parses the parameters for `node` from the text of a parameter file;
/// `source` is the file name used in error messages.
///
/// Section selection, when the file has `ros__parameters` blocks:
/// * a section applies if its name equals `node` (a leading `/` does not
///   matter), or if the base names (last path component) are equal and one
///   of the two has no namespace; names may also be nested mappings
///   (`lab: {mrtwin_stand: {ros__parameters: ...}}`);
/// * wildcard sections (`/**`, `/lab/*`, `/**/mrtwin_stand`) apply if they
///   match the node's name;
/// * wildcard sections are merged first, then named sections, recursively,
///   so node keys override wildcard keys; within each group file order
///   decides.
///
/// A file with no `ros__parameters` at all is taken whole. An empty file
/// gives an empty mapping (so a `default` struct gets all defaults).
///
/// # Errors
/// [`ConfigError::Syntax`] for invalid YAML, [`ConfigError::Structure`] for
/// a malformed `ros__parameters` layout, [`ConfigError::NodeNotFound`] if no
/// section applies, [`ConfigError::UnknownKey`] and
/// [`ConfigError::InvalidValue`] for deserialization errors, each with the
/// dotted key path and its line in `text`.
pub fn parse_params<T: DeserializeOwned>(
    text: &str,
    source: &str,
    node: &str,
) -> Result<T, ConfigError> {
    match select(text, source, node)? {
        Selection::Found(selected) => {
            let origins = [Origin::File(selected.origin)];
            deserialize_tree(selected.tree, &origins)
        }
        Selection::NotFound { available } => Err(ConfigError::NodeNotFound {
            file: source.to_owned(),
            node: node.to_owned(),
            available,
        }),
    }
}

/// Loads a node's parameters as ROS 2 would from parsed command-line
/// arguments: every `--params-file` in order (later files override earlier
/// ones, key by key), then the `-p` overrides, for the node named
/// [`RosArgs::fully_qualified_name`]`(default_node)`.
///
/// Files that have no section for the node are skipped, as in ROS 2, but at
/// least one file must have one if any file is given. With no files, only
/// the `-p` overrides (and the type's defaults) apply.
///
/// # Errors
/// As [`load_params`]; errors caused by a `-p` override name it, e.g.
/// ``command line `-p gain:=abc`, key gain: invalid type ...``.
pub fn load_node_params<T: DeserializeOwned>(
    args: &RosArgs,
    default_node: &str,
) -> Result<T, ConfigError> {
    let node = args.fully_qualified_name(default_node);
    let mut files = Vec::with_capacity(args.params_files.len());
    for path in &args.params_files {
        let name = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| io_error(&name, e))?;
        files.push((name, text));
    }

    let mut tree = Value::Mapping(Mapping::new());
    let mut origins = Vec::new();
    let mut available = Vec::new();
    for (name, text) in &files {
        match select(text, name, &node)? {
            Selection::Found(selected) => {
                deep_merge(&mut tree, selected.tree);
                origins.push(Origin::File(selected.origin));
            }
            Selection::NotFound { available: more } => available.extend(more),
        }
    }
    if origins.is_empty() && !files.is_empty() {
        return Err(ConfigError::NodeNotFound {
            file: files
                .iter()
                .map(|(name, _)| name.as_str())
                .collect::<Vec<_>>()
                .join(", "),
            node,
            available,
        });
    }

    apply_param_overrides(&mut tree, &args.params);
    origins.extend(args.params.iter().map(|(name, value)| Origin::Override {
        label: format!("command line `-p {name}:={value}`"),
        key: param_path(name),
    }));
    deserialize_tree(tree, &origins)
}

/// Where part of a merged parameter tree came from; lowest precedence first
/// in the slices passed around below.
enum Origin<'a> {
    File(FileOrigin<'a>),
    Override { label: String, key: Vec<String> },
}

/// Deserializes `tree` into `T`, mapping errors back to their source.
fn deserialize_tree<T: DeserializeOwned>(
    tree: Value,
    origins: &[Origin<'_>],
) -> Result<T, ConfigError> {
    let err = match serde_path_to_error::deserialize::<_, T>(tree) {
        Ok(value) => return Ok(value),
        Err(err) => err,
    };
    let mut path = Vec::new();
    for segment in err.path().iter() {
        match segment {
            serde_path_to_error::Segment::Map { key } => path.push(Seg::Key(key.clone())),
            serde_path_to_error::Segment::Enum { variant } => {
                path.push(Seg::Key(variant.clone()));
            }
            serde_path_to_error::Segment::Seq { index } => path.push(Seg::Index(*index)),
            serde_path_to_error::Segment::Unknown => break,
        }
    }
    let message = err.into_inner().to_string();
    if let Some((name, expected)) = parse_unknown_field(&message) {
        if path.last() != Some(&Seg::Key(name.to_owned())) {
            path.push(Seg::Key(name.to_owned()));
        }
        let (file, line) = resolve(origins, &path);
        return Err(ConfigError::UnknownKey {
            file,
            line,
            key: display_path(&path),
            expected: expected.to_owned(),
        });
    }
    let (file, line) = resolve(origins, &path);
    Err(ConfigError::InvalidValue {
        file,
        line,
        key: display_path(&path),
        message,
    })
}

/// Splits serde's "unknown field `x`, expected one of `a`, `b`" into
/// the field name and the part after the comma.
fn parse_unknown_field(message: &str) -> Option<(&str, &str)> {
    let rest = message.strip_prefix("unknown field `")?;
    let (name, expected) = rest.split_once("`, ")?;
    Some((name, expected))
}

/// Finds which origin (and line) a key path came from: the highest
/// precedence origin that contains the whole path, else the one with the
/// deepest matching prefix.
fn resolve(origins: &[Origin<'_>], path: &[Seg]) -> (String, Option<usize>) {
    let mut best: Option<(usize, &str, Option<usize>)> = None;
    for origin in origins.iter().rev() {
        match origin {
            Origin::Override { label, key } => {
                let related = !path.is_empty()
                    && key
                        .iter()
                        .zip(path)
                        .all(|(k, seg)| matches!(seg, Seg::Key(s) if s == k));
                if related {
                    return (label.clone(), None);
                }
            }
            Origin::File(file) => {
                for prefix in file.sections.iter().rev() {
                    let mut full: Vec<Seg> = prefix.iter().cloned().map(Seg::Key).collect();
                    full.extend_from_slice(path);
                    let (depth, line) = file.source.locate(&full);
                    let Some(depth) = depth.checked_sub(prefix.len()) else {
                        continue;
                    };
                    if depth == path.len() {
                        return (file.name.to_owned(), line);
                    }
                    if best.is_none_or(|(best_depth, _, _)| depth > best_depth) {
                        best = Some((depth, file.name, line));
                    }
                }
            }
        }
    }
    match best {
        Some((_, name, line)) => (name.to_owned(), line),
        None => {
            let name = origins.iter().find_map(|origin| match origin {
                Origin::File(file) => Some(file.name.to_owned()),
                Origin::Override { .. } => None,
            });
            (name.unwrap_or_else(|| "command line".to_owned()), None)
        }
    }
}

/// Writes a ROS 2 parameter file: one `NODE: ros__parameters: …` section per
/// `(node, parameters)` pair, in order, with a `# ` comment header.
///
/// The result reads back with [`parse_params`] into the type it was written
/// from (the round trip is tested).
///
/// # Errors
/// The serializer's message when a value cannot be written as YAML.
pub fn params_yaml<T: serde::Serialize>(
    header: &str,
    sections: &[(&str, &T)],
) -> Result<String, String> {
    let mut out = String::new();
    for line in header.lines() {
        out.push_str("# ");
        out.push_str(line);
        out.push('\n');
    }
    for (node, params) in sections {
        let body = serde_norway::to_string(params).map_err(|e| e.to_string())?;
        out.push_str(node);
        out.push_str(":\n  ros__parameters:\n");
        for line in body.lines() {
            out.push_str("    ");
            out.push_str(line);
            out.push('\n');
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests;

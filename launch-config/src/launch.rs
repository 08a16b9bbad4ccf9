//! Launch files in the ROS 2 launch YAML style:
//!
//! ```yaml
//! launch:
//!   - node:
//!       pkg: mrtwin
//!       exec: stand            # stand | twin | record | fleet
//!       name: mrtwin_stand
//!       namespace: /lab
//!       param:
//!         - from: stand.params.yaml      # relative to the launch file
//!         - { name: rate_hz, value: 1000 }
//!       remap:
//!         - { from: sensor/sample, to: rig/sample }
//! ```
//!
//! Unknown keys and wrong types are errors naming the file, key and line (the same
//! machinery as parameter files).

use std::path::{Path, PathBuf};

use serde::Deserialize;
use serde_norway::Value;

use crate::locate::{display_path, Seg, SourceText};
use crate::overrides::valid_param_name;
use crate::{parse_params, ConfigError};

/// A launch file.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LaunchFile {
    /// The entries, started in order.
    pub launch: Vec<LaunchEntry>,
}

/// One entry of `launch:` (only `- node: {...}` entries exist here).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LaunchEntry {
    /// `- node: {...}`.
    pub node: NodeEntry,
}

/// A node to start.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NodeEntry {
    /// Package (must be `mrtwin`).
    pub pkg: String,
    /// Executable (`stand`, `twin`, `record`).
    pub exec: String,
    /// Node name (`-r __node:=`).
    #[serde(default)]
    pub name: Option<String>,
    /// Namespace (`-r __ns:=`).
    #[serde(default)]
    pub namespace: Option<String>,
    /// Parameter files and single parameters.
    #[serde(default)]
    pub param: Vec<ParamEntry>,
    /// Remappings.
    #[serde(default)]
    pub remap: Vec<RemapEntry>,
    /// Extra command-line arguments of the executable (before `--ros-args`).
    #[serde(default)]
    pub args: Option<String>,
}

/// `- from: FILE` or `- {name: N, value: V}`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ParamEntry {
    /// A parameter file.
    #[serde(default)]
    pub from: Option<String>,
    /// A parameter name (dotted for nested keys).
    #[serde(default)]
    pub name: Option<String>,
    /// Its value.
    #[serde(default)]
    pub value: Option<Value>,
}

/// `- {from: A, to: B}`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RemapEntry {
    /// Original name.
    pub from: String,
    /// New name.
    pub to: String,
}

impl NodeEntry {
    /// The `--ros-args` part of this node's command line; parameter files are resolved
    /// relative to `base` (the launch file's directory).
    pub fn ros_args(&self, base: &Path) -> Vec<String> {
        let mut a = vec!["--ros-args".to_string()];
        if let Some(n) = &self.name {
            a.extend(["-r".into(), format!("__node:={n}")]);
        }
        if let Some(ns) = &self.namespace {
            a.extend(["-r".into(), format!("__ns:={ns}")]);
        }
        for p in &self.param {
            if let Some(f) = &p.from {
                let path: PathBuf = base.join(f);
                a.extend(["--params-file".into(), path.display().to_string()]);
            }
            if let (Some(n), Some(v)) = (&p.name, &p.value) {
                let text = match v {
                    Value::String(s) => s.clone(),
                    other => serde_norway::to_string(other)
                        .unwrap_or_default()
                        .trim()
                        .to_string(),
                };
                a.extend(["-p".into(), format!("{n}:={text}")]);
            }
        }
        for r in &self.remap {
            a.extend(["-r".into(), format!("{}:={}", r.from, r.to)]);
        }
        a
    }
}

/// Read and check a launch file.
pub fn load_launch(path: &Path) -> Result<LaunchFile, ConfigError> {
    let name = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|e| crate::io_error(&name, e))?;
    parse_launch(&text, &name)
}

/// Parse and check the text of a launch file; `source` names it in errors.
///
/// Beyond the types, each node must be `pkg: mrtwin` with `exec` stand, twin, record or
/// fleet,
/// and everything that becomes its `--ros-args` must be what [`crate::parse_ros_args`]
/// reads back as written: a non-empty `name` and `namespace`, parameter names without
/// empty `.`-separated parts or `:=`, remappings between non-empty names (`from` without
/// `:=`).
/// Errors name the file, the entry (`launch[0].node.param[1]`) and its line.
pub fn parse_launch(text: &str, source: &str) -> Result<LaunchFile, ConfigError> {
    let file: LaunchFile = parse_params(text, source, "/launch")?;
    let lines = SourceText::new(text);
    for (i, LaunchEntry { node: n }) in file.launch.iter().enumerate() {
        // `launch[i].node.<field>[index]`, with the line of the deepest part found.
        let bad = |field: &str, index: Option<usize>, message: String| {
            let mut path = vec![
                Seg::Key("launch".into()),
                Seg::Index(i),
                Seg::Key("node".into()),
            ];
            path.push(Seg::Key(field.into()));
            path.extend(index.map(Seg::Index));
            ConfigError::Structure {
                file: source.to_string(),
                line: lines.locate(&path).1,
                message: format!("{}: {message}", display_path(&path)),
            }
        };
        if n.pkg != "mrtwin" {
            return Err(bad("pkg", None, format!("pkg '{}' is not mrtwin", n.pkg)));
        }
        if !["stand", "twin", "record", "fleet"].contains(&n.exec.as_str()) {
            return Err(bad(
                "exec",
                None,
                format!("exec '{}' is not stand, twin, record or fleet", n.exec),
            ));
        }
        if n.name
            .as_deref()
            .is_some_and(|v| v.trim_matches('/').is_empty())
        {
            return Err(bad("name", None, "the node name must not be empty".into()));
        }
        if n.namespace.as_deref().is_some_and(str::is_empty) {
            return Err(bad(
                "namespace",
                None,
                "the namespace must not be empty (the root is `/`)".into(),
            ));
        }
        for (j, p) in n.param.iter().enumerate() {
            match (&p.from, &p.name, &p.value) {
                (Some(_), None, None) => {}
                (None, Some(name), Some(_)) => {
                    if !valid_param_name(name) || name.contains(":=") {
                        return Err(bad(
                            "param",
                            Some(j),
                            format!(
                                "parameter name '{name}' must not be empty, have empty `.`-separated parts or contain `:=`"
                            ),
                        ));
                    }
                }
                _ => {
                    return Err(bad(
                        "param",
                        Some(j),
                        "each param is either {from: FILE} or {name: N, value: V}".into(),
                    ))
                }
            }
        }
        for (j, r) in n.remap.iter().enumerate() {
            if r.from.is_empty() || r.from.contains(":=") || r.to.is_empty() {
                return Err(bad(
                    "remap",
                    Some(j),
                    format!(
                        "remap from '{}' to '{}': neither may be empty, nor `from` contain `:=`",
                        r.from, r.to
                    ),
                ));
            }
        }
    }
    Ok(file)
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = "launch:\n  - node:\n      pkg: mrtwin\n      exec: twin\n      name: t\n      namespace: /lab\n      param:\n        - from: p.yaml\n        - {name: stale_after_s, value: 0.5}\n      remap:\n        - {from: a, to: b}\n";

    #[test]
    fn parses_and_builds_ros_args() {
        let f = parse_launch(GOOD, "l.yaml").unwrap();
        let n = &f.launch[0].node;
        assert_eq!(
            n.ros_args(Path::new("/cfg")),
            [
                "--ros-args",
                "-r",
                "__node:=t",
                "-r",
                "__ns:=/lab",
                "--params-file",
                "/cfg/p.yaml",
                "-p",
                "stale_after_s:=0.5",
                "-r",
                "a:=b"
            ]
        );
    }

    #[test]
    fn unknown_key_names_file_key_and_line() {
        let bad = GOOD.replace("      name: t\n", "      name: t\n      nmae: x\n");
        let e = parse_launch(&bad, "l.yaml").unwrap_err().to_string();
        assert!(
            e.contains("l.yaml") && e.contains("nmae") && e.contains("line 6"),
            "{e}"
        );
        let bad = GOOD.replace("exec: twin", "exec: nope");
        let e = parse_launch(&bad, "l.yaml").unwrap_err().to_string();
        assert!(e.contains("exec 'nope'"), "{e}");
    }

    /// Found by the fuzzer (issue 15, `fuzz-parsers --parser launch --seed 1`, input
    /// 13559): a parameter name with an empty `.` part was accepted, and the node then
    /// refused the `-p` argument the launch file made of it.
    #[test]
    fn what_the_node_would_refuse_is_an_error_with_its_line() {
        let fuzzed = "launch:\n- node:\n    pkg: mrtwin\n    exec: record\n    name: stand\n    \
                      namespace: /a/b\n    param:\n    - from: /abs.yaml\n    - from: \
                      ../cfg/twin.yaml\n    remap:\n    - from: sensor/sample\n      to: \
                      rig/sample\n- node:\n    pkg: mrtwin\n    exec: record\n    namespace: \
                      /lab\n    param:\n    - from: p.yaml\n    - name: \
                      two.._chamber.bulk_modulus_pa\n      value: all\n    remap:\n    - \
                      from: sensor/sample\n      to: rig/sample\n";
        let e = parse_launch(fuzzed, "l.yaml").unwrap_err().to_string();
        assert_eq!(
            e,
            "l.yaml line 19: launch[1].node.param[1]: parameter name \
             'two.._chamber.bulk_modulus_pa' must not be empty, have empty `.`-separated parts \
             or contain `:=`"
        );
        for (from, to, wanted) in [
            (
                "      name: t\n",
                "      name: ''\n",
                "line 5: launch[0].node.name:",
            ),
            (
                "namespace: /lab",
                "namespace: ''",
                "line 6: launch[0].node.namespace:",
            ),
            (
                "{name: stale_after_s",
                "{name: a:=b",
                "line 9: launch[0].node.param[1]:",
            ),
            (
                "{from: a, to: b}",
                "{from: '', to: b}",
                "line 11: launch[0].node.remap[0]:",
            ),
            (
                "{from: a, to: b}",
                "{from: __node, to: ''}",
                "line 11: launch[0].node.remap[0]:",
            ),
        ] {
            let e = parse_launch(&GOOD.replace(from, to), "l.yaml")
                .unwrap_err()
                .to_string();
            assert!(e.starts_with(&format!("l.yaml {wanted}")), "{e}");
        }
        // Everything accepted makes arguments the node reads back.
        let n = &parse_launch(GOOD, "l.yaml").unwrap().launch[0].node;
        crate::parse_ros_args(&n.ros_args(Path::new("/cfg"))).unwrap();
    }
}

//! Generators and checks of the configuration parsers: ROS 2 parameter files of the twin
//! and the stand nodes (`launch_config::parse_params` into `node::config::TwinNodeParams`
//! and `node::stand::StandParams`, then the node's own checks), launch files
//! (`launch_config::parse_launch`) and `--ros-args` (`launch_config::parse_ros_args`,
//! then `load_node_params` with the `-p` overrides).
//!
//! The parameter files start from the nodes' own parameter trees (every key with a value
//! of the right type), keep a random part of them, change some values, keys and section
//! names, use dotted keys, wildcards, namespaces, anchors and merge keys, and are then
//! mostly mutated as text.

use std::sync::OnceLock;

use launch_config::{load_node_params, params_yaml, parse_launch, parse_params, parse_ros_args};
use node::config::{TwinNodeParams, STAND_NODE, TWIN_NODE};
use node::stand::StandParams;
use serde_norway::{Mapping, Value};

use super::mutate::mutate;
use super::rng::Rng;
use super::{names_file, FuzzInput, Parser, Scratch, Verdict};

/// Largest generated file.
const MAX_TEXT: usize = 4096;

/// The configuration parsers.
pub fn parsers() -> Vec<Parser> {
    vec![
        Parser {
            name: "params-twin",
            entry: "launch_config::parse_params::<node::config::TwinNodeParams>, validate, pipeline_config; accepted → params_yaml → parse round trip",
            generate: generate_twin_params,
            check: check_twin_params,
        },
        Parser {
            name: "params-stand",
            entry: "launch_config::parse_params::<node::stand::StandParams>; accepted → params_yaml → parse round trip",
            generate: generate_stand_params,
            check: check_stand_params,
        },
        Parser {
            name: "launch",
            entry: "launch_config::parse_launch; accepted → NodeEntry::ros_args → parse_ros_args",
            generate: generate_launch,
            check: check_launch,
        },
        Parser {
            name: "ros-args",
            entry: "launch_config::parse_ros_args, fully_qualified_name, load_node_params::<TwinNodeParams> (-p overrides)",
            generate: generate_ros_args,
            check: check_ros_args,
        },
    ]
}

/// A node's parameter tree and its keys (a dictionary for the mutations).
struct Schema {
    tree: Value,
    keys: Vec<Vec<u8>>,
}

fn schema_of<T: serde::Serialize + Default>() -> Schema {
    let tree = serde_norway::to_value(T::default()).expect("parameters serialise");
    let mut keys = Vec::new();
    collect_keys(&tree, &mut keys);
    keys.sort();
    keys.dedup();
    Schema { tree, keys }
}

fn collect_keys(v: &Value, out: &mut Vec<Vec<u8>>) {
    if let Value::Mapping(m) = v {
        for (k, v) in m {
            if let Some(k) = k.as_str() {
                out.push(k.as_bytes().to_vec());
            }
            collect_keys(v, out);
        }
    }
}

fn twin_schema() -> &'static Schema {
    static S: OnceLock<Schema> = OnceLock::new();
    S.get_or_init(schema_of::<TwinNodeParams>)
}

fn stand_schema() -> &'static Schema {
    static S: OnceLock<Schema> = OnceLock::new();
    S.get_or_init(schema_of::<StandParams>)
}

/// Words that are values somewhere in the parameters (model, effect and transport names).
const VALUE_WORDS: &[&str] = &[
    "bingham",
    "spencer",
    "direct-shear",
    "two-chamber",
    "paper",
    "all",
    "none",
    "gas_spring,fluid_compressibility",
    "seal_friction",
    "ros2",
    "zenoh",
    "iceoryx2",
    "peer",
    "client",
    "tcp/127.0.0.1:7447",
    "/lab",
    "sensor/sample",
    "/diagnostics",
    "best_effort",
    "reliable",
    "",
    " ",
    "a b",
];

/// A random YAML value of any kind.
fn random_value(rng: &mut Rng, depth: usize) -> Value {
    match rng.below(if depth > 2 { 7 } else { 9 }) {
        0 => Value::Null,
        1 => Value::Bool(rng.one_in(2)),
        2 => Value::Number((rng.next_u64() as i64 >> rng.below(64)).into()),
        3 => Value::Number(rng.any_f64().into()),
        4 => Value::Number(rng.plain_f64().into()),
        5 | 6 => Value::String((*rng.pick(VALUE_WORDS)).to_owned()),
        7 => Value::Sequence(
            (0..rng.below(4))
                .map(|_| random_value(rng, depth + 1))
                .collect(),
        ),
        _ => {
            let mut m = Mapping::new();
            for _ in 0..rng.below(3) {
                m.insert(
                    Value::String((*rng.pick(VALUE_WORDS)).to_owned()),
                    random_value(rng, depth + 1),
                );
            }
            Value::Mapping(m)
        }
    }
}

/// A random part of `tree` (mappings thinned out); `changed` is set when a value, a key or
/// the layout was changed in a way that may make the file invalid.
///
/// Only the two outer levels are thinned: deeper structs (warn/error threshold pairs) have
/// required fields.
fn random_subtree(
    rng: &mut Rng,
    tree: &Value,
    keys: &[Vec<u8>],
    changed: &mut bool,
    depth: usize,
) -> Value {
    match tree {
        Value::Mapping(m) => {
            let mut out = Mapping::new();
            for (k, v) in m {
                if depth < 2 && rng.one_in(3) {
                    continue;
                }
                let mut key = k.clone();
                if rng.one_in(300) {
                    // Another known key, perhaps at the wrong level.
                    key = Value::String(
                        String::from_utf8_lossy(rng.pick(keys).as_slice()).into_owned(),
                    );
                    *changed = true;
                }
                let value = if rng.one_in(200) {
                    *changed = true;
                    random_value(rng, 0)
                } else {
                    random_subtree(rng, v, keys, changed, depth + 1)
                };
                // ROS-style dotted keys for a nested mapping.
                if let (Value::Mapping(inner), Some(name)) = (&value, key.as_str()) {
                    if rng.one_in(6) && !inner.is_empty() {
                        for (ik, iv) in inner {
                            if let Some(ik) = ik.as_str() {
                                out.insert(Value::String(format!("{name}.{ik}")), iv.clone());
                            }
                        }
                        continue;
                    }
                }
                out.insert(key, value);
            }
            Value::Mapping(out)
        }
        other => other.clone(),
    }
}

/// The name of a section that applies to `node` (or, when `matching` is false, may not).
fn section_name(rng: &mut Rng, node: &str, matching: bool) -> String {
    if matching {
        (*rng.pick(&["NODE", "/NODE", "/**", "/**/NODE", "**"])).replace("NODE", node)
    } else {
        (*rng.pick(&[
            "/lab/NODE",
            "other_node",
            "/lab/*",
            "/*/NODE",
            "/**/o*r",
            "/**/**/*",
            "*",
            "ros__parameters",
            "",
        ]))
        .replace("NODE", node)
    }
}

/// A parameter file for `node` from `schema`; valid when nothing was changed.
fn generate_params(rng: &mut Rng, schema: &Schema, node: &str) -> FuzzInput {
    let mut changed = false;
    let mut doc = Mapping::new();
    let sections = rng.range(1, 3);
    for i in 0..sections {
        let matching = i == 0 || !rng.one_in(3);
        let name = section_name(rng, node, matching);
        changed |= !matching;
        let params = random_subtree(rng, &schema.tree, &schema.keys, &mut changed, 0);
        let mut body = Mapping::new();
        body.insert(Value::String("ros__parameters".into()), params);
        if rng.one_in(8) && !name.starts_with('/') && !name.is_empty() {
            // Nested namespace form: `lab: {node: {ros__parameters: …}}`.
            let mut inner = Mapping::new();
            inner.insert(Value::String(name), Value::Mapping(body));
            doc.insert(Value::String("lab".into()), Value::Mapping(inner));
            changed = true;
        } else {
            doc.insert(Value::String(name), Value::Mapping(body));
        }
    }
    let mut text = if rng.one_in(10) {
        // Without sections: the file is taken whole.
        changed = true;
        serde_norway::to_string(&random_subtree(
            rng,
            &schema.tree,
            &schema.keys,
            &mut changed,
            0,
        ))
    } else {
        serde_norway::to_string(&Value::Mapping(doc))
    }
    .unwrap_or_default();
    if rng.one_in(10) {
        // Anchors, aliases and merge keys.
        text.push_str("x: &anchor {a: 1}\ny:\n  <<: *anchor\n  b: [*anchor, *anchor]\n");
        changed = true;
    }
    let mut data = text.into_bytes();
    if !rng.one_in(4) {
        let mut dictionary: Vec<&[u8]> = schema.keys.iter().map(Vec::as_slice).collect();
        dictionary.extend(CONFIG_DICTIONARY);
        mutate(rng, &mut data, &dictionary, MAX_TEXT);
        changed = true;
    }
    FuzzInput::single("params.yaml", data, !changed)
}

const CONFIG_DICTIONARY: &[&[u8]] = &[
    b"ros__parameters:",
    b"/**:",
    b"/**/",
    b"*",
    b": ",
    b"- ",
    b"&a ",
    b"*a",
    b"<<: *a",
    b"!!str ",
    b"!!float ",
    b"!tag ",
    b"{",
    b"}",
    b"[",
    b"]",
    b"'",
    b"\"",
    b"|\n",
    b">-\n",
    b"\t",
    b"~",
    b"---\n",
    b".",
    b"..",
    b".inf",
    b".nan",
    b"-1",
    b"1e400",
    b"18446744073709551616",
    b"\xc3\xa9",
    b"? ",
    b"#",
];

/// The shared check of the parameter files of type `T`.
fn check_params<T>(input: &FuzzInput, node: &str) -> Result<Option<T>, String>
where
    T: serde::de::DeserializeOwned + serde::Serialize,
{
    let text = String::from_utf8_lossy(input.part("params.yaml"));
    let params: T = match parse_params(&text, "params.yaml", node) {
        Ok(p) => p,
        Err(e) if input.valid => return Err(format!("valid parameter file rejected: {e}")),
        Err(e) => return names_file(&e.to_string(), "params.yaml").map(|_| None),
    };
    // Round trip: written as a parameter file and read again, the same parameters.
    let written = params_yaml("round trip", &[(node, &params)])
        .map_err(|e| format!("round trip: parameters do not write: {e}"))?;
    let again: T = parse_params(&written, "written.yaml", node)
        .map_err(|e| format!("round trip: written parameters do not read back: {e}"))?;
    let same = serde_norway::to_string(&again).ok() == serde_norway::to_string(&params).ok();
    if !same {
        return Err("round trip: parameters change when written and read back".into());
    }
    Ok(Some(params))
}

fn generate_twin_params(rng: &mut Rng) -> FuzzInput {
    generate_params(rng, twin_schema(), TWIN_NODE)
}

fn check_twin_params(input: &FuzzInput, _: &Scratch) -> Result<Verdict, String> {
    match check_params::<TwinNodeParams>(input, TWIN_NODE)? {
        Some(p) => {
            // What the node does with them next: its own checks.
            let _ = p.pipeline_config();
            let _ = p.transport_settings("/mrtwin_twin");
            Ok(Verdict::Accepted)
        }
        None => Ok(Verdict::Rejected),
    }
}

fn generate_stand_params(rng: &mut Rng) -> FuzzInput {
    generate_params(rng, stand_schema(), STAND_NODE)
}

fn check_stand_params(input: &FuzzInput, _: &Scratch) -> Result<Verdict, String> {
    Ok(match check_params::<StandParams>(input, STAND_NODE)? {
        Some(_) => Verdict::Accepted,
        None => Verdict::Rejected,
    })
}

const NAMES: &[&str] = &["mrtwin_twin", "stand", "rec_1", "/abs", "a/b", "n"];

/// A launch file of 1 to 3 nodes; valid when every node is well formed.
fn generate_launch(rng: &mut Rng) -> FuzzInput {
    let mut valid = true;
    let mut entries = Vec::new();
    let nodes = if rng.one_in(8) { 0 } else { rng.range(1, 3) };
    for _ in 0..nodes {
        let mut node = Mapping::new();
        let mut put = |k: &str, v: Value| {
            node.insert(Value::String(k.into()), v);
        };
        if rng.one_in(12) {
            valid = false;
            put("pkg", Value::String("other".into()));
        } else {
            put("pkg", Value::String("mrtwin".into()));
        }
        if rng.one_in(12) {
            valid = false;
            put("exec", Value::String("talker".into()));
        } else {
            put(
                "exec",
                Value::String((*rng.pick(&["stand", "twin", "record"])).into()),
            );
        }
        if rng.one_in(2) {
            put("name", Value::String((*rng.pick(NAMES)).into()));
        }
        if rng.one_in(2) {
            put(
                "namespace",
                Value::String((*rng.pick(&["/lab", "lab", "/a/b"])).into()),
            );
        }
        if rng.one_in(4) {
            put("args", Value::String("--fast".into()));
        }
        let mut params = Vec::new();
        for _ in 0..rng.below(3) {
            let mut p = Mapping::new();
            if rng.one_in(2) {
                p.insert(
                    Value::String("from".into()),
                    Value::String((*rng.pick(&["p.yaml", "../cfg/twin.yaml", "/abs.yaml"])).into()),
                );
            } else {
                p.insert(
                    Value::String("name".into()),
                    Value::String(
                        (*rng.pick(&["stale_after_s", "two_chamber.bulk_modulus_pa", "model"]))
                            .into(),
                    ),
                );
                // `value: null` is no value at all (an invalid entry).
                let value = match random_value(rng, 1) {
                    Value::Null => Value::Bool(true),
                    v => v,
                };
                p.insert(Value::String("value".into()), value);
            }
            if rng.one_in(16) {
                valid = false;
                p.insert(Value::String("from".into()), Value::String("x.yaml".into()));
                p.insert(Value::String("name".into()), Value::String("x".into()));
            }
            params.push(Value::Mapping(p));
        }
        if !params.is_empty() || rng.one_in(4) {
            put("param", Value::Sequence(params));
        }
        if rng.one_in(2) {
            let mut r = Mapping::new();
            r.insert(
                Value::String("from".into()),
                Value::String("sensor/sample".into()),
            );
            r.insert(
                Value::String("to".into()),
                Value::String("rig/sample".into()),
            );
            put("remap", Value::Sequence(vec![Value::Mapping(r)]));
        }
        let mut entry = Mapping::new();
        entry.insert(Value::String("node".into()), Value::Mapping(node));
        entries.push(Value::Mapping(entry));
    }
    let mut doc = Mapping::new();
    doc.insert(Value::String("launch".into()), Value::Sequence(entries));
    let mut data = serde_norway::to_string(&Value::Mapping(doc))
        .unwrap_or_default()
        .into_bytes();
    if !rng.one_in(4) {
        let mut dictionary: Vec<&[u8]> = vec![
            b"launch:",
            b"node:",
            b"pkg: mrtwin",
            b"exec: twin",
            b"name: ",
            b"namespace: ",
            b"param:",
            b"remap:",
            b"from: ",
            b"to: ",
            b"value: ",
            b"args: ",
        ];
        dictionary.extend(CONFIG_DICTIONARY);
        mutate(rng, &mut data, &dictionary, MAX_TEXT);
        valid = false;
    }
    FuzzInput::single("launch.yaml", data, valid)
}

fn check_launch(input: &FuzzInput, _: &Scratch) -> Result<Verdict, String> {
    let text = String::from_utf8_lossy(input.part("launch.yaml"));
    let file = match parse_launch(&text, "launch.yaml") {
        Ok(f) => f,
        Err(e) if input.valid => return Err(format!("valid launch file rejected: {e}")),
        Err(e) => return names_file(&e.to_string(), "launch.yaml"),
    };
    // What `mrtwin launch` does next: each node's command line, parsed by the node.
    for (i, entry) in file.launch.iter().enumerate() {
        let args = entry.node.ros_args(std::path::Path::new("/cfg"));
        parse_ros_args(&args).map_err(|e| {
            format!("launch[{i}]: the accepted node's --ros-args {args:?} do not parse: {e}")
        })?;
    }
    Ok(Verdict::Accepted)
}

/// Arguments of a command line, one per NUL-separated part.
fn split_args(data: &[u8]) -> Vec<String> {
    if data.is_empty() {
        return Vec::new();
    }
    data.split(|&b| b == 0)
        .map(|a| String::from_utf8_lossy(a).into_owned())
        .collect()
}

/// A command line: program arguments and `--ros-args` sections with every flag, with
/// well-formed values (valid) or, after mutation, anything.
fn generate_ros_args(rng: &mut Rng) -> FuzzInput {
    let keys = &twin_schema().keys;
    let mut args: Vec<String> = Vec::new();
    if rng.one_in(2) {
        args.extend(["mrtwin".into(), "node".into()]);
    }
    let sections = rng.range(1, 2);
    for s in 0..sections {
        if !args.is_empty() || rng.one_in(2) {
            args.push("--ros-args".into());
        }
        for _ in 0..rng.below(6) {
            match rng.below(4) {
                0 => {
                    args.push((*rng.pick(&["-r", "--remap"])).into());
                    args.push(
                        (*rng.pick(&["__node:=twin", "__name:=t", "__ns:=/lab", "a:=b", "/x:=/y"]))
                            .into(),
                    );
                }
                1 => {
                    args.push("--params-file".into());
                    args.push("params.yaml".into());
                }
                _ => {
                    args.push((*rng.pick(&["-p", "--param"])).into());
                    let mut name = String::from_utf8_lossy(rng.pick(keys).as_slice()).into_owned();
                    if rng.one_in(3) {
                        name = format!("two_chamber.{name}");
                    }
                    let value = serde_norway::to_string(&random_value(rng, 2))
                        .unwrap_or_default()
                        .trim()
                        .to_owned();
                    args.push(format!("{name}:={value}"));
                }
            }
        }
        if s + 1 < sections {
            args.push("--".into());
            args.push("--user-flag".into());
        }
    }
    let mut data = args.join("\0").into_bytes();
    let mut valid = true;
    if !rng.one_in(4) {
        let dictionary: &[&[u8]] = &[
            b"\0--ros-args\0",
            b"\0--\0",
            b"\0-p\0",
            b"\0-r\0",
            b"\0--params-file\0",
            b":=",
            b"__node:=",
            b"__ns:=",
            b"..",
            b".",
            b"\0",
            b"[1, 2]",
            b"{a: 1}",
        ];
        mutate(rng, &mut data, dictionary, 1024);
        valid = false;
    }
    FuzzInput::single("args", data, valid)
}

fn check_ros_args(input: &FuzzInput, _: &Scratch) -> Result<Verdict, String> {
    let args = split_args(input.part("args"));
    let mut parsed = match parse_ros_args(&args) {
        Ok(p) => p,
        Err(e) if input.valid => return Err(format!("valid arguments rejected: {e}")),
        Err(_) => return Ok(Verdict::Rejected),
    };
    let _ = parsed.fully_qualified_name(TWIN_NODE);
    // The overrides alone (the files are not on this machine): errors name the command line.
    parsed.params_files.clear();
    if let Err(e) = load_node_params::<TwinNodeParams>(&parsed, TWIN_NODE) {
        let message = e.to_string();
        if !message.contains("command line") {
            return Err(format!(
                "an override's error does not name the command line: {message}"
            ));
        }
    }
    Ok(Verdict::Accepted)
}

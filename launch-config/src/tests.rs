//! End-to-end tests of parameter loading and error reporting.

use std::collections::BTreeMap;
use std::path::PathBuf;

use serde::Deserialize;

use super::*;

#[derive(Debug, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
struct Params {
    model: String,
    rate_hz: f64,
    two_chamber: TwoChamber,
    valves: Vec<Valve>,
    tags: BTreeMap<String, u32>,
}

#[derive(Debug, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
struct TwoChamber {
    bulk_modulus_pa: f64,
    volume_m3: f64,
    seal: Seal,
}

#[derive(Debug, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
struct Seal {
    friction_n: f64,
    enabled: bool,
}

#[derive(Debug, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
struct Valve {
    name: String,
    gain: f64,
}

/// Asserts the error names `file`, `key` and `line`, in its fields and in
/// its message.
#[track_caller]
fn assert_at(err: &ConfigError, file: &str, line: usize, key: &str) {
    let text = err.to_string();
    assert_eq!(err.file(), Some(file), "{text}");
    assert_eq!(err.line(), Some(line), "{text}");
    assert_eq!(err.key(), Some(key), "{text}");
    assert!(text.starts_with(&format!("{file} line {line}")), "{text}");
    assert!(text.contains(key), "{text}");
}

fn parse(text: &str, node: &str) -> Result<Params, ConfigError> {
    parse_params(text, "params.yaml", node)
}

const FILE: &str = "\
# mrtwin stand parameters
/**:
  ros__parameters:
    rate_hz: 100.0
    two_chamber:
      volume_m3: 0.002
      seal:
        friction_n: 12.0
mrtwin_stand:
  ros__parameters:
    model: two-chamber
    two_chamber:
      bulk_modulus_pa: 5.0e8
      seal:
        enabled: true
    valves:
      - name: main
        gain: 1.5
      - name: bypass
        gain: 0.5
other_node:
  ros__parameters:
    model: other
";

#[test]
fn wildcard_and_node_merge_recursively() {
    let params = parse(FILE, "mrtwin_stand").expect("valid file");
    assert_eq!(
        params,
        Params {
            model: "two-chamber".into(),
            rate_hz: 100.0,
            two_chamber: TwoChamber {
                bulk_modulus_pa: 5.0e8,
                volume_m3: 0.002,
                seal: Seal {
                    friction_n: 12.0,
                    enabled: true,
                },
            },
            valves: vec![
                Valve {
                    name: "main".into(),
                    gain: 1.5,
                },
                Valve {
                    name: "bypass".into(),
                    gain: 0.5,
                },
            ],
            tags: BTreeMap::new(),
        }
    );
}

#[test]
fn node_keys_override_wildcard_whatever_the_order() {
    let text = "\
mrtwin_stand:
  ros__parameters:
    rate_hz: 250.0
/**:
  ros__parameters:
    rate_hz: 100.0
    model: shared
";
    let params = parse(text, "mrtwin_stand").expect("valid file");
    assert_eq!(params.rate_hz, 250.0);
    assert_eq!(params.model, "shared");
}

#[test]
fn wildcard_alone_applies_to_any_node() {
    let params = parse(FILE, "/lab/some_node").expect("wildcard applies");
    assert_eq!(params.rate_hz, 100.0);
    assert_eq!(params.model, "");
}

#[test]
fn namespaced_sections_and_nodes() {
    let text = "\
/lab/mrtwin_stand:
  ros__parameters:
    model: lab
/field/mrtwin_stand:
  ros__parameters:
    model: field
";
    let p: Params = parse(text, "/lab/mrtwin_stand").expect("exact fqn");
    assert_eq!(p.model, "lab");
    let p: Params = parse(text, "/field/mrtwin_stand").expect("exact fqn");
    assert_eq!(p.model, "field");
    // A bare node name matches by its last path component (both, in order).
    let p: Params = parse(text, "mrtwin_stand").expect("base name");
    assert_eq!(p.model, "field");
    // A plain section name matches a namespaced node.
    let p: Params = parse(FILE, "/lab/mrtwin_stand").expect("base name");
    assert_eq!(p.model, "two-chamber");
}

#[test]
fn plain_yaml_is_taken_whole() {
    let text = "model: plain\ntwo_chamber:\n  bulk_modulus_pa: 1.0e9\n";
    let params = parse(text, "anything").expect("plain file");
    assert_eq!(params.model, "plain");
    assert_eq!(params.two_chamber.bulk_modulus_pa, 1.0e9);

    let empty = parse("# nothing here\n", "anything").expect("empty file");
    assert_eq!(empty, Params::default());
}

#[test]
fn plain_yaml_errors_have_lines() {
    let text = "model: plain\ntwo_chamber:\n  seal:\n    enabled: maybe\n";
    let err = parse(text, "n").unwrap_err();
    assert_at(&err, "params.yaml", 4, "two_chamber.seal.enabled");
    assert!(err.to_string().contains("expected a boolean"), "{err}");
}

#[test]
fn dotted_keys_are_nested_names() {
    let text = "\
mrtwin_stand:
  ros__parameters:
    two_chamber.bulk_modulus_pa: 7.0e8
    two_chamber:
      volume_m3: 0.001
    two_chamber.seal.frictoin_n: 3.0
";
    let err = parse(text, "mrtwin_stand").unwrap_err();
    assert_at(&err, "params.yaml", 6, "two_chamber.seal.frictoin_n");

    let ok = text.replace("frictoin", "friction");
    let params = parse(&ok, "mrtwin_stand").expect("valid");
    assert_eq!(params.two_chamber.bulk_modulus_pa, 7.0e8);
    assert_eq!(params.two_chamber.volume_m3, 0.001);
    assert_eq!(params.two_chamber.seal.friction_n, 3.0);
}

#[test]
fn unknown_key_names_file_path_line_and_allowed_keys() {
    let text = FILE.replace("      bulk_modulus_pa: 5.0e8", "      bulk_modulus: 5.0e8");
    let err = parse(&text, "mrtwin_stand").unwrap_err();
    assert_at(&err, "params.yaml", 13, "two_chamber.bulk_modulus");
    assert!(matches!(err, ConfigError::UnknownKey { .. }));
    assert_eq!(
        err.to_string(),
        "params.yaml line 13: unknown key two_chamber.bulk_modulus \
         (expected one of `bulk_modulus_pa`, `volume_m3`, `seal`)"
    );
}

#[test]
fn unknown_top_level_and_deep_keys() {
    let text = FILE.replace("    model: two-chamber", "    modle: two-chamber");
    let err = parse(&text, "mrtwin_stand").unwrap_err();
    assert_at(&err, "params.yaml", 11, "modle");

    let text = FILE.replace("        enabled: true", "        enable: true");
    let err = parse(&text, "mrtwin_stand").unwrap_err();
    assert_at(&err, "params.yaml", 15, "two_chamber.seal.enable");
}

#[test]
fn unknown_key_in_wildcard_section_points_into_it() {
    let text = FILE.replace("        friction_n: 12.0", "        friction: 12.0");
    let err = parse(&text, "mrtwin_stand").unwrap_err();
    assert_at(&err, "params.yaml", 8, "two_chamber.seal.friction");
}

#[test]
fn unknown_key_in_sequence_element() {
    let text = FILE.replace("        gain: 0.5", "        gian: 0.5");
    let err = parse(&text, "mrtwin_stand").unwrap_err();
    assert_at(&err, "params.yaml", 20, "valves[1].gian");
}

#[test]
fn wrong_type_names_key_and_line() {
    let text = FILE.replace("bulk_modulus_pa: 5.0e8", "bulk_modulus_pa: abc");
    let err = parse(&text, "mrtwin_stand").unwrap_err();
    assert_at(&err, "params.yaml", 13, "two_chamber.bulk_modulus_pa");
    assert_eq!(
        err.to_string(),
        "params.yaml line 13, key two_chamber.bulk_modulus_pa: \
         invalid type: string \"abc\", expected f64"
    );

    let text = FILE.replace("gain: 1.5", "gain: [1]");
    let err = parse(&text, "mrtwin_stand").unwrap_err();
    assert_at(&err, "params.yaml", 18, "valves[0].gain");

    let text = FILE.replace("    rate_hz: 100.0", "    rate_hz: fast");
    let err = parse(&text, "mrtwin_stand").unwrap_err();
    assert_at(&err, "params.yaml", 4, "rate_hz");
}

#[test]
fn wrong_type_of_a_whole_struct() {
    let text = "mrtwin_stand:\n  ros__parameters:\n    two_chamber: 5\n";
    let err = parse(text, "mrtwin_stand").unwrap_err();
    assert_at(&err, "params.yaml", 3, "two_chamber");
    assert!(
        err.to_string().contains("expected struct TwoChamber"),
        "{err}"
    );
}

#[test]
fn map_values_are_checked_too() {
    let text = "n:\n  ros__parameters:\n    tags:\n      a: 1\n      b: -2\n";
    let err = parse(text, "n").unwrap_err();
    assert_at(&err, "params.yaml", 5, "tags.b");
}

#[test]
fn yaml_syntax_error_has_line() {
    let text = "mrtwin_stand:\n  ros__parameters:\n    model: [unclosed\n    rate_hz: 1.0\n";
    let err = parse(text, "mrtwin_stand").unwrap_err();
    assert!(matches!(err, ConfigError::Syntax { .. }), "{err:?}");
    assert_eq!(err.file(), Some("params.yaml"));
    let line = err.line().expect("syntax errors have a line");
    assert!((3..=5).contains(&line), "{err}");
    assert!(
        err.to_string()
            .starts_with(&format!("params.yaml line {line}: YAML syntax error: ")),
        "{err}"
    );

    let err = parse("a: 1\nb: [\n  c: d: e\n", "n").unwrap_err();
    assert!(
        matches!(err, ConfigError::Syntax { line: Some(_), .. }),
        "{err}"
    );

    let err = parse("a: 1\na: 2\n", "n").unwrap_err();
    assert!(err.to_string().contains("duplicate"), "{err}");
    assert_eq!(err.line(), Some(2), "{err}");

    let text = "n:\n  ros__parameters:\n    a: 1\n    b:\n      c: 1\n    a: 2\n";
    let err = parse(text, "n").unwrap_err();
    assert_eq!(
        err.to_string(),
        "params.yaml line 6: YAML syntax error: n.ros__parameters: duplicate entry with key \"a\""
    );
}

#[test]
fn missing_node_section() {
    let err = parse(FILE.replace("/**:", "/ns/*:").as_str(), "mrtwin_bench").unwrap_err();
    assert!(matches!(err, ConfigError::NodeNotFound { .. }));
    assert_eq!(
        err.to_string(),
        "params.yaml: no parameters for node `mrtwin_bench` \
         (sections in file: mrtwin_stand, other_node; no `/**` wildcard)"
    );
}

#[test]
fn malformed_ros_layout() {
    let text = "mrtwin_stand:\n  ros__parameters: 5\n";
    let err = parse(text, "mrtwin_stand").unwrap_err();
    assert!(
        matches!(err, ConfigError::Structure { line: Some(2), .. }),
        "{err}"
    );

    let text = "mrtwin_stand:\n  ros__parameters:\n    model: x\nstray: 1\n";
    let err = parse(text, "mrtwin_stand").unwrap_err();
    assert!(
        matches!(err, ConfigError::Structure { line: Some(4), .. }),
        "{err}"
    );
    assert!(err.to_string().contains("`stray`"), "{err}");

    let text = "ros__parameters:\n  model: x\n";
    let err = parse(text, "mrtwin_stand").unwrap_err();
    assert!(
        matches!(err, ConfigError::Structure { line: Some(1), .. }),
        "{err}"
    );

    // An empty section is fine: all defaults.
    let params = parse("mrtwin_stand:\n  ros__parameters:\n", "mrtwin_stand").expect("empty");
    assert_eq!(params, Params::default());
}

#[test]
fn yaml_merge_keys_are_applied() {
    let text = "\
base: &base
  ros__parameters:
    rate_hz: 10.0
mrtwin_stand:
  <<: *base
";
    let params = parse(text, "mrtwin_stand").expect("merge keys");
    assert_eq!(params.rate_hz, 10.0);
}

#[test]
fn value_output_returns_merged_tree() {
    let tree: Value = parse_params(FILE, "params.yaml", "other_node").expect("value");
    let expected: Value = serde_norway::from_str(
        "rate_hz: 100.0\nmodel: other\ntwo_chamber: {volume_m3: 0.002, seal: {friction_n: 12.0}}\n",
    )
    .expect("yaml");
    assert_eq!(tree, expected);
}

/// A temporary directory removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn new(tag: &str) -> Self {
        let dir =
            std::env::temp_dir().join(format!("launch-config-test-{}-{tag}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("create temp dir");
        Self(dir)
    }

    fn write(&self, name: &str, text: &str) -> PathBuf {
        let path = self.0.join(name);
        std::fs::write(&path, text).expect("write temp file");
        path
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

#[test]
fn load_params_reads_files_and_names_them() {
    let dir = TempDir::new("load");
    let path = dir.write("params.yaml", FILE);
    let params: Params = load_params(&path, "mrtwin_stand").expect("valid file");
    assert_eq!(params.model, "two-chamber");

    let bad = dir.write("bad.yaml", &FILE.replace("gain: 0.5", "gain: high"));
    let err = load_params::<Params>(&bad, "mrtwin_stand").unwrap_err();
    let name = bad.display().to_string();
    assert_at(&err, &name, 20, "valves[1].gain");
}

#[test]
fn missing_file() {
    let err = load_params::<Params>(Path::new("missing.yaml"), "n").unwrap_err();
    assert!(matches!(err, ConfigError::Io { .. }));
    assert_eq!(
        err.to_string(),
        "missing.yaml: cannot read file: No such file or directory"
    );
    assert!(std::error::Error::source(&err).is_some());
}

#[test]
fn load_node_params_merges_files_and_overrides() {
    let dir = TempDir::new("node");
    let base = dir.write("base.yaml", FILE);
    let lab = dir.write(
        "lab.yaml",
        "/lab/stand:\n  ros__parameters:\n    two_chamber:\n      volume_m3: 0.004\n",
    );
    let unrelated = dir.write(
        "unrelated.yaml",
        "someone_else:\n  ros__parameters:\n    x: 1\n",
    );
    let args: Vec<String> = [
        "mrtwin",
        "--ros-args",
        "--params-file",
        base.to_str().expect("utf-8 temp path"),
        "--params-file",
        lab.to_str().expect("utf-8 temp path"),
        "--params-file",
        unrelated.to_str().expect("utf-8 temp path"),
        "-r",
        "__node:=stand",
        "-r",
        "__ns:=/lab",
        "-p",
        "two_chamber.seal.enabled:=true",
        "-p",
        "model:=from-cli",
    ]
    .iter()
    .map(|s| (*s).to_owned())
    .collect();
    let ros = parse_ros_args(&args).expect("valid args");
    let params: Params = load_node_params(&ros, "mrtwin_stand").expect("valid");
    assert_eq!(params.model, "from-cli");
    assert_eq!(params.rate_hz, 100.0); // wildcard in base.yaml
    assert_eq!(params.two_chamber.volume_m3, 0.004); // lab.yaml wins
    assert_eq!(params.two_chamber.seal.friction_n, 12.0);
    assert!(params.two_chamber.seal.enabled);

    // An error in the second file is reported there.
    let mut bad = ros.clone();
    let lab_bad = dir.write(
        "lab_bad.yaml",
        "/lab/stand:\n  ros__parameters:\n    two_chamber:\n      volume_m3: big\n",
    );
    bad.params_files[1] = lab_bad.clone();
    let err = load_node_params::<Params>(&bad, "mrtwin_stand").unwrap_err();
    assert_at(
        &err,
        &lab_bad.display().to_string(),
        4,
        "two_chamber.volume_m3",
    );

    // An error caused by a -p override names the override.
    let mut bad = ros.clone();
    bad.params
        .push(("two_chamber.bulk_modulus_pa".into(), "abc".into()));
    let err = load_node_params::<Params>(&bad, "mrtwin_stand").unwrap_err();
    assert_eq!(
        err.to_string(),
        "command line `-p two_chamber.bulk_modulus_pa:=abc`, key two_chamber.bulk_modulus_pa: \
         invalid type: string \"abc\", expected f64"
    );
    let mut bad = ros.clone();
    bad.params.push(("two_chamber.bulk".into(), "1".into()));
    let err = load_node_params::<Params>(&bad, "mrtwin_stand").unwrap_err();
    assert!(matches!(err, ConfigError::UnknownKey { .. }), "{err}");
    assert_eq!(err.file(), Some("command line `-p two_chamber.bulk:=1`"));

    // No file has the node: error naming all files.
    let only_unrelated = RosArgs {
        params_files: vec![unrelated.clone()],
        ..RosArgs::default()
    };
    let err = load_node_params::<Params>(&only_unrelated, "mrtwin_stand").unwrap_err();
    assert!(matches!(err, ConfigError::NodeNotFound { .. }), "{err}");

    // No files at all: defaults plus overrides.
    let cli_only = parse_ros_args(&["-p".to_owned(), "rate_hz:=5".to_owned()]).expect("args");
    let params: Params = load_node_params(&cli_only, "n").expect("defaults");
    assert_eq!(params.rate_hz, 5.0);
}

#[test]
fn a_written_parameter_file_reads_back_for_each_node() {
    #[derive(Debug, Default, PartialEq, Deserialize, serde::Serialize)]
    #[serde(deny_unknown_fields, default)]
    struct Written {
        model: String,
        coefficients: [f64; 3],
        inner: Inner,
    }
    #[derive(Debug, Default, PartialEq, Deserialize, serde::Serialize)]
    #[serde(deny_unknown_fields, default)]
    struct Inner {
        tiny: f64,
        big: f64,
    }
    let p = Written {
        model: "two-chamber".into(),
        coefficients: [-0.1, 1.0 / 3.0, 45_000.5],
        inner: Inner {
            tiny: 1.234_567_890_123e-9,
            big: 7.5e14,
        },
    };
    let text = params_yaml(
        "written by a test\nsecond line",
        &[("a_node", &p), ("b_node", &p)],
    )
    .unwrap();
    assert!(text.starts_with("# written by a test\n# second line\n"));
    for node in ["a_node", "/b_node"] {
        let back: Written = parse_params(&text, "w.yaml", node).unwrap();
        assert_eq!(back, p, "{node}");
    }
}

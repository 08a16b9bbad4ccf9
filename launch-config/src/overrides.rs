//! Command-line parameter overrides (`-p a.b:=1.5`).

use serde_norway::{Mapping, Value};

use crate::select::deep_merge;

/// Sets dotted keys in a parameter tree from `(name, value)` pairs, as given
/// by `-p name:=value` on the command line.
///
/// * `name` is split on `.` into nested mapping keys (`two_chamber.bulk_modulus_pa`
///   sets `bulk_modulus_pa` inside `two_chamber`); missing levels are created.
/// * `value` is parsed as YAML, like ROS 2 does: `1.5` is a float, `3` an
///   integer, `true` a boolean, `[1, 2]` a sequence, anything else (including
///   the empty string and text that does not parse) a string.
/// * Later overrides win. A mapping value is merged into an existing mapping;
///   any other value replaces what was there. A non-mapping found on the way
///   (including `yaml` itself) is replaced by a mapping.
/// * Names with an empty component (`""`, `a..b`, `.a`) are skipped;
///   [`parse_ros_args`](crate::parse_ros_args) rejects them up front.
pub fn apply_param_overrides(yaml: &mut Value, overrides: &[(String, String)]) {
    for (name, value) in overrides {
        let parts: Vec<&str> = name.split('.').collect();
        if parts.iter().any(|part| part.is_empty()) {
            continue;
        }
        set_path(yaml, &parts, parse_value(value));
    }
}

/// Is `name` usable as a dotted parameter name?
pub(crate) fn valid_param_name(name: &str) -> bool {
    !name.split('.').any(str::is_empty)
}

/// The dotted parameter name as path components.
pub(crate) fn param_path(name: &str) -> Vec<String> {
    name.split('.').map(str::to_owned).collect()
}

fn set_path(target: &mut Value, parts: &[&str], value: Value) {
    let Some((first, rest)) = parts.split_first() else {
        deep_merge(target, value);
        return;
    };
    if !target.is_mapping() {
        *target = Value::Mapping(Mapping::new());
    }
    if let Value::Mapping(map) = target {
        let entry = map
            .entry(Value::String((*first).to_owned()))
            .or_insert(Value::Null);
        set_path(entry, rest, value);
    }
}

/// Parses a command-line value the way ROS 2 does (YAML scalar or sequence).
fn parse_value(text: &str) -> Value {
    if text.trim().is_empty() {
        return Value::String(text.to_owned());
    }
    match serde_norway::from_str::<Value>(text) {
        Ok(Value::Mapping(_)) | Err(_) => Value::String(text.to_owned()),
        Ok(value) => value,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn yaml(text: &str) -> Value {
        serde_norway::from_str(text).expect("test YAML")
    }

    fn ov(pairs: &[(&str, &str)]) -> Vec<(String, String)> {
        pairs
            .iter()
            .map(|(k, v)| ((*k).to_owned(), (*v).to_owned()))
            .collect()
    }

    #[test]
    fn sets_nested_keys_with_yaml_types() {
        let mut tree = yaml("model: a\ntwo_chamber: {bulk_modulus_pa: 1.0, volume_m3: 2.0}\n");
        apply_param_overrides(
            &mut tree,
            &ov(&[
                ("two_chamber.bulk_modulus_pa", "1.5"),
                ("model", "two-chamber"),
                ("new.deep.flag", "true"),
                ("count", "3"),
                ("list", "[1, 2]"),
                ("text", "a: b"),
                ("empty", ""),
                ("broken", "[unclosed"),
            ]),
        );
        let expected = yaml(
            "model: two-chamber\n\
             two_chamber: {bulk_modulus_pa: 1.5, volume_m3: 2.0}\n\
             new: {deep: {flag: true}}\n\
             count: 3\n\
             list: [1, 2]\n\
             text: 'a: b'\n\
             empty: ''\n\
             broken: '[unclosed'\n",
        );
        assert_eq!(tree, expected);
    }

    #[test]
    fn replaces_scalars_on_the_way_and_skips_bad_names() {
        let mut tree = yaml("a: 5");
        apply_param_overrides(&mut tree, &ov(&[("a.b", "1"), ("", "x"), ("c..d", "2")]));
        assert_eq!(tree, yaml("a: {b: 1}"));

        let mut null = Value::Null;
        apply_param_overrides(&mut null, &ov(&[("x", "abc")]));
        assert_eq!(null, yaml("x: abc"));
    }

    #[test]
    fn later_overrides_win() {
        let mut tree = Value::Null;
        apply_param_overrides(&mut tree, &ov(&[("a", "1"), ("a", "2")]));
        assert_eq!(tree, yaml("a: 2"));
    }
}

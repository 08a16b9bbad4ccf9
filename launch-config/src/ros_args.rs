//! The ROS 2 command-line convention (`--ros-args ... [--]`).

use std::path::PathBuf;

use crate::error::ConfigError;
use crate::overrides::valid_param_name;

/// ROS 2 arguments parsed by [`parse_ros_args`].
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct RosArgs {
    /// `--params-file FILE`, in command-line order (later files win).
    pub params_files: Vec<PathBuf>,
    /// `-r __node:=NAME` (or `__name:=NAME`).
    pub node_name: Option<String>,
    /// `-r __ns:=NS`.
    pub namespace: Option<String>,
    /// All other `-r FROM:=TO` remappings, in order.
    pub remaps: Vec<(String, String)>,
    /// `-p NAME:=VALUE` overrides, in order (values still unparsed text).
    pub params: Vec<(String, String)>,
    /// Arguments outside any `--ros-args` section (e.g. the program name and
    /// the application's own flags), in order.
    pub other_args: Vec<String>,
}

impl RosArgs {
    /// The node's fully qualified name: `-r __node` (or `default_name`)
    /// inside `-r __ns` (or the root namespace). A `default_name` that
    /// already starts with `/` is taken as fully qualified when no
    /// `__node`/`__ns` remap is given.
    pub fn fully_qualified_name(&self, default_name: &str) -> String {
        if self.node_name.is_none() && self.namespace.is_none() && default_name.starts_with('/') {
            return default_name.to_owned();
        }
        let name = self
            .node_name
            .as_deref()
            .unwrap_or(default_name)
            .trim_matches('/');
        let namespace = self.namespace.as_deref().unwrap_or("").trim_matches('/');
        if namespace.is_empty() {
            format!("/{name}")
        } else {
            format!("/{namespace}/{name}")
        }
    }
}

/// Parses ROS 2 command-line arguments.
///
/// ROS arguments follow `--ros-args` and run up to `--` or the end; there
/// may be several such sections. Everything outside them (e.g. the program
/// name) lands in [`RosArgs::other_args`]. If `args` contains no
/// `--ros-args` at all, the whole slice is read as ROS arguments, so callers
/// may pass just the ROS part (without the program name).
///
/// Supported inside a section:
/// `--params-file FILE`, `-r`/`--remap FROM:=TO` (with `__node`/`__name` and
/// `__ns` setting [`RosArgs::node_name`] and [`RosArgs::namespace`]) and
/// `-p`/`--param NAME:=VALUE`.
///
/// # Errors
/// [`ConfigError::UnknownArgument`] for any other argument,
/// [`ConfigError::MissingArgumentValue`] for a flag at the end,
/// [`ConfigError::InvalidArgument`] for a value without `:=`, with an empty
/// name, or an empty node name.
pub fn parse_ros_args(args: &[String]) -> Result<RosArgs, ConfigError> {
    let has_marker = args.iter().any(|arg| arg == "--ros-args");
    let mut in_ros = !has_marker;
    let mut out = RosArgs::default();
    let mut iter = args.iter();
    while let Some(arg) = iter.next() {
        if arg == "--ros-args" {
            in_ros = true;
            continue;
        }
        if !in_ros {
            out.other_args.push(arg.clone());
            continue;
        }
        match arg.as_str() {
            "--" => in_ros = false,
            "--params-file" => {
                let file = next_value(&mut iter, arg)?;
                out.params_files.push(PathBuf::from(file));
            }
            "-r" | "--remap" => {
                let value = next_value(&mut iter, arg)?;
                let (from, to) = split_assignment(arg, value)?;
                match from {
                    "__node" | "__name" | "__ns" if to.is_empty() => {
                        return Err(invalid(arg, value, "empty value"));
                    }
                    "__node" | "__name" => out.node_name = Some(to.to_owned()),
                    "__ns" => out.namespace = Some(to.to_owned()),
                    _ => out.remaps.push((from.to_owned(), to.to_owned())),
                }
            }
            "-p" | "--param" => {
                let value = next_value(&mut iter, arg)?;
                let (name, text) = split_assignment(arg, value)?;
                if !valid_param_name(name) {
                    return Err(invalid(
                        arg,
                        value,
                        "parameter names must not have empty `.`-separated parts",
                    ));
                }
                out.params.push((name.to_owned(), text.to_owned()));
            }
            _ => return Err(ConfigError::UnknownArgument { arg: arg.clone() }),
        }
    }
    Ok(out)
}

fn next_value<'a>(
    iter: &mut impl Iterator<Item = &'a String>,
    flag: &str,
) -> Result<&'a str, ConfigError> {
    iter.next()
        .map(String::as_str)
        .ok_or_else(|| ConfigError::MissingArgumentValue {
            flag: flag.to_owned(),
        })
}

/// Splits `NAME:=VALUE`; the name must not be empty.
fn split_assignment<'a>(flag: &str, value: &'a str) -> Result<(&'a str, &'a str), ConfigError> {
    match value.split_once(":=") {
        Some(("", _)) => Err(invalid(flag, value, "empty name before `:=`")),
        Some(pair) => Ok(pair),
        None => Err(invalid(flag, value, "expected NAME:=VALUE")),
    }
}

fn invalid(flag: &str, value: &str, reason: &str) -> ConfigError {
    ConfigError::InvalidArgument {
        flag: flag.to_owned(),
        value: value.to_owned(),
        reason: reason.to_owned(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(text: &str) -> Vec<String> {
        text.split_whitespace().map(str::to_owned).collect()
    }

    #[test]
    fn parses_full_ros_section() {
        let parsed = parse_ros_args(&args(
            "mrtwin run --fast --ros-args --params-file a.yaml -r __node:=stand \
             -r __ns:=/lab --remap /force:=/stand/force -p two_chamber.bulk_modulus_pa:=1.5e9 \
             --param model:=two-chamber --params-file b.yaml -- --user-flag",
        ))
        .expect("valid args");
        assert_eq!(
            parsed,
            RosArgs {
                params_files: vec![PathBuf::from("a.yaml"), PathBuf::from("b.yaml")],
                node_name: Some("stand".into()),
                namespace: Some("/lab".into()),
                remaps: vec![("/force".into(), "/stand/force".into())],
                params: vec![
                    ("two_chamber.bulk_modulus_pa".into(), "1.5e9".into()),
                    ("model".into(), "two-chamber".into()),
                ],
                other_args: args("mrtwin run --fast --user-flag"),
            }
        );
        assert_eq!(parsed.fully_qualified_name("mrtwin_stand"), "/lab/stand");
    }

    #[test]
    fn without_marker_everything_is_ros() {
        let parsed = parse_ros_args(&args("--params-file p.yaml -r __name:=n -p x:=")).expect("ok");
        assert_eq!(parsed.params_files, vec![PathBuf::from("p.yaml")]);
        assert_eq!(parsed.node_name.as_deref(), Some("n"));
        assert_eq!(parsed.params, vec![("x".into(), String::new())]);
        assert!(parsed.other_args.is_empty());
        assert_eq!(parse_ros_args(&[]).expect("empty"), RosArgs::default());
    }

    #[test]
    fn several_sections() {
        let parsed =
            parse_ros_args(&args("prog --ros-args -p a:=1 -- mid --ros-args -p b:=2")).expect("ok");
        assert_eq!(parsed.params.len(), 2);
        assert_eq!(parsed.other_args, args("prog mid"));
    }

    #[test]
    fn unknown_flag_is_named() {
        let err = parse_ros_args(&args("--ros-args --log-level debug")).unwrap_err();
        assert!(matches!(&err, ConfigError::UnknownArgument { arg } if arg == "--log-level"));
        assert!(err.to_string().contains("`--log-level`"), "{err}");
        let err = parse_ros_args(&args("stray")).unwrap_err();
        assert!(err.to_string().contains("`stray`"), "{err}");
    }

    #[test]
    fn malformed_values() {
        let err = parse_ros_args(&args("--ros-args --params-file")).unwrap_err();
        assert_eq!(
            err.to_string(),
            "ROS argument `--params-file` needs a value"
        );
        let err = parse_ros_args(&args("-p model")).unwrap_err();
        assert_eq!(
            err.to_string(),
            "invalid ROS argument `-p model`: expected NAME:=VALUE"
        );
        for bad in ["-p :=1", "-p a..b:=1", "-r __node:=", "--remap :=x"] {
            let err = parse_ros_args(&args(bad)).unwrap_err();
            assert!(
                matches!(err, ConfigError::InvalidArgument { .. }),
                "{bad}: {err}"
            );
        }
    }

    #[test]
    fn fully_qualified_names() {
        let none = RosArgs::default();
        assert_eq!(none.fully_qualified_name("stand"), "/stand");
        assert_eq!(none.fully_qualified_name("/ns/stand"), "/ns/stand");
        let ns = RosArgs {
            namespace: Some("lab/".into()),
            ..RosArgs::default()
        };
        assert_eq!(ns.fully_qualified_name("stand"), "/lab/stand");
    }
}

//! The error type of this crate.

use std::io;

use thiserror::Error;

use crate::locate::SourceText;

/// Everything that can go wrong while reading parameter files or ROS 2
/// command-line arguments.
///
/// Every file-related variant names the file (as given by the caller), and,
/// where the problem can be pinned to a place in the file, the 1-based line
/// number in the *original* text and the dotted key path relative to the
/// node's `ros__parameters` block (for example `two_chamber.bulk_modulus_pa`,
/// or `valves[1].gain` for sequence elements).
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum ConfigError {
    /// The file could not be read (missing, unreadable, not UTF-8, ...).
    #[error("{file}: cannot read file: {reason}")]
    Io {
        /// The file as given by the caller.
        file: String,
        /// Human-readable reason, without the OS error code.
        reason: String,
        /// The underlying I/O error.
        #[source]
        source: io::Error,
    },

    /// The file is not valid YAML.
    #[error("{}: YAML syntax error: {message}", at(.file, .line))]
    Syntax {
        /// The file as given by the caller.
        file: String,
        /// 1-based line of the error, if the parser reported one.
        line: Option<usize>,
        /// 1-based column of the error, if the parser reported one.
        column: Option<usize>,
        /// The parser's message, without its location suffix.
        message: String,
    },

    /// The file is valid YAML but does not follow the `ros__parameters`
    /// layout (for example a `ros__parameters` entry that is not a mapping,
    /// or a top-level key without any `ros__parameters` below it).
    #[error("{}: {message}", at(.file, .line))]
    Structure {
        /// The file as given by the caller.
        file: String,
        /// 1-based line of the offending entry, if known.
        line: Option<usize>,
        /// What is wrong.
        message: String,
    },

    /// The file has `ros__parameters` sections, but none for the requested
    /// node and no wildcard (`/**`) section either.
    #[error(
        "{file}: no parameters for node `{node}` (sections in file: {}; no `/**` wildcard)",
        list(.available)
    )]
    NodeNotFound {
        /// The file(s) searched.
        file: String,
        /// The node that was asked for.
        node: String,
        /// The node sections that the file does have.
        available: Vec<String>,
    },

    /// A key that the target type does not know (`deny_unknown_fields`).
    #[error("{}: unknown key {key} ({expected})", at(.file, .line))]
    UnknownKey {
        /// The file (or command-line override) the key came from.
        file: String,
        /// 1-based line of the key, if known.
        line: Option<usize>,
        /// Dotted path of the unknown key.
        key: String,
        /// The allowed keys, as reported by serde
        /// (`expected one of `a`, `b``).
        expected: String,
    },

    /// A value of the wrong type or out of its domain, or any other
    /// deserialization error at a known key.
    #[error("{}{}: {message}", at(.file, .line), key_suffix(.key))]
    InvalidValue {
        /// The file (or command-line override) the value came from.
        file: String,
        /// 1-based line of the key, if known.
        line: Option<usize>,
        /// Dotted path of the key (empty for the root of the parameters).
        key: String,
        /// serde's message, e.g. `invalid type: string "abc", expected f64`.
        message: String,
    },

    /// A flag in a `--ros-args` section that this crate does not support.
    #[error(
        "unknown ROS argument `{arg}` (supported: --params-file FILE, -r/--remap FROM:=TO, \
         -p/--param NAME:=VALUE, --)"
    )]
    UnknownArgument {
        /// The offending argument.
        arg: String,
    },

    /// A flag that needs a value came last.
    #[error("ROS argument `{flag}` needs a value")]
    MissingArgumentValue {
        /// The flag without a value.
        flag: String,
    },

    /// A flag's value is malformed (e.g. `-p name` without `:=`).
    #[error("invalid ROS argument `{flag} {value}`: {reason}")]
    InvalidArgument {
        /// The flag.
        flag: String,
        /// Its value.
        value: String,
        /// What is wrong with it.
        reason: String,
    },
}

impl ConfigError {
    /// The file (or command-line source) the error refers to, if any.
    pub fn file(&self) -> Option<&str> {
        match self {
            Self::Io { file, .. }
            | Self::Syntax { file, .. }
            | Self::Structure { file, .. }
            | Self::NodeNotFound { file, .. }
            | Self::UnknownKey { file, .. }
            | Self::InvalidValue { file, .. } => Some(file),
            Self::UnknownArgument { .. }
            | Self::MissingArgumentValue { .. }
            | Self::InvalidArgument { .. } => None,
        }
    }

    /// The 1-based line number in the original file, if known.
    pub fn line(&self) -> Option<usize> {
        match self {
            Self::Syntax { line, .. }
            | Self::Structure { line, .. }
            | Self::UnknownKey { line, .. }
            | Self::InvalidValue { line, .. } => *line,
            _ => None,
        }
    }

    /// The dotted key path the error refers to, if any.
    pub fn key(&self) -> Option<&str> {
        match self {
            Self::UnknownKey { key, .. } | Self::InvalidValue { key, .. } => Some(key),
            _ => None,
        }
    }
}

/// `file line N`, or just `file` when the line is unknown.
fn at(file: &str, line: &Option<usize>) -> String {
    match line {
        Some(line) => format!("{file} line {line}"),
        None => file.to_owned(),
    }
}

/// `, key a.b` or nothing for the root.
fn key_suffix(key: &str) -> String {
    if key.is_empty() {
        String::new()
    } else {
        format!(", key {key}")
    }
}

fn list(items: &[String]) -> String {
    if items.is_empty() {
        "none".to_owned()
    } else {
        items.join(", ")
    }
}

/// Builds [`ConfigError::Io`] with the OS error code stripped from the
/// message (`No such file or directory`, not `... (os error 2)`).
pub(crate) fn io_error(file: &str, source: io::Error) -> ConfigError {
    let text = source.to_string();
    let reason = match text.rfind(" (os error ") {
        Some(pos) if text.ends_with(')') => text[..pos].to_owned(),
        _ => text,
    };
    ConfigError::Io {
        file: file.to_owned(),
        reason,
        source,
    }
}

/// Builds [`ConfigError::Syntax`] from a YAML parser error. For duplicate
/// keys the parser points at the start of the mapping; the line of the
/// duplicate itself is looked up in `source`.
pub(crate) fn syntax_error(
    file: &str,
    err: &serde_norway::Error,
    source: &SourceText<'_>,
) -> ConfigError {
    let location = err.location();
    let mut message = err.to_string();
    // The parser appends " at line L column C" (possibly followed by a
    // context); the line is reported separately, so drop the first marker.
    if let Some(loc) = &location {
        let marker = format!(" at line {} column {}", loc.line(), loc.column());
        if let Some(pos) = message.find(&marker) {
            message.replace_range(pos..pos + marker.len(), "");
        }
    }
    let mut line = location.as_ref().map(|l| l.line());
    if let (Some(loc), Some(key)) = (&location, duplicate_key(&message)) {
        if let Some(duplicate) = source.duplicate_key_line(loc.line(), loc.column(), &key) {
            line = Some(duplicate);
        }
    }
    ConfigError::Syntax {
        file: file.to_owned(),
        line,
        column: location.as_ref().map(|l| l.column()),
        message,
    }
}

/// The key of a `duplicate entry with key "x"` message.
fn duplicate_key(message: &str) -> Option<String> {
    const MARKER: &str = "duplicate entry with key \"";
    let start = message.find(MARKER)? + MARKER.len();
    let quoted = &message[start..];
    let mut key = String::new();
    let mut chars = quoted.chars();
    while let Some(c) = chars.next() {
        match c {
            '"' => return Some(key),
            '\\' => key.push(chars.next()?),
            other => key.push(other),
        }
    }
    None
}

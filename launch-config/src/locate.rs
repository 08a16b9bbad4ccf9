//! Maps key paths back to line numbers in the original YAML text.
//!
//! Parameters are deserialized from a sub-tree (the merged `ros__parameters`
//! blocks), so serde's errors carry no usable position. This module walks the
//! original text, indentation-aware, to find the line of a key path such as
//! `mrtwin_stand.ros__parameters.two_chamber.bulk_modulus_pa`.
//!
//! It understands block mappings (plain, single- and double-quoted keys),
//! block sequences (including indentless ones and `- key: value` items),
//! comments, block scalars (`|`, `>`) and ROS-style dotted keys
//! (`two_chamber.bulk_modulus_pa: 1.0` matches the path
//! `two_chamber` → `bulk_modulus_pa`). Anything inside flow collections
//! (`{...}`, `[...]`) resolves to the line of the enclosing key. When a path
//! cannot be found completely, the deepest matching prefix is reported.

use std::fmt::Write as _;

/// One segment of a key path.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) enum Seg {
    /// A mapping key.
    Key(String),
    /// A sequence index.
    Index(usize),
}

/// Renders a path as `a.b[2].c`; the empty path renders as an empty string.
pub(crate) fn display_path(path: &[Seg]) -> String {
    let mut out = String::new();
    for seg in path {
        match seg {
            Seg::Key(key) => {
                if !out.is_empty() {
                    out.push('.');
                }
                out.push_str(key);
            }
            Seg::Index(index) => {
                let _ = write!(out, "[{index}]");
            }
        }
    }
    out
}

/// A significant line: no blank lines, comments or block-scalar content.
#[derive(Clone, Copy, Debug)]
struct Line<'a> {
    /// 1-based line number in the original text.
    no: usize,
    /// Column where `text` starts.
    indent: usize,
    /// The line's content, without indentation and trailing whitespace.
    text: &'a str,
}

/// Pre-scanned YAML text that answers "on which line is this key path?".
#[derive(Debug)]
pub(crate) struct SourceText<'a> {
    lines: Vec<Line<'a>>,
}

impl<'a> SourceText<'a> {
    /// Scans `text` once; never fails (malformed input just finds less).
    pub(crate) fn new(text: &'a str) -> Self {
        let mut lines = Vec::new();
        // While inside a block scalar: lines indented deeper than this belong
        // to the scalar and are skipped.
        let mut scalar_indent: Option<usize> = None;
        for (index, raw) in text.lines().enumerate() {
            let trimmed = raw.trim_start_matches(' ');
            let indent = raw.len() - trimmed.len();
            let content = trimmed.trim_end();
            if let Some(limit) = scalar_indent {
                if content.is_empty() || indent > limit {
                    continue;
                }
                scalar_indent = None;
            }
            if content.is_empty()
                || content.starts_with('#')
                || content.starts_with('%')
                || content == "---"
                || content == "..."
                || content.starts_with("--- ")
            {
                continue;
            }
            lines.push(Line {
                no: index + 1,
                indent,
                text: content,
            });
            if opens_block_scalar(content) {
                scalar_indent = Some(indent);
            }
        }
        Self { lines }
    }

    /// Finds `path` in the text. Returns how many segments matched and the
    /// line of the deepest matched segment (`None` when nothing matched).
    pub(crate) fn locate(&self, path: &[Seg]) -> (usize, Option<usize>) {
        find(&self.lines, path)
    }

    /// The line of the second `key` entry of the block mapping that starts at
    /// 1-based `line`/`column` (where the YAML parser reports a duplicate).
    pub(crate) fn duplicate_key_line(
        &self,
        line: usize,
        column: usize,
        key: &str,
    ) -> Option<usize> {
        let indent = column.checked_sub(1)?;
        let start = self.lines.iter().position(|l| l.no >= line)?;
        let mut seen = false;
        for (n, entry) in self.lines[start..].iter().enumerate() {
            let text = if n == 0 && entry.no == line {
                // The mapping may start mid-line, after `- `.
                let offset = indent.checked_sub(entry.indent)?;
                entry.text.get(offset..)?
            } else if entry.indent < indent {
                break;
            } else if entry.indent == indent {
                entry.text
            } else {
                continue;
            };
            if split_key(text).is_some_and(|(k, _)| k == key) {
                if seen {
                    return Some(entry.no);
                }
                seen = true;
            }
        }
        None
    }

    /// The line of `path` if the whole path is present.
    #[cfg(test)]
    pub(crate) fn line_of(&self, path: &[Seg]) -> Option<usize> {
        match self.locate(path) {
            (depth, line) if depth == path.len() => line,
            _ => None,
        }
    }
}

/// Searches `block` (the lines of one collection) for `path`.
///
/// Several entries may match the first segment (e.g. `a:` and a dotted
/// `a.b:`); the first complete match wins, else the deepest partial one.
fn find(block: &[Line<'_>], path: &[Seg]) -> (usize, Option<usize>) {
    let (Some(first), Some(seg)) = (block.first(), path.first()) else {
        return (0, None);
    };
    let indent = first.indent;
    let mut best = (0, None);
    let mut seq_index = 0;
    let mut i = 0;
    while i < block.len() {
        let line = block[i];
        if line.indent < indent {
            break;
        }
        if line.indent > indent {
            i += 1;
            continue;
        }
        let end = entry_end(block, i);
        let candidate = match seg {
            Seg::Key(_) => split_key(line.text).and_then(|(key, _)| {
                let consumed = key_match(&key, path);
                (consumed > 0).then(|| {
                    let (depth, found) = find(&block[i + 1..end], &path[consumed..]);
                    (consumed + depth, found.or(Some(line.no)))
                })
            }),
            Seg::Index(wanted) => seq_item(line.text).and_then(|item| {
                seq_index += 1;
                (seq_index - 1 == *wanted).then(|| {
                    let mut lines = Vec::with_capacity(end - i);
                    if !item.is_empty() {
                        lines.push(Line {
                            no: line.no,
                            indent: line.indent + (line.text.len() - item.len()),
                            text: item,
                        });
                    }
                    lines.extend_from_slice(&block[i + 1..end]);
                    let (depth, found) = find(&lines, &path[1..]);
                    (1 + depth, found.or(Some(line.no)))
                })
            }),
        };
        if let Some(candidate) = candidate {
            if candidate.0 == path.len() {
                return candidate;
            }
            if candidate.0 > best.0 {
                best = candidate;
            }
        }
        i = end;
    }
    best
}

/// Index just past the entry starting at `block[start]`: its deeper-indented
/// lines, plus (for a key) an indentless sequence at the same indentation.
fn entry_end(block: &[Line<'_>], start: usize) -> usize {
    let indent = block[start].indent;
    let is_key = seq_item(block[start].text).is_none();
    let mut end = start + 1;
    while let Some(line) = block.get(end) {
        let child = line.indent > indent
            || (is_key && line.indent == indent && seq_item(line.text).is_some());
        if !child {
            break;
        }
        end += 1;
    }
    end
}

/// How many path segments the (possibly dotted) `key` consumes; 0 if none.
fn key_match(key: &str, path: &[Seg]) -> usize {
    if matches!(path.first(), Some(Seg::Key(k)) if k == key) {
        return 1;
    }
    if !key.contains('.') {
        return 0;
    }
    let parts: Vec<&str> = key.split('.').collect();
    let all_match = parts.len() <= path.len()
        && parts
            .iter()
            .zip(path)
            .all(|(part, seg)| matches!(seg, Seg::Key(k) if k == part));
    if all_match {
        parts.len()
    } else {
        0
    }
}

/// If `text` is a block sequence item (`- x` or `-`), returns its content.
fn seq_item(text: &str) -> Option<&str> {
    let rest = text.strip_prefix('-')?;
    if rest.is_empty() {
        Some(rest)
    } else if rest.starts_with([' ', '\t']) {
        Some(rest.trim_start())
    } else {
        None
    }
}

/// Splits `key: value` into the (unquoted) key and the rest after the colon.
pub(crate) fn split_key(text: &str) -> Option<(String, &str)> {
    let after_colon = |rest: &str| -> Option<usize> {
        let trimmed = rest.trim_start();
        let colon = rest.len() - trimmed.len();
        let tail = trimmed.strip_prefix(':')?;
        (tail.is_empty() || tail.starts_with([' ', '\t'])).then_some(colon + 1)
    };
    if let Some(body) = text.strip_prefix('"') {
        let mut key = String::new();
        let mut chars = body.char_indices();
        while let Some((pos, c)) = chars.next() {
            match c {
                '"' => {
                    let rest = &body[pos + 1..];
                    let colon = after_colon(rest)?;
                    return Some((key, &rest[colon..]));
                }
                '\\' => match chars.next() {
                    Some((_, 'n')) => key.push('\n'),
                    Some((_, 't')) => key.push('\t'),
                    Some((_, other)) => key.push(other),
                    None => return None,
                },
                other => key.push(other),
            }
        }
        return None;
    }
    if let Some(body) = text.strip_prefix('\'') {
        let mut key = String::new();
        let mut chars = body.char_indices().peekable();
        while let Some((pos, c)) = chars.next() {
            if c != '\'' {
                key.push(c);
                continue;
            }
            if matches!(chars.peek(), Some((_, '\''))) {
                chars.next();
                key.push('\'');
                continue;
            }
            let rest = &body[pos + 1..];
            let colon = after_colon(rest)?;
            return Some((key, &rest[colon..]));
        }
        return None;
    }
    if text.starts_with(['{', '[', '?', '&', '*', '!', '|', '>', '#']) {
        return None;
    }
    let bytes = text.as_bytes();
    for (pos, &b) in bytes.iter().enumerate() {
        match b {
            b'#' if pos > 0 && matches!(bytes[pos - 1], b' ' | b'\t') => return None,
            b':' if matches!(bytes.get(pos + 1), None | Some(b' ' | b'\t')) => {
                let key = text[..pos].trim_end();
                return (!key.is_empty()).then(|| (key.to_owned(), &text[pos + 1..]));
            }
            _ => {}
        }
    }
    None
}

/// Does this line end in a block scalar header (`key: |`, `- >-`, ...)?
fn opens_block_scalar(text: &str) -> bool {
    let mut value = text;
    loop {
        if let Some(item) = seq_item(value) {
            value = item;
        } else if let Some((_, rest)) = split_key(value) {
            value = rest.trim_start();
        } else {
            break;
        }
        if value.starts_with(['|', '>']) {
            return true;
        }
        if value.is_empty() {
            return false;
        }
    }
    value.starts_with(['|', '>'])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn path(spec: &str) -> Vec<Seg> {
        spec.split('/')
            .map(|part| match part.parse::<usize>() {
                Ok(i) => Seg::Index(i),
                Err(_) => Seg::Key(part.to_owned()),
            })
            .collect()
    }

    const TEXT: &str = "\
# comment
mrtwin_stand:
  ros__parameters:
    model: two-chamber   # trailing: comment
    description: |
      gain: not a key
      bulk_modulus_pa: nope
    two_chamber:

      bulk_modulus_pa: 5.0e8
      'quoted key': 1
      \"dq\": 2
    valves:
      - name: a
        gain: 1.0
      - name: b
        gain: 2.0
    list:
    - 1
    - 2
    flow: {a: 1, b: 2}
    limits.max_force_n: 100.0
\"/**\":
  ros__parameters:
    model: x
";

    #[test]
    fn finds_nested_keys() {
        let src = SourceText::new(TEXT);
        let root = "mrtwin_stand/ros__parameters";
        let line = |p: &str| src.line_of(&path(&format!("{root}/{p}")));
        assert_eq!(line("model"), Some(4));
        assert_eq!(line("description"), Some(5));
        assert_eq!(line("two_chamber"), Some(8));
        assert_eq!(line("two_chamber/bulk_modulus_pa"), Some(10));
        assert_eq!(line("two_chamber/quoted key"), Some(11));
        assert_eq!(line("two_chamber/dq"), Some(12));
        assert_eq!(line("valves/0/gain"), Some(15));
        assert_eq!(line("valves/1"), Some(16));
        assert_eq!(line("valves/1/name"), Some(16));
        assert_eq!(line("valves/1/gain"), Some(17));
        assert_eq!(line("list/1"), Some(20));
        assert_eq!(line("limits/max_force_n"), Some(22));
        let wildcard = [
            Seg::Key("/**".into()),
            Seg::Key("ros__parameters".into()),
            Seg::Key("model".into()),
        ];
        assert_eq!(src.line_of(&wildcard), Some(25));
    }

    #[test]
    fn block_scalar_content_is_not_keys() {
        let src = SourceText::new(TEXT);
        assert_eq!(
            src.locate(&path("mrtwin_stand/ros__parameters/gain")),
            (2, Some(3))
        );
    }

    #[test]
    fn partial_matches_report_deepest_line() {
        let src = SourceText::new(TEXT);
        assert_eq!(
            src.locate(&path("mrtwin_stand/ros__parameters/flow/a")),
            (3, Some(21))
        );
        assert_eq!(
            src.locate(&path("mrtwin_stand/ros__parameters/two_chamber/nope")),
            (3, Some(8))
        );
        assert_eq!(src.locate(&path("nope")), (0, None));
    }

    #[test]
    fn split_key_variants() {
        assert_eq!(split_key("a: 1"), Some(("a".into(), " 1")));
        assert_eq!(split_key("a:"), Some(("a".into(), "")));
        assert_eq!(split_key("/**:"), Some(("/**".into(), "")));
        assert_eq!(
            split_key("url: http://x"),
            Some(("url".into(), " http://x"))
        );
        assert_eq!(split_key("a:b"), None);
        assert_eq!(split_key("x # a: b"), None);
        assert_eq!(split_key("'it''s': 1"), Some(("it's".into(), " 1")));
        assert_eq!(split_key("\"a\\\"b\" : 1"), Some(("a\"b".into(), " 1")));
        assert_eq!(split_key("\"unterminated: 1"), None);
        assert_eq!(split_key("{a: 1}"), None);
    }

    #[test]
    fn duplicate_keys() {
        let src = SourceText::new("a: 1\nb:\n  - x: 1\n    y: 2\n    x: 3\na: 2\n");
        assert_eq!(src.duplicate_key_line(1, 1, "a"), Some(6));
        assert_eq!(src.duplicate_key_line(3, 5, "x"), Some(5));
        assert_eq!(src.duplicate_key_line(3, 5, "y"), None);
        assert_eq!(src.duplicate_key_line(9, 1, "a"), None);
    }

    #[test]
    fn display_paths() {
        assert_eq!(display_path(&path("a/b/2/c")), "a.b[2].c");
        assert_eq!(display_path(&[]), "");
        assert_eq!(display_path(&path("0/x")), "[0].x");
    }
}

//! Diagnostics: every problem with a protocol or rig file names the file, line and column,
//! says what is wrong and how to fix it, and renders with the offending line.
//!
//! Parse errors come located from the YAML parser. Problems found after parsing (a depth
//! beyond the thickness, a role the rig lacks) carry a [`YamlPath`]; [`locate`] walks the
//! document a second time with serde and stops at that path, so the parser reports the
//! value's position exactly as it does for its own errors.

use std::fmt;
use std::path::{Path, PathBuf};

use rig::config::{PathSeg, YamlPath};
use serde::Serialize;
use serde::de::{self, DeserializeSeed, IgnoredAny, MapAccess, SeqAccess, Visitor};

/// How bad a diagnostic is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Severity {
    /// The file cannot be run.
    Error,
    /// The file runs, but probably not as meant.
    Warning,
}

/// One located problem.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Diagnostic {
    /// Error or warning.
    pub severity: Severity,
    /// The file it is in.
    pub file: PathBuf,
    /// 1-based line; 0 when the problem is the file as a whole.
    pub line: usize,
    /// 1-based column.
    pub column: usize,
    /// What is wrong.
    pub message: String,
    /// How to fix it.
    pub fix: String,
    /// The offending source line, for display.
    #[serde(skip)]
    pub source_line: Option<String>,
}

impl Diagnostic {
    /// A problem with the file as a whole (unreadable, missing).
    pub fn file_level(file: &Path, message: impl Into<String>, fix: impl Into<String>) -> Self {
        Self {
            severity: Severity::Error,
            file: file.to_path_buf(),
            line: 0,
            column: 0,
            message: message.into(),
            fix: fix.into(),
            source_line: None,
        }
    }

    /// A problem at `path` in the document `text` of `file`.
    pub fn at_path(
        file: &Path,
        text: &str,
        path: &YamlPath,
        severity: Severity,
        message: impl Into<String>,
        fix: impl Into<String>,
    ) -> Self {
        let (line, column) = locate(text, path).unwrap_or((1, 1));
        Self {
            severity,
            file: file.to_path_buf(),
            line,
            column,
            message: message.into(),
            fix: fix.into(),
            source_line: text.lines().nth(line.saturating_sub(1)).map(str::to_string),
        }
    }

    /// Turns a YAML/serde error into a located diagnostic with a fix.
    pub fn from_yaml_error(file: &Path, text: &str, err: &serde_yaml::Error) -> Self {
        let (mut line, mut column) = err
            .location()
            .map(|l| (l.line(), l.column()))
            .unwrap_or((1, 1));
        let mut message = err.to_string();
        if let Some(i) = message.rfind(" at line ") {
            message.truncate(i);
        }
        let (message, fix) = explain(&message);
        // Errors inside internally tagged maps (indenter, markers) are reported at the
        // map's start; move them to the offending key when the message names one.
        if let Some(key) = quoted_after(&message, "unknown field `")
            && let Some((l, c)) = find_key_below(text, line, &key)
        {
            (line, column) = (l, c);
        }
        // A duplicate key is reported at its mapping: point at the second occurrence.
        if let Some(key) = message
            .split("key \"")
            .nth(1)
            .and_then(|r| r.split('"').next())
            .filter(|_| message.contains("appears twice"))
            && let Some((l, c)) = second_key_after(text, line, column, key)
        {
            (line, column) = (l, c);
        }
        Self {
            severity: Severity::Error,
            file: file.to_path_buf(),
            line,
            column,
            message,
            fix,
            source_line: text.lines().nth(line.saturating_sub(1)).map(str::to_string),
        }
    }

    /// True for errors.
    pub fn is_error(&self) -> bool {
        self.severity == Severity::Error
    }
}

impl fmt::Display for Diagnostic {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let kind = match self.severity {
            Severity::Error => "error",
            Severity::Warning => "warning",
        };
        if self.line == 0 {
            writeln!(f, "{}: {kind}: {}", self.file.display(), self.message)?;
        } else {
            writeln!(
                f,
                "{}:{}:{}: {kind}: {}",
                self.file.display(),
                self.line,
                self.column,
                self.message
            )?;
            if let Some(src) = &self.source_line {
                let gutter = self.line.to_string().len();
                writeln!(f, "{:gutter$} |", "")?;
                writeln!(f, "{} | {src}", self.line)?;
                writeln!(f, "{:gutter$} | {:>col$}", "", "^", col = self.column)?;
            }
        }
        write!(f, "  fix: {}", self.fix)
    }
}

/// Splits a serde message into (message, fix), inventing the fix for serde's own messages.
fn explain(message: &str) -> (String, String) {
    if let Some((m, fix)) = message.split_once("; fix: ") {
        return (m.to_string(), fix.to_string());
    }
    if let Some(unknown) = quoted_after(message, "unknown field `")
        .or_else(|| quoted_after(message, "unknown variant `"))
    {
        let expected = expected_names(message);
        let best = expected
            .iter()
            .map(|e| (e, strsim::levenshtein(e, &unknown)))
            .min_by_key(|(_, d)| *d);
        let fix = match best {
            Some((e, d)) if d <= 3 => format!("did you mean `{e}`?"),
            _ if expected.is_empty() => format!("remove `{unknown}`"),
            _ => format!("remove `{unknown}`; allowed here: {}", expected.join(", ")),
        };
        return (message.to_string(), fix);
    }
    if message.contains("duplicate entry") {
        return (
            message.replace("duplicate entry", "a key appears twice in this mapping:"),
            "keep one of the two (the second used to win silently)".to_string(),
        );
    }
    if let Some(field) = quoted_after(message, "missing field `") {
        return (
            message.to_string(),
            format!("add `{field}:` to this mapping (`gelrig schema` describes every key)"),
        );
    }
    if message.contains("invalid type") || message.contains("invalid value") {
        return (
            message.to_string(),
            "give this key a value of the type `gelrig schema` names".to_string(),
        );
    }
    (
        message.to_string(),
        "fix the YAML here: check indentation, a missing `:` or `-`, and quote values that \
         start with a special character"
            .to_string(),
    )
}

/// The second `key:` at or after (`line`, `column`), 1-based, as a key (preceded by the
/// start of a line, a space, `{` or `,`).
fn second_key_after(text: &str, line: usize, column: usize, key: &str) -> Option<(usize, usize)> {
    let needle = format!("{key}:");
    let mut seen = 0;
    for (i, l) in text.lines().enumerate().skip(line.saturating_sub(1)) {
        let from = if i + 1 == line {
            column.saturating_sub(1)
        } else {
            0
        };
        let mut start = from.min(l.len());
        while let Some(k) = l.get(start..).and_then(|rest| rest.find(&needle)) {
            let at = start + k;
            let before = l[..at].chars().last();
            if before.is_none_or(|c| c == ' ' || c == '{' || c == ',' || c == '\t') {
                seen += 1;
                if seen == 2 {
                    return Some((i + 1, l[..at].chars().count() + 1));
                }
            }
            start = at + needle.len();
        }
    }
    None
}

fn quoted_after(message: &str, prefix: &str) -> Option<String> {
    let start = message.find(prefix)? + prefix.len();
    let rest = &message[start..];
    Some(rest[..rest.find('`')?].to_string())
}

/// The names in serde's "expected one of `a`, `b`" / "expected `a` or `b`".
fn expected_names(message: &str) -> Vec<String> {
    let Some(i) = message.find("expected") else {
        return Vec::new();
    };
    message[i..]
        .split('`')
        .skip(1)
        .step_by(2)
        .map(str::to_string)
        .collect()
}

/// Finds `key:` at or below `from_line` (1-based) before the indentation drops back.
fn find_key_below(text: &str, from_line: usize, key: &str) -> Option<(usize, usize)> {
    let lines: Vec<&str> = text.lines().collect();
    let start = from_line.checked_sub(1)?;
    for (i, l) in lines.iter().enumerate().skip(start).take(40) {
        for (col, _) in l.match_indices(key) {
            let before = &l[..col];
            let after = &l[col + key.len()..];
            let at_word_start = before.ends_with([' ', '{', ',', '-']) || before.is_empty();
            if at_word_start && after.trim_start().starts_with(':') {
                return Some((i + 1, before.chars().count() + 1));
            }
        }
    }
    None
}

const FOUND: &str = "\u{0}gelrig-locate\u{0}";

/// Line and column (1-based) of the value at `path` in `text`, or of its nearest ancestor
/// that exists. `None` if the text does not parse.
pub fn locate(text: &str, path: &YamlPath) -> Option<(usize, usize)> {
    let mut segs: &[PathSeg] = &path.0;
    loop {
        let de = serde_yaml::Deserializer::from_str(text);
        match (Seek { rest: segs }).deserialize(de) {
            Err(e) if e.to_string().contains(FOUND) => {
                return e.location().map(|l| (l.line(), l.column()));
            }
            _ => {}
        }
        if segs.is_empty() {
            return None;
        }
        segs = &segs[..segs.len() - 1];
    }
}

struct Seek<'a> {
    rest: &'a [PathSeg],
}

impl<'de> DeserializeSeed<'de> for Seek<'_> {
    type Value = ();
    fn deserialize<D: de::Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        if self.rest.is_empty() {
            // Fail *inside* the value, so the parser stamps the value's own position.
            return d.deserialize_any(Found);
        }
        d.deserialize_any(SeekVisitor { rest: self.rest })
    }
}

struct Found;

impl<'de> Visitor<'de> for Found {
    type Value = ();
    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("any value")
    }
    fn visit_bool<E: de::Error>(self, _: bool) -> Result<(), E> {
        Err(E::custom(FOUND))
    }
    fn visit_i64<E: de::Error>(self, _: i64) -> Result<(), E> {
        Err(E::custom(FOUND))
    }
    fn visit_u64<E: de::Error>(self, _: u64) -> Result<(), E> {
        Err(E::custom(FOUND))
    }
    fn visit_f64<E: de::Error>(self, _: f64) -> Result<(), E> {
        Err(E::custom(FOUND))
    }
    fn visit_str<E: de::Error>(self, _: &str) -> Result<(), E> {
        Err(E::custom(FOUND))
    }
    fn visit_unit<E: de::Error>(self) -> Result<(), E> {
        Err(E::custom(FOUND))
    }
    fn visit_none<E: de::Error>(self) -> Result<(), E> {
        Err(E::custom(FOUND))
    }
    fn visit_seq<A: SeqAccess<'de>>(self, _: A) -> Result<(), A::Error> {
        Err(de::Error::custom(FOUND))
    }
    fn visit_map<A: MapAccess<'de>>(self, _: A) -> Result<(), A::Error> {
        Err(de::Error::custom(FOUND))
    }
}

struct SeekVisitor<'a> {
    rest: &'a [PathSeg],
}

impl<'de> Visitor<'de> for SeekVisitor<'_> {
    type Value = ();
    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("any value")
    }
    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<(), A::Error> {
        while let Some(key) = map.next_key::<AnyKey>()? {
            match &self.rest[0] {
                PathSeg::Key(k) if *k == key.0 => {
                    map.next_value_seed(Seek {
                        rest: &self.rest[1..],
                    })?;
                }
                _ => {
                    map.next_value::<IgnoredAny>()?;
                }
            }
        }
        Ok(())
    }
    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<(), A::Error> {
        let mut i = 0;
        loop {
            let found = match &self.rest[0] {
                PathSeg::Index(n) if *n == i => seq.next_element_seed(Seek {
                    rest: &self.rest[1..],
                })?,
                _ => seq.next_element::<IgnoredAny>()?.map(|_| ()),
            };
            if found.is_none() {
                return Ok(());
            }
            i += 1;
        }
    }
    fn visit_bool<E: de::Error>(self, _: bool) -> Result<(), E> {
        Ok(())
    }
    fn visit_i64<E: de::Error>(self, _: i64) -> Result<(), E> {
        Ok(())
    }
    fn visit_u64<E: de::Error>(self, _: u64) -> Result<(), E> {
        Ok(())
    }
    fn visit_f64<E: de::Error>(self, _: f64) -> Result<(), E> {
        Ok(())
    }
    fn visit_str<E: de::Error>(self, _: &str) -> Result<(), E> {
        Ok(())
    }
    fn visit_unit<E: de::Error>(self) -> Result<(), E> {
        Ok(())
    }
}

/// A mapping key of any scalar type, as text.
struct AnyKey(String);

impl<'de> de::Deserialize<'de> for AnyKey {
    fn deserialize<D: de::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl Visitor<'_> for V {
            type Value = AnyKey;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("a scalar key")
            }
            fn visit_str<E: de::Error>(self, v: &str) -> Result<AnyKey, E> {
                Ok(AnyKey(v.to_string()))
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<AnyKey, E> {
                Ok(AnyKey(v.to_string()))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<AnyKey, E> {
                Ok(AnyKey(v.to_string()))
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<AnyKey, E> {
                Ok(AnyKey(v.to_string()))
            }
            fn visit_bool<E: de::Error>(self, v: bool) -> Result<AnyKey, E> {
                Ok(AnyKey(v.to_string()))
            }
            fn visit_unit<E: de::Error>(self) -> Result<AnyKey, E> {
                Ok(AnyKey("null".into()))
            }
        }
        d.deserialize_any(V)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DOC: &str = "name: x\nsequence:\n  - home: {axes: [normal]}\n  - stepped:\n      axis: normal\n      to: 25 %\n";

    #[test]
    fn locates_nested_values() {
        let p = YamlPath::root()
            .key("sequence")
            .index(1)
            .key("stepped")
            .key("to");
        assert_eq!(locate(DOC, &p), Some((6, 11)));
        let p = YamlPath::root()
            .key("sequence")
            .index(0)
            .key("home")
            .key("axes")
            .index(0);
        assert_eq!(locate(DOC, &p), Some((3, 19)));
        // A missing leaf falls back to its parent mapping.
        let p = YamlPath::root()
            .key("sequence")
            .index(1)
            .key("stepped")
            .key("speed");
        assert_eq!(locate(DOC, &p).map(|l| l.0), Some(5));
    }

    #[test]
    fn explains_serde_messages() {
        let (_, fix) = explain("unknown field `sped`, expected one of `axis`, `speed`, `settle`");
        assert_eq!(fix, "did you mean `speed`?");
        let (_, fix) = explain("missing field `settle`");
        assert!(fix.contains("add `settle:`"));
        let (m, fix) = explain("`2` has no unit (a length expected); fix: write `2 mm`");
        assert_eq!(
            (m.as_str(), fix.as_str()),
            ("`2` has no unit (a length expected)", "write `2 mm`")
        );
    }
}

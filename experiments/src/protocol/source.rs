//! Reading a protocol or rig file before serde sees it.
//!
//! Paths come from users and from files (`rig:` in a protocol), so they may point anywhere:
//! `/dev/urandom` used to be read until memory ran out and `/etc/shadow`'s first line was
//! quoted back in a diagnostic. A source is therefore a regular file of bounded size, UTF-8
//! (a byte-order mark is accepted and dropped), whose nesting is shallow enough to parse in
//! bounded time (a document nested 100,000 levels deep took a minute), whose mappings name
//! each key once (a repeated `normal:` under `retract:` used to retract to the last one,
//! silently), and which is a YAML mapping at all — a file that is not is reported without
//! quoting a byte of it.

use std::io::Read;
use std::path::Path;

use crate::diag::Diagnostic;

/// Largest protocol or rig file: the shipped ones are under 5 kB.
pub const MAX_SOURCE_BYTES: u64 = 1 << 20;
/// Deepest indentation (columns) or flow nesting (`[`/`{`) a source may have: the deepest
/// legitimate protocol (16 nested blocks) stays well inside.
pub const MAX_NESTING: usize = 200;

/// Reads `path` as the text of `what` (`the protocol`, `the rig file`).
pub fn read(path: &Path, what: &str) -> Result<String, Vec<Diagnostic>> {
    let fail = |message: String, fix: String| vec![Diagnostic::file_level(path, message, fix)];
    let meta = std::fs::metadata(path).map_err(|e| {
        fail(
            format!("cannot read {what}: {e}"),
            format!(
                "check the path `{}` and that the file is readable",
                path.display()
            ),
        )
    })?;
    if !meta.is_file() {
        return Err(fail(
            format!("{what} is not a regular file"),
            "name a YAML file (devices, pipes and directories are not protocols)".into(),
        ));
    }
    if meta.len() > MAX_SOURCE_BYTES {
        return Err(fail(
            format!(
                "{what} is {} bytes, over the {} bytes a protocol or rig file may have",
                meta.len(),
                MAX_SOURCE_BYTES
            ),
            "check that this is the right file".into(),
        ));
    }
    let mut bytes = Vec::new();
    std::fs::File::open(path)
        .and_then(|f| f.take(MAX_SOURCE_BYTES + 1).read_to_end(&mut bytes))
        .map_err(|e| {
            fail(
                format!("cannot read {what}: {e}"),
                "check that the file is readable".into(),
            )
        })?;
    let text = String::from_utf8(bytes).map_err(|e| {
        fail(
            format!(
                "{what} is not UTF-8 text (byte {} is not)",
                e.utf8_error().valid_up_to()
            ),
            "save it as UTF-8".into(),
        )
    })?;
    let text = match text.strip_prefix('\u{feff}') {
        Some(rest) => rest.to_string(),
        None => text,
    };
    nesting(path, &text)?;
    Ok(text)
}

/// Rejects a source nested deeper than [`MAX_NESTING`], located at the first line that is.
fn nesting(path: &Path, text: &str) -> Result<(), Vec<Diagnostic>> {
    let mut flow = 0usize;
    for (i, line) in text.lines().enumerate() {
        let indent = line.len() - line.trim_start_matches([' ', '\t']).len();
        let (mut quote, mut deepest) = (None, flow);
        for c in line.chars() {
            match (quote, c) {
                (None, '#') => break,
                (None, '\'' | '"') => quote = Some(c),
                (Some(q), c) if c == q => quote = None,
                (None, '[' | '{') => {
                    flow += 1;
                    deepest = deepest.max(flow);
                }
                (None, ']' | '}') => flow = flow.saturating_sub(1),
                _ => {}
            }
        }
        if indent > MAX_NESTING || deepest > MAX_NESTING {
            return Err(vec![Diagnostic {
                line: i + 1,
                column: 1,
                ..Diagnostic::file_level(
                    path,
                    format!("the document nests more than {MAX_NESTING} levels deep here"),
                    "flatten it: no protocol needs more than a few levels",
                )
            }]);
        }
    }
    Ok(())
}

/// True if some line of `text` starts a top-level `key:` as our files do; a file without
/// one is not quoted in diagnostics.
fn looks_like_ours(text: &str) -> bool {
    text.lines().any(|l| {
        l.split_once(':').is_some_and(|(k, _)| {
            !k.is_empty() && k.chars().all(|c| c.is_ascii_lowercase() || c == '_')
        })
    })
}

/// Parses `text` as a generic YAML document: duplicate keys are located errors. A document
/// that is not a mapping, or a mapping with none of `keys` (the top-level keys of the kind
/// of file expected), is reported without its content: `rig: /etc/shadow` parses as a
/// mapping with one odd key, and must not be quoted back.
pub fn mapping(path: &Path, text: &str, what: &str, keys: &[&str]) -> Result<(), Vec<Diagnostic>> {
    let not_ours = || {
        vec![Diagnostic::file_level(
            path,
            format!(
                "this is not {what}: it is not a YAML mapping with its keys ({})",
                keys.join(", ")
            ),
            "check the path (the file's content is not shown: it may not be meant to be)",
        )]
    };
    let value: serde_yaml::Value = match serde_yaml::from_str(text) {
        Ok(v) => v,
        Err(_) if !looks_like_ours(text) => return Err(not_ours()),
        Err(e) => return Err(vec![Diagnostic::from_yaml_error(path, text, &e)]),
    };
    let ours = value
        .as_mapping()
        .is_some_and(|m| keys.iter().any(|k| m.contains_key(*k)));
    if ours { Ok(()) } else { Err(not_ours()) }
}

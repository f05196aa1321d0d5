//! `--set KEY=VALUE` and `--name`: a protocol varied from the command line without editing
//! its file.

use serde_yaml::{Mapping, Value};
use sha2::{Digest, Sha256};

use super::Overrides;

/// `text` with `o` applied, as YAML; or why not, and the fix.
pub(super) fn apply(text: &str, o: &Overrides) -> Result<String, (String, String)> {
    let mut doc: Value = serde_yaml::from_str(text).map_err(|e| {
        (
            format!("the protocol does not parse, so --set cannot edit it: {e}"),
            "fix the file first (gelrig validate names the place)".to_string(),
        )
    })?;
    for item in &o.set {
        let Some((key, value)) = item.split_once('=') else {
            return Err((
                format!("--set {item:?} has no `=`"),
                "write --set KEY=VALUE, e.g. --set indenter.diameter=10mm".into(),
            ));
        };
        let value: Value = serde_yaml::from_str(value.trim()).map_err(|e| {
            (
                format!("--set {key}: the value {value:?} is not YAML ({e})"),
                "quote it, e.g. --set 'settle={fixed: 60 s}'".into(),
            )
        })?;
        set(&mut doc, key.trim(), value)?;
    }
    let name = match &o.name {
        Some(n) => n.clone(),
        None if !o.set.is_empty() => {
            let base = doc
                .get("name")
                .and_then(Value::as_str)
                .unwrap_or("protocol");
            let digest = Sha256::digest(o.set.join("\n").as_bytes());
            let short: String = digest.iter().take(3).map(|b| format!("{b:02x}")).collect();
            format!("{base}-{short}")
        }
        None => return serde_yaml::to_string(&doc).map_err(|e| (e.to_string(), String::new())),
    };
    if let Value::Mapping(m) = &mut doc {
        m.insert(Value::from("name"), Value::from(name));
    }
    serde_yaml::to_string(&doc).map_err(|e| (e.to_string(), "report this".into()))
}

/// Sets `value` at the dotted `key` (mapping keys, or indices into sequences) of `doc`,
/// creating mappings on the way.
fn set(doc: &mut Value, key: &str, value: Value) -> Result<(), (String, String)> {
    let parts: Vec<&str> = key.split('.').collect();
    if parts.iter().any(|p| p.is_empty()) {
        return Err((
            format!("--set {key}: an empty part in the key"),
            "write dotted keys, e.g. indenter.diameter or sequence.3.stepped.step".into(),
        ));
    }
    let mut at = doc;
    for (k, part) in parts.iter().enumerate() {
        let last = k + 1 == parts.len();
        at = match at {
            Value::Mapping(m) => {
                let entry = m
                    .entry(Value::from(*part))
                    .or_insert_with(|| Value::Mapping(Mapping::new()));
                if last {
                    *entry = value;
                    return Ok(());
                }
                entry
            }
            Value::Sequence(items) => {
                let i: usize = part.parse().map_err(|_| {
                    (
                        format!("--set {key}: `{part}` indexes a list, so it must be a number"),
                        format!(
                            "count the list's items from 0 (this one has {})",
                            items.len()
                        ),
                    )
                })?;
                let n = items.len();
                // A sequence item is a block (a mapping of one key, its kind): a key naming
                // another kind would add a second key, which the parser reports far from the
                // cause.
                let kind_of = |v: &Value| match v {
                    Value::Mapping(m) if m.len() == 1 => {
                        m.keys().next().and_then(Value::as_str).map(str::to_string)
                    }
                    _ => None,
                };
                if let (Some(next), Some(kind)) = (parts.get(k + 1), items.get(i).and_then(kind_of))
                    && kind != *next
                {
                    let same: Vec<String> = items
                        .iter()
                        .enumerate()
                        .filter(|(_, v)| kind_of(v).as_deref() == Some(*next))
                        .map(|(j, _)| j.to_string())
                        .collect();
                    let prefix = parts[..k].join(".");
                    return Err((
                        format!(
                            "--set {key}: item {i} of `{prefix}` is a `{kind}` block, not `{next}`"
                        ),
                        if same.is_empty() {
                            format!(
                                "no item of `{prefix}` is a `{next}` block; `gelrig plan` lists the blocks"
                            )
                        } else {
                            format!(
                                "the `{next}` block is item {} ({prefix}.{}.{next}…)",
                                same.join(", "),
                                same[0]
                            )
                        },
                    ));
                }
                let Some(item) = items.get_mut(i) else {
                    return Err((
                        format!("--set {key}: the list has {n} items, no item {i}"),
                        format!("count from 0 to {}", n.saturating_sub(1)),
                    ));
                };
                if last {
                    *item = value;
                    return Ok(());
                }
                item
            }
            _ => {
                return Err((
                    format!(
                        "--set {key}: `{}` is a value, not a mapping or list",
                        parts[..k].join(".")
                    ),
                    "set the value itself, or a key of a mapping".into(),
                ));
            }
        };
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_set_edits_the_value_and_names_the_variant() {
        let text = "name: p\nindenter: {shape: flat_circle, diameter: 9.5 mm}\nsequence:\n  - home: {axes: [normal]}\n";
        let o = Overrides {
            set: vec![
                "indenter.diameter=10 mm".into(),
                "sequence.0.home.axes=[normal, shear]".into(),
            ],
            name: None,
            fidelity: None,
        };
        let out: Value = serde_yaml::from_str(&apply(text, &o).expect("ok")).expect("ok");
        assert_eq!(out["indenter"]["diameter"], Value::from("10 mm"));
        assert_eq!(out["sequence"][0]["home"]["axes"][1], Value::from("shear"));
        let name = out["name"].as_str().expect("ok");
        assert!(name.starts_with("p-") && name.len() == 8, "{name}");
        // The same overrides, the same name; --name wins.
        let again: Value = serde_yaml::from_str(&apply(text, &o).expect("ok")).expect("ok");
        assert_eq!(again["name"], out["name"]);
        let named = Overrides {
            name: Some("mine".into()),
            ..o
        };
        let out: Value = serde_yaml::from_str(&apply(text, &named).expect("ok")).expect("ok");
        assert_eq!(out["name"], Value::from("mine"));
    }

    #[test]
    fn a_set_into_the_wrong_block_names_the_right_one() {
        let text = "sequence:\n  - home: {axes: [normal]}\n  - tare: {duration: 1 s}\n  - repeat: {times: 2, blocks: []}\n";
        let o = Overrides {
            set: vec!["sequence.0.repeat.times=3".into()],
            name: None,
            fidelity: None,
        };
        let (what, fix) = apply(text, &o).expect_err("item 0 is home");
        assert!(
            what.contains("item 0 of `sequence` is a `home` block, not `repeat`"),
            "{what}"
        );
        assert!(fix.contains("item 2"), "{fix}");
        let o = Overrides {
            set: vec!["sequence.2.repeat.times=3".into()],
            name: None,
            fidelity: None,
        };
        assert!(apply(text, &o).is_ok());
    }

    #[test]
    fn a_bad_set_says_what_and_how() {
        let text = "name: p\nsequence:\n  - home: {axes: [normal]}\n";
        for (set, says) in [
            ("indenter", "no `=`"),
            ("sequence.5.home=x", "no item 5"),
            ("sequence.x=1", "must be a number"),
            ("name.first=1", "is a value"),
            ("a..b=1", "empty part"),
        ] {
            let o = Overrides {
                set: vec![set.into()],
                name: None,
                fidelity: None,
            };
            let (m, fix) = apply(text, &o).expect_err("refused");
            assert!(m.contains(says) && !fix.is_empty(), "{set}: {m}");
        }
    }
}

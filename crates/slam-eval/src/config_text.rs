//! Checks of a configuration file's text that serde cannot make while reading it.
//!
//! toml 0.9 reads a TOML array into a fixed-size setting (`[f64; 3]`, `[f64; 2]`) by taking
//! as many values as the setting holds and dropping the rest without a word: its array
//! deserializer never checks that the sequence ended. A file's
//! `extra-motion-noise = [0.0, 0.0, 0.0, 99.0]` ran with the 99 silently ignored.
//! [`overlong_array`] finds such a key by comparing every array of the text with the same
//! key of the configuration read from it, serialised back: a list setting (`Vec`) reads back
//! as long as it was given, a fixed-size one as long as it takes.

use serde::Serialize;
use toml::de::{DeTable, DeValue};

/// An array of a configuration file with more values than its setting takes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct OverlongArray {
    /// The dotted key path, as written in the file (`motion.odometry.alpha`).
    pub key: String,
    /// The number of values the file gives.
    pub given: usize,
    /// The number of values the setting takes.
    pub takes: usize,
    /// The 1-based line of the array in the text.
    pub line: usize,
}

impl std::fmt::Display for OverlongArray {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "`{}` takes {} values, the file gives {} (the extra values would be ignored)",
            self.key, self.takes, self.given
        )
    }
}

/// The first array of `text` (a TOML document `config` was read from) that is longer than
/// the same key's array in `config`, serialised back; `None` when every array was read
/// whole, or when the text does not parse or `config` does not serialise (both are reported
/// by the reading itself).
pub fn overlong_array<C: Serialize>(text: &str, config: &C) -> Option<OverlongArray> {
    let given = DeTable::parse(text).ok()?;
    let read = toml::Table::try_from(config).ok()?;
    let mut path = Vec::new();
    walk_table(text, given.get_ref(), &read, &mut path)
}

fn walk_table(
    text: &str,
    given: &DeTable<'_>,
    read: &toml::Table,
    path: &mut Vec<String>,
) -> Option<OverlongArray> {
    for (key, value) in given.iter() {
        let name: &str = key.get_ref();
        let Some(read_value) = read.get(name) else {
            continue;
        };
        path.push(name.to_string());
        let found = walk_value(text, value.get_ref(), value.span().start, read_value, path);
        path.pop();
        if found.is_some() {
            return found;
        }
    }
    None
}

fn walk_value(
    text: &str,
    given: &DeValue<'_>,
    start: usize,
    read: &toml::Value,
    path: &mut Vec<String>,
) -> Option<OverlongArray> {
    match (given, read) {
        (DeValue::Table(t), toml::Value::Table(r)) => walk_table(text, t, r, path),
        (DeValue::Array(a), toml::Value::Array(r)) if a.len() > r.len() => Some(OverlongArray {
            key: path.join("."),
            given: a.len(),
            takes: r.len(),
            line: text[..start.min(text.len())].matches('\n').count() + 1,
        }),
        (DeValue::Array(a), toml::Value::Array(r)) => a
            .iter()
            .zip(r)
            .find_map(|(g, r)| walk_value(text, g.get_ref(), g.span().start, r, path)),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::Deserialize;

    #[derive(Debug, Default, Serialize, Deserialize)]
    #[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
    struct Inner {
        alpha: [f64; 4],
        list: Vec<f64>,
    }

    #[derive(Debug, Default, Serialize, Deserialize)]
    #[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
    struct Outer {
        noise: [f64; 3],
        inner: Inner,
    }

    /// The reading this guards against: toml takes the first values and drops the rest.
    #[test]
    fn toml_alone_drops_the_extra_values() {
        let c: Outer = toml::from_str("noise = [1.0, 2.0, 3.0, 99.0]\n").unwrap();
        assert_eq!(c.noise, [1.0, 2.0, 3.0]);
    }

    #[test]
    fn an_overlong_fixed_array_is_found_with_its_key_and_line() {
        let text = "noise = [1.0, 2.0, 3.0]\n\n[inner]\nlist = [1.0]\nalpha = [0, 0, 0, 0, 5]\n";
        let c: Outer = toml::from_str(text).unwrap();
        let found = overlong_array(text, &c).unwrap();
        assert_eq!(
            found,
            OverlongArray {
                key: "inner.alpha".into(),
                given: 5,
                takes: 4,
                line: 5
            }
        );
        assert!(found
            .to_string()
            .contains("`inner.alpha` takes 4 values, the file gives 5"));
        let text = "noise = [1.0, 2.0, 3.0, 99.0]\n";
        let c: Outer = toml::from_str(text).unwrap();
        assert_eq!(overlong_array(text, &c).unwrap().key, "noise");
    }

    /// Arrays of the right length, lists of any length and keys left out pass.
    #[test]
    fn arrays_read_whole_pass() {
        let text = "noise = [1.0, 2.0, 3.0]\n[inner]\nlist = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]\n";
        let c: Outer = toml::from_str(text).unwrap();
        assert_eq!(overlong_array(text, &c), None);
        assert_eq!(overlong_array("", &Outer::default()), None);
    }
}

//! Configuration files (`slam optimize`'s; filters' are read by `slam_eval::factory`): TOML
//! deserialised straight into a config struct.
//!
//! Every config struct of slam-rs is `#[serde(rename_all = "kebab-case",
//! deny_unknown_fields, default)]`, so a file may set any subset of the keys (the rest keep
//! their documented defaults) and a misspelt key is an error naming it, with the line it is
//! on. Keys are kebab-case (`gate-probability`); a key in the snake_case of earlier
//! versions (`gate_probability`) is refused with a hint naming its kebab-case spelling.

use crate::error::CliError;
use serde::de::DeserializeOwned;
use serde::Serialize;
use std::path::Path;

/// A loaded configuration.
pub(crate) struct Loaded<C> {
    /// The configuration: the file's values over the defaults.
    pub config: C,
}

/// Reads `path` into `C`, or returns `C::default()` when no file is given.
pub(crate) fn load<C: DeserializeOwned + Serialize + Default>(
    path: Option<&Path>,
) -> Result<Loaded<C>, CliError> {
    let Some(path) = path else {
        return Ok(Loaded {
            config: C::default(),
        });
    };
    let text = std::fs::read_to_string(path).map_err(|e| CliError::Read {
        path: path.to_path_buf(),
        source: e,
    })?;
    parse(&text, path)
}

/// Parses TOML `text` (read from `path`, for messages) into `C`.
/// An array longer than its fixed-size setting is an error naming the key (toml would drop
/// the extra values silently; [`slam_eval::config_text::overlong_array`]).
pub(crate) fn parse<C: DeserializeOwned + Serialize>(
    text: &str,
    path: &Path,
) -> Result<Loaded<C>, CliError> {
    let config = toml::from_str::<C>(text).map_err(|e| config_error(text, path, &e))?;
    if let Some(long) = slam_eval::config_text::overlong_array(text, &config) {
        return Err(CliError::Config {
            path: path.to_path_buf(),
            line: Some(long.line),
            message: long.to_string(),
        });
    }
    Ok(Loaded { config })
}

/// Serialises a config back to TOML (for the `config.toml` a run writes beside its output).
pub(crate) fn to_toml<C: Serialize>(config: &C) -> String {
    toml::to_string_pretty(config).unwrap_or_else(|e| format!("# could not serialise: {e}\n"))
}

/// One-line message for a TOML error: file, line, and toml's own message (which names an
/// unknown key and lists the expected ones).
fn config_error(text: &str, path: &Path, e: &toml::de::Error) -> CliError {
    let line = e
        .span()
        .map(|span| text[..span.start.min(text.len())].matches('\n').count() + 1);
    CliError::Config {
        path: path.to_path_buf(),
        line,
        message: format!(
            "{}{}",
            e.message().trim().replace('\n', " "),
            snake_case_hint(e.message())
        ),
    }
}

/// For serde's "unknown field `a_b`" about a key with an underscore: the hint that keys are
/// kebab-case now, naming the spelling to use; for an association key at the top of a file,
/// that it moved into the `[association]` table.
fn snake_case_hint(message: &str) -> String {
    if let Some(hint) = slam_models::association::moved_key_hint(message) {
        return hint;
    }
    let key = message
        .strip_prefix("unknown field `")
        .and_then(|rest| rest.split('`').next());
    match key {
        Some(k) if k.contains('_') => format!(
            " (config keys are kebab-case: write `{}`)",
            k.replace('_', "-")
        ),
        _ => String::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::Deserialize;

    #[derive(Debug, Default, Deserialize, Serialize, PartialEq)]
    #[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
    struct Demo {
        particles: usize,
        sigma: f64,
        min_range: f64,
    }

    /// An old snake_case key is an error (never silently ignored) that names the
    /// kebab-case key to write instead; the kebab-case key parses.
    #[test]
    fn an_old_snake_case_key_is_refused_with_its_kebab_case_spelling() {
        let err = parse::<Demo>("min_range = 0.9\n", Path::new("x.toml"))
            .err()
            .unwrap()
            .to_string();
        assert!(
            err.contains("unknown field `min_range`") && err.contains("write `min-range`"),
            "{err}"
        );
        let ok: Loaded<Demo> = parse("min-range = 0.9\n", Path::new("x.toml")).unwrap();
        assert_eq!(ok.config.min_range, 0.9);
    }

    /// An association key at the top of a file (where files before the `[association]`
    /// table had it) is refused with the table to move it to.
    #[test]
    fn an_old_flat_association_key_names_the_table() {
        #[derive(Debug, Default, Deserialize, Serialize)]
        #[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
        struct Holder {
            association: slam_models::association::AssociationOptions,
        }
        let err = parse::<Holder>("\nmin-sightings = 2\n", Path::new("x.toml"))
            .err()
            .unwrap()
            .to_string();
        assert!(
            err.contains("line 2") && err.contains("under `[association]`"),
            "{err}"
        );
    }

    #[test]
    fn partial_file_keeps_defaults() {
        let l: Loaded<Demo> = parse("particles = 7\n", Path::new("x.toml")).unwrap();
        assert_eq!(
            l.config,
            Demo {
                particles: 7,
                ..Demo::default()
            }
        );
    }

    #[test]
    fn unknown_key_is_named_with_its_line() {
        let err = parse::<Demo>("particles = 7\n\nsigmaa = 1.0\n", Path::new("x.toml"))
            .err()
            .unwrap();
        let msg = err.to_string();
        assert!(msg.contains("sigmaa"), "{msg}");
        assert!(msg.contains("line 3"), "{msg}");
        assert!(!msg.contains('\n'), "{msg}");
    }

    /// An array with more values than its fixed-size setting takes is refused naming the
    /// file, the line, the key and both counts (toml alone kept the first values and
    /// dropped the rest: `slam optimize --config` ran with part of a setting ignored).
    #[test]
    fn an_overlong_fixed_array_is_refused_naming_the_key() {
        #[derive(Debug, Default, Deserialize, Serialize)]
        #[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
        struct Fixed {
            particles: usize,
            drift: [f64; 2],
        }
        let err = parse::<Fixed>(
            "particles = 3
drift = [0.1, 0.2, 0.3]
",
            Path::new("x.toml"),
        )
        .err()
        .unwrap()
        .to_string();
        assert!(
            err.contains("x.toml")
                && err.contains("line 2")
                && err.contains("`drift` takes 2 values, the file gives 3"),
            "{err}"
        );
        let ok: Loaded<Fixed> = parse(
            "drift = [0.1, 0.2]
",
            Path::new("x.toml"),
        )
        .unwrap();
        assert_eq!(ok.config.drift, [0.1, 0.2]);
    }

    #[test]
    fn wrong_type_is_an_error() {
        assert!(parse::<Demo>("particles = \"many\"\n", Path::new("x.toml")).is_err());
    }
}

//! The pipeline configuration (`pipeline.toml`): every knob of every stage, with its unit.
//!
//! The repository's `pipeline.toml` is embedded in the binary and is the default; a user file
//! given with `--config` replaces it whole. Unknown keys are errors naming the key and the file.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

/// The default configuration, exactly as shipped in the repository's `pipeline.toml`.
pub const DEFAULT_TOML: &str = include_str!("../pipeline.toml");

/// Errors reading or checking a configuration file.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    #[error("{path}: cannot read the configuration: {source}")]
    Read {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: {message}")]
    Parse { path: PathBuf, message: String },
    #[error("{path}: `{key}` is {value}, expected a finite number")]
    NotFinite {
        path: PathBuf,
        key: String,
        value: String,
    },
    #[error("{path}: `{field}` is {value}, expected {expected}")]
    Invalid {
        path: PathBuf,
        field: &'static str,
        value: String,
        expected: &'static str,
    },
}

/// The whole pipeline configuration.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Config {
    pub ingest: crate::image::IngestConfig,
    pub landmarks: crate::register::landmarks::CheckConfig,
    pub rigid: RigidConfig,
    pub articulate: crate::register::articulate::ArticulateConfig,
    pub deform: crate::register::deform::DeformConfig,
    pub refine: crate::register::refine::RefineConfig,
    /// The chain search of `landmarks --auto` and `run --auto-landmarks`.
    #[serde(default)]
    pub auto_landmarks: crate::register::chain_search::SearchConfig,
    pub validate: ValidateConfig,
}

/// Whether `run` and `batch` validate each package's mechanics (`[validate]`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ValidateConfig {
    /// Validate every package against its atlas (transfer function gates).
    pub enabled: bool,
    /// Add the static-pressure (UDSP) curve and its gates.
    pub static_pressure: bool,
}

/// Knobs of the rigid (landmark) alignment.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RigidConfig {
    /// Fit an isotropic scale as well (Umeyama) instead of a pure rigid motion (Kabsch).
    pub with_scale: bool,
}

impl Config {
    /// The embedded default configuration.
    pub fn default_config() -> Result<Config, ConfigError> {
        Config::from_toml_str(DEFAULT_TOML, Path::new("<embedded pipeline.toml>"))
    }

    /// Loads `path`, or the embedded default when `path` is `None`.
    pub fn load(path: Option<&Path>) -> Result<Config, ConfigError> {
        match path {
            None => Config::default_config(),
            Some(p) => {
                let text = crate::io_util::read_text(p).map_err(|source| ConfigError::Read {
                    path: p.to_path_buf(),
                    source,
                })?;
                Config::from_toml_str(&text, p)
            }
        }
    }

    /// Parses and checks a configuration; `path` is only used in messages.
    pub fn from_toml_str(text: &str, path: &Path) -> Result<Config, ConfigError> {
        let raw: toml::Table = toml::from_str(text).map_err(|e| ConfigError::Parse {
            path: path.to_path_buf(),
            message: e.to_string().trim_end().replace('\n', " "),
        })?;
        refuse_non_finite(&raw, "", path)?;
        let config: Config = toml::from_str(text).map_err(|e| ConfigError::Parse {
            path: path.to_path_buf(),
            message: e.to_string().trim_end().replace('\n', " "),
        })?;
        config.check(path)?;
        Ok(config)
    }

    /// The canonical serialisation: compact JSON, fields in declaration order, floats in
    /// their shortest round-trip form. Equal configurations give equal text, whatever the
    /// TOML's layout, comments or key order.
    pub fn canonical_json(&self) -> String {
        serde_json::to_string(self).unwrap_or_default()
    }

    /// SHA-256 (hex) of [`Config::canonical_json`]: the configuration's identity in package
    /// manifests and batch resume.
    pub fn sha256(&self) -> String {
        crate::io_util::sha256_hex(self.canonical_json().as_bytes())
    }

    fn check(&self, path: &Path) -> Result<(), ConfigError> {
        let positive = |field: &'static str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(ConfigError::Invalid {
                    path: path.to_path_buf(),
                    field,
                    value: v.to_string(),
                    expected: "a finite number > 0",
                })
            }
        };
        positive("ingest.max_file_mib", self.ingest.max_file_mib)?;
        positive("ingest.max_volume_mib", self.ingest.max_volume_mib)?;
        positive(
            "ingest.slice_gap_tolerance",
            self.ingest.slice_gap_tolerance,
        )?;
        positive(
            "ingest.orientation_tolerance",
            self.ingest.orientation_tolerance,
        )?;
        self.landmarks
            .validate()
            .map_err(|(field, value, expected)| ConfigError::Invalid {
                path: path.to_path_buf(),
                field,
                value,
                expected,
            })?;
        let d = &self.deform;
        for (field, v) in [
            ("deform.search_range_mm", d.probe.search_range_mm),
            ("deform.intensity_shift_hu", d.probe.intensity_shift_hu),
            ("deform.ratio_threshold", d.probe.ratio_threshold),
            (
                "deform.regularisation_modulus_pa",
                d.regularisation_modulus_pa,
            ),
            ("deform.min_modulus_ratio", d.min_modulus_ratio),
            (
                "deform.spring_stiffness_per_area",
                d.spring_stiffness_per_area,
            ),
            ("deform.neighbour_tolerance_mm", d.neighbour_tolerance_mm),
            ("deform.eardrum_offset_weight", d.eardrum_offset_weight),
            ("deform.tolerance_mm", d.tolerance_mm),
            ("articulate.joint_weight", self.articulate.joint_weight),
            ("articulate.damping", self.articulate.damping),
            ("articulate.prior", self.articulate.prior),
            (
                "articulate.search_range_mm",
                self.articulate.search_range_mm,
            ),
            ("articulate.tolerance_mm", self.articulate.tolerance_mm),
            ("refine.smoothness", self.refine.smoothness),
            ("refine.search_range_mm", self.refine.search_range_mm),
            (
                "auto_landmarks.coarse_spacing_mm",
                self.auto_landmarks.coarse_spacing_mm,
            ),
            ("auto_landmarks.min_score", self.auto_landmarks.min_score),
            (
                "auto_landmarks.max_voxel_mm",
                self.auto_landmarks.max_voxel_mm,
            ),
            (
                "auto_landmarks.rotations",
                self.auto_landmarks.rotations as f64,
            ),
            (
                "auto_landmarks.candidates",
                self.auto_landmarks.candidates as f64,
            ),
        ] {
            positive(field, v)?;
        }
        Ok(())
    }
}

/// Refuses `nan` and `inf` anywhere in the file, naming the key: every knob is a finite
/// number, and a NaN slips through comparisons that range checks are made of.
fn refuse_non_finite(table: &toml::Table, prefix: &str, path: &Path) -> Result<(), ConfigError> {
    for (key, value) in table {
        let name = format!("{prefix}{key}");
        match value {
            toml::Value::Float(v) if !v.is_finite() => {
                return Err(ConfigError::NotFinite {
                    path: path.to_path_buf(),
                    key: name,
                    value: v.to_string(),
                });
            }
            toml::Value::Table(t) => refuse_non_finite(t, &format!("{name}."), path)?,
            toml::Value::Array(items) => {
                for item in items {
                    if let toml::Value::Table(t) = item {
                        refuse_non_finite(t, &format!("{name}."), path)?;
                    } else if let toml::Value::Float(v) = item
                        && !v.is_finite()
                    {
                        return Err(ConfigError::NotFinite {
                            path: path.to_path_buf(),
                            key: name,
                            value: v.to_string(),
                        });
                    }
                }
            }
            _ => {}
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every float of the default configuration set to nan, +inf or -inf is refused naming
    /// its key (a NaN in three landmark-check keys used to give a package `verify` rejects).
    #[test]
    fn every_float_knob_refuses_nan_and_infinity_naming_the_key() {
        let lines: Vec<&str> = DEFAULT_TOML.lines().collect();
        let mut section = String::new();
        let mut tried = 0;
        for (n, line) in lines.iter().enumerate() {
            let t = line.trim();
            if t.starts_with('[') {
                section = t.trim_matches(|c| c == '[' || c == ']').to_string();
                continue;
            }
            let Some((key, value)) = t.split_once('=') else {
                continue;
            };
            if t.starts_with('#') || value.trim().parse::<f64>().is_err() || !value.contains('.') {
                continue;
            }
            for bad in ["nan", "inf", "-inf"] {
                let mut edited = lines.clone();
                let replaced = format!("{} = {bad}", key.trim());
                edited[n] = &replaced;
                let text = edited.join("\n");
                let err = Config::from_toml_str(&text, Path::new("c.toml")).unwrap_err();
                let key = format!("{section}.{}", key.trim());
                assert!(
                    err.to_string().contains(&format!("`{key}`")),
                    "{key}: {err}"
                );
            }
            tried += 1;
        }
        assert!(tried >= 25, "only {tried} float keys found");
    }

    #[test]
    fn embedded_default_parses() {
        let c = Config::default_config().unwrap();
        assert!(c.ingest.max_file_mib >= 1024.0);
    }

    #[test]
    fn sha256_follows_values_not_layout() {
        let c = Config::default_config().unwrap();
        // comments and blank lines do not matter; a changed value does
        let bare: String = DEFAULT_TOML
            .lines()
            .filter(|l| !l.trim_start().starts_with('#') && !l.trim().is_empty())
            .map(|l| format!("{l}\n"))
            .collect();
        let same = Config::from_toml_str(&bare, Path::new("bare.toml")).unwrap();
        assert_eq!(same.sha256(), c.sha256());
        let changed =
            DEFAULT_TOML.replace("slice_gap_tolerance = 0.2", "slice_gap_tolerance = 0.3");
        let other = Config::from_toml_str(&changed, Path::new("p.toml")).unwrap();
        assert_ne!(other.sha256(), c.sha256());
    }

    #[test]
    fn unknown_key_is_named_with_the_file() {
        let text = DEFAULT_TOML.replace("[ingest]", "[ingest]\nbogus_knob = 3");
        let err = Config::from_toml_str(&text, Path::new("my.toml")).unwrap_err();
        let msg = err.to_string();
        assert!(msg.contains("my.toml"), "{msg}");
        assert!(msg.contains("bogus_knob"), "{msg}");
    }

    #[test]
    fn a_bad_landmark_band_is_rejected_by_name() {
        for (from, to, key) in [
            (
                "umbo_isj_typical_mm = [2.1, 3.35]",
                "umbo_isj_typical_mm = [3.35, 2.1]",
                "landmarks.umbo_isj_typical_mm",
            ),
            (
                "imj_isj_possible_mm = [3.0, 7.2]",
                "imj_isj_possible_mm = [3.0, nan]",
                "landmarks.imj_isj_possible_mm",
            ),
            (
                "umbo_imj_possible_mm = [4.0, 8.0]",
                "umbo_imj_possible_mm = [-inf, 8.0]",
                "landmarks.umbo_imj_possible_mm",
            ),
            (
                "umbo_imj_possible_mm = [4.0, 8.0]",
                "umbo_imj_possible_mm = [5.0, 8.0]",
                "landmarks.umbo_imj_possible_mm",
            ),
            (
                "scale_ratio_range = [0.67, 1.5]",
                "scale_ratio_range = [1.5, 0.67]",
                "landmarks.scale_ratio_range",
            ),
            (
                "swap_border_gain = 0.25",
                "swap_border_gain = inf",
                "landmarks.swap_border_gain",
            ),
        ] {
            assert!(DEFAULT_TOML.contains(from), "{from}");
            let text = DEFAULT_TOML.replace(from, to);
            let err = Config::from_toml_str(&text, Path::new("p.toml")).unwrap_err();
            let msg = err.to_string();
            assert!(msg.contains(key) && msg.contains("p.toml"), "{to}: {msg}");
        }
    }

    #[test]
    fn non_positive_knob_is_rejected_by_name() {
        let text = DEFAULT_TOML.replace("slice_gap_tolerance = 0.2", "slice_gap_tolerance = -1");
        let err = Config::from_toml_str(&text, Path::new("p.toml")).unwrap_err();
        assert!(
            err.to_string().contains("ingest.slice_gap_tolerance"),
            "{err}"
        );
    }
}

//! The mechanical validation of a run's package (`[validate]` in pipeline.toml): the
//! registered atlas against the atlas it came from (transfer function, and the static-pressure
//! curve when asked), gates relative to the atlas (docs/mechanics.md). The atlas's own
//! mechanics are computed once per process and atlas, so a cohort shares them.

use std::collections::BTreeMap;
use std::sync::{Arc, LazyLock, Mutex};

use nalgebra::Point3;

use crate::Error;
use crate::atlas::Atlas;
use crate::config::ValidateConfig;
use crate::export::atlas_sha256;
use crate::mechanics::{
    Mechanics, UdspOptions, Validation, ValidationOptions, mechanics, validate_package_against,
};

type Slot = Arc<Mutex<Option<Arc<Mechanics>>>>;

/// The atlases' own mechanics, by (atlas SHA-256, with the static-pressure curve).
static REFERENCES: LazyLock<Mutex<BTreeMap<(String, bool), Slot>>> =
    LazyLock::new(|| Mutex::new(BTreeMap::new()));

/// What `[validate]` asks for: the default 1/3-octave transfer function, and the gate
/// pressures ±1, ±2, ±4 kPa when `static_pressure` is on.
pub fn options(cfg: &ValidateConfig) -> ValidationOptions {
    ValidationOptions {
        udsp: cfg.static_pressure.then(|| UdspOptions {
            pressures_pa: crate::mechanics::udsp::GATE_PRESSURES_PA.to_vec(),
            ..UdspOptions::default()
        }),
        ..ValidationOptions::default()
    }
}

/// The atlas's mechanics at its rest shape, computed on the first call for this atlas.
fn reference(atlas: &Atlas, options: &ValidationOptions) -> Result<Arc<Mechanics>, Error> {
    let key = (atlas_sha256(atlas)?, options.udsp.is_some());
    let slot = {
        let mut map = REFERENCES.lock().unwrap_or_else(|e| e.into_inner());
        map.entry(key).or_default().clone()
    };
    // held while computing: a second case of the same atlas waits instead of computing again
    let mut cached = slot.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(m) = cached.as_ref() {
        return Ok(m.clone());
    }
    let m = Arc::new(mechanics(atlas, atlas.nodes(), options)?);
    *cached = Some(m.clone());
    Ok(m)
}

/// Validates `atlas` with its nodes at `registered` against `atlas` itself.
pub fn validate_registered(
    atlas: &Atlas,
    registered: &[Point3<f64>],
    cfg: &ValidateConfig,
) -> Result<Validation, Error> {
    let options = options(cfg);
    let reference = reference(atlas, &options)?;
    Ok(validate_package_against(
        &reference, atlas, registered, &options,
    )?)
}

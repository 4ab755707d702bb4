//! Pathologies of the ossicular chain, as temporal-bone studies make them and finite-element
//! studies model them: a stapes fixed in the oval window (otosclerosis; the annular ligament
//! stiffened), a malleus fixed by its anterior ligament (the anterior mallear ligament
//! stiffened), and a disarticulated incudostapedial joint (the joint removed). Each turns the
//! atlas into the atlas of that ear, so that the same checks measure it (negative controls of
//! the normal-ear bands) and a package of it can be rehearsed. The measured changes they are
//! checked against: docs/mechanics.md, "Pathologies".

use serde::{Deserialize, Serialize};

use super::error::MechanicsError;
use crate::atlas::Atlas;

/// The factor a fixation multiplies the fixing tissue's stiffness by: enough to hold the
/// bone (the stapes's velocity stops falling well before it, docs/mechanics.md).
pub const FIXATION_FACTOR: f64 = 1e3;

/// The factor a disarticulation multiplies the joint's modulus by: the joint's elements stay
/// (their mass is 0.1 mg) but carry no load.
pub const DISARTICULATION_FACTOR: f64 = 1e-6;

/// The anterior mallear ligament's region in the atlas.
const ANTERIOR_MALLEAR_LIGAMENT: &str = "anterior_malleal_ligament";
/// The incudostapedial joint's region in the atlas.
const INCUDOSTAPEDIAL_JOINT: &str = "incudostapedial_joint";

/// The state of the ear.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum Condition {
    /// The atlas as it is.
    #[default]
    Normal,
    /// The stapedial annular ligament 1000 times stiffer (otosclerosis).
    StapesFixation,
    /// The anterior mallear ligament 1000 times stiffer.
    MalleusFixation,
    /// The incudostapedial joint's modulus times 1e-6 (the joint separated).
    IsDisarticulation,
}

impl Condition {
    /// The name the command line and the records use (`stapes-fixation`, ...).
    pub fn name(self) -> &'static str {
        match self {
            Condition::Normal => "normal",
            Condition::StapesFixation => "stapes-fixation",
            Condition::MalleusFixation => "malleus-fixation",
            Condition::IsDisarticulation => "is-disarticulation",
        }
    }

    /// Whether this is the normal ear (for serde's `skip_serializing_if`).
    pub fn is_normal(&self) -> bool {
        *self == Condition::Normal
    }

    /// The atlas of an ear in this condition (the same mesh and nodes).
    pub fn apply(self, atlas: &Atlas) -> Result<Atlas, MechanicsError> {
        let mut ear = atlas.clone();
        match self {
            Condition::Normal => {}
            Condition::StapesFixation => {
                ear.supports.annular_ligament_stiffness_n_per_m *= FIXATION_FACTOR;
            }
            Condition::MalleusFixation => {
                scale_region(&mut ear, ANTERIOR_MALLEAR_LIGAMENT, FIXATION_FACTOR, self)?;
            }
            Condition::IsDisarticulation => {
                scale_region(
                    &mut ear,
                    INCUDOSTAPEDIAL_JOINT,
                    DISARTICULATION_FACTOR,
                    self,
                )?;
            }
        }
        Ok(ear)
    }
}

/// Gives region `name` its own copy of its material with the modulus times `factor` (the
/// material may be shared with other regions, which keep theirs).
fn scale_region(
    atlas: &mut Atlas,
    name: &str,
    factor: f64,
    condition: Condition,
) -> Result<(), MechanicsError> {
    let missing = || MechanicsError::BadAtlas {
        what: format!(
            "{condition:?} needs the region {name} with its material; the atlas has none"
        ),
    };
    let region = atlas
        .regions
        .iter_mut()
        .find(|r| r.name == name)
        .ok_or_else(missing)?;
    let mut material = atlas
        .materials
        .get(&region.material)
        .cloned()
        .ok_or_else(missing)?;
    material.youngs_modulus_pa *= factor;
    material.source = format!("{} (x {factor:e}: {condition:?})", material.source);
    let key = format!("{name} ({condition:?})");
    region.material = key.clone();
    atlas.materials.insert(key, material);
    Ok(())
}

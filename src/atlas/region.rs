//! The regions of the atlas: the rows of Table 1 of Kazmitcheff et al. 2013 ("Mechanical
//! parameters used in our atlas"). Volumetric regions carry the labels of the labelled domain
//! (1..=15, 0 = outside); the two eardrum regions are membrane (surface) regions.

/// A volumetric region. The discriminant is its label in the labelled domain.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Region {
    MalleusHead = 1,
    MalleusNeck = 2,
    MalleusHandle = 3,
    IncusBody = 4,
    IncusShortProcess = 5,
    IncusLongProcess = 6,
    Stapes = 7,
    IncudomalleolarJoint = 8,
    IncudostapedialJoint = 9,
    SuperiorMallealLigament = 10,
    AnteriorMallealLigament = 11,
    LateralMallealLigament = 12,
    PosteriorIncudalLigament = 13,
    TensorTympaniTendon = 14,
    StapediusTendon = 15,
}

/// The three ossicles.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Bone {
    Malleus,
    Incus,
    Stapes,
}

impl Region {
    /// Every volumetric region, in label order.
    pub const ALL: [Region; 15] = [
        Region::MalleusHead,
        Region::MalleusNeck,
        Region::MalleusHandle,
        Region::IncusBody,
        Region::IncusShortProcess,
        Region::IncusLongProcess,
        Region::Stapes,
        Region::IncudomalleolarJoint,
        Region::IncudostapedialJoint,
        Region::SuperiorMallealLigament,
        Region::AnteriorMallealLigament,
        Region::LateralMallealLigament,
        Region::PosteriorIncudalLigament,
        Region::TensorTympaniTendon,
        Region::StapediusTendon,
    ];

    /// The label of the region in the labelled domain.
    pub fn label(self) -> u16 {
        self as u16
    }

    /// The region with label `label` (None for 0 or out of range).
    pub fn from_label(label: u16) -> Option<Region> {
        Region::ALL.get(usize::from(label).checked_sub(1)?).copied()
    }

    /// A stable snake_case name, used in files and reports.
    pub fn name(self) -> &'static str {
        match self {
            Region::MalleusHead => "malleus_head",
            Region::MalleusNeck => "malleus_neck",
            Region::MalleusHandle => "malleus_handle",
            Region::IncusBody => "incus_body",
            Region::IncusShortProcess => "incus_short_process",
            Region::IncusLongProcess => "incus_long_process",
            Region::Stapes => "stapes",
            Region::IncudomalleolarJoint => "incudomalleolar_joint",
            Region::IncudostapedialJoint => "incudostapedial_joint",
            Region::SuperiorMallealLigament => "superior_malleal_ligament",
            Region::AnteriorMallealLigament => "anterior_malleal_ligament",
            Region::LateralMallealLigament => "lateral_malleal_ligament",
            Region::PosteriorIncudalLigament => "posterior_incudal_ligament",
            Region::TensorTympaniTendon => "tensor_tympani_tendon",
            Region::StapediusTendon => "stapedius_tendon",
        }
    }

    /// The ossicle a region is part of (None for joints, ligaments and tendons).
    pub fn bone(self) -> Option<Bone> {
        match self {
            Region::MalleusHead | Region::MalleusNeck | Region::MalleusHandle => {
                Some(Bone::Malleus)
            }
            Region::IncusBody | Region::IncusShortProcess | Region::IncusLongProcess => {
                Some(Bone::Incus)
            }
            Region::Stapes => Some(Bone::Stapes),
            _ => None,
        }
    }

    /// The two joints, in label order.
    pub const JOINTS: [Region; 2] = [Region::IncudomalleolarJoint, Region::IncudostapedialJoint];

    /// The two ossicles a joint connects (None for every other region).
    pub fn joined_bones(self) -> Option<[Bone; 2]> {
        match self {
            Region::IncudomalleolarJoint => Some([Bone::Malleus, Bone::Incus]),
            Region::IncudostapedialJoint => Some([Bone::Incus, Bone::Stapes]),
            _ => None,
        }
    }
}

impl Bone {
    pub fn name(self) -> &'static str {
        match self {
            Bone::Malleus => "malleus",
            Bone::Incus => "incus",
            Bone::Stapes => "stapes",
        }
    }

    /// The regions making up the bone.
    pub fn regions(self) -> &'static [Region] {
        match self {
            Bone::Malleus => &[
                Region::MalleusHead,
                Region::MalleusNeck,
                Region::MalleusHandle,
            ],
            Bone::Incus => &[
                Region::IncusBody,
                Region::IncusShortProcess,
                Region::IncusLongProcess,
            ],
            Bone::Stapes => &[Region::Stapes],
        }
    }
}

/// A region of the eardrum membrane. Ids continue the label numbering (16, 17) so that every
/// Table 1 row has one number, but they never appear in the volumetric label field.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MembraneRegion {
    ParsTensa = 16,
    ParsFlaccida = 17,
}

impl MembraneRegion {
    pub fn id(self) -> u16 {
        self as u16
    }

    pub fn name(self) -> &'static str {
        match self {
            MembraneRegion::ParsTensa => "pars_tensa",
            MembraneRegion::ParsFlaccida => "pars_flaccida",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn labels_round_trip_and_bones_partition_the_ossicle_regions() {
        for (k, r) in Region::ALL.iter().enumerate() {
            assert_eq!(usize::from(r.label()), k + 1);
            assert_eq!(Region::from_label(r.label()), Some(*r));
        }
        assert_eq!(Region::from_label(0), None);
        assert_eq!(Region::from_label(16), None);
        for b in [Bone::Malleus, Bone::Incus, Bone::Stapes] {
            assert!(b.regions().iter().all(|r| r.bone() == Some(b)));
        }
    }
}

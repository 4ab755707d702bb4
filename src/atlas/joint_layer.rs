//! The joints as meshed: each joint's layer volume and its interfaces with its two bones.
//!
//! The lattice mesher cannot resolve a 0.2 mm layer at a 0.33 mm edge: a joint comes out one
//! or two tetrahedra thick. Its stiffness across (E · area / thickness) would then be that of
//! a thicker joint, so the atlas scales the joint's modulus by the mesh's thickness over the
//! anatomy's (volume / interface area against the thickness in the anatomy file), keeping the
//! stiffness per area of the anatomical layer. A joint that touches one of its bones over no
//! face joins nothing and is refused.

use super::Anatomy;
use super::region::{Bone, Region};
use crate::mesh::TetMesh;

/// One joint's layer in the mesh.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointLayer {
    pub region: Region,
    /// Volume of the joint's tetrahedra (mm³).
    pub volume_mm3: f64,
    /// Mean of the areas of its interfaces with its two bones (mm²).
    pub area_mm2: f64,
    /// The layer's thickness in the anatomy (mm).
    pub anatomical_thickness_mm: f64,
}

impl JointLayer {
    /// Volume over interface area (mm).
    pub fn mesh_thickness_mm(&self) -> f64 {
        self.volume_mm3 / self.area_mm2
    }

    /// The factor on the joint's Young's modulus that gives the meshed layer the stiffness
    /// per area of the anatomical one.
    pub fn stiffness_scale(&self) -> f64 {
        self.mesh_thickness_mm() / self.anatomical_thickness_mm
    }
}

/// Measures both joints' layers in `mesh`; an error names a joint that misses a bone.
pub fn joint_layers(mesh: &TetMesh, anatomy: &Anatomy) -> Result<Vec<JointLayer>, String> {
    let faces = mesh.interior_faces();
    let spec = &anatomy.spec().joints;
    Region::JOINTS
        .iter()
        .filter_map(|joint| joint.joined_bones().map(|bones| (joint, bones)))
        .map(|(joint, bones)| {
            let label = joint.label();
            let area_with = |bone: Bone| -> f64 {
                faces
                    .iter()
                    .filter(|(_, a, b)| {
                        let (ra, rb) = (mesh.regions[*a], mesh.regions[*b]);
                        let other = if ra == label { rb } else { ra };
                        (ra == label) != (rb == label)
                            && Region::from_label(other).and_then(|r| r.bone()) == Some(bone)
                    })
                    .map(|(f, _, _)| mesh.face_area(f))
                    .sum()
            };
            let areas = bones.map(area_with);
            if let Some(k) = areas.iter().position(|a| *a <= 0.0) {
                return Err(format!(
                    "the {} touches the {} over no face: it joins nothing",
                    joint.name(),
                    bones[k].name()
                ));
            }
            let thickness = match joint {
                Region::IncudomalleolarJoint => spec.incudomalleolar.thickness,
                _ => spec.incudostapedial.thickness,
            };
            Ok(JointLayer {
                region: *joint,
                volume_mm3: mesh.region_volume(label),
                area_mm2: 0.5 * (areas[0] + areas[1]),
                anatomical_thickness_mm: thickness,
            })
        })
        .collect()
}

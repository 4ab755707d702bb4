//! The default atlas's ossicles meet only through their joints, each ossicle is one piece, and
//! the three landmarks sit where docs/anatomy.md defines them (umbo: the manubrium's tip at
//! the eardrum; IMJ and ISJ: the centres of the two joints' interfaces).

use std::collections::BTreeMap;

use nalgebra::Point3;
use otoatlas::atlas::{Atlas, Bone, Region, default_atlas};

fn atlas() -> Atlas {
    match default_atlas() {
        Ok(a) => a,
        Err(e) => panic!("embedded atlas: {e}"),
    }
}

fn bone_of(label: u16) -> Option<Bone> {
    Region::from_label(label).and_then(|r| r.bone())
}

fn centroid(atlas: &Atlas, tets: &[usize]) -> Point3<f64> {
    let mesh = &atlas.mesh.tets;
    let (mut sum, mut volume) = (nalgebra::Vector3::zeros(), 0.0);
    for &t in tets {
        let v = mesh.tet_volume(t);
        let c = mesh
            .corners(t)
            .iter()
            .fold(nalgebra::Vector3::zeros(), |s, p| s + p.coords)
            / 4.0;
        sum += c * v;
        volume += v;
    }
    Point3::from(sum / volume)
}

#[test]
fn no_face_is_shared_by_two_ossicles() {
    let atlas = atlas();
    let mesh = &atlas.mesh.tets;
    let mut contacts: BTreeMap<(&str, &str), usize> = BTreeMap::new();
    for (_, a, b) in mesh.interior_faces() {
        if let (Some(x), Some(y)) = (bone_of(mesh.regions[a]), bone_of(mesh.regions[b]))
            && x != y
        {
            *contacts.entry((x.name(), y.name())).or_default() += 1;
        }
    }
    assert!(contacts.is_empty(), "bone on bone faces: {contacts:?}");
}

#[test]
fn each_joint_meets_exactly_its_two_bones() {
    let atlas = atlas();
    let mesh = &atlas.mesh.tets;
    let faces = mesh.interior_faces();
    for joint in Region::JOINTS {
        let Some(bones) = joint.joined_bones() else {
            panic!("{} joins no bones", joint.name());
        };
        let mut area: BTreeMap<&str, f64> = BTreeMap::new();
        for (f, a, b) in &faces {
            let (ra, rb) = (mesh.regions[*a], mesh.regions[*b]);
            let other = if ra == joint.label() {
                rb
            } else if rb == joint.label() {
                ra
            } else {
                continue;
            };
            if let Some(bone) = bone_of(other) {
                *area.entry(bone.name()).or_default() += mesh.face_area(f);
            }
        }
        let touched: Vec<&str> = area.keys().copied().collect();
        let mut expected: Vec<&str> = bones.iter().map(|b| b.name()).collect();
        expected.sort_unstable();
        assert_eq!(touched, expected, "{}: {area:?}", joint.name());
        // an interface, not a point contact: at least a few faces on each side
        for (bone, a) in &area {
            assert!(
                *a > 0.3,
                "{} meets the {bone} over {a:.3} mm2 only",
                joint.name()
            );
        }
    }
}

#[test]
fn each_ossicle_is_one_piece() {
    let atlas = atlas();
    let mesh = &atlas.mesh.tets;
    let n = mesh.tets.len();
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for (_, a, b) in mesh.interior_faces() {
        let (x, y) = (bone_of(mesh.regions[a]), bone_of(mesh.regions[b]));
        if x.is_some() && x == y {
            let (ra, rb) = (root(&mut parent, a), root(&mut parent, b));
            parent[ra] = rb;
        }
    }
    for bone in [Bone::Malleus, Bone::Incus, Bone::Stapes] {
        let mut roots: Vec<usize> = (0..n)
            .filter(|&t| bone_of(mesh.regions[t]) == Some(bone))
            .map(|t| root(&mut parent, t))
            .collect();
        roots.sort_unstable();
        roots.dedup();
        assert_eq!(roots.len(), 1, "{} is {} pieces", bone.name(), roots.len());
    }
}

#[test]
fn landmarks_sit_at_their_definitions() {
    let atlas = atlas();
    let mesh = &atlas.mesh.tets;
    let at = atlas.landmark_positions(atlas.nodes());
    // Umbo: the manubrium's tip, where the eardrum's cone has its apex. The handle's tet
    // holding it is the malleus handle, no handle node lies beyond it along the manubrium,
    // and an eardrum node is within one membrane edge (0.24 mm).
    let handle: Vec<usize> = (0..mesh.tets.len())
        .filter(|&t| mesh.regions[t] == Region::MalleusHandle.label())
        .collect();
    let imj = at.incudomalleolar;
    let reach = (at.umbo - imj).norm();
    let farthest = handle
        .iter()
        .flat_map(|&t| mesh.corners(t))
        .map(|p| (p - imj).norm())
        .fold(0.0, f64::max);
    assert!(
        farthest - reach < 0.2,
        "a handle node lies {:.3} mm beyond the umbo from the IMJ",
        farthest - reach
    );
    let drum_nodes: Vec<u32> = atlas.mesh.triangles.iter().flatten().copied().collect();
    let nearest_drum = drum_nodes
        .iter()
        .map(|&n| (atlas.nodes()[n as usize] - at.umbo).norm())
        .fold(f64::INFINITY, f64::min);
    assert!(
        nearest_drum < 0.24,
        "eardrum {nearest_drum:.3} mm from the umbo"
    );
    // IMJ and ISJ: inside their joint, at the centre of its layer.
    for (joint, point) in [
        (Region::IncudomalleolarJoint, imj),
        (Region::IncudostapedialJoint, at.incudostapedial),
    ] {
        let tets: Vec<usize> = (0..mesh.tets.len())
            .filter(|&t| mesh.regions[t] == joint.label())
            .collect();
        let c = centroid(&atlas, &tets);
        let off = (point - c).norm();
        assert!(
            off < 0.15,
            "{}: landmark {off:.3} mm from the layer's centre",
            joint.name()
        );
    }
}

/// A fused chain segmentation (a CT's, which does not separate the ossicles) is scored against
/// `Atlas::chain_surface`: the outer surface of bones and joints as one solid. Built here the
/// other way round, from the ossicles' and the joints' own closed surfaces with every facet
/// two of them share cancelled, it must be the same surface, closed, and without the
/// joint-facing facets of the ossicles.
#[test]
fn the_chain_surface_is_the_outer_surface_of_bones_and_joints() {
    use otoatlas::atlas::Part;
    use otoatlas::mesh::tet::BoundaryOf;
    use otoatlas::mesh::topology::surface_topology;
    let atlas = atlas();
    let nodes = atlas.nodes().to_vec();
    let mut pieces: Vec<Vec<[u32; 3]>> = Part::BONES
        .iter()
        .map(|p| atlas.part_triangles(*p))
        .collect();
    for joint in Region::JOINTS {
        pieces.push(
            atlas
                .mesh
                .tets
                .boundary(BoundaryOf::Region(joint.label()))
                .node_triangles(),
        );
    }
    let mut count: BTreeMap<[u32; 3], usize> = BTreeMap::new();
    for t in pieces.iter().flatten() {
        let mut k = *t;
        k.sort_unstable();
        *count.entry(k).or_default() += 1;
    }
    let area = |t: &[u32; 3]| {
        let [a, b, c] = t.map(|i| nodes[i as usize]);
        (b - a).cross(&(c - a)).norm() / 2.0
    };
    let outer: f64 = count
        .iter()
        .filter(|(_, n)| **n == 1)
        .map(|(t, _)| area(t))
        .sum();
    let shared: f64 = count
        .iter()
        .filter(|(_, n)| **n == 2)
        .map(|(t, _)| area(t))
        .sum();
    assert!(count.values().all(|n| *n <= 2), "a facet on three surfaces");
    let chain = atlas.chain_surface(&nodes);
    assert!(
        (chain.area() - outer).abs() < 1e-9 * outer,
        "chain surface {:.4} mm², outer facets {outer:.4} mm²",
        chain.area()
    );
    // the joints' interfaces with their bones: a few mm² each side
    assert!(shared > 1.0, "shared facets {shared:.3} mm²");
    let topology = surface_topology(&chain);
    assert!(topology.is_closed_oriented_manifold(), "{topology:?}");
}

/// The eardrum hangs on the manubrium along its whole attachment line: the drum's nodes that
/// are malleus nodes run from the umbo up the manubrium, all fifteen nodes of the line, none
/// missing between them (no gap of two membrane edges, 0.48 mm). Before the builder tied every line node (2026-11-27), two of the
/// default line's fifteen were left free, and a finer drum was tied at fewer points still
/// (docs/mechanics.md, "The eardrum's own convergence").
#[test]
fn the_eardrum_is_tied_to_the_manubrium_along_its_attachment_line() {
    let atlas = atlas();
    let mesh = &atlas.mesh.tets;
    let at = atlas.landmark_positions(atlas.nodes());
    let malleus: std::collections::BTreeSet<u32> = (0..mesh.tets.len())
        .filter(|&t| bone_of(mesh.regions[t]) == Some(Bone::Malleus))
        .flat_map(|t| mesh.tets[t])
        .collect();
    let mut tied: Vec<f64> = atlas
        .mesh
        .triangles
        .iter()
        .flatten()
        .copied()
        .collect::<std::collections::BTreeSet<u32>>()
        .into_iter()
        .filter(|n| malleus.contains(n))
        .map(|n| (atlas.nodes()[n as usize] - at.umbo).norm())
        .collect();
    tied.sort_by(f64::total_cmp);
    assert!(tied.len() >= 15, "{} drum nodes tied: {tied:?}", tied.len());
    assert!(tied[0] < 0.24, "no tie at the umbo: {tied:?}");
    let gap = tied.windows(2).map(|w| w[1] - w[0]).fold(0.0, f64::max);
    assert!(gap <= 0.45, "a gap of {gap:.3} mm between ties: {tied:?}");
    assert!(
        tied[tied.len() - 1] > 3.0,
        "the ties end {:.2} mm from the umbo",
        tied[tied.len() - 1]
    );
}

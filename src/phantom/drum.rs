//! Where a point lies relative to the eardrum cone (`atlas::Eardrum`): its height along the
//! annulus normal above the membrane point of the same generator, and that point's (s, θ);
//! the slopes of those coordinates (so distances can bound them), and the box filter that lets
//! a sheet thinner than a sample show as partial volume.

use nalgebra::{Point3, Vector3};

use crate::atlas::Eardrum;

/// Where a point lies relative to the eardrum cone.
#[derive(Debug, Clone, Copy)]
pub struct DrumPosition {
    /// Signed distance along the medial normal from the membrane (+ medial).
    pub height: f64,
    /// Radial fraction from the umbo (0) to the annulus (1); > 1 outside the annulus.
    pub s: f64,
    pub theta: f64,
}

/// Where `p` lies relative to the cone of `d`: the generator through the projection of `p`
/// onto the annulus plane, in the plane's elliptic coordinates.
pub fn drum_position(d: &Eardrum, p: &Point3<f64>) -> DrumPosition {
    let to_uv = |q: &Point3<f64>| {
        let r = q - d.annulus_center;
        (
            r.dot(&d.superior) / d.semi_axis_superior,
            r.dot(&d.anterior) / d.semi_axis_anterior,
        )
    };
    let (au, av) = to_uv(&d.apex);
    let (pu, pv) = to_uv(p);
    let (du, dv) = (pu - au, pv - av);
    let len = (du * du + dv * dv).sqrt();
    if len < 1e-12 {
        return DrumPosition {
            height: (p - d.apex).dot(&d.medial_normal),
            s: 0.0,
            theta: 0.0,
        };
    }
    let (ux, uy) = (du / len, dv / len);
    // the generator through p meets the unit circle at apex_uv + t (ux, uy)
    let b = au * ux + av * uy;
    let c = au * au + av * av - 1.0;
    let t = -b + (b * b - c).max(0.0).sqrt();
    let theta = (av + t * uy).atan2(au + t * ux);
    let s = len / t.max(1e-12);
    let on_membrane = d.point(s, theta);
    DrumPosition {
        height: (p - on_membrane).dot(&d.medial_normal),
        s,
        theta,
    }
}

/// Lipschitz bounds of the drum height and, near the annulus, of s.
#[derive(Debug, Clone, Copy)]
pub struct DrumSlopes {
    pub height: f64,
    pub s: f64,
}

impl DrumSlopes {
    /// The largest gradients of the height (over the membrane and 1 mm either side, away from
    /// the umbo) and of s (near the annulus), by central differences on a dense (s, θ)
    /// sampling, with a 20 % margin: the cone's height along the annulus normal is steeper
    /// than a distance.
    pub fn measure(d: &Eardrum) -> DrumSlopes {
        let h = 1e-4;
        let grad = |p: &Point3<f64>, f: &dyn Fn(&DrumPosition) -> f64| {
            Vector3::from_fn(|c, _| {
                let mut e = Vector3::zeros();
                e[c] = h;
                (f(&drum_position(d, &(p + e))) - f(&drum_position(d, &(p - e)))) / (2.0 * h)
            })
            .norm()
        };
        let (mut height, mut s_max) = (0.0f64, 0.0f64);
        for i in 1..=24 {
            let s = 0.05 * i as f64; // 0.05 .. 1.2
            for k in 0..96 {
                let theta = std::f64::consts::TAU * k as f64 / 96.0;
                for off in [-1.0, -0.3, 0.0, 0.3, 1.0] {
                    let p = d.point(s, theta) + d.medial_normal * off;
                    if s >= 0.2 {
                        height = height.max(grad(&p, &|q| q.height));
                    }
                    if s >= 0.8 {
                        s_max = s_max.max(grad(&p, &|q| q.s));
                    }
                }
            }
        }
        DrumSlopes {
            height: 1.2 * height.max(1.0),
            s: 1.2 * s_max,
        }
    }
}

/// The eardrum sheet is box-filtered over a sample's footprint along its normal: the covered
/// fraction of `[h - f/2, h + f/2]` by `[-t/2, t/2]`, so a sheet thinner than the sample
/// spacing still shows as partial volume instead of aliasing.
pub fn sheet_fraction(height: f64, thickness: f64, footprint: f64) -> f64 {
    if footprint <= 0.0 {
        return if height.abs() <= 0.5 * thickness {
            1.0
        } else {
            0.0
        };
    }
    let lo = (height - 0.5 * footprint).max(-0.5 * thickness);
    let hi = (height + 0.5 * footprint).min(0.5 * thickness);
    ((hi - lo) / footprint).clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atlas::Anatomy;

    #[test]
    fn drum_position_is_zero_on_the_membrane_and_signed_off_it() {
        let a = Anatomy::default_right().unwrap();
        let d = a.eardrum();
        for (sf, th) in [(0.2, 0.3), (0.7, 2.5), (0.95, -1.2)] {
            let p = d.point(sf, th);
            let pos = drum_position(d, &p);
            assert!(
                pos.height.abs() < 1e-9 && (pos.s - sf).abs() < 1e-9,
                "{sf} {th}"
            );
            let off = drum_position(d, &(p + d.medial_normal * 0.1));
            assert!(off.height > 0.0);
        }
        let slopes = DrumSlopes::measure(d);
        assert!(slopes.height >= 1.2 && slopes.height < 3.0, "{slopes:?}");
    }

    #[test]
    fn a_sheet_thinner_than_the_footprint_keeps_its_mass() {
        // sliding a 0.074 mm sheet across footprints of 0.1 mm: the covered fraction
        // integrates to the thickness
        let (t, f) = (0.074, 0.1);
        let n = 4000;
        let dh = 1.0 / n as f64;
        let total: f64 = (0..n)
            .map(|k| sheet_fraction(-0.5 + (k as f64 + 0.5) * dh, t, f) * dh)
            .sum();
        assert!((total - t).abs() < 1e-6, "{total}");
        assert_eq!(sheet_fraction(0.0, t, 0.0), 1.0);
        assert_eq!(sheet_fraction(0.05, t, 0.0), 0.0);
    }
}

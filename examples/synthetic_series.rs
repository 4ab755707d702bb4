//! Writes a synthetic CT series (int16, one file per slice) for demos and benchmarks:
//! a bone ellipsoid shell in soft tissue in air, on an oblique grid.
//!
//! `cargo run --release --example synthetic_series -- OUT_DIR [NX NY NZ] [SPACING_MM]`

use std::path::PathBuf;
use std::time::Instant;

use nalgebra::{Rotation3, Vector3};
use otoatlas::image::Volume;
use otoatlas::image::dicom::Rescale;
use otoatlas::image::dicom::write::{SeriesIdentity, SliceRescale, uid_from, write_series};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let out = PathBuf::from(
        args.first()
            .ok_or("usage: synthetic_series OUT_DIR [NX NY NZ] [SPACING_MM]")?,
    );
    let n = |i: usize, d: usize| -> Result<usize, Box<dyn std::error::Error>> {
        Ok(args.get(i).map(|s| s.parse()).transpose()?.unwrap_or(d))
    };
    let dims = [n(1, 256)?, n(2, 256)?, n(3, 120)?];
    let spacing: f64 = args.get(4).map(|s| s.parse()).transpose()?.unwrap_or(0.2);
    let start = Instant::now();
    let centre = Vector3::new(dims[0] as f64, dims[1] as f64, dims[2] as f64) * (0.5 * spacing);
    let radii = centre * 0.8;
    let mut data = Vec::with_capacity(dims.iter().product());
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let p = Vector3::new(i as f64, j as f64, k as f64) * spacing - centre;
                let r = p.component_div(&radii).norm();
                let hu = if r < 0.6 {
                    40.0 // soft tissue
                } else if r < 0.8 {
                    1800.0 // bone shell
                } else if r < 1.0 {
                    40.0
                } else {
                    -1000.0 // air
                };
                data.push(hu);
            }
        }
    }
    let volume = Volume {
        dims,
        spacing: [spacing; 3],
        origin: Vector3::new(-20.0, -30.0, 15.0),
        direction: *Rotation3::from_euler_angles(0.05, -0.1, 0.2).matrix(),
        data,
    };
    let identity = SeriesIdentity {
        study_uid: uid_from("synthetic/study"),
        series_uid: uid_from(&format!("synthetic/series/{dims:?}")),
        frame_of_reference_uid: uid_from("synthetic/for"),
        patient_name: "SYNTHETIC^SERIES".into(),
        patient_id: "SYN-0000".into(),
        patient_birth_date: "19800101".into(),
        series_description: "otoatlas synthetic series".into(),
        laterality: Some("R".into()),
    };
    let rescale = SliceRescale::Fixed(Rescale {
        slope: 1.0,
        intercept: -1024.0,
    });
    let files = write_series(&out, &volume, &identity, &rescale)?;
    eprintln!(
        "wrote {} slices of {}x{} to {} in {:.2} s",
        files.len(),
        dims[0],
        dims[1],
        out.display(),
        start.elapsed().as_secs_f64()
    );
    Ok(())
}

//! `otoatlas phantom`: make synthetic CBCT cases with known ground truth.

use std::fmt::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::Args;
use serde_json::json;

use super::Report;
use crate::Error;
use crate::phantom::{
    ChainAnatomy, ChainPhantoms, ChainShape, PhantomError, PhantomOptions, generate_case,
    generate_chain_case, write_case,
};
use crate::progress::Reporter;
use crate::register::Side;

/// Make synthetic temporal-bone CBCT cases (DICOM + NIfTI, landmarks, true surfaces and label
/// map, truth.json) from seeded variations of the atlas, or around a real ossicular chain.
#[derive(Debug, Args)]
#[command(
    after_help = "Case k (1-based) is OUT/case-k in three digits (case-001, case-002, ...),
made from seed S + k - 1; the same seed always gives byte-identical files.

Examples:
  otoatlas phantom --out sample_cases --cases 3 --seed 2026
  otoatlas phantom --out /tmp/cases --cases 1 --seed 7 --spacing 0.2 --side left --artefacts
  otoatlas phantom --out real --cases 4 --seed 1 --anatomy CHAIN_DIR --blur 0.3
  otoatlas phantom --out varied --cases 16 --seed 701 --anatomy CHAIN_DIR --vary-shape
  otoatlas phantom --out turned --cases 16 --seed 1101 --anatomy CHAIN_DIR --vary-articulation

--anatomy CHAIN_DIR holds malleus, incus and stapes surfaces (or one fused chain.ply;
.ply, .stl or .obj, in the folder or its surfaces/) and a landmark file that says the side
(landmarks.json); the chain is the truth, mirrored when the side drawn or asked for is the
other one, and the eardrum, canal, cavity and oval window come from the atlas around it.
--vary-shape gives each case its own linear variation of the chain's shape (about its
centroid, landmarks alike), drawn from the seed apart from the case's other draws: a few real
chains give a development set of many. --vary-articulation instead turns each case's stapes
about the ISJ landmark (up to 25 degrees) and malleus about the IMJ landmark (up to 8), for a
chain whose ossicles are apart."
)]
pub struct PhantomArgs {
    /// Folder the case folders are written into (created if needed).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Number of cases.
    #[arg(long, default_value_t = 1, value_name = "N")]
    pub cases: u32,
    /// Seed of the first case.
    #[arg(long, default_value_t = 1, value_name = "S")]
    pub seed: u64,
    /// Voxel spacing in mm (0.125 to 0.3); drawn per case when absent.
    #[arg(long, value_name = "MM")]
    pub spacing: Option<f64>,
    /// Image noise standard deviation in HU (default 40).
    #[arg(long, value_name = "HU")]
    pub noise: Option<f64>,
    /// Add cone-beam artefacts (cupping, rings, streaks).
    #[arg(long)]
    pub artefacts: bool,
    /// The ear's side; drawn per case when absent.
    #[arg(long, value_enum)]
    pub side: Option<Side>,
    /// Point-spread function FWHM in mm (default 0.25).
    #[arg(long, value_name = "MM")]
    pub blur: Option<f64>,
    /// A real ossicular chain to image instead of the atlas: a folder of closed surfaces in mm
    /// (.ply, .stl, .obj, or a .vtu's triangles or tetrahedra) named for the malleus, incus and
    /// stapes, or one fused chain; with a landmark file stating the side, or the landmarks and
    /// side are proposed.
    #[arg(long, value_name = "CHAIN_DIR")]
    pub anatomy: Option<PathBuf>,
    /// Vary the real chain's shape per case: stretched by 0.87-1.15 along three random
    /// directions and sheared by up to 0.12 (truth.json's anatomy.variation).
    #[arg(long, requires = "anatomy")]
    pub vary_shape: bool,
    /// Vary the real chain's articulation per case: the stapes turned about the ISJ landmark
    /// by up to 25 degrees, the malleus about the IMJ landmark by up to 8, each about a random
    /// axis (truth.json's anatomy.articulation); the chain's ossicles must be apart.
    #[arg(long, requires = "anatomy", conflicts_with = "vary_shape")]
    pub vary_articulation: bool,
    /// Print machine-readable JSON on stdout.
    #[arg(long)]
    pub json: bool,
}

/// Fails early, with exit code 2, when `dir` cannot be written into.
fn check_writable(dir: &Path) -> Result<(), Error> {
    let unwritable = |e: std::io::Error| {
        Error::Usage(format!("--out {}: cannot write there: {e}", dir.display()))
    };
    std::fs::create_dir_all(dir).map_err(unwritable)?;
    let probe = dir.join(format!(".otoatlas-write-probe.{}", std::process::id()));
    std::fs::write(&probe, b"").map_err(unwritable)?;
    std::fs::remove_file(&probe).map_err(unwritable)
}

/// The folder of the `k`-th case (from 1) under `out`.
fn case_dir(out: &Path, k: u64) -> PathBuf {
    out.join(format!("case-{k:03}"))
}

/// Refuses, before any work, a `--out` where a case folder this run would replace is not a
/// phantom (it has no `truth.json`, which every phantom has): a patient's case in a cohort
/// folder given as `--out` by mistake is never replaced.
fn check_replaceable(out: &Path, cases: u32) -> Result<(), Error> {
    for k in 1..=u64::from(cases) {
        let dir = case_dir(out, k);
        if dir.exists() && !dir.join("truth.json").is_file() {
            return Err(Error::Usage(format!(
                "--out {}: {} exists and is not a phantom (no truth.json); phantom replaces only its own cases, so give another --out",
                out.display(),
                dir.display()
            )));
        }
    }
    Ok(())
}

pub fn run(args: &PhantomArgs, progress: &dyn Reporter) -> Result<Report, Error> {
    if args.cases == 0 {
        return Err(Error::Usage("--cases 0: expected at least one case".into()));
    }
    let options = PhantomOptions {
        spacing_mm: args.spacing,
        noise_sd_hu: args.noise,
        artefacts: args.artefacts,
        side: args.side,
        blur_mm: args.blur,
    };
    options.check()?;
    let chain = args
        .anatomy
        .as_deref()
        .map(ChainAnatomy::load)
        .transpose()
        .map_err(PhantomError::from)?;
    let notes: Vec<String> = chain.iter().flat_map(|c| c.notes.clone()).collect();
    for note in &notes {
        progress.log(&format!("anatomy: {note}"));
    }
    if let (Some(chain), true) = (&chain, args.vary_articulation) {
        // before anything is written
        chain.check_articulable().map_err(PhantomError::from)?;
    }
    let mut chain = chain.map(|chain| {
        let shape = match (args.vary_shape, args.vary_articulation) {
            (true, _) => ChainShape::Varied,
            (_, true) => ChainShape::Articulated,
            _ => ChainShape::AsGiven,
        };
        ChainPhantoms::new(chain, shape)
    });
    check_writable(&args.out)?;
    check_replaceable(&args.out, args.cases)?;
    let bar = progress.task("phantom", u64::from(args.cases));
    let mut text = String::new();
    let mut cases = Vec::new();
    for k in 1..=u64::from(args.cases) {
        let start = Instant::now();
        let seed = args.seed.wrapping_add(k - 1);
        let case = match &mut chain {
            Some(chain) => generate_chain_case(seed, &options, chain)?,
            None => generate_case(seed, &options)?,
        };
        let path = write_case(&case_dir(&args.out, k), &case)?;
        let seconds = start.elapsed().as_secs_f64();
        let t = &case.truth;
        let _ = writeln!(
            text,
            "{}  seed {seed}  {} ear  {:.3} mm  {}x{}x{} voxels  {seconds:.1} s",
            path.display(),
            t.side.as_str(),
            t.image.spacing_mm[0],
            t.image.dims[0],
            t.image.dims[1],
            t.image.dims[2],
        );
        cases.push(json!({
            "path": path,
            "seed": seed,
            "side": t.side.as_str(),
            "spacing_mm": t.image.spacing_mm[0],
            "dims": t.image.dims,
            "seconds": seconds,
        }));
        bar.message(&format!("case-{k:03} written"));
        bar.inc(1);
    }
    bar.finish(&format!("{} case(s) in {}", args.cases, args.out.display()));
    Ok(Report {
        text,
        json: json!({ "out": args.out, "cases": cases, "notes": notes }),
    })
}

//! `meshdev_compare REFERENCE TEST`: surface distances per structure between a reference (the
//! manual segmentation) and a test surface (a registered model), with the metrics defined in
//! the otoatlas `meshdev` module (MASD headline, ASSD, RMS, HD, HD95, signed bias, surface Dice,
//! and the MeshDev-compatible one-sided per-vertex mean and max).

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::Parser;
use otoatlas::config::Config;
use otoatlas::io_util::write_atomic;
use otoatlas::mesh::io::ply::{VertexAttributes, ply_bytes};
use otoatlas::meshdev::structures::{
    StructuresError, default_label_table, load_structures, pair_structures, parse_label_table,
};
use otoatlas::meshdev::{ColourRange, CompareOptions, Sampling, compare};

/// Compare surfaces per structure (mm).
#[derive(Debug, Parser)]
#[command(
    version,
    after_help = "REFERENCE and TEST are each a mesh file (.ply .stl .obj .vtu), a label map
(.nii .nii.gz; labels 1=malleus 2=incus 3=stapes 4=eardrum unless --labels), or a folder of
per-structure meshes named by structure. A reference named 'ossicles' or 'chain' is compared
with the union of the test's malleus, incus and stapes (their outer surface when each is
closed).

Examples:
  meshdev_compare sample_cases/case-001/segmentation out/case-001/registered/surfaces
  meshdev_compare seg/labels.nii.gz reg/surfaces --json --map out/deviation.ply
  meshdev_compare manual.stl model.ply --pair manual=model --tolerance 0.125

Exit codes: 0 ok, 1 comparison failed, 2 bad usage or input."
)]
struct Args {
    /// The reference (manual segmentation).
    reference: PathBuf,
    /// The test surface (registered model).
    test: PathBuf,
    /// Print JSON: {"structures": {NAME: {"masd", "assd", "rms", "hd", "hd95", "bias", ...}}}.
    #[arg(long)]
    json: bool,
    /// Write the per-vertex signed deviation of the test surface as PLY (quality + RGB);
    /// with several structures, one file per structure: OUT.NAME.ply.
    #[arg(long, value_name = "OUT.ply")]
    map: Option<PathBuf>,
    /// Area-weighted samples per surface (default: 10 per triangle, 1e4..1e6).
    #[arg(long, value_name = "N")]
    samples: Option<usize>,
    /// Surface Dice tolerance in mm (one voxel is customary).
    #[arg(long, default_value_t = 0.2, value_name = "MM")]
    tolerance: f64,
    /// Colour range of the deviation map (mm), symmetric: -R..+R.
    #[arg(long, default_value_t = 0.5, value_name = "MM")]
    colour_range: f64,
    /// Label table of label maps, e.g. "1=malleus,2=incus,3=stapes,4=eardrum".
    #[arg(long, value_name = "TABLE")]
    labels: Option<String>,
    /// Pair a reference structure with test structures: REF=TEST or REF=T1+T2 (repeatable).
    #[arg(long = "pair", value_name = "REF=TEST")]
    pairs: Vec<String>,
}

fn main() -> ExitCode {
    let args = Args::parse();
    match run(&args) {
        Ok(text) => {
            print!("{text}");
            ExitCode::SUCCESS
        }
        Err((code, message)) => {
            if args.json {
                println!(
                    "{}",
                    serde_json::json!({ "error": message, "exit_code": code })
                );
            }
            eprintln!("error: {message}");
            ExitCode::from(code)
        }
    }
}

fn usage(message: String) -> (u8, String) {
    (2, message)
}

fn run(args: &Args) -> Result<String, (u8, String)> {
    let labels = match &args.labels {
        Some(t) => parse_label_table(t).map_err(|e| usage(format!("--labels {e}")))?,
        None => default_label_table(),
    };
    let mut aliases = BTreeMap::new();
    for p in &args.pairs {
        let (r, t) = p
            .split_once('=')
            .ok_or_else(|| usage(format!("--pair {p:?}: expected REF=TEST")))?;
        aliases.insert(
            r.trim().to_ascii_lowercase(),
            t.split('+').map(|s| s.trim().to_string()).collect(),
        );
    }
    let ingest = Config::default_config()
        .map_err(|e| usage(e.to_string()))?
        .ingest;
    let load = |p: &Path| {
        load_structures(p, &labels, &ingest).map_err(|e| {
            // a folder that cannot be listed is this run's failure; anything else is the input
            let code = match e {
                StructuresError::Io { .. } => 1,
                _ => 2,
            };
            (code, e.to_string())
        })
    };
    let (reference, test) = (load(&args.reference)?, load(&args.test)?);
    let (pairs, unpaired) = pair_structures(&reference, &test, &aliases);
    if pairs.is_empty() {
        return Err(usage(format!(
            "no structure pairs: reference has {:?}, test has {:?} (use --pair REF=TEST)",
            reference.iter().map(|s| &s.name).collect::<Vec<_>>(),
            test.iter().map(|s| &s.name).collect::<Vec<_>>()
        )));
    }
    let colour_range = ColourRange {
        min_mm: -args.colour_range,
        max_mm: args.colour_range,
    };
    let options = CompareOptions {
        sampling: Sampling::Area {
            count: args.samples,
            seed: 1,
        },
        colour_range,
        ..CompareOptions::with_tolerance(args.tolerance)
    };
    let mut json = serde_json::Map::new();
    let mut text = format!(
        "{:<10} {:>7} {:>7} {:>7} {:>7} {:>7} {:>8} {:>7} {:>9} {:>9}\n",
        "structure", "MASD", "ASSD", "RMS", "HD", "HD95", "bias", "Dice", "MD mean", "MD max"
    );
    for pair in &pairs {
        let result = compare(&pair.test, &pair.reference, &options)
            .map_err(|e| (1, format!("{}: {e}", pair.name)))?;
        let d = &result.distances;
        let _ = writeln!(
            text,
            "{:<10} {:>7.3} {:>7.3} {:>7.3} {:>7.3} {:>7.3} {:>+8.3} {:>7.3} {:>9.3} {:>9.3}",
            pair.name,
            d.masd,
            d.assd,
            d.rms,
            d.hd,
            d.hd95,
            d.bias,
            d.surface_dice,
            d.meshdev_mean,
            d.meshdev_max
        );
        json.insert(
            pair.name.clone(),
            serde_json::to_value(d).map_err(|e| (1, e.to_string()))?,
        );
        if let Some(map) = &args.map {
            let out = if pairs.len() == 1 {
                map.clone()
            } else {
                map.with_extension(format!("{}.ply", pair.name))
            };
            let attrs = VertexAttributes {
                quality: Some(result.deviation.quality.clone()),
                colors: Some(result.deviation.colours.clone()),
            };
            let bytes = ply_bytes(&pair.test, &attrs)
                .map_err(|e| (1, format!("{}: {e}", out.display())))?;
            write_atomic(&out, &bytes).map_err(|e| (1, e.to_string()))?;
        }
    }
    let _ = writeln!(
        text,
        "(mm; Dice at {} mm; MD = MeshDev-style one-sided per-vertex test->reference)",
        args.tolerance
    );
    let notes: Vec<&str> = pairs.iter().filter_map(|p| p.note.as_deref()).collect();
    for note in &notes {
        let _ = writeln!(text, "note: {note}");
    }
    for u in &unpaired {
        let _ = writeln!(text, "unpaired: {u}");
    }
    if args.json {
        let doc = serde_json::json!({ "structures": json, "unpaired": unpaired, "notes": notes, "tolerance_mm": args.tolerance });
        return Ok(serde_json::to_string_pretty(&doc).unwrap_or_default() + "\n");
    }
    Ok(text)
}

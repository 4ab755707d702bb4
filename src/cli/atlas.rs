//! `otoatlas atlas`: build, describe and export the mechanical atlas (the embedded default or
//! an atlas folder).

use std::fmt::Write;
use std::path::{Path, PathBuf};

use clap::{Args, Subcommand};

use super::Report;
use crate::Error;
use crate::atlas::build::{DEFAULT_MEMBRANE_EDGE_MM, FINE_MEMBRANE_EDGE_MM};
use crate::atlas::export::export_atlas;
use crate::atlas::import::{ImportRequest, import_atlas};
use crate::atlas::summary::summarise;
use crate::atlas::surfaces::{SurfaceBuild, build_from_surfaces};
use crate::atlas::volume::{DEFAULT_EDGE_MM, FINE_EDGE_MM};
use crate::atlas::{Anatomy, Atlas, Part, build_atlas, load_atlas, write_atlas};
use crate::ear::Side;
use crate::progress::Reporter;

/// Build, describe or export the mechanical atlas.
#[derive(Debug, Args)]
pub struct AtlasArgs {
    #[command(subcommand)]
    pub command: AtlasCommand,
    /// Print machine-readable JSON on stdout.
    #[arg(long, global = true)]
    pub json: bool,
}

#[derive(Debug, Subcommand)]
pub enum AtlasCommand {
    /// Mesh an anatomy file, or closed bone surfaces, into an atlas folder (deterministic:
    /// same input, same bytes).
    #[command(after_help = "Examples:
  otoatlas atlas build --out assets/atlas            # the embedded default, rebuilt
  otoatlas atlas build --fine --out fine-atlas       # ~200,000 tetrahedra, a finer eardrum too")]
    Build(BuildArgs),
    /// Element counts, volumes, mesh quality, materials, boundary sets and landmarks.
    Info(SourceArgs),
    /// Write surfaces/{malleus,incus,stapes,eardrum}.ply, volume.vtu and the landmarks.
    Export(ExportArgs),
    /// Make an atlas folder from a tagged volume mesh (.vtu or .msh) and a mapping file.
    #[command(after_help = "Examples:
  otoatlas atlas import --mesh chain.vtu --labels chain_labels.txt \\
      --mapping chain.mapping.toml --landmarks chain_landmarks.json --side right --out my-atlas
The mapping file format is in docs/atlas-format.md.")]
    Import(ImportArgs),
}

#[derive(Debug, Args)]
pub struct ImportArgs {
    /// The tagged volume mesh: VTU (tags in the `region` cell array or the mapping's
    /// tag_array) or Gmsh MSH 2.2 ASCII (physical tags).
    #[arg(long, value_name = "FILE")]
    pub mesh: PathBuf,
    /// The mapping file (TOML): tag -> region, part, material, thickness; dropped tags; node
    /// sets and surfaces.
    #[arg(long, value_name = "FILE")]
    pub mapping: PathBuf,
    /// The umbo, incudomalleolar and incudostapedial landmarks in the mesh's frame (.json,
    /// .fcsv, .mrk.json or .csv).
    #[arg(long, value_name = "FILE")]
    pub landmarks: PathBuf,
    /// One integer tag per cell (tetrahedra, then triangles, in file order), replacing the
    /// mesh's own tags.
    #[arg(long, value_name = "FILE")]
    pub labels: Option<PathBuf>,
    /// The ear; default: the side the landmark file states.
    #[arg(long, value_enum)]
    pub side: Option<Side>,
    /// The atlas's name in its manifest.
    #[arg(long, default_value = "imported")]
    pub name: String,
    /// Output folder.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
}

#[derive(Debug, Args)]
pub struct SourceArgs {
    /// An atlas folder (atlas.json + mesh); default: the embedded atlas.
    #[arg(long, value_name = "DIR")]
    pub atlas: Option<PathBuf>,
    /// Mirror the atlas to this side first.
    #[arg(long, value_enum)]
    pub side: Option<Side>,
}

#[derive(Debug, Args)]
pub struct ExportArgs {
    #[command(flatten)]
    pub source: SourceArgs,
    /// Output folder.
    pub out: PathBuf,
}

#[derive(Debug, Args)]
pub struct BuildArgs {
    /// The anatomy description (TOML); default: the embedded assets/anatomy.toml.
    #[arg(long, value_name = "FILE", conflicts_with = "surfaces")]
    pub anatomy: Option<PathBuf>,
    /// Build from closed surfaces instead: DIR/{malleus,incus,stapes}.{ply,stl,obj} (bones
    /// only: no eardrum, ligaments, node sets or load surfaces).
    #[arg(long, value_name = "DIR", requires = "landmarks")]
    pub surfaces: Option<PathBuf>,
    /// With --surfaces: the three landmarks in the surfaces' frame.
    #[arg(long, value_name = "FILE", requires = "surfaces")]
    pub landmarks: Option<PathBuf>,
    /// With --surfaces: the ear (default: the side the landmark file states).
    #[arg(long, value_enum, requires = "surfaces")]
    pub side: Option<Side>,
    /// Target tetrahedron edge (mm).
    #[arg(long, value_name = "MM", default_value_t = DEFAULT_EDGE_MM, conflicts_with = "fine")]
    pub edge: f64,
    /// The fine variant: tetrahedra of 0.11 mm and eardrum triangles of 0.17 mm.
    #[arg(long)]
    pub fine: bool,
    /// Target eardrum triangle edge (mm) [default: 0.24, with --fine 0.17].
    #[arg(long, value_name = "MM")]
    pub membrane_edge: Option<f64>,
    /// The atlas's name in its manifest.
    #[arg(long, default_value = "default")]
    pub name: String,
    /// Output folder.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
}

pub fn run(args: &AtlasArgs, progress: &dyn Reporter) -> Result<Report, Error> {
    match &args.command {
        AtlasCommand::Build(b) => build(b, progress),
        AtlasCommand::Info(s) => info(s),
        AtlasCommand::Export(e) => export(e),
        AtlasCommand::Import(i) => import(i),
    }
}

fn build(args: &BuildArgs, progress: &dyn Reporter) -> Result<Report, Error> {
    let (edge, membrane_edge) = if args.fine {
        (FINE_EDGE_MM, FINE_MEMBRANE_EDGE_MM)
    } else {
        (args.edge, DEFAULT_MEMBRANE_EDGE_MM)
    };
    let membrane_edge = args.membrane_edge.unwrap_or(membrane_edge);
    for (name, v) in [("--edge", edge), ("--membrane-edge", membrane_edge)] {
        if !(v.is_finite() && (0.02..=2.0).contains(&v)) {
            return Err(Error::Usage(format!(
                "{name} {v}: expected an edge length from 0.02 to 2 mm"
            )));
        }
    }
    progress.log(&format!("atlas build: meshing at {edge} mm"));
    let atlas = match (&args.surfaces, &args.landmarks) {
        (Some(dir), Some(landmarks)) => build_from_surfaces(&SurfaceBuild {
            dir,
            landmarks,
            side: args.side,
            name: &args.name,
            edge_mm: edge,
        })?,
        _ => {
            let anatomy = match &args.anatomy {
                Some(p) => Anatomy::load(p)?,
                None => Anatomy::default_right()?,
            };
            build_atlas(&anatomy, &args.name, edge, membrane_edge)
                .map_err(crate::atlas::AtlasError::from)?
        }
    };
    write_atlas(&args.out, &atlas)?;
    wrote(&args.out, &atlas)
}

fn import(args: &ImportArgs) -> Result<Report, Error> {
    let atlas = import_atlas(&ImportRequest {
        mesh: &args.mesh,
        mapping: &args.mapping,
        landmarks: &args.landmarks,
        labels: args.labels.as_deref(),
        side: args.side,
        name: &args.name,
    })?;
    write_atlas(&args.out, &atlas)?;
    wrote(&args.out, &atlas)
}

/// The report of a command that wrote an atlas folder.
fn wrote(out: &Path, atlas: &Atlas) -> Result<Report, Error> {
    let summary = summarise(atlas);
    Ok(Report {
        text: format!(
            "wrote {}: {} tetrahedra, {} membrane triangles, {} nodes\n",
            out.display(),
            summary.tetrahedra,
            summary.membrane_triangles,
            summary.nodes
        ),
        json: serde_json::to_value(&summary).unwrap_or_default(),
    })
}

fn info(args: &SourceArgs) -> Result<Report, Error> {
    let atlas = load_atlas(args.atlas.as_deref(), args.side)?;
    let s = summarise(&atlas);
    let mut text = String::new();
    let _ = writeln!(
        text,
        "atlas '{}' ({} ear): {} nodes, {} tetrahedra, {} membrane triangles",
        s.name,
        s.side.as_str(),
        s.nodes,
        s.tetrahedra,
        s.membrane_triangles
    );
    let _ = writeln!(
        text,
        "\n{:<28} {:>5} {:>8} {:>10}  {:>7} {:>7} {:>6}  {:>10} {:>8} {:>8}",
        "region",
        "label",
        "elements",
        "size",
        "min°",
        "med°",
        "r/e",
        "E [Pa]",
        "ρ kg/m³",
        "mass mg"
    );
    for r in &s.regions {
        let m = s.materials.get(&r.material);
        let (min, med, re) = r
            .quality
            .map_or((String::new(), String::new(), String::new()), |q| {
                (
                    format!("{:.1}", q.min_dihedral_deg),
                    format!("{:.1}", q.median_min_dihedral_deg),
                    format!("{:.2}", q.median_radius_edge),
                )
            });
        let _ = writeln!(
            text,
            "{:<28} {:>5} {:>8} {:>6.3} {:<3}  {:>7} {:>7} {:>6}  {:>10.3e} {:>8.0} {:>8.3}",
            r.name,
            r.label,
            r.elements,
            r.size,
            r.unit,
            min,
            med,
            re,
            m.map_or(f64::NAN, |m| m.youngs_modulus_pa),
            m.map_or(f64::NAN, |m| m.density_kg_m3),
            r.mass_mg,
        );
    }
    let ossicles: Vec<String> = Part::BONES
        .iter()
        .filter_map(|p| {
            let o = s.ossicles.get(p.name())?;
            let shape = o
                .shape_volume_mm3
                .map_or(String::new(), |v| format!(" ({v:.2} in its shape)"));
            Some(format!(
                "{} {:.2} mm^3{shape}, {:.1} mg",
                p.name(),
                o.volume_mm3,
                o.mass_mg
            ))
        })
        .collect();
    let _ = writeln!(text, "ossicles: {}", ossicles.join("; "));
    let _ = writeln!(text, "\nboundary node sets:");
    for (k, v) in &s.node_sets {
        let _ = writeln!(text, "  {k:<40} {v} nodes");
    }
    let _ = writeln!(text, "load surfaces:");
    for (k, v) in &s.surfaces {
        let _ = writeln!(text, "  {k:<40} {v} triangles");
    }
    let _ = writeln!(text, "landmarks (mm):");
    for (k, p) in &s.landmarks {
        let _ = writeln!(text, "  {k:<16} {:8.3} {:8.3} {:8.3}", p[0], p[1], p[2]);
    }
    Ok(Report {
        text,
        json: serde_json::to_value(&s).unwrap_or_default(),
    })
}

fn export(args: &ExportArgs) -> Result<Report, Error> {
    let atlas = load_atlas(args.source.atlas.as_deref(), args.source.side)?;
    let written = export_atlas(&atlas, atlas.nodes(), &args.out)?;
    let files: Vec<String> = written
        .files
        .iter()
        .map(|p| p.display().to_string())
        .collect();
    Ok(Report {
        text: files.iter().map(|f| format!("wrote {f}\n")).collect(),
        json: serde_json::json!({ "files": files, "side": atlas.side.as_str() }),
    })
}

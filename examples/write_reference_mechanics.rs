//! `cargo run --release --example write_reference_mechanics`: writes
//! `assets/reference_mechanics.json`, the embedded default atlas's transfer function and
//! gate-pressure static curve that `run` validates packages against (rerun it whenever the default atlas changes; the test
//! `tests/mechanics_packages.rs` fails while the file is stale).

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let reference = otoatlas::pipeline::mechanics::compute_embedded_reference()?;
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/reference_mechanics.json");
    let text = serde_json::to_string_pretty(&reference)? + "\n";
    otoatlas::io_util::write_atomic(&path, text.as_bytes())?;
    println!("wrote {}", path.display());
    Ok(())
}

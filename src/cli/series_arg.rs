//! `--series`: which DICOM series to read where a folder holds several. `inspect`, `run` and
//! `landmarks` take the same flag, which the error listing a folder's series names.

use clap::Args;

#[derive(Debug, Args)]
pub struct SeriesArg {
    /// Which series to read when the DICOM folder holds several: its SeriesInstanceUID, or a
    /// prefix (at least 6 hex digits) of its SHA-256 as `otoatlas inspect` lists them.
    #[arg(long = "series", value_name = "UID_OR_HASH")]
    pub uid: Option<String>,
}

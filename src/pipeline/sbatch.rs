//! A Slurm job-array script for a cohort: each array task runs `otoatlas batch --resume` on
//! its shard (the shard comes from `SLURM_ARRAY_TASK_ID`/`SLURM_ARRAY_TASK_COUNT`), and the
//! results are merged with `otoatlas cohort-report DIR` once every task has finished.

use std::path::Path;

use crate::mechanics::Condition;

/// What the script runs.
pub struct SbatchSpec<'a> {
    /// The otoatlas executable the tasks run (absolute).
    pub exe: &'a Path,
    /// The cohort folder or manifest (absolute).
    pub cohort: &'a Path,
    /// The batch output folder (absolute).
    pub out: &'a Path,
    /// Array tasks (shards).
    pub tasks: usize,
    /// Cases at once within a task, and CPUs asked per task.
    pub jobs: usize,
    pub config: Option<&'a Path>,
    pub atlas: Option<&'a Path>,
    /// Pass `--keep-phi` to every task.
    pub keep_phi: bool,
    /// Pass `--case-memory-limit` to every task \[MiB\].
    pub case_memory_limit_mib: Option<u64>,
    /// Pass `--condition` to every task (unless normal).
    pub condition: Condition,
}

/// Quotes `text` for a POSIX shell.
fn quote(text: &str) -> String {
    format!("'{}'", text.replace('\'', r"'\''"))
}

fn quoted(path: &Path) -> String {
    quote(&path.to_string_lossy())
}

/// The script's text.
pub fn sbatch_script(spec: &SbatchSpec) -> String {
    let mut command = format!(
        "{} --quiet batch {} --out {} --jobs {} --resume",
        quoted(spec.exe),
        quoted(spec.cohort),
        quoted(spec.out),
        spec.jobs
    );
    if let Some(c) = spec.config {
        command.push_str(&format!(" --config {}", quoted(c)));
    }
    if let Some(a) = spec.atlas {
        command.push_str(&format!(" --atlas {}", quoted(a)));
    }
    if spec.keep_phi {
        command.push_str(" --keep-phi");
    }
    if let Some(mib) = spec.case_memory_limit_mib {
        command.push_str(&format!(" --case-memory-limit {mib}"));
    }
    if !spec.condition.is_normal() {
        command.push_str(&format!(" --condition {}", spec.condition.name()));
    }
    let merge = format!("{} cohort-report {}", quoted(spec.exe), quoted(spec.out));
    let logs = spec.out.join("slurm");
    format!(
        "#!/bin/bash\n\
         # otoatlas cohort as a Slurm job array: one shard of the cohort per array task.\n\
         # Submit:  sbatch THIS_FILE\n\
         # Merge when every task has finished (or submit it with --dependency=afterany:JOBID):\n\
         #   {merge}\n\
         #SBATCH --job-name=otoatlas\n\
         #SBATCH --array=0-{last}\n\
         #SBATCH --cpus-per-task={jobs}\n\
         #SBATCH --output={logs}/%A_%a.log\n\
         set -euo pipefail\n\
         exec {command}\n",
        last = spec.tasks.max(1) - 1,
        jobs = spec.jobs.max(1),
        logs = logs.to_string_lossy(),
    )
}

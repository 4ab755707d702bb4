//! Progress for long stages: indicatif bars on a terminal, plain log lines otherwise (CI, pipes,
//! batch logs). Log lines go through the same place so they never tear a bar.

use std::collections::BTreeMap;
use std::io::IsTerminal;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Mutex, OnceLock};

use indicatif::{MultiProgress, ProgressBar, ProgressDrawTarget, ProgressStyle};

static MULTI: OnceLock<MultiProgress> = OnceLock::new();
static QUIET: AtomicBool = AtomicBool::new(false);
/// Set while a cohort runs: the inner units of work of each case stay silent and each running
/// case shows one line with its stage instead.
static COHORT: AtomicBool = AtomicBool::new(false);
static CASE_LINES: Mutex<BTreeMap<String, ProgressBar>> = Mutex::new(BTreeMap::new());

fn multi() -> &'static MultiProgress {
    MULTI.get_or_init(|| {
        let target = if std::io::stderr().is_terminal() {
            ProgressDrawTarget::stderr()
        } else {
            ProgressDrawTarget::hidden()
        };
        MultiProgress::with_draw_target(target)
    })
}

fn interactive() -> bool {
    std::io::stderr().is_terminal() && !QUIET.load(Ordering::Relaxed)
}

/// Silences log lines and bars (`--quiet`).
pub fn set_quiet(quiet: bool) {
    QUIET.store(quiet, Ordering::Relaxed);
}

/// Prints one log line on stderr without tearing any active bar.
pub fn log(message: impl AsRef<str>) {
    if QUIET.load(Ordering::Relaxed) {
        return;
    }
    let line = message.as_ref();
    multi().suspend(|| eprintln!("{line}"));
}

/// A unit of long work with a known length: a bar on a terminal, or a log line at each tenth
/// of the way and at the end otherwise. Cheap to share across rayon workers.
pub struct Progress {
    bar: Option<ProgressBar>,
    /// Inside a cohort: no bar and no log lines.
    silent: bool,
    label: String,
    len: u64,
    done: AtomicU64,
    last_tenth: AtomicU64,
}

impl Progress {
    /// Starts a unit of work of `len` steps named `label`.
    pub fn new(label: impl Into<String>, len: u64) -> Progress {
        let label = label.into();
        let silent = COHORT.load(Ordering::Relaxed);
        let bar = (interactive() && !silent).then(|| {
            let bar = multi().add(ProgressBar::new(len));
            let style = ProgressStyle::with_template(
                "{prefix:>12.bold} [{bar:30}] {pos}/{len} {elapsed_precise} {msg}",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> ");
            bar.set_style(style);
            bar.set_prefix(label.clone());
            bar
        });
        Progress {
            bar,
            label,
            silent,
            len,
            done: AtomicU64::new(0),
            last_tenth: AtomicU64::new(0),
        }
    }

    /// Records `n` more steps done.
    pub fn inc(&self, n: u64) {
        let done = self.done.fetch_add(n, Ordering::Relaxed) + n;
        match &self.bar {
            Some(bar) => bar.inc(n),
            None if self.len > 0 && !self.silent => {
                let tenth = done * 10 / self.len;
                let previous = self.last_tenth.fetch_max(tenth, Ordering::Relaxed);
                if tenth > previous && tenth < 10 {
                    log(format!(
                        "{}: {}% ({done}/{})",
                        self.label,
                        tenth * 10,
                        self.len
                    ));
                }
            }
            None => {}
        }
    }

    /// Sets a short status message (shown on the bar, or logged).
    pub fn message(&self, msg: impl Into<String>) {
        let msg = msg.into();
        match &self.bar {
            Some(bar) => bar.set_message(msg),
            None if !self.silent => log(format!("{}: {msg}", self.label)),
            None => {}
        }
    }

    /// Ends the unit of work with a summary line.
    pub fn finish(&self, summary: impl AsRef<str>) {
        if let Some(bar) = &self.bar {
            bar.finish_and_clear();
        }
        if !self.silent {
            log(format!("{}: {}", self.label, summary.as_ref()));
        }
    }
}

/// The display of a running cohort: a bar over the cases and, on a terminal, one line per
/// running case showing its stage; plain log lines otherwise. Dropping it ends cohort mode.
pub struct Cohort {
    bar: Progress,
}

impl Cohort {
    /// Starts the display for `len` cases.
    pub fn start(len: u64) -> Cohort {
        let bar = Progress::new("cohort", len);
        COHORT.store(true, Ordering::Relaxed);
        Cohort { bar }
    }

    /// A case starts: it gets its line.
    pub fn case_started(&self, id: &str) {
        if interactive() {
            let line = multi().add(ProgressBar::new_spinner());
            let style = ProgressStyle::with_template("{prefix:>12} {spinner} {msg} {elapsed}")
                .unwrap_or_else(|_| ProgressStyle::default_spinner());
            line.set_style(style);
            line.set_prefix(id.to_string());
            line.enable_steady_tick(std::time::Duration::from_millis(200));
            if let Ok(mut lines) = CASE_LINES.lock() {
                lines.insert(id.to_string(), line);
            }
        }
    }

    /// A case ended with `outcome` (one line kept in the log).
    pub fn case_finished(&self, id: &str, outcome: &str) {
        if let Some(line) = CASE_LINES.lock().ok().and_then(|mut l| l.remove(id)) {
            line.finish_and_clear();
        }
        log(format!("{id}: {outcome}"));
        self.bar.inc(1);
    }
}

impl Drop for Cohort {
    fn drop(&mut self) {
        COHORT.store(false, Ordering::Relaxed);
        if let Some(bar) = &self.bar.bar {
            bar.finish_and_clear();
        }
    }
}

/// The case `id` enters `stage`: its cohort line shows it (no-op outside a cohort display).
pub fn case_stage(id: &str, stage: &str) {
    if let Some(line) = CASE_LINES.lock().ok().and_then(|l| l.get(id).cloned()) {
        line.set_message(stage.to_string());
    }
}

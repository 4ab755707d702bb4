//! Progress for long stages: indicatif bars on a terminal, plain log lines otherwise (CI, pipes,
//! batch logs). Log lines go through the same place so they never tear a bar.

use std::io::IsTerminal;
use std::sync::OnceLock;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use indicatif::{MultiProgress, ProgressBar, ProgressDrawTarget, ProgressStyle};

static MULTI: OnceLock<MultiProgress> = OnceLock::new();
static QUIET: AtomicBool = AtomicBool::new(false);

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
    label: String,
    len: u64,
    done: AtomicU64,
    last_tenth: AtomicU64,
}

impl Progress {
    /// Starts a unit of work of `len` steps named `label`.
    pub fn new(label: impl Into<String>, len: u64) -> Progress {
        let label = label.into();
        let bar = interactive().then(|| {
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
            None if self.len > 0 => {
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
            None => log(format!("{}: {msg}", self.label)),
        }
    }

    /// Ends the unit of work with a summary line.
    pub fn finish(&self, summary: impl AsRef<str>) {
        if let Some(bar) = &self.bar {
            bar.finish_and_clear();
        }
        log(format!("{}: {}", self.label, summary.as_ref()));
    }
}

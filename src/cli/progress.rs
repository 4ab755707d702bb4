//! The command line's progress display: indicatif bars on a terminal, plain log lines otherwise
//! (CI, pipes, batch logs). Log lines go through the same place so they never tear a bar.
//! During a cohort, each running case shows one line with its stage and the cases' own units
//! of work stay silent.

use std::collections::BTreeMap;
use std::io::IsTerminal;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use indicatif::{MultiProgress, ProgressBar, ProgressDrawTarget, ProgressStyle};

use crate::progress::{Reporter, Task};

/// The display on stderr.
pub struct Terminal {
    multi: MultiProgress,
    /// `--quiet`: no log lines and no bars.
    quiet: bool,
    /// stderr is a terminal (bars) rather than a log.
    interactive: bool,
    /// A cohort runs: inner units of work are silent.
    cohort: AtomicBool,
    cohort_bar: Mutex<Option<Counter>>,
    case_lines: Mutex<BTreeMap<String, ProgressBar>>,
}

impl Terminal {
    /// The display, silent with `quiet`.
    pub fn new(quiet: bool) -> Terminal {
        let interactive = std::io::stderr().is_terminal();
        let target = if interactive {
            ProgressDrawTarget::stderr()
        } else {
            ProgressDrawTarget::hidden()
        };
        Terminal {
            multi: MultiProgress::with_draw_target(target),
            quiet,
            interactive: interactive && !quiet,
            cohort: AtomicBool::new(false),
            cohort_bar: Mutex::new(None),
            case_lines: Mutex::new(BTreeMap::new()),
        }
    }

    fn counter(&self, label: &str, len: u64, silent: bool) -> Counter {
        let bar = (self.interactive && !silent).then(|| {
            let bar = self.multi.add(ProgressBar::new(len));
            let style = ProgressStyle::with_template(
                "{prefix:>12.bold} [{bar:30}] {pos}/{len} {elapsed_precise} {msg}",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> ");
            bar.set_style(style);
            bar.set_prefix(label.to_string());
            bar
        });
        Counter {
            bar,
            silent,
            label: label.to_string(),
            len,
            done: AtomicU64::new(0),
            last_tenth: AtomicU64::new(0),
        }
    }
}

impl Reporter for Terminal {
    fn log(&self, line: &str) {
        if !self.quiet {
            self.multi.suspend(|| eprintln!("{line}"));
        }
    }

    fn task(&self, label: &str, len: u64) -> Box<dyn Task + '_> {
        Box::new(Bar {
            terminal: self,
            counter: self.counter(label, len, self.cohort.load(Ordering::Relaxed)),
        })
    }

    fn case_stage(&self, id: &str, stage: &str) {
        if let Some(line) = self.case_lines.lock().ok().and_then(|l| l.get(id).cloned()) {
            line.set_message(stage.to_string());
        }
    }

    fn cohort_started(&self, cases: u64) {
        if let Ok(mut slot) = self.cohort_bar.lock() {
            *slot = Some(self.counter("cohort", cases, false));
        }
        self.cohort.store(true, Ordering::Relaxed);
    }

    fn case_started(&self, id: &str) {
        if self.interactive {
            let line = self.multi.add(ProgressBar::new_spinner());
            let style = ProgressStyle::with_template("{prefix:>12} {spinner} {msg} {elapsed}")
                .unwrap_or_else(|_| ProgressStyle::default_spinner());
            line.set_style(style);
            line.set_prefix(id.to_string());
            line.enable_steady_tick(std::time::Duration::from_millis(200));
            if let Ok(mut lines) = self.case_lines.lock() {
                lines.insert(id.to_string(), line);
            }
        }
    }

    fn case_finished(&self, id: &str, outcome: &str) {
        if let Some(line) = self.case_lines.lock().ok().and_then(|mut l| l.remove(id)) {
            line.finish_and_clear();
        }
        self.log(&format!("{id}: {outcome}"));
        if let Ok(slot) = self.cohort_bar.lock()
            && let Some(counter) = slot.as_ref()
        {
            counter.inc(1, self);
        }
    }

    fn cohort_finished(&self) {
        self.cohort.store(false, Ordering::Relaxed);
        if let Ok(mut slot) = self.cohort_bar.lock()
            && let Some(counter) = slot.take()
            && let Some(bar) = &counter.bar
        {
            bar.finish_and_clear();
        }
    }
}

/// Progress of one unit of work: a bar on a terminal, or a log line at each tenth of the way
/// otherwise. Cheap to share across rayon workers.
struct Counter {
    bar: Option<ProgressBar>,
    /// Inside a cohort: no bar and no log lines.
    silent: bool,
    label: String,
    len: u64,
    done: AtomicU64,
    last_tenth: AtomicU64,
}

impl Counter {
    fn inc(&self, n: u64, terminal: &Terminal) {
        let done = self.done.fetch_add(n, Ordering::Relaxed) + n;
        match &self.bar {
            Some(bar) => bar.inc(n),
            None if self.len > 0 && !self.silent => {
                let tenth = done * 10 / self.len;
                let previous = self.last_tenth.fetch_max(tenth, Ordering::Relaxed);
                if tenth > previous && tenth < 10 {
                    terminal.log(&format!(
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
}

/// A unit of work on the display.
struct Bar<'a> {
    terminal: &'a Terminal,
    counter: Counter,
}

impl Task for Bar<'_> {
    fn inc(&self, n: u64) {
        self.counter.inc(n, self.terminal);
    }

    fn message(&self, message: &str) {
        let c = &self.counter;
        match &c.bar {
            Some(bar) => bar.set_message(message.to_string()),
            None if !c.silent => self.terminal.log(&format!("{}: {message}", c.label)),
            None => {}
        }
    }

    fn finish(&self, summary: &str) {
        let c = &self.counter;
        if let Some(bar) = &c.bar {
            bar.finish_and_clear();
        }
        if !c.silent {
            self.terminal.log(&format!("{}: {summary}", c.label));
        }
    }
}

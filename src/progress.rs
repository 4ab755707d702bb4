//! Progress of long work as the library reports it: the caller passes in a [`Reporter`] (the
//! command line's draws bars on a terminal and plain log lines otherwise; [`Silent`] says
//! nothing), so the library itself never prints and keeps no display state.

/// Where the library reports progress.
pub trait Reporter: Sync {
    /// One line for the log (a note, a warning, a stage's outcome).
    fn log(&self, line: &str);
    /// A unit of work of `len` steps named `label`.
    fn task(&self, label: &str, len: u64) -> Box<dyn Task + '_>;
    /// Case `id` enters `stage` (a cohort display shows it on the case's line).
    fn case_stage(&self, id: &str, stage: &str) {
        let _ = (id, stage);
    }
    /// A cohort of `cases` starts: until [`Reporter::cohort_finished`], the cases' own units
    /// of work are the display's to show or not.
    fn cohort_started(&self, cases: u64) {
        let _ = cases;
    }
    /// A case of the cohort starts.
    fn case_started(&self, id: &str) {
        let _ = id;
    }
    /// A case of the cohort ended with `outcome`.
    fn case_finished(&self, id: &str, outcome: &str) {
        self.log(&format!("{id}: {outcome}"));
    }
    /// The cohort ended.
    fn cohort_finished(&self) {}
}

/// A unit of long work with a known length.
pub trait Task: Sync {
    /// `n` more steps done.
    fn inc(&self, n: u64);
    /// A short status message.
    fn message(&self, message: &str);
    /// The end, with a summary line.
    fn finish(&self, summary: &str);
}

/// Reports nothing: for library users and tests that want no output.
pub struct Silent;

impl Reporter for Silent {
    fn log(&self, _line: &str) {}

    fn task(&self, _label: &str, _len: u64) -> Box<dyn Task + '_> {
        Box::new(Silent)
    }

    fn case_finished(&self, _id: &str, _outcome: &str) {}
}

impl Task for Silent {
    fn inc(&self, _n: u64) {}

    fn message(&self, _message: &str) {}

    fn finish(&self, _summary: &str) {}
}

//! How one case of a cohort runs and how it ended ([`CaseStatus`]): in this process
//! ([`run_here`], a panic being the case's failure), or in a child process of the same
//! executable ([`run_in_child`]), so that nothing a case does (an abort on a failed
//! allocation, a segmentation fault, the kernel's out-of-memory kill) can take the cohort
//! down: such an end is that case's failure, named by its signal.
//!
//! The parent writes a [`Job`] (the case, its options and the configuration, as JSON) to the
//! child's stdin and reads events back from its stdout, one JSON line each: log lines and
//! stages for the display, then the case's [`CaseStatus`]. The child runs the case with
//! [`run_here`], the code a case runs in-process, under an optional address-space
//! limit (`RLIMIT_AS`) it sets on itself before anything else. Its stderr (where Rust writes
//! "memory allocation of N bytes failed" before aborting) is kept, its first line given as the
//! reason when the child ends without a status.

use std::ffi::OsString;
use std::io::{BufRead, BufReader, Read, Write};
use std::panic::AssertUnwindSafe;
use std::path::PathBuf;
use std::process::{Command, ExitStatus, Stdio};
use std::sync::Mutex;
use std::time::Instant;

use serde::{Deserialize, Serialize};

use super::{AutoLandmarks, Case, RunOptions, Stage, run_case};
use crate::config::Config;
use crate::mechanics::Condition;
use crate::progress::{Reporter, Silent, Task};

/// How one case of the cohort ended, as `DIR/cases/ID/status.json` records it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CaseStatus {
    pub id: String,
    pub outcome: Outcome,
    /// The error of a failed case.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
    /// Wall time of the run \[s\] (0 for a case skipped by `--resume`).
    pub seconds: f64,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Outcome {
    Ok,
    Failed,
    /// Skipped by `--resume`: the case's outputs were already complete and current.
    Resumed,
}

/// Runs `case` in this process (a case's child runs it so too) and returns how it ended; a
/// panic is the case's failure.
pub fn run_here(
    case: &Case,
    run_opts: &RunOptions,
    config: &Config,
    progress: &dyn Reporter,
) -> CaseStatus {
    let started = Instant::now();
    let result = std::panic::catch_unwind(AssertUnwindSafe(|| {
        run_case(case, run_opts, config, progress)
    }));
    let error = match result {
        Ok(Ok(_)) => None,
        Ok(Err(e)) => Some(e.to_string()),
        Err(panic) => Some(format!(
            "internal error (please report): {}",
            panic
                .downcast_ref::<String>()
                .map(String::as_str)
                .or_else(|| panic.downcast_ref::<&str>().copied())
                .unwrap_or("panic")
        )),
    };
    CaseStatus {
        id: case.id.clone(),
        outcome: if error.is_some() {
            Outcome::Failed
        } else {
            Outcome::Ok
        },
        error,
        seconds: started.elapsed().as_secs_f64(),
    }
}

/// How to start a case's child process.
#[derive(Debug, Clone)]
pub struct CaseProcess {
    /// The executable (the running one, `std::env::current_exe()`).
    pub program: PathBuf,
    /// The arguments that make it serve one job ([`serve`]) from stdin.
    pub args: Vec<OsString>,
    /// The address space each child may use \[MiB\] (`RLIMIT_AS`); none: the parent's limit.
    pub memory_limit_mib: Option<u64>,
}

/// What a child is asked to run. Paths travel as `OsString` so that a name that is not UTF-8
/// reaches the child unchanged.
#[derive(Debug, Serialize, Deserialize)]
pub struct Job {
    id: String,
    root: OsString,
    image: OsString,
    landmarks: Option<OsString>,
    segmentation: Option<OsString>,
    series: Option<String>,
    out: OsString,
    atlas: Option<OsString>,
    keep_phi: bool,
    condition: Condition,
    config: Config,
    /// Threads of the child's pool.
    threads: usize,
    memory_limit_mib: Option<u64>,
    /// The supervising process's id: the child ends with it (a batch killed with SIGKILL
    /// must not leave children writing into its output).
    parent: u32,
}

/// One line of a child's stdout.
#[derive(Debug, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
enum Event {
    Log(String),
    Stage(String),
    Status(CaseStatus),
}

/// The most of a child's stderr kept \[bytes\]; the rest is read and dropped.
const STDERR_KEPT: u64 = 64 * 1024;

/// Runs `case` from its first stage in a child process and returns how it ended. Never fails:
/// a child that cannot start, or ends without a status, is the case's failure with the reason.
pub fn run_in_child(
    process: &CaseProcess,
    case: &Case,
    run_opts: &RunOptions,
    config: &Config,
    threads: usize,
    progress: &dyn Reporter,
) -> CaseStatus {
    let job = Job {
        id: case.id.clone(),
        root: case.root.clone().into_os_string(),
        image: case.image.clone().into_os_string(),
        landmarks: case.landmarks.clone().map(PathBuf::into_os_string),
        segmentation: case.segmentation.clone().map(PathBuf::into_os_string),
        series: case.series.clone(),
        out: run_opts.out.clone().into_os_string(),
        atlas: run_opts.atlas.clone().map(PathBuf::into_os_string),
        keep_phi: run_opts.keep_phi,
        condition: run_opts.condition,
        config: config.clone(),
        threads,
        memory_limit_mib: process.memory_limit_mib,
        parent: std::process::id(),
    };
    let started = Instant::now();
    let error = match supervise(process, &job, &case.id, progress) {
        Ok(status) => return status,
        Err(reason) => reason,
    };
    CaseStatus {
        id: case.id.clone(),
        outcome: Outcome::Failed,
        error: Some(error),
        seconds: started.elapsed().as_secs_f64(),
    }
}

/// Starts the child, forwards its events and waits for it: its status, or why there is none.
fn supervise(
    process: &CaseProcess,
    job: &Job,
    id: &str,
    progress: &dyn Reporter,
) -> Result<CaseStatus, String> {
    let input = serde_json::to_vec(job).map_err(|e| format!("cannot describe the case: {e}"))?;
    let mut child = Command::new(&process.program)
        .args(&process.args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| format!("cannot start {}: {e}", process.program.display()))?;
    let (stdin, stdout, stderr) = (child.stdin.take(), child.stdout.take(), child.stderr.take());
    let (status, stderr_text) = std::thread::scope(|scope| {
        let stderr_reader = scope.spawn(move || {
            let mut text = String::new();
            if let Some(stderr) = stderr {
                let mut stderr = stderr;
                let _ = (&mut stderr).take(STDERR_KEPT).read_to_string(&mut text);
                let _ = std::io::copy(&mut stderr, &mut std::io::sink());
            }
            text
        });
        if let Some(mut stdin) = stdin {
            // a child that dies at once closes the pipe; its end is reported below
            let _ = stdin.write_all(&input);
        }
        let mut status = None;
        if let Some(stdout) = stdout {
            for line in BufReader::new(stdout).lines() {
                let Ok(line) = line else { break };
                match serde_json::from_str::<Event>(&line) {
                    Ok(Event::Log(text)) => progress.log(&text),
                    Ok(Event::Stage(stage)) => progress.case_stage(id, &stage),
                    Ok(Event::Status(s)) => status = Some(s),
                    Err(_) => {}
                }
            }
        }
        (status, stderr_reader.join().unwrap_or_default())
    });
    let ended = child
        .wait()
        .map_err(|e| format!("lost the case's process: {e}"))?;
    match status {
        Some(status) => Ok(status),
        None => Err(abnormal_end(ended, &stderr_text, process.memory_limit_mib)),
    }
}

/// Why a child ended without a status, in one line.
fn abnormal_end(ended: ExitStatus, stderr: &str, memory_limit_mib: Option<u64>) -> String {
    use std::os::unix::process::ExitStatusExt;
    let how = match (ended.signal(), ended.code()) {
        (Some(signal), _) => format!("was killed by signal {signal} ({})", signal_name(signal)),
        (None, Some(code)) => format!("ended with exit code {code} and no result"),
        (None, None) => "ended with no result".to_string(),
    };
    let mut reason = format!("the case's process {how}");
    if let Some(first) = stderr.lines().map(str::trim).find(|l| !l.is_empty()) {
        let first: String = first.chars().take(200).collect();
        reason.push_str(&format!(": {first}"));
    }
    if let Some(mib) = memory_limit_mib {
        reason.push_str(&format!(" (under --case-memory-limit {mib} MiB)"));
    }
    reason
}

/// The name and the usual cause of the signals that end a process.
fn signal_name(signal: i32) -> &'static str {
    match signal {
        4 => "SIGILL",
        6 => "SIGABRT, an abort, such as a failed memory allocation",
        7 => "SIGBUS",
        8 => "SIGFPE",
        9 => "SIGKILL, such as the kernel's out-of-memory killer",
        11 => "SIGSEGV, a segmentation fault",
        15 => "SIGTERM",
        24 => "SIGXCPU, over its CPU time limit",
        _ => "a signal",
    }
}

/// The child's side: reads one [`Job`] from `input`, sets its memory limit, runs the case
/// and writes its events and status to `output`. Returns whether it could report a status.
pub fn serve(input: impl Read, output: impl Write + Send) -> bool {
    let reporter = EventWriter {
        output: Mutex::new(output),
    };
    let mut text = Vec::new();
    let job: Job = match input
        .take(64 * 1024 * 1024)
        .read_to_end(&mut text)
        .map_err(|e| e.to_string())
        .and_then(|_| serde_json::from_slice(&text).map_err(|e| e.to_string()))
    {
        Ok(job) => job,
        Err(e) => {
            reporter.log(&format!("cannot read the case to run: {e}"));
            return false;
        }
    };
    drop(text);
    let started = Instant::now();
    let failed = |error: String| CaseStatus {
        id: job.id.clone(),
        outcome: Outcome::Failed,
        error: Some(error),
        seconds: started.elapsed().as_secs_f64(),
    };
    if let Err(e) = end_with_parent(job.parent) {
        reporter.log(&e);
        return false;
    }
    let status = match set_memory_limit(job.memory_limit_mib) {
        Err(e) => failed(format!("cannot set --case-memory-limit: {e}")),
        Ok(()) => match rayon::ThreadPoolBuilder::new()
            .num_threads(job.threads.max(1))
            .build()
        {
            Err(e) => failed(format!("cannot start the case's threads: {e}")),
            Ok(pool) => {
                let case = Case {
                    root: job.root.clone().into(),
                    id: job.id.clone(),
                    image: job.image.clone().into(),
                    landmarks: job.landmarks.clone().map(PathBuf::from),
                    segmentation: job.segmentation.clone().map(PathBuf::from),
                    series: job.series.clone(),
                };
                let run_opts = RunOptions {
                    out: job.out.clone().into(),
                    from: Stage::Ingest,
                    landmarks: None,
                    atlas: job.atlas.clone().map(PathBuf::from),
                    side: None,
                    keep_phi: job.keep_phi,
                    auto_landmarks: AutoLandmarks::WhenMissing,
                    condition: job.condition,
                };
                pool.install(|| run_here(&case, &run_opts, &job.config, &reporter))
            }
        },
    };
    reporter.send(&Event::Status(status))
}

/// Makes this process end when `parent` does (Linux `PR_SET_PDEATHSIG`): a supervisor killed
/// with SIGKILL cannot stop its children itself, and a child left running would go on
/// writing the case's output while a resumed batch writes it again. Fails if `parent` has
/// already ended.
#[cfg(target_os = "linux")]
fn end_with_parent(parent: u32) -> Result<(), String> {
    use rustix::process::{Signal, getppid, set_parent_process_death_signal};
    set_parent_process_death_signal(Some(Signal::KILL))
        .map_err(|e| format!("cannot tie the case's process to its batch: {e}"))?;
    // the parent may have ended before the signal was set: then this process was re-parented
    if getppid().map(|p| p.as_raw_pid().unsigned_abs()) != Some(parent) {
        return Err(format!(
            "the batch that started this case (process {parent}) has ended"
        ));
    }
    Ok(())
}

/// Elsewhere a child outlives a supervisor killed with SIGKILL.
#[cfg(not(target_os = "linux"))]
fn end_with_parent(_parent: u32) -> Result<(), String> {
    Ok(())
}

#[cfg(target_os = "linux")]
fn set_memory_limit(mib: Option<u64>) -> Result<(), String> {
    use rustix::process::{Resource, Rlimit, getrlimit, setrlimit};
    let Some(mib) = mib else { return Ok(()) };
    let bytes = mib.saturating_mul(1024 * 1024);
    let hard = getrlimit(Resource::As).maximum;
    let limit = Rlimit {
        current: Some(hard.map_or(bytes, |h| h.min(bytes))),
        maximum: hard,
    };
    setrlimit(Resource::As, limit).map_err(|e| e.to_string())
}

#[cfg(not(target_os = "linux"))]
fn set_memory_limit(mib: Option<u64>) -> Result<(), String> {
    match mib {
        None => Ok(()),
        Some(_) => Err("not supported on this system".into()),
    }
}

/// The child's reporter: log lines and stages as events; units of work stay silent, as they
/// do in a cohort's display.
struct EventWriter<W> {
    output: Mutex<W>,
}

impl<W: Write> EventWriter<W> {
    fn send(&self, event: &Event) -> bool {
        let Ok(mut line) = serde_json::to_vec(event) else {
            return false;
        };
        line.push(b'\n');
        self.output
            .lock()
            .is_ok_and(|mut out| out.write_all(&line).and_then(|_| out.flush()).is_ok())
    }
}

impl<W: Write + Send> Reporter for EventWriter<W> {
    fn log(&self, line: &str) {
        self.send(&Event::Log(line.to_string()));
    }

    fn task(&self, _label: &str, _len: u64) -> Box<dyn Task + '_> {
        Box::new(Silent)
    }

    fn case_stage(&self, _id: &str, stage: &str) {
        self.send(&Event::Stage(stage.to_string()));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::os::unix::process::ExitStatusExt;

    #[test]
    fn an_abnormal_end_names_the_signal_the_first_stderr_line_and_the_limit() {
        let abort = ExitStatus::from_raw(6); // killed by SIGABRT
        let reason = abnormal_end(
            abort,
            "\nmemory allocation of 1258291200 bytes failed\nstack backtrace:\n",
            Some(1536),
        );
        assert_eq!(
            reason,
            "the case's process was killed by signal 6 (SIGABRT, an abort, such as a failed \
             memory allocation): memory allocation of 1258291200 bytes failed (under \
             --case-memory-limit 1536 MiB)"
        );
        let exited = ExitStatus::from_raw(3 << 8);
        assert_eq!(
            abnormal_end(exited, "", None),
            "the case's process ended with exit code 3 and no result"
        );
    }

    #[test]
    fn events_are_one_json_line_each() {
        let writer = EventWriter {
            output: Mutex::new(Vec::new()),
        };
        writer.log("deform: 12 iterations");
        writer.case_stage("c1", "score");
        let out = writer.output.into_inner().unwrap();
        let lines: Vec<&str> = std::str::from_utf8(&out).unwrap().lines().collect();
        assert_eq!(
            lines,
            [r#"{"log":"deform: 12 iterations"}"#, r#"{"stage":"score"}"#]
        );
    }
}

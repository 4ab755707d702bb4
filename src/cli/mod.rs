//! The command line: argument definitions (clap) and the dispatch to the library. Each command
//! lives in its own file; this one only parses, runs and maps errors to exit codes.

pub mod atlas;
mod batch;
mod exit;
mod inspect;
mod landmarks;
mod out_arg;
mod package_arg;
mod phantom;
mod progress;
mod run;
mod series_arg;
mod simulate;
mod validate;
mod verify;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

use crate::Error;
use progress::Terminal;

/// otoatlas: register a validated middle-ear mechanical atlas onto a patient's cone-beam CT
/// and export a ready-to-simulate finite-element model.
#[derive(Debug, Parser)]
#[command(name = "otoatlas", version, about, long_about = None)]
#[command(after_help = "Exit codes: 0 ok, 1 a case failed, 2 bad usage, configuration or input.")]
pub struct Cli {
    /// Pipeline configuration (TOML); default: the embedded pipeline.toml.
    #[arg(long, global = true, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// No progress bars or log lines on stderr.
    #[arg(long, short, global = true)]
    pub quiet: bool,
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    Inspect(inspect::InspectArgs),
    Landmarks(landmarks::LandmarksArgs),
    Run(run::RunArgs),
    Batch(batch::BatchArgs),
    CohortReport(batch::CohortReportArgs),
    Atlas(atlas::AtlasArgs),
    Phantom(phantom::PhantomArgs),
    Validate(validate::ValidateArgs),
    Simulate(simulate::SimulateArgs),
    Verify(verify::VerifyArgs),
    /// One case of a batch, in the process `batch` starts for it.
    #[command(name = batch::CASE_COMMAND, hide = true)]
    Case(batch::CaseArgs),
}

/// What a command hands back: text for a person, JSON for a script. A JSON object with
/// `"passed": false` (a failed verdict) makes the command exit with 1 after printing.
pub struct Report {
    pub text: String,
    pub json: serde_json::Value,
}

/// Entry point of the `otoatlas` binary.
pub fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            let code = if e.use_stderr() { 2 } else { 0 };
            let _ = e.print();
            return ExitCode::from(code);
        }
    };
    // The command runs on rayon's workers rather than beside them. Called from outside its
    // pool, every parallel loop hands its work over and the calling thread sleeps until it is
    // done: on two cores, the many short loops of the registration made 46,000 context
    // switches and took a quarter of the deformable stage (BENCHMARKS.md, "The command on
    // rayon's workers"). Without a pool (threads refused), the command runs as it is.
    match rayon::ThreadPoolBuilder::new().build() {
        Ok(pool) => pool.install(|| execute(&cli)),
        Err(_) => execute(&cli),
    }
}

/// Runs the parsed command and maps its outcome to the exit code.
fn execute(cli: &Cli) -> ExitCode {
    let json = match &cli.command {
        Command::Inspect(a) => a.json,
        Command::Landmarks(a) => a.json,
        Command::Atlas(a) => a.json,
        Command::Run(a) => a.json,
        Command::Batch(a) => a.json,
        Command::CohortReport(a) => a.json,
        Command::Phantom(a) => a.json,
        Command::Validate(a) => a.json,
        Command::Simulate(a) => a.json,
        Command::Verify(a) => a.json,
        Command::Case(_) => false,
    };
    let terminal = Terminal::new(cli.quiet);
    let result = match &cli.command {
        Command::Inspect(a) => inspect::run(a, cli.config.as_deref(), &terminal),
        Command::Landmarks(a) => landmarks::run(a, cli.config.as_deref(), &terminal),
        Command::Atlas(a) => atlas::run(a, &terminal),
        Command::Run(a) => run::run(a, cli.config.as_deref(), &terminal),
        Command::Batch(a) => batch::run(a, cli.config.as_deref(), &terminal),
        Command::CohortReport(a) => batch::cohort_report(a),
        Command::Phantom(a) => phantom::run(a, &terminal),
        Command::Validate(a) => validate::run(a, &terminal),
        Command::Simulate(a) => simulate::run(a),
        Command::Verify(a) => verify::run(a),
        Command::Case(a) => return batch::case(a),
    };
    match result {
        Ok(report) => {
            if json {
                let body = serde_json::to_string_pretty(&report.json).unwrap_or_default();
                print_stdout(&format!("{body}\n"));
            } else {
                print_stdout(&report.text);
            }
            // a report that carries a verdict which failed is a failed case
            if report.json.get("passed") == Some(&serde_json::Value::Bool(false)) {
                ExitCode::from(exit::ExitStatus::CaseFailed as u8)
            } else {
                ExitCode::SUCCESS
            }
        }
        Err(err) => fail(&err, json),
    }
}

fn fail(err: &Error, json: bool) -> ExitCode {
    let code = exit::exit_status(err) as u8;
    if json {
        let body = serde_json::json!({ "error": err.to_string(), "exit_code": code });
        let body = serde_json::to_string_pretty(&body).unwrap_or_default();
        print_stdout(&format!("{body}\n"));
    }
    eprintln!("error: {err}");
    ExitCode::from(code)
}

/// Writes to stdout, ignoring a closed pipe (`otoatlas inspect x | head` must not panic).
fn print_stdout(text: &str) {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    let _ = out.write_all(text.as_bytes()).and_then(|_| out.flush());
}

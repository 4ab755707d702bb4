//! The `otoatlas` command: parse the command line, call the library, map errors to exit codes.

fn main() -> std::process::ExitCode {
    otoatlas::cli::main()
}

//! The binary's error type: the exit code follows docs/cli.md (2 bad usage or input, 1 runtime).

use std::fmt;

/// The exit status of a refused input (a bad flag, file or value): `error: …` on stderr.
pub const BAD_INPUT_EXIT: u8 = 2;

/// What went wrong, and whose fault it was.
#[derive(Debug)]
pub enum CliError {
    /// Bad flags, files, specs or databases: exit 2.
    Input(String),
    /// Anything else: exit 1.
    Runtime(String),
}

impl CliError {
    pub fn input(what: impl fmt::Display) -> Self {
        CliError::Input(what.to_string())
    }
    pub fn runtime(what: impl fmt::Display) -> Self {
        CliError::Runtime(what.to_string())
    }
    pub fn exit_code(&self) -> u8 {
        match self {
            CliError::Input(_) => BAD_INPUT_EXIT,
            CliError::Runtime(_) => 1,
        }
    }
}

impl fmt::Display for CliError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CliError::Input(s) | CliError::Runtime(s) => f.write_str(s),
        }
    }
}

impl std::error::Error for CliError {}

pub type CliResult<T = ()> = Result<T, CliError>;

impl From<risktwin_store::library::LibraryError> for CliError {
    /// A library file at fault (not a library, a wrong schema, a damaged page, a stored value
    /// out of its range) is bad input, exit 2; anything else (I/O, a lock) a runtime failure.
    fn from(e: risktwin_store::library::LibraryError) -> Self {
        if e.blames_the_file() { CliError::input(e) } else { CliError::runtime(e) }
    }
}

impl From<risktwin_bench::BenchError> for CliError {
    /// A benchmark's bad input exits 2, anything else 1.
    fn from(e: risktwin_bench::BenchError) -> Self {
        match e {
            risktwin_bench::BenchError::Input(what) => CliError::Input(what),
            risktwin_bench::BenchError::Runtime(what) => CliError::Runtime(what),
        }
    }
}

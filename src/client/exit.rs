//! The exit codes of a client command, the contract a CI step reads.

use std::process::ExitCode;

/// How a client command ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Exit {
    /// 0: the work succeeded (and kept every threshold given).
    Succeeded,
    /// 1: a run failed, diverged or was cancelled, or a sweep crossed a threshold; the result,
    /// if there is one, is still written.
    RunFailed,
    /// 2: the scene or sweep is not valid (the server's problem is printed field by field), or
    /// the command line is not.
    BadInput,
    /// 3: the server could not be reached, or refused the work (401, 403, 429, 503, ...).
    Unavailable,
}

impl Exit {
    /// The process exit status.
    pub fn code(self) -> u8 {
        match self {
            Self::Succeeded => 0,
            Self::RunFailed => 1,
            Self::BadInput => 2,
            Self::Unavailable => 3,
        }
    }
}

impl From<Exit> for ExitCode {
    fn from(exit: Exit) -> Self {
        ExitCode::from(exit.code())
    }
}

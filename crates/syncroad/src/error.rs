//! The one error funnel: commands return a [`Status`] or an error; only `main` turns them into
//! exit codes (see [`crate::exit_codes`]).

/// An error caused by the user's input (exit code 2). Its source, when there is one, keeps the
/// cause chain (`{:#}` prints it).
#[derive(Debug, thiserror::Error)]
#[error("{message}")]
pub struct InputError {
    message: String,
    #[source]
    source: Option<Box<dyn std::error::Error + Send + Sync + 'static>>,
}

impl InputError {
    /// An input error with a message of its own.
    pub fn new(message: impl Into<String>) -> Self {
        Self {
            message: message.into(),
            source: None,
        }
    }

    /// An input error that says where (`context`), with the library's error as its cause.
    pub fn caused(
        context: impl Into<String>,
        source: impl std::error::Error + Send + Sync + 'static,
    ) -> Self {
        Self {
            message: context.into(),
            source: Some(Box::new(source)),
        }
    }
}

/// How a command ended, when it did not fail.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Status {
    /// Synchronized, certified, every run completed, the regression check passed.
    Success,
    /// Not synchronized or inconclusive; not certified; a regression.
    NotSynchronized,
    /// A run failed part-way (its partial results are written).
    RunFailed,
    /// Interrupted by the user (partial results are written).
    Interrupted,
}

impl Status {
    /// Success when `ok`, else "not synchronized".
    pub fn verdict(ok: bool) -> Self {
        if ok {
            Status::Success
        } else {
            Status::NotSynchronized
        }
    }
}

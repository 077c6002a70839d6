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

    /// An input error about `field`: the library's error as it is when its message already
    /// names the field (no `field: field = …` twice), else with the field before it.
    pub fn about(field: &str, source: impl std::error::Error + Send + Sync + 'static) -> Self {
        if source.to_string().starts_with(field) {
            Self::new(source.to_string())
        } else {
            Self::caused(field, source)
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
    /// The command did its job and what it checks held: synchronized, certified, every run
    /// completed (and none matched `--fail-on`), the regression check passed; or it checks
    /// nothing (an open road without vehicles of its own ran to its end).
    Success,
    /// What the command checks did not hold: not synchronized or inconclusive; not
    /// certified; a run matched `--fail-on`; a regression.
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

/// An error and its causes on one line, `outer: cause: cause`, like `{:#}`, except that a cause
/// whose text the line already ends with is not repeated (library errors that print their
/// source in their own message, as `thiserror`'s `{0}` with `#[from]` does).
pub fn describe(err: &anyhow::Error) -> String {
    let mut line = String::new();
    for cause in err.chain() {
        let text = cause.to_string();
        if line.ends_with(&text) {
            continue;
        }
        if !line.is_empty() {
            line.push_str(": ");
        }
        line.push_str(&text);
    }
    line
}

/// Why an output folder cannot be created: a path that names no possible folder (a name over
/// the file system's limit, a file on the way, no permission, a read-only file system) is the
/// user's to change (exit 2); anything else is a failure of the run.
pub(crate) fn folder_error(flag: &str, dir: &std::path::Path, e: std::io::Error) -> anyhow::Error {
    // A link whose target is missing is no file: say what it is.
    if let Ok(target) = std::fs::read_link(dir) {
        if !dir.exists() {
            return InputError::new(format!(
                "{flag} = {}: cannot create the output folder: it is a symbolic link to {}, which does not exist; create that folder or choose another {flag}",
                dir.display(),
                target.display()
            ))
            .into();
        }
    }
    let why = match e.raw_os_error() {
        Some(libc::ENAMETOOLONG) => {
            Some("a name in it is longer than the file system allows (255 bytes per name)")
        }
        Some(libc::ENOTDIR) => Some("a part of it is a file, not a folder"),
        Some(libc::EEXIST) => Some("it is an existing file (or device), not a folder"),
        Some(libc::EACCES) | Some(libc::EPERM) => Some("permission denied"),
        Some(libc::EROFS) => Some("the file system is read-only"),
        _ => None,
    };
    match why {
        Some(why) => InputError::new(format!(
            "{flag} = {}: cannot create the output folder: {why}; choose another {flag}",
            dir.display()
        ))
        .into(),
        None => anyhow::Error::new(e).context(format!(
            "{flag} = {}: cannot create the output folder",
            dir.display()
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, thiserror::Error)]
    #[error("inner fault")]
    struct Inner;

    #[derive(Debug, thiserror::Error)]
    #[error("outer: {0}")]
    struct Outer(#[from] Inner);

    #[test]
    fn a_cause_is_printed_once() {
        let e = anyhow::Error::new(Outer(Inner)).context("scenario x.json");
        assert_eq!(
            format!("{e:#}"),
            "scenario x.json: outer: inner fault: inner fault"
        );
        assert_eq!(describe(&e), "scenario x.json: outer: inner fault");
        let plain = anyhow::Error::new(Inner).context("a").context("b");
        assert_eq!(describe(&plain), "b: a: inner fault");
    }

    #[test]
    fn an_error_about_a_field_names_it_once() {
        let named = InputError::about("--baselines", Inner);
        assert_eq!(
            format!("{:#}", anyhow::Error::new(named)),
            "--baselines: inner fault"
        );
        #[derive(Debug, thiserror::Error)]
        #[error("--baselines = x: unknown driver")]
        struct Own;
        let own = InputError::about("--baselines", Own);
        assert_eq!(own.to_string(), "--baselines = x: unknown driver");
    }
}

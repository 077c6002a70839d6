//! `--fail-on`: what makes a comparison or a sweep exit 1, for CI.
//!
//! A comparison or a sweep that ran every run to its end did its job and exits 0 whatever the
//! runs found: finding that a driver jams or collides is a result, not a failure. A CI job
//! that must stop on such a finding says which with `--fail-on unsafe,not-synchronized`; the
//! command then names every run that matched on stderr and exits 1 (what it checks did not
//! hold). Failed runs stay exit 3 and take precedence.

use crate::error::Status;

/// A finding a comparison or a sweep can gate on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, clap::ValueEnum)]
pub enum FailOn {
    /// A run judged unsafe (collisions, overlaps, teleports or emergency braking:
    /// `safe = false`). A run with no safety judgement does not match.
    Unsafe,
    /// A run whose verdict is `not_synchronized`.
    NotSynchronized,
    /// A run whose verdict is `inconclusive`.
    Inconclusive,
}

impl FailOn {
    /// The words of the stderr line.
    fn words(self) -> &'static str {
        match self {
            FailOn::Unsafe => "unsafe",
            FailOn::NotSynchronized => "not synchronized",
            FailOn::Inconclusive => "inconclusive",
        }
    }

    /// Whether a run with this verdict (`synchronized`, `not_synchronized`, `inconclusive`)
    /// and safety judgement matches.
    fn matches(self, verdict: Option<&str>, safe: Option<bool>) -> bool {
        match self {
            FailOn::Unsafe => safe == Some(false),
            FailOn::NotSynchronized => verdict == Some("not_synchronized"),
            FailOn::Inconclusive => verdict == Some("inconclusive"),
        }
    }
}

/// One judged run: its name, its verdict and its safety.
pub struct Judged<'a> {
    /// The run's name (a compare run, a sweep point's number and values).
    pub name: String,
    /// `sync.verdict` as the record writes it.
    pub verdict: Option<&'a str>,
    /// `safe`; `None` when the run could not be judged.
    pub safe: Option<bool>,
}

/// Exit 1 when a run matches one of `on` (each finding named on stderr, with up to 20 runs),
/// else success.
pub fn judge<'a>(on: &[FailOn], runs: impl IntoIterator<Item = Judged<'a>>) -> Status {
    let runs: Vec<Judged<'a>> = runs.into_iter().collect();
    let mut on = on.to_vec();
    on.sort();
    on.dedup();
    let mut hit = false;
    for f in on {
        let names: Vec<&str> = runs
            .iter()
            .filter(|r| f.matches(r.verdict, r.safe))
            .map(|r| r.name.as_str())
            .collect();
        if names.is_empty() {
            continue;
        }
        hit = true;
        let more = names.len().saturating_sub(20);
        crate::stdout::errln!(
            "fail-on {}: {} of {} runs: {}{}",
            f.words(),
            names.len(),
            runs.len(),
            names[..names.len() - more].join(", "),
            if more > 0 {
                format!(" and {more} more")
            } else {
                String::new()
            }
        );
    }
    Status::verdict(!hit)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(name: &str, verdict: &'static str, safe: Option<bool>) -> Judged<'static> {
        Judged {
            name: name.to_string(),
            verdict: Some(verdict),
            safe,
        }
    }

    #[test]
    fn only_the_findings_asked_for_fail() {
        let runs = || {
            vec![
                run("a", "synchronized", Some(true)),
                run("b", "not_synchronized", Some(true)),
                run("c", "inconclusive", None),
            ]
        };
        assert_eq!(judge(&[], runs()), Status::Success);
        assert_eq!(judge(&[FailOn::Unsafe], runs()), Status::Success);
        assert_eq!(
            judge(&[FailOn::NotSynchronized], runs()),
            Status::NotSynchronized
        );
        assert_eq!(
            judge(&[FailOn::Inconclusive], runs()),
            Status::NotSynchronized
        );
        let mut unsafe_runs = runs();
        unsafe_runs[0].safe = Some(false);
        assert_eq!(
            judge(&[FailOn::Unsafe], unsafe_runs),
            Status::NotSynchronized
        );
    }
}

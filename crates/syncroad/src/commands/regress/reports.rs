//! The regression check for CI pages: JUnit XML (one test case per metric and per stamp) and a
//! Markdown summary.

use std::path::Path;

use std::collections::BTreeMap;
use std::fmt::Write as _;

use quick_junit::{NonSuccessKind, Report, TestCase, TestCaseStatus, TestSuite};

use super::{Comparison, Failure};

/// Where `regress` reports besides stdout, and whether stamps must match.
#[derive(Debug, Clone, Default)]
pub struct Reports {
    /// `--junit FILE`.
    pub junit: Option<std::path::PathBuf>,
    /// `--markdown FILE`.
    pub markdown: Option<std::path::PathBuf>,
    /// `--strict`: a stamp mismatch fails.
    pub strict: bool,
}

/// The comparison as JUnit XML (written by `quick-junit`): one test case per metric, and one
/// per stamp (failing only with `strict`).
pub fn junit(c: &Comparison, baseline: &Path, strict: bool) -> anyhow::Result<String> {
    let suite_name = baseline.display().to_string();
    let failed: BTreeMap<&str, &Failure> = c.failures.iter().map(|f| (f.key.as_str(), f)).collect();
    let mut suite = TestSuite::new(suite_name.as_str());
    for k in &c.keys {
        let status = match failed.get(k.as_str()) {
            None => TestCaseStatus::success(),
            Some(f) => {
                let mut st = TestCaseStatus::non_success(NonSuccessKind::Failure);
                st.set_message(f.why.as_str())
                    .set_description(format!("baseline {} fresh {}", f.base, f.fresh));
                st
            }
        };
        let mut case = TestCase::new(k.as_str(), status);
        case.set_classname(suite_name.as_str());
        suite.add_test_case(case);
    }
    for n in &c.stamp_notes {
        let key = n.split(':').next().unwrap_or(n);
        let mut case = if strict {
            let mut st = TestCaseStatus::non_success(NonSuccessKind::Failure);
            st.set_message("recorded on another version or platform (--strict)")
                .set_description(n.as_str());
            TestCase::new(format!("stamp.{key}"), st)
        } else {
            let mut case = TestCase::new(format!("stamp.{key}"), TestCaseStatus::success());
            case.set_system_out(n.as_str());
            case
        };
        case.set_classname(suite_name.as_str());
        suite.add_test_case(case);
    }
    let mut report = Report::new("syncroad regress");
    report.add_test_suite(suite);
    Ok(report.to_string()?)
}

fn md_cell(s: &str) -> String {
    s.replace('|', "\\|").replace('\n', " ")
}

/// The comparison as a Markdown summary for a CI job page.
pub fn markdown(c: &Comparison, baseline: &Path, strict: bool) -> String {
    let pass = c.failures.is_empty() && (!strict || c.stamp_notes.is_empty());
    let mut s = String::new();
    let _ = writeln!(
        s,
        "### syncroad regress `{}`: {}\n",
        baseline.display(),
        if pass { "PASS" } else { "FAIL" }
    );
    let _ = writeln!(
        s,
        "{} metrics compared, {} outside their tolerance.\n",
        c.compared,
        c.failures.len()
    );
    if !c.stamp_notes.is_empty() {
        let _ = writeln!(
            s,
            "Recorded on another version or platform{}:\n",
            if strict {
                " (fails with --strict)"
            } else {
                " (compared with the stated tolerances)"
            }
        );
        for n in &c.stamp_notes {
            let _ = writeln!(s, "- {}", md_cell(n));
        }
        s.push('\n');
    }
    if !c.failures.is_empty() {
        s.push_str("| metric | baseline | fresh | why |\n|---|---:|---:|---|\n");
        for f in &c.failures {
            let _ = writeln!(
                s,
                "| `{}` | {} | {} | {} |",
                f.key,
                md_cell(&f.base),
                md_cell(&f.fresh),
                md_cell(&f.why)
            );
        }
    }
    s
}

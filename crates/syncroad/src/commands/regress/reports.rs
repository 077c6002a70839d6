//! The regression check for CI pages: JUnit XML (one test case per metric and per stamp) and a
//! Markdown summary.

use std::path::Path;

use std::collections::BTreeMap;
use std::fmt::Write as _;

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

fn xml_escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for ch in s.chars() {
        match ch {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            c if (c as u32) < 0x20 && !matches!(c, '\n' | '\t' | '\r') => {}
            c => out.push(c),
        }
    }
    out
}

/// The comparison as JUnit XML: one test case per metric, and one per stamp (failing only
/// with `strict`).
pub fn junit(c: &Comparison, baseline: &Path, strict: bool) -> String {
    let suite = xml_escape(&baseline.display().to_string());
    let failed: BTreeMap<&str, &Failure> = c.failures.iter().map(|f| (f.key.as_str(), f)).collect();
    let stamp_failures = if strict { c.stamp_notes.len() } else { 0 };
    let mut s = String::from("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
    let _ = writeln!(
        s,
        "<testsuites name=\"syncroad regress\" tests=\"{}\" failures=\"{}\">",
        c.keys.len() + c.stamp_notes.len(),
        c.failures.len() + stamp_failures
    );
    let _ = writeln!(
        s,
        "  <testsuite name=\"{suite}\" tests=\"{}\" failures=\"{}\">",
        c.keys.len() + c.stamp_notes.len(),
        c.failures.len() + stamp_failures
    );
    for k in &c.keys {
        let name = xml_escape(k);
        match failed.get(k.as_str()) {
            None => {
                let _ = writeln!(s, "    <testcase classname=\"{suite}\" name=\"{name}\"/>");
            }
            Some(f) => {
                let _ = writeln!(
                    s,
                    "    <testcase classname=\"{suite}\" name=\"{name}\">\n      <failure message=\"{}\">baseline {} fresh {}</failure>\n    </testcase>",
                    xml_escape(&f.why),
                    xml_escape(&f.base),
                    xml_escape(&f.fresh)
                );
            }
        }
    }
    for n in &c.stamp_notes {
        let key = n.split(':').next().unwrap_or(n);
        let name = xml_escape(&format!("stamp.{key}"));
        let body = if strict {
            format!(
                "<failure message=\"recorded on another version or platform (--strict)\">{}</failure>",
                xml_escape(n)
            )
        } else {
            format!("<system-out>{}</system-out>", xml_escape(n))
        };
        let _ = writeln!(
            s,
            "    <testcase classname=\"{suite}\" name=\"{name}\">\n      {body}\n    </testcase>"
        );
    }
    s.push_str("  </testsuite>\n</testsuites>\n");
    s
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

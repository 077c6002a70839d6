//! Every command example of the user guide (`docs/src/*.md`) and of `README.md` runs as printed.
//!
//! The convention (documented in `docs/src/architecture.md`, "Command examples"):
//! * a command example is a fenced block of language `console`; `sh`, `bash` and `shell` blocks
//!   are refused, so no command can slip past this test;
//! * a line starting with `$ ` is a command (a line ending in `\` continues it); it runs in
//!   bash, in a scratch folder that links the repository's top-level entries (so `out/` and
//!   `jobs/` are the scratch folder's own), with `target/release` first on `PATH`, so
//!   `syncroad` is the binary under test. The blocks of one page run in order in one folder,
//!   so a later example can read what an earlier one wrote;
//! * the lines after a command, up to the next `$ `, are its output as the page shows it: each
//!   must match a whole line of what the command printed (stdout and stderr), in order; `...`
//!   inside a line matches any text, a line of only `...` stands for lines left out;
//! * every command must exit 0, except the last of a block preceded by
//!   `<!-- example exit=N -->`; `<!-- example test-args: ARGS -->` appends ARGS to the block's
//!   last command (the page must say so beside it); `<!-- example not-run: REASON -->` skips the
//!   block and needs a reason. `timeout=S` (default 900 s) bounds each command of a block;
//!   `table` says that the Markdown table right after the block (blank lines between allowed)
//!   is the last command's output too, so the rendered table is checked row by row.
//!
//! One test per page, so the pages run in parallel; `every_page_is_checked` fails when a page
//! of `docs/src` is not in the list. Each command's wall time is printed (`--nocapture`).

mod common;

use std::fs::File;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::repo;
use pulldown_cmark::{CodeBlockKind, Event, Parser, Tag, TagEnd};

/// What the comment before a block says about how to test it.
#[derive(Debug, Default, Clone, PartialEq)]
struct Directive {
    exit: i32,
    table: bool,
    test_args: Option<String>,
    not_run: Option<String>,
    timeout_s: u64,
}

/// One `$ ` command of a block with the output lines the page shows after it.
#[derive(Debug, Clone, PartialEq)]
struct Step {
    command: String,
    expected: Vec<String>,
}

/// One ```console block.
#[derive(Debug, Clone)]
struct Example {
    line: usize,
    directive: Directive,
    steps: Vec<Step>,
}

const DEFAULT_TIMEOUT_S: u64 = 900;

fn parse_directive(html: &str) -> Result<Option<Directive>, String> {
    let t = html.trim();
    let Some(body) = t.strip_prefix("<!--").and_then(|b| b.strip_suffix("-->")) else {
        return Ok(None);
    };
    let Some(mut rest) = body.trim().strip_prefix("example") else {
        return Ok(None);
    };
    let mut d = Directive {
        timeout_s: DEFAULT_TIMEOUT_S,
        ..Directive::default()
    };
    loop {
        rest = rest.trim_start();
        if rest.is_empty() {
            return Ok(Some(d));
        }
        if let Some(reason) = rest.strip_prefix("not-run:") {
            let reason = reason.trim();
            if reason.is_empty() {
                return Err(format!("`{t}`: not-run needs a reason"));
            }
            d.not_run = Some(reason.to_string());
            return Ok(Some(d));
        }
        if let Some(args) = rest.strip_prefix("test-args:") {
            d.test_args = Some(args.trim().to_string());
            return Ok(Some(d));
        }
        let end = rest.find(char::is_whitespace).unwrap_or(rest.len());
        let (word, tail) = rest.split_at(end);
        if word == "table" {
            d.table = true;
            rest = tail;
            continue;
        }
        match word.split_once('=') {
            Some(("exit", v)) => d.exit = v.parse().map_err(|_| format!("`{t}`: exit={v}"))?,
            Some(("timeout", v)) => {
                d.timeout_s = v.parse().map_err(|_| format!("`{t}`: timeout={v}"))?
            }
            _ => {
                return Err(format!(
                "`{t}`: unknown `{word}` (valid: exit=N, timeout=S, table, test-args: ARGS, not-run: REASON)"
            ))
            }
        }
        rest = tail;
    }
}

fn parse_steps(body: &str) -> Result<Vec<Step>, String> {
    let mut steps: Vec<Step> = Vec::new();
    let mut continuing = false;
    for line in body.lines() {
        if continuing {
            let step = steps.last_mut().unwrap();
            step.command.push('\n');
            step.command.push_str(line);
            continuing = line.ends_with('\\');
        } else if let Some(cmd) = line.strip_prefix("$ ") {
            steps.push(Step {
                command: cmd.to_string(),
                expected: Vec::new(),
            });
            continuing = line.ends_with('\\');
        } else if let Some(step) = steps.last_mut() {
            step.expected.push(line.trim_end().to_string());
        } else if !line.trim().is_empty() {
            return Err(format!("output before any `$ ` command: `{line}`"));
        }
    }
    if steps.is_empty() {
        return Err("a console block without a `$ ` command".into());
    }
    Ok(steps)
}

/// The console blocks of one page, with the line each starts on.
fn examples(text: &str) -> Result<Vec<Example>, String> {
    let line_of = |offset: usize| text[..offset].matches('\n').count() + 1;
    let mut out = Vec::new();
    let mut pending: Option<(usize, Directive)> = None;
    let mut current: Option<(usize, String, String)> = None;
    for (event, range) in Parser::new(text).into_offset_iter() {
        match event {
            Event::Start(Tag::CodeBlock(CodeBlockKind::Fenced(info))) => {
                let lang = info.split([',', ' ']).next().unwrap_or("").to_string();
                current = Some((line_of(range.start), lang, String::new()));
            }
            Event::Text(t) if current.is_some() => current.as_mut().unwrap().2.push_str(&t),
            Event::End(TagEnd::CodeBlock) => {
                let Some((line, lang, body)) = current.take() else {
                    continue;
                };
                let directive = pending.take().map(|(_, d)| d);
                match lang.as_str() {
                    "sh" | "bash" | "shell" | "zsh" | "shell-session" => {
                        return Err(format!(
                            "line {line}: a ```{lang} block; write commands as ```console with `$ ` lines so they are tested"
                        ))
                    }
                    "console" => {
                        let mut steps =
                            parse_steps(&body).map_err(|e| format!("line {line}: {e}"))?;
                        if directive.as_ref().is_some_and(|d| d.table) {
                            let rows = table_after(&text[range.end..]);
                            if rows.is_empty() {
                                return Err(format!("line {line}: `table`, but no table follows the block"));
                            }
                            steps.last_mut().unwrap().expected.extend(rows);
                        }
                        let directive = directive.unwrap_or(Directive {
                            timeout_s: DEFAULT_TIMEOUT_S,
                            ..Directive::default()
                        });
                        out.push(Example {
                            line,
                            directive,
                            steps,
                        });
                    }
                    _ if directive.is_some() => {
                        return Err(format!("line {line}: an example directive before a ```{lang} block"))
                    }
                    _ => {}
                }
            }
            Event::Html(h) | Event::InlineHtml(h) => {
                if let Some(d) = parse_directive(&h)
                    .map_err(|e| format!("line {}: {e}", line_of(range.start)))?
                {
                    pending = Some((line_of(range.start), d));
                }
            }
            Event::Start(Tag::HtmlBlock) => {}
            Event::Start(_) | Event::Text(_) => {
                if let Some((line, _)) = pending.take() {
                    return Err(format!(
                        "line {line}: an example directive not directly above a ```console block"
                    ));
                }
            }
            _ => {}
        }
    }
    if let Some((line, _)) = pending {
        return Err(format!(
            "line {line}: an example directive at the end of the page"
        ));
    }
    Ok(out)
}

/// The rows of the Markdown table that starts after blank lines at the beginning of `rest`.
fn table_after(rest: &str) -> Vec<String> {
    rest.lines()
        .skip_while(|l| l.trim().is_empty())
        .take_while(|l| l.starts_with('|'))
        .map(|l| l.trim_end().to_string())
        .collect()
}

/// Whether `actual` matches `pattern`, where `...` stands for any text.
fn line_matches(pattern: &str, actual: &str) -> bool {
    let pieces: Vec<&str> = pattern.split("...").collect();
    if pieces.len() == 1 {
        return pattern == actual;
    }
    let (first, last) = (pieces[0], pieces[pieces.len() - 1]);
    if !actual.starts_with(first) || actual.len() < first.len() + last.len() {
        return false;
    }
    let mut rest = &actual[first.len()..];
    for piece in &pieces[1..pieces.len() - 1] {
        match rest.find(piece) {
            Some(i) => rest = &rest[i + piece.len()..],
            None => return false,
        }
    }
    rest.ends_with(last)
}

/// The first expected line (with its number) that has no match, in order, in `output`.
fn first_unmatched<'a>(expected: &'a [String], output: &str) -> Option<&'a str> {
    let mut lines = output.lines().map(str::trim_end);
    expected
        .iter()
        .filter(|e| e.trim() != "..." && !e.trim().is_empty())
        .find(|e| !lines.any(|a| line_matches(e, a)))
        .map(String::as_str)
}

/// A scratch folder linking every top-level entry of the repository but `out`, `jobs`,
/// `target` and `.git`.
fn scratch(page: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("syncroad-guide-{}-{page}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let root = repo().canonicalize().unwrap();
    for e in std::fs::read_dir(&root).unwrap().flatten() {
        let name = e.file_name();
        if ["out", "jobs", "target", ".git"].iter().any(|n| name == *n) {
            continue;
        }
        std::os::unix::fs::symlink(e.path(), dir.join(&name)).unwrap();
    }
    dir
}

/// Runs one command in bash in `dir`: (exit code, stdout and stderr as written, wall time).
fn run_step(dir: &Path, command: &str, timeout: Duration) -> (i32, String, Duration) {
    let bin_dir = Path::new(env!("CARGO_BIN_EXE_syncroad")).parent().unwrap();
    let path = format!(
        "{}:{}",
        bin_dir.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let log = dir.join(".example-output");
    let file = File::create(&log).unwrap();
    let start = Instant::now();
    let mut child = std::os::unix::process::CommandExt::process_group(
        Command::new("bash")
            .args(["-o", "pipefail", "-c", command])
            .current_dir(dir)
            .env("PATH", path)
            .stdin(Stdio::null())
            .stdout(file.try_clone().unwrap())
            .stderr(file),
        0,
    )
    .spawn()
    .expect("bash runs");
    let code = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status.code().unwrap_or(-1);
        }
        if start.elapsed() > timeout {
            // SAFETY: kill(2) on the process group this test created for the command.
            unsafe { libc::kill(-(child.id() as i32), libc::SIGKILL) };
            let _ = child.wait();
            break -2;
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let output = String::from_utf8_lossy(&std::fs::read(&log).unwrap()).into_owned();
    (code, output, start.elapsed())
}

/// Runs every example of one page; panics with every failure.
fn check_page(rel: &str) {
    let text = std::fs::read_to_string(repo().join(rel)).unwrap();
    let examples = examples(&text).unwrap_or_else(|e| panic!("{rel}: {e}"));
    let page = rel.replace(['/', '.'], "-");
    let dir = scratch(&page);
    let mut failures = Vec::new();
    for ex in &examples {
        if let Some(reason) = &ex.directive.not_run {
            eprintln!("{rel}:{}: not run: {reason}", ex.line);
            continue;
        }
        for (i, step) in ex.steps.iter().enumerate() {
            let last = i + 1 == ex.steps.len();
            let mut command = step.command.clone();
            if let (true, Some(args)) = (last, &ex.directive.test_args) {
                command = format!("{command} {args}");
            }
            let want = if last { ex.directive.exit } else { 0 };
            let timeout = Duration::from_secs(ex.directive.timeout_s);
            let (code, output, took) = run_step(&dir, &command, timeout);
            eprintln!(
                "{rel}:{}: {:.1} s, exit {code}: {command}",
                ex.line,
                took.as_secs_f64()
            );
            let tail: String = output
                .lines()
                .rev()
                .take(25)
                .collect::<Vec<_>>()
                .into_iter()
                .rev()
                .collect::<Vec<_>>()
                .join("\n");
            if code != want {
                failures.push(format!(
                    "{rel}:{}: `{command}` exited {code}, the page expects {want}\n{tail}",
                    ex.line
                ));
            } else if let Some(missing) = first_unmatched(&step.expected, &output) {
                failures.push(format!("{rel}:{}: `{command}` did not print the line the page shows:\n  {missing}\nit printed:\n{output}", ex.line));
            }
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
    assert!(failures.is_empty(), "{}", failures.join("\n\n"));
}

/// The pages this test runs: README.md and every chapter of the guide.
const PAGES: &[&str] = &[
    "README.md",
    "docs/src/introduction.md",
    "docs/src/getting-started.md",
    "docs/src/commands.md",
    "docs/src/scenarios.md",
    "docs/src/own-network.md",
    "docs/src/drivers.md",
    "docs/src/human-preset.md",
    "docs/src/wave-dampers.md",
    "docs/src/compare.md",
    "docs/src/metrics.md",
    "docs/src/regression.md",
    "docs/src/stability.md",
    "docs/src/linear-agents.md",
    "docs/src/sweeps.md",
    "docs/src/python.md",
    "docs/src/own-controller.md",
    "docs/src/learning.md",
    "docs/src/watching.md",
    "docs/src/figures.md",
    "docs/src/experiments.md",
    "docs/src/experiment-sugiyama.md",
    "docs/src/experiment-platoon.md",
    "docs/src/experiment-human-ring.md",
    "docs/src/experiment-gain-delay.md",
    "docs/src/experiment-penetration.md",
    "docs/src/experiment-noisy.md",
    "docs/src/experiment-open-road.md",
    "docs/src/published.md",
    "docs/src/backends.md",
    "docs/src/performance.md",
    "docs/src/reliability.md",
    "docs/src/architecture.md",
];

#[test]
fn every_page_is_checked() {
    let mut missing = Vec::new();
    for e in std::fs::read_dir(repo().join("docs/src"))
        .unwrap()
        .flatten()
    {
        let name = e.file_name().to_string_lossy().into_owned();
        let rel = format!("docs/src/{name}");
        if name.ends_with(".md") && name != "SUMMARY.md" && !PAGES.contains(&rel.as_str()) {
            missing.push(rel);
        }
    }
    assert!(
        missing.is_empty(),
        "pages not in guide.rs's PAGES: {missing:?}"
    );
    for p in PAGES {
        assert!(repo().join(p).is_file(), "{p} is listed but missing");
    }
}

macro_rules! pages {
    ($($name:ident => $path:literal),* $(,)?) => {
        mod page { $( #[test] fn $name() { super::check_page($path); } )* }
    };
}

pages! {
    readme => "README.md",
    introduction => "docs/src/introduction.md",
    getting_started => "docs/src/getting-started.md",
    commands => "docs/src/commands.md",
    scenarios => "docs/src/scenarios.md",
    own_network => "docs/src/own-network.md",
    drivers => "docs/src/drivers.md",
    human_preset => "docs/src/human-preset.md",
    wave_dampers => "docs/src/wave-dampers.md",
    compare => "docs/src/compare.md",
    metrics => "docs/src/metrics.md",
    regression => "docs/src/regression.md",
    stability => "docs/src/stability.md",
    linear_agents => "docs/src/linear-agents.md",
    sweeps => "docs/src/sweeps.md",
    python => "docs/src/python.md",
    own_controller => "docs/src/own-controller.md",
    learning => "docs/src/learning.md",
    watching => "docs/src/watching.md",
    figures => "docs/src/figures.md",
    experiments => "docs/src/experiments.md",
    experiment_sugiyama => "docs/src/experiment-sugiyama.md",
    experiment_platoon => "docs/src/experiment-platoon.md",
    experiment_human_ring => "docs/src/experiment-human-ring.md",
    experiment_gain_delay => "docs/src/experiment-gain-delay.md",
    experiment_penetration => "docs/src/experiment-penetration.md",
    experiment_noisy => "docs/src/experiment-noisy.md",
    experiment_open_road => "docs/src/experiment-open-road.md",
    published => "docs/src/published.md",
    backends => "docs/src/backends.md",
    performance => "docs/src/performance.md",
    reliability => "docs/src/reliability.md",
    architecture => "docs/src/architecture.md",
}

/// The convention itself: a test that cannot fail is a defect, so the parser and the matcher
/// are checked on pages made to fail.
mod convention {
    use super::*;

    #[test]
    fn output_lines_match_in_order_with_wildcards() {
        assert!(line_matches("a ... b", "a xyz b"));
        assert!(line_matches("...", "anything"));
        assert!(!line_matches("a ... b", "a xyz c"));
        assert!(!line_matches("exact", "exact "));
        let out = "one\ntwo 2.5 s\nthree\n";
        let want = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        assert_eq!(first_unmatched(&want(&["one", "...", "three"]), out), None);
        assert_eq!(first_unmatched(&want(&["two ... s", "three"]), out), None);
        assert_eq!(first_unmatched(&want(&["three", "one"]), out), Some("one"));
        assert_eq!(first_unmatched(&want(&["four"]), out), Some("four"));
    }

    #[test]
    fn blocks_directives_and_refusals() {
        let page = "text\n\n<!-- example exit=1 test-args: --shard 0/4 -->\n```console\n$ syncroad a \\\n  --b\nout 1\n...\n$ syncroad c\n```\n\n```json\n{}\n```\n";
        let ex = examples(page).unwrap();
        assert_eq!(ex.len(), 1);
        assert_eq!(ex[0].line, 4);
        assert_eq!(ex[0].directive.exit, 1);
        assert_eq!(ex[0].directive.test_args.as_deref(), Some("--shard 0/4"));
        assert_eq!(ex[0].steps[0].command, "syncroad a \\\n  --b");
        assert_eq!(ex[0].steps[0].expected, vec!["out 1", "..."]);
        assert_eq!(ex[0].steps[1].command, "syncroad c");
        assert!(examples("```sh\nsyncroad run x\n```\n")
            .unwrap_err()
            .contains("```console"));
        assert!(examples("<!-- example not-run: -->\n```console\n$ x\n```\n").is_err());
        assert!(examples("<!-- example exit=1 -->\n\nprose\n\n```console\n$ x\n```\n").is_err());
        assert!(examples("<!-- example frobnicate -->\n```console\n$ x\n```\n").is_err());
        assert!(examples("```console\nno command\n```\n").is_err());
        let tabled = examples("<!-- example table -->\n```console\n$ x\nhead\n```\n\n| a | b |\n|---|---|\n| 1 | 2 |\n\nprose\n").unwrap();
        assert_eq!(
            tabled[0].steps[0].expected,
            vec!["head", "| a | b |", "|---|---|", "| 1 | 2 |"]
        );
        assert!(examples("<!-- example table -->\n```console\n$ x\n```\n\nprose\n").is_err());
        let skipped =
            examples("<!-- example not-run: needs Slurm -->\n```console\n$ sbatch x\n```\n")
                .unwrap();
        assert_eq!(skipped[0].directive.not_run.as_deref(), Some("needs Slurm"));
    }

    #[test]
    fn commands_run_with_their_exit_code_and_a_timeout() {
        let dir = scratch("convention");
        let (code, out, _) = run_step(&dir, "syncroad --version; exit 3", Duration::from_secs(60));
        assert_eq!(code, 3);
        assert!(out.starts_with("syncroad "), "{out}");
        // Stopped by its time limit (-2), and killed: had the kill missed, waiting for it
        // would have taken the sleep's whole length, however loaded the machine.
        let (code, _, took) = run_step(&dir, "sleep 300", Duration::from_millis(300));
        assert_eq!(code, -2);
        assert!(took < Duration::from_secs(300), "{took:?}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}

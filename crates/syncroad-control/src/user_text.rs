//! Text that comes from the user's code (an exception's message and traceback, a worker's last
//! output) on its way to a terminal, a log or `metrics.json`: control characters escaped, so
//! that no ANSI sequence reaches the terminal raw; every line set off by `| `, so that no
//! line of it can pass for syncroad's own (`verdict: synchronized`); and long text cut to
//! [`SHOWN_CHARS`], with the whole of it in the run folder's [`FULL_TEXT_FILE`].

/// How much of the user's text a message shows \[characters\].
pub const SHOWN_CHARS: usize = 4000;

/// How much of it a run keeps at all \[bytes\]: a controller that raises an exception of
/// 50 MB would otherwise carry it through every message and file.
pub const KEPT_BYTES: usize = 1 << 20;

/// The file of a run folder that holds the user's whole text when a message shows part of it.
pub const FULL_TEXT_FILE: &str = "error.txt";

/// `text` with control characters other than newline and tab written as Rust escapes
/// (`\u{1b}` for ESC), so that it prints as what it is.
pub fn escaped(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        if c.is_control() && c != '\n' && c != '\t' {
            out.extend(c.escape_default());
        } else {
            out.push(c);
        }
    }
    out
}

/// `text` cut to its first [`KEPT_BYTES`] (at a character boundary), with a note of how much
/// was left out.
pub fn kept(text: String) -> String {
    if text.len() <= KEPT_BYTES {
        return text;
    }
    let mut end = KEPT_BYTES;
    while !text.is_char_boundary(end) {
        end -= 1;
    }
    format!(
        "{}\n[… {} more bytes of this text were not kept]",
        &text[..end],
        text.len() - end
    )
}

/// Whether a message shows less than the whole of `text` ([`shown`]).
pub fn is_cut(text: &str) -> bool {
    text.chars().nth(SHOWN_CHARS).is_some()
}

/// `text` as a message shows it: escaped ([`escaped`]), each line after `| `, and cut to
/// [`SHOWN_CHARS`] with a note naming [`FULL_TEXT_FILE`] when longer.
pub fn shown(text: &str) -> String {
    let total = text.chars().count();
    let part: String = text.chars().take(SHOWN_CHARS).collect();
    let mut out = String::new();
    for (k, line) in escaped(part.trim_end()).lines().enumerate() {
        if k > 0 {
            out.push('\n');
        }
        out.push_str("  | ");
        out.push_str(line);
    }
    if total > SHOWN_CHARS {
        out.push_str(&format!(
            "\n  [… {} more characters; the whole text is in {FULL_TEXT_FILE} in the run's folder]",
            total - SHOWN_CHARS
        ));
    }
    out
}

/// `text` escaped ([`escaped`]) and cut to [`SHOWN_CHARS`] with a note naming
/// [`FULL_TEXT_FILE`] when longer: for syncroad's own messages that carry the user's text
/// inside (a worker's last output, set off line by line where it is quoted).
pub fn capped(text: &str) -> String {
    let total = text.chars().count();
    let mut out = escaped(&text.chars().take(SHOWN_CHARS).collect::<String>());
    if total > SHOWN_CHARS {
        out.push_str(&format!(
            "\n  [… {} more characters; the whole text is in {FULL_TEXT_FILE} in the run's folder]",
            total - SHOWN_CHARS
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn control_characters_are_escaped_and_lines_set_off() {
        let s = shown("boom \u{1b}[31mred\u{1b}[0m\r\nverdict: synchronized\u{7}");
        assert_eq!(
            s,
            "  | boom \\u{1b}[31mred\\u{1b}[0m\\r\n  | verdict: synchronized\\u{7}"
        );
        assert!(!s.lines().any(|l| l.starts_with("verdict")));
        assert!(!s.contains('\u{1b}'));
    }

    #[test]
    fn long_text_is_cut_with_a_note_and_kept_to_a_bound() {
        let long = "é".repeat(10_000);
        assert!(is_cut(&long) && !is_cut("short"));
        let s = shown(&long);
        assert!(s.ends_with(
            "[… 6000 more characters; the whole text is in error.txt in the run's folder]"
        ));
        assert_eq!(s.matches('é').count(), SHOWN_CHARS);
        let huge = kept("x".repeat(3 * KEPT_BYTES));
        assert!(huge.len() < KEPT_BYTES + 100);
        assert!(huge.ends_with(&format!(
            "[… {} more bytes of this text were not kept]",
            2 * KEPT_BYTES
        )));
        // A cut inside a character moves to its start.
        let cut = kept(format!("a{}", "é".repeat(KEPT_BYTES)));
        assert!(cut.is_char_boundary(cut.find('\n').unwrap()));
    }
}

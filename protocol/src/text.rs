//! What of a peer's text a message may show: control characters escaped (no terminal
//! escapes or forged log lines reach a reader), and at most a given number of bytes.

/// `text` with its control characters escaped, cut to at most `max` bytes (then ending
/// in `…`).
pub fn short(text: &str, max: usize) -> String {
    let mut shown = String::with_capacity(text.len().min(max) + 3);
    for c in text.chars() {
        if c.is_control() {
            shown.extend(c.escape_default());
        } else {
            shown.push(c);
        }
        if shown.len() > max {
            break;
        }
    }
    if shown.len() <= max {
        return shown;
    }
    let mut end = max;
    while !shown.is_char_boundary(end) {
        end -= 1;
    }
    shown.truncate(end);
    shown.push('…');
    shown
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn control_characters_are_escaped_and_long_text_cut_at_a_char_boundary() {
        assert_eq!(short("a\x1b[31mb\n", 64), "a\\u{1b}[31mb\\n");
        assert_eq!(short("plain", 5), "plain");
        assert_eq!(short("abcdef", 3), "abc…");
        // 'é' is two bytes: a cut inside it moves back to its start.
        assert_eq!(short("aé", 2), "a…");
        assert!(short(&"x".repeat(100_000), 300).len() <= 303);
    }
}

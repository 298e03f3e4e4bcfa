//! Where a character of a TOML string value lies in the file: the parsed string and its
//! source differ wherever the source has escapes (`\"`, `\u00e4`, a line-ending backslash),
//! so an error at the n-th character of the value is located by walking the source.

/// Byte offset, in `raw` (a TOML string value as written, from its opening quote), of the
/// character at index `n` of the parsed string (its end if the string is shorter). Basic
/// strings (`"…"`, `"""…"""`) decode escapes — `\uXXXX`, `\UXXXXXXXX`, `\xHH` and the
/// one-letter ones count one character each, a line-ending backslash none; literal strings
/// (`'…'`, `'''…'''`) have none. A newline right after a multi-line opening is not part of
/// the value.
///
/// ```
/// use armature_cli::toml_string::raw_offset;
/// // "abs(\u0076) + ä": the 'ä' is the 10th character (index 9) of the value.
/// let raw = r#""abs(\u0076) + ä""#;
/// assert_eq!(&raw[raw_offset(raw, 9)..], "ä\"");
/// assert_eq!(raw_offset("'a\\b'", 2), 3);
/// ```
pub fn raw_offset(raw: &str, n: usize) -> usize {
    let (quote, multi) = match raw.as_bytes() {
        [b'"', b'"', b'"', ..] => (b'"', true),
        [b'\'', b'\'', b'\'', ..] => (b'\'', true),
        [b'\'', ..] => (b'\'', false),
        _ => (b'"', false),
    };
    let mut i = if multi { 3 } else { 1 }.min(raw.len());
    if multi {
        i += [&b"\r\n"[..], &b"\n"[..]]
            .iter()
            .find(|nl| raw.as_bytes()[i..].starts_with(nl))
            .map_or(0, |nl| nl.len());
    }
    let bytes = raw.as_bytes();
    let mut count = 0;
    while i < raw.len() {
        if quote == b'"' && bytes[i] == b'\\' {
            let (len, chars) = escape(&raw[i..], multi);
            if chars > 0 && count == n {
                return i;
            }
            count += chars;
            i += len;
            continue;
        }
        if count == n {
            return i;
        }
        count += 1;
        i += raw[i..].chars().next().map_or(1, char::len_utf8);
    }
    raw.len()
}

/// The source length of the escape at the start of `s` (a backslash) and how many characters
/// of the value it stands for.
fn escape(s: &str, multi: bool) -> (usize, usize) {
    let hex = |len: usize| (1 + len).min(s.len());
    match s.as_bytes().get(1) {
        Some(b'u') => (hex(5), 1),
        Some(b'U') => (hex(9), 1),
        Some(b'x') => (hex(3), 1),
        Some(c) if multi && c.is_ascii_whitespace() => {
            // A line-ending backslash: it and all whitespace up to the next character vanish.
            let rest = s[1..].trim_start_matches([' ', '\t', '\r', '\n']);
            (s.len() - rest.len(), 0)
        }
        Some(_) => (2.min(s.len()), 1),
        None => (1, 1),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Any string as the toml crate writes it (basic or literal, one line or several), or
    /// escaped by hand: the offset of each character in the source decodes to that character.
    fn check(value: &str, raw: &str) -> Result<(), TestCaseError> {
        let basic = raw.starts_with('"');
        let close = if raw.starts_with("\"\"\"") || raw.starts_with("'''") { 3 } else { 1 };
        let parsed: toml::Value = toml::from_str(&format!("v = {raw}")).unwrap();
        prop_assert_eq!(parsed["v"].as_str(), Some(value));
        for (n, c) in value.chars().enumerate() {
            let at = raw_offset(raw, n);
            let tail = &raw[at..];
            let decoded = if !basic {
                tail.chars().next()
            } else if let Some(e) = tail.strip_prefix("\\u") {
                char::from_u32(u32::from_str_radix(&e[..4], 16).unwrap())
            } else if let Some(e) = tail.strip_prefix("\\U") {
                char::from_u32(u32::from_str_radix(&e[..8], 16).unwrap())
            } else if let Some(e) = tail.strip_prefix('\\') {
                Some(match e.chars().next().unwrap() {
                    'n' => '\n',
                    't' => '\t',
                    'r' => '\r',
                    'b' => '\u{8}',
                    'f' => '\u{c}',
                    'e' => '\u{1b}',
                    other => other,
                })
            } else {
                tail.chars().next()
            };
            prop_assert_eq!(decoded, Some(c), "char {} of {:?} in {}", n, value, raw);
        }
        prop_assert_eq!(raw_offset(raw, value.chars().count()), raw.len() - close);
        Ok(())
    }

    proptest! {
        #[test]
        fn offsets_of_escaped_basic_strings_decode_to_their_characters(value in "[a-zä\"\\\\\t\n\u{1}-\u{1f}✓ ]{0,24}") {
            let raw = toml::Value::String(value.clone()).to_string();
            check(&value, &raw)?;
            // The same with every character written as \uXXXX or \UXXXXXXXX.
            let escaped: String = value.chars().enumerate().map(|(i, c)| if i % 2 == 0 {
                format!("\\u{:04X}", c as u32)
            } else {
                format!("\\U{:08X}", c as u32)
            }).collect();
            check(&value, &format!("\"{escaped}\""))?;
        }
    }

    #[test]
    fn literal_and_multi_line_strings() {
        assert_eq!(raw_offset("'a\\u0041b'", 2), 3);
        let raw = "\"\"\"\nab\\\n    cd\"\"\"";
        // "abcd": the newline after the opening and the line-ending backslash vanish.
        assert_eq!(&raw[raw_offset(raw, 0)..raw_offset(raw, 0) + 1], "a");
        assert_eq!(&raw[raw_offset(raw, 2)..raw_offset(raw, 2) + 1], "c");
        assert_eq!(raw_offset("'''\nxy'''", 1), 5);
    }
}

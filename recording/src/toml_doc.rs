//! An owned TOML tree that keeps the byte span of every key and value, built from toml's
//! spanned `DeTable`, so that each later error can name `file:line:column`: the one home of
//! located TOML errors for every file bench reads (scenario, bench config, model file).

use std::ops::Range;

use toml::de::{DeTable, DeValue};
use toml::Spanned;

/// Deepest nesting of arrays and tables accepted (guards the recursion below).
const MAX_DEPTH: usize = 64;

/// A value with the byte range it occupies in the text.
#[derive(Debug, Clone)]
pub struct Node {
    /// Byte range of the value.
    pub span: Range<usize>,
    /// The value.
    pub value: Value,
}

/// A TOML value; numbers are kept as `f64` (integers as exact as `f64` holds them).
#[derive(Debug, Clone)]
pub enum Value {
    /// A string.
    Str(String),
    /// A number (integer or float).
    Num(f64),
    /// A boolean.
    Bool(bool),
    /// A date-time (kept only as a kind: no file of bench takes one).
    Datetime,
    /// An array.
    Array(Vec<Node>),
    /// A table, keys in source order.
    Table(Vec<Entry>),
}

/// A key of a table, with its span, and its value.
#[derive(Debug, Clone)]
pub struct Entry {
    /// The key.
    pub key: String,
    /// Byte range of the key.
    pub key_span: Range<usize>,
    /// Its value.
    pub node: Node,
}

impl Value {
    /// TOML's name of the value's type, for messages.
    pub fn type_name(&self) -> &'static str {
        match self {
            Value::Str(_) => "a string",
            Value::Num(_) => "a number",
            Value::Bool(_) => "a boolean",
            Value::Datetime => "a date-time",
            Value::Array(_) => "an array",
            Value::Table(_) => "a table",
        }
    }
}

/// Parse `text` as TOML. On syntax errors returns every error toml reports, as (span, message).
pub fn parse(text: &str) -> Result<Node, Vec<(Range<usize>, String)>> {
    let (doc, errors) = DeTable::parse_recoverable(text);
    if !errors.is_empty() {
        return Err(errors
            .iter()
            .map(|e| {
                let span = e.span().unwrap_or(0..0);
                (span, format!("TOML syntax: {}", e.message().trim()))
            })
            .collect());
    }
    let span = doc.span();
    let mut errs = Vec::new();
    let table = convert_table(doc.get_ref(), 0, &mut errs);
    if errs.is_empty() {
        Ok(Node { span, value: Value::Table(table) })
    } else {
        Err(errs)
    }
}

fn convert_table(
    t: &DeTable<'_>,
    depth: usize,
    errs: &mut Vec<(Range<usize>, String)>,
) -> Vec<Entry> {
    let mut out: Vec<Entry> = t
        .iter()
        .map(|(k, v)| Entry {
            key: k.get_ref().to_string(),
            key_span: k.span(),
            node: convert(v, depth + 1, errs),
        })
        .collect();
    // Source order, whatever order the map keeps.
    out.sort_by_key(|e| e.key_span.start);
    out
}

fn convert(v: &Spanned<DeValue<'_>>, depth: usize, errs: &mut Vec<(Range<usize>, String)>) -> Node {
    let span = v.span();
    if depth > MAX_DEPTH {
        errs.push((span.clone(), format!("nested deeper than {MAX_DEPTH} levels")));
        return Node { span, value: Value::Datetime };
    }
    let value = match v.get_ref() {
        DeValue::String(s) => Value::Str(s.to_string()),
        DeValue::Integer(i) => {
            Value::Num(i128::from_str_radix(i.as_str(), i.radix()).map_or(f64::NAN, |x| x as f64))
        }
        DeValue::Float(f) => Value::Num(f.as_str().parse::<f64>().unwrap_or(f64::NAN)),
        DeValue::Boolean(b) => Value::Bool(*b),
        DeValue::Datetime(_) => Value::Datetime,
        DeValue::Array(a) => Value::Array(a.iter().map(|x| convert(x, depth + 1, errs)).collect()),
        DeValue::Table(t) => Value::Table(convert_table(t, depth, errs)),
    };
    Node { span, value }
}

/// The span of the value at the dotted `path` of keys in TOML `text` (`None` when the text
/// does not parse or has no such key).
pub fn value_span(text: &str, path: &[&str]) -> Option<Range<usize>> {
    let mut node = parse(text).ok()?;
    for key in path {
        let Value::Table(entries) = node.value else { return None };
        node = entries.into_iter().find(|e| e.key == *key)?.node;
    }
    Some(node.span)
}

/// A TOML file's text from its `bytes`. TOML files are UTF-8: for bytes that are not, the
/// offset of the first bad byte, its 1-based line and column, and a message.
pub fn utf8_text(bytes: Vec<u8>) -> Result<String, (usize, usize, usize, String)> {
    String::from_utf8(bytes).map_err(|e| {
        let at = e.utf8_error().valid_up_to();
        let bytes = e.into_bytes();
        let valid = bytes.get(..at).and_then(|b| std::str::from_utf8(b).ok()).unwrap_or("");
        let (line, column) = line_col(valid, at);
        let byte = bytes.get(at).copied().unwrap_or(0);
        (
            at,
            line,
            column,
            format!("not UTF-8 text (byte {at} is 0x{byte:02X}): TOML files are UTF-8"),
        )
    })
}

/// 1-based line and column (in characters) of byte offset `pos` in `text`.
pub fn line_col(text: &str, pos: usize) -> (usize, usize) {
    let mut pos = pos.min(text.len());
    while !text.is_char_boundary(pos) {
        pos -= 1;
    }
    let before = text.get(..pos).unwrap_or("");
    let line = before.matches('\n').count() + 1;
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    let column = before.get(line_start..).map_or(0, |s| s.chars().count()) + 1;
    (line, column)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bytes_that_are_not_utf8_are_located() {
        // Found by scripts/bad_inputs.py: such a file gave "stream did not contain valid
        // UTF-8" with no place in it.
        let (at, line, column, message) =
            utf8_text(b"a = 1\nb = \"\xC2\xB0\xFF\"\n".to_vec()).expect_err("not UTF-8");
        assert_eq!((at, line, column), (13, 2, 7));
        assert!(message.contains("0xFF"), "{message}");
        assert_eq!(utf8_text(b"x = \"\xC2\xB0\"".to_vec()).ok().as_deref(), Some("x = \"°\""));
    }

    #[test]
    fn line_col_counts_characters_not_bytes() {
        let text = "a = 1\nb = \"°°x\"\n";
        let x = text.find('x').unwrap_or(0);
        assert_eq!(line_col(text, x), (2, 8));
        assert_eq!(line_col(text, 0), (1, 1));
        assert_eq!(line_col(text, 10_000), (3, 1));
        // Inside a multi-byte character: snaps back to it.
        let deg = text.find('°').unwrap_or(0);
        assert_eq!(line_col(text, deg + 1), (2, 6));
    }

    #[test]
    fn spans_point_at_values_and_keys_in_source_order() {
        let text = "[site]\nzeta = 1\nalpha = 0x10\n";
        let Ok(Node { value: Value::Table(top), .. }) = parse(text) else { panic!("parses") };
        let Value::Table(site) = &top[0].node.value else { panic!("table") };
        assert_eq!(site[0].key, "zeta");
        assert_eq!(site[1].key, "alpha");
        assert!(matches!(site[1].node.value, Value::Num(x) if x == 16.0));
        assert_eq!(&text[site[1].node.span.clone()], "0x10");
        assert_eq!(line_col(text, site[1].key_span.start), (3, 1));
    }

    #[test]
    fn syntax_errors_have_spans() {
        let Err(errs) = parse("a = \nb = 2") else { panic!("must fail") };
        assert!(!errs.is_empty());
        assert!(errs[0].1.starts_with("TOML syntax"));
    }
}

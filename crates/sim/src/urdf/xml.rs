//! Checks on the raw text before any XML reader sees it, and the pass that
//! writes the document back out with PartNet-Mobility's mistakes mended.
use super::{MAX_ATTRIBUTES, MAX_NUMBER_TOKEN, MAX_XML_DEPTH, quoted, urdf_err};
use crate::error::Result;
use std::fmt::Write as _;
use std::path::Path;

const NUMERIC_ATTRS: &[&str] = &[
    "xyz", "rpy", "lower", "upper", "effort", "velocity", "value", "ixx", "ixy", "ixz", "iyy",
    "iyz", "izz", "radius", "length", "size", "scale", "rgba", "damping", "friction",
];

/// Nesting depth and attributes per element, checked on the raw text before
/// any XML reader sees it: deep nesting overflows recursive readers' stacks,
/// and thousands of attributes on one element make their duplicate checks
/// quadratic. Malformed markup is left to the XML reader's message.
pub(super) fn check_xml_shape(text: &str, path: &Path) -> Result<()> {
    let b = text.as_bytes();
    let line = |at: usize| 1 + b.iter().take(at).filter(|c| **c == b'\n').count();
    let after = |from: usize, end: &[u8]| -> usize {
        b.get(from..)
            .unwrap_or_default()
            .windows(end.len())
            .position(|w| w == end)
            .map_or(b.len(), |k| from + k + end.len())
    };
    let (mut i, mut depth) = (0usize, 0usize);
    while let Some(off) = b.get(i..).and_then(|r| r.iter().position(|c| *c == b'<')) {
        let s = i + off;
        let rest = b.get(s..).unwrap_or_default();
        if rest.starts_with(b"<!--") {
            i = after(s, b"-->");
        } else if rest.starts_with(b"<![CDATA[") {
            i = after(s, b"]]>");
        } else if rest.starts_with(b"<?") {
            i = after(s, b"?>");
        } else if rest.starts_with(b"<!") {
            i = after(s, b">");
        } else if rest.starts_with(b"</") {
            depth = depth.saturating_sub(1);
            i = after(s, b">");
        } else {
            let (mut k, mut quote, mut attributes) = (s + 1, None, 0usize);
            while let Some(&c) = b.get(k) {
                match (quote, c) {
                    (Some(q), c) if c == q => quote = None,
                    (Some(_), _) => {}
                    (None, c @ (b'"' | b'\'')) => quote = Some(c),
                    (None, b'=') => attributes += 1,
                    (None, b'>') => break,
                    _ => {}
                }
                k += 1;
            }
            if attributes > MAX_ATTRIBUTES {
                return Err(urdf_err(
                    path,
                    format!(
                        "line {}: an element with {attributes} attributes; at most {MAX_ATTRIBUTES}",
                        line(s)
                    ),
                ));
            }
            if b.get(k.wrapping_sub(1)) != Some(&b'/') {
                depth += 1;
                if depth > MAX_XML_DEPTH {
                    return Err(urdf_err(
                        path,
                        format!(
                            "line {}: elements nested more than {MAX_XML_DEPTH} deep",
                            line(s)
                        ),
                    ));
                }
            }
            i = (k + 1).min(b.len());
        }
    }
    Ok(())
}

/// Writes the element back out as XML, fixing what PartNet-Mobility files get
/// wrong: `<limit>` without velocity/effort and stray characters in numbers.
pub(super) fn mend(
    node: roxmltree::Node<'_, '_>,
    path: &Path,
    line_of: &dyn Fn(roxmltree::Node<'_, '_>) -> u32,
    out: &mut String,
) -> Result<()> {
    let name = node.tag_name().name();
    let _ = write!(out, "<{name}");
    for a in node.attributes() {
        let value = if NUMERIC_ATTRS.contains(&a.name())
            && !(name == "material" || name == "link" || name == "joint")
        {
            mend_numbers(a.value()).ok_or_else(|| {
                urdf_err(
                    path,
                    format!(
                        "<{name}> at line {}: attribute {}=\"{}\" is not a list of numbers",
                        line_of(node),
                        a.name(),
                        quoted(a.value())
                    ),
                )
            })?
        } else {
            a.value().to_owned()
        };
        let _ = write!(out, " {}=\"{}\"", a.name(), escape(&value));
    }
    if name == "limit" {
        for (attr, default) in [("velocity", "1.0"), ("effort", "100.0")] {
            if node.attribute(attr).is_none() {
                let _ = write!(out, " {attr}=\"{default}\"");
            }
        }
    }
    out.push('>');
    for child in node.children() {
        if child.is_element() {
            mend(child, path, line_of, out)?;
        } else if let Some(t) = child.text() {
            out.push_str(&escape(t));
        }
    }
    let _ = write!(out, "</{name}>");
    Ok(())
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('"', "&quot;")
}

/// Keeps each whitespace-separated token that is a number, or the longest
/// numeric prefix of one with stray characters (`0.5,` -> `0.5`).
fn mend_numbers(value: &str) -> Option<String> {
    let mut parts = Vec::new();
    for tok in value
        .split(|c: char| c.is_whitespace() || c == ',')
        .filter(|t| !t.is_empty())
    {
        if tok.len() > MAX_NUMBER_TOKEN {
            return None;
        }
        if tok.parse::<f64>().is_ok() {
            parts.push(tok.to_owned());
            continue;
        }
        let prefix = (1..tok.len())
            .rev()
            .filter(|&k| tok.is_char_boundary(k))
            .map(|k| &tok[..k])
            .find(|p| p.parse::<f64>().is_ok())?;
        parts.push(prefix.to_owned());
    }
    (!parts.is_empty()).then(|| parts.join(" "))
}

/// Numeric character references must name a character XML allows
/// (`#x9 | #xA | #xD | [#x20-#xD7FF] | [#xE000-#xFFFD] | [#x10000-#x10FFFF]`):
/// a reference beyond Unicode such as `&#x110000;` is not text, yet a lenient
/// reader passes it on.
pub(super) fn check_char_refs(text: &str, path: &Path) -> Result<()> {
    let mut rest = text;
    let mut offset = 0;
    while let Some(at) = rest.find("&#") {
        let start = offset + at;
        let tail = rest.get(at + 2..).unwrap_or_default();
        let end = tail.find(';').filter(|e| *e <= 12);
        let code = end.and_then(|e| {
            let digits = tail.get(..e)?;
            match digits.strip_prefix('x') {
                Some(hex) => u32::from_str_radix(hex, 16).ok(),
                None => digits.parse::<u32>().ok(),
            }
        });
        let allowed = code.is_some_and(
            |c| matches!(c, 0x9 | 0xA | 0xD | 0x20..=0xD7FF | 0xE000..=0xFFFD | 0x10000..=0x10FFFF),
        );
        if !allowed {
            let line = 1 + text.get(..start).unwrap_or_default().matches('\n').count();
            let shown: String = text
                .get(start..)
                .unwrap_or_default()
                .chars()
                .take(16)
                .collect();
            return Err(urdf_err(
                path,
                format!(
                    "line {line}: character reference `{}` names no character XML allows (expected &#N; or &#xH; up to U+10FFFF, not a control character or surrogate)",
                    quoted(shown.split(';').next().unwrap_or_default())
                ),
            ));
        }
        offset = start + 2;
        rest = text.get(offset..).unwrap_or_default();
    }
    Ok(())
}

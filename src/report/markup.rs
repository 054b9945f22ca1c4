//! The page's pieces of markup: escaped text, a figure, a table.

use std::fmt::Write;

/// HTML-escapes text.
pub(super) fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// A figure: the SVG or a note why it is missing.
pub(super) fn figure(out: &mut String, id: &str, svg: Option<String>, caption: &str) {
    let _ = write!(out, "<figure class=\"plot\" id=\"{id}\">");
    match svg {
        Some(svg) => out.push_str(&svg),
        None => out.push_str("<p class=\"missing\">nothing to draw in the inputs</p>"),
    }
    let _ = writeln!(out, "<figcaption>{caption}</figcaption></figure>");
}

/// A table with a header row.
pub(super) fn table(out: &mut String, id: &str, head: &[&str], rows: &[Vec<String>]) {
    let _ = write!(out, "<table id=\"{id}\"><thead><tr>");
    for h in head {
        let _ = write!(out, "<th>{}</th>", esc(h));
    }
    out.push_str("</tr></thead><tbody>");
    for r in rows {
        out.push_str("<tr>");
        for c in r {
            // Cells are escaped by the caller where they hold text from the inputs (some
            // carry markup of their own: the traffic lights).
            let _ = write!(out, "<td>{c}</td>");
        }
        out.push_str("</tr>");
    }
    out.push_str("</tbody></table>\n");
}

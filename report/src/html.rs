//! The report's documents: `report.md` and a self-contained `report.html` (plots inlined),
//! from the sections the analyses wrote.

use std::fmt::Write as _;
use std::fs;

use base64::Engine as _;

use super::ReportError;
use super::RunData;
use super::out::{Out, werr};

/// What a report document is about: its title and the line under it.
pub(super) struct Heading {
    pub(super) title: String,
    pub(super) what: String,
}

impl Heading {
    /// One run's report.
    pub(super) fn run(data: &RunData) -> Self {
        Self {
            title: format!("Report: {}", data.protocol_name),
            what: format!("Run `{}`.", data.dir.display()),
        }
    }
}

pub(super) fn write_md(h: &Heading, out: &Out) -> Result<(), ReportError> {
    // Markdown renderers pass HTML through: the name is escaped here too.
    let mut md = format!("# {}\n\n{}\n\n", esc(&h.title), h.what);
    for s in &out.sections {
        let _ = writeln!(md, "## {}\n\n{}", s.title, s.text);
        for p in &s.plots {
            let file = if p.ends_with(".svg") {
                p.clone()
            } else {
                format!("{p}.svg")
            };
            let _ = writeln!(md, "![{}]({file})\n", p.trim_end_matches(".svg"));
        }
    }
    let p = out.dir.join("report.md");
    fs::write(&p, md).map_err(|e| werr(&p)(e.to_string()))
}

/// Text from data (a protocol's name, a label, a path) made inert in HTML: a protocol named
/// `</title><script>…` must show as text, not run.
pub(super) fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
        .replace('\'', "&#39;")
}

/// Minimal markdown → HTML for what the sections contain: tables, bold, inline code,
/// paragraphs. The text is escaped first, so markup can only come from `**` and backticks.
fn md_to_html(text: &str) -> String {
    let bold = |s: String| {
        let mut o = String::new();
        for (i, code) in s.split('`').enumerate() {
            if i % 2 == 1 {
                let _ = write!(o, "<code>{code}</code>");
                continue;
            }
            for (j, part) in code.split("**").enumerate() {
                if j % 2 == 1 {
                    let _ = write!(o, "<b>{part}</b>");
                } else {
                    o.push_str(part);
                }
            }
        }
        o
    };
    let mut html = String::new();
    let mut in_table = false;
    for line in text.lines() {
        let l = line.trim();
        if l.starts_with('|') {
            if l.starts_with("|---") {
                continue;
            }
            let cells: Vec<String> = l
                .trim_matches('|')
                .split('|')
                .map(|c| bold(esc(c.trim())))
                .collect();
            let tag = if in_table { "td" } else { "th" };
            if !in_table {
                html.push_str("<table>");
                in_table = true;
            }
            let _ = write!(
                html,
                "<tr>{}</tr>",
                cells
                    .iter()
                    .map(|c| format!("<{tag}>{c}</{tag}>"))
                    .collect::<String>()
            );
        } else {
            if in_table {
                html.push_str("</table>\n");
                in_table = false;
            }
            if !l.is_empty() {
                let _ = writeln!(html, "<p>{}</p>", bold(esc(l)));
            }
        }
    }
    if in_table {
        html.push_str("</table>\n");
    }
    html
}

pub(super) fn write_html(h: &Heading, out: &Out) -> Result<(), ReportError> {
    let mut html = format!(
        "<!doctype html><html><head><meta charset=\"utf-8\"><title>gelrig {}</title><style>body{{font-family:sans-serif;max-width:980px;margin:auto;padding:1em}}table{{border-collapse:collapse;margin:.5em 0}}td,th{{border:1px solid #ccc;padding:2px 8px;font-size:90%}}img{{max-width:100%}}</style></head><body><h1>{}</h1>{}",
        esc(&h.title),
        esc(&h.title),
        md_to_html(&h.what)
    );
    for s in &out.sections {
        let _ = write!(html, "<h2>{}</h2>{}", esc(&s.title), md_to_html(&s.text));
        for p in &s.plots {
            let file = if p.ends_with(".svg") {
                out.dir.join(p)
            } else {
                out.dir.join(format!("{p}.png"))
            };
            let bytes = fs::read(&file).map_err(|e| werr(&file)(e.to_string()))?;
            let mime = if p.ends_with(".svg") {
                "image/svg+xml"
            } else {
                "image/png"
            };
            let _ = write!(
                html,
                "<p><img alt=\"{}\" src=\"data:{mime};base64,{}\"></p>",
                esc(p),
                base64::engine::general_purpose::STANDARD.encode(bytes)
            );
        }
    }
    html.push_str("</body></html>\n");
    let p = out.dir.join("report.html");
    fs::write(&p, html).map_err(|e| werr(&p)(e.to_string()))
}

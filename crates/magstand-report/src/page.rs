//! The self-contained HTML report: one page, SVG figures inline, no network needed to view it;
//! every figure is also written as a standalone SVG file next to it.
use std::path::Path;

use magstand_core::atomic_file;

use crate::ReportError;

/// A figure on the page.
#[derive(Debug, Clone)]
pub struct Figure {
    /// File name without extension; also the element id.
    pub name: String,
    /// One sentence under the figure.
    pub caption: String,
    /// The SVG text.
    pub svg: String,
}

impl Figure {
    /// The name of the figure's standalone file, `NAME.svg`.
    pub fn file_name(&self) -> String {
        format!("{}.svg", self.name)
    }
}

/// A section of the page.
#[derive(Debug, Clone, Default)]
pub struct Section {
    /// Heading.
    pub title: String,
    /// Paragraphs above the figures (plain text, escaped when written).
    pub text: Vec<String>,
    /// Tables: header cells and rows of cells (plain text).
    pub tables: Vec<(Vec<String>, Vec<Vec<String>>)>,
    /// Figures.
    pub figures: Vec<Figure>,
}

/// The file name of the page [`Report::write`] writes.
pub const PAGE: &str = "index.html";

impl Section {
    /// An empty section titled `title`.
    pub fn new(title: &str) -> Self {
        Self {
            title: title.into(),
            ..Default::default()
        }
    }

    /// Adds a figure.
    pub fn figure(&mut self, name: &str, caption: &str, svg: String) {
        self.figures.push(Figure {
            name: name.into(),
            caption: caption.into(),
            svg,
        });
    }
}

/// The whole report.
#[derive(Debug, Clone, Default)]
pub struct Report {
    /// Page title.
    pub title: String,
    /// What was run: (what, value) lines of the header, so the page can be reproduced.
    pub provenance: Vec<(String, String)>,
    /// Sections in order.
    pub sections: Vec<Section>,
}

/// Escapes text for HTML.
pub fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

const STYLE: &str = "body{font-family:sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;color:#222}\
h1{font-size:1.6em}h2{border-bottom:1px solid #ccc;padding-bottom:.2em;margin-top:2em}\
figure{margin:1.5em 0}figcaption{color:#555;font-size:.9em}svg{max-width:100%;height:auto}\
table{border-collapse:collapse;margin:1em 0;font-size:.9em}td,th{border:1px solid #ccc;padding:.3em .6em;text-align:right}\
th{background:#f3f3f3}td:first-child,th:first-child{text-align:left}\
dl.prov{display:grid;grid-template-columns:max-content auto;gap:.2em 1em;font-size:.9em}dl.prov dt{color:#555}\
dl.prov dd{margin:0;font-family:monospace;word-break:break-all}";

impl Report {
    /// The page as HTML text.
    pub fn to_html(&self) -> String {
        let mut h = format!(
            "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{}</title><style>{STYLE}</style></head><body>\n<h1>{}</h1>\n<dl class=\"prov\">",
            escape(&self.title),
            escape(&self.title)
        );
        for (k, v) in &self.provenance {
            h += &format!("<dt>{}</dt><dd>{}</dd>", escape(k), escape(v));
        }
        h += "</dl>\n";
        for (i, s) in self.sections.iter().enumerate() {
            h += &format!(
                "<section id=\"section-{}\"><h2>{}</h2>\n",
                i + 1,
                escape(&s.title)
            );
            for p in &s.text {
                h += &format!("<p>{}</p>\n", escape(p));
            }
            for (head, rows) in &s.tables {
                h += "<table><tr>";
                for c in head {
                    h += &format!("<th>{}</th>", escape(c));
                }
                h += "</tr>";
                for r in rows {
                    h += "<tr>";
                    for c in r {
                        h += &format!("<td>{}</td>", escape(c));
                    }
                    h += "</tr>";
                }
                h += "</table>\n";
            }
            for f in &s.figures {
                // The SVG goes in as it is: plotters writes well-formed SVG, and inlining it
                // keeps the page viewable offline.
                h += &format!(
                    "<figure class=\"figure\" id=\"fig-{}\">{}<figcaption>{} (<a href=\"{}.svg\">{}.svg</a>)</figcaption></figure>\n",
                    escape(&f.name),
                    f.svg,
                    escape(&f.caption),
                    escape(&f.name),
                    escape(&f.name)
                );
            }
            h += "</section>\n";
        }
        h + "</body></html>\n"
    }

    /// The names of the files [`Report::write`] writes: one SVG per figure and the page.
    pub fn file_names(&self) -> Vec<String> {
        self.sections
            .iter()
            .flat_map(|s| s.figures.iter().map(Figure::file_name))
            .chain([PAGE.to_string()])
            .collect()
    }

    /// Writes `dir/index.html` and every figure as `dir/NAME.svg` (each atomically); `dir` must
    /// exist. Returns the page's path.
    pub fn write(&self, dir: &Path) -> Result<std::path::PathBuf, ReportError> {
        for s in &self.sections {
            for f in &s.figures {
                atomic_file::write_bytes(&dir.join(f.file_name()), f.svg.as_bytes())?;
            }
        }
        let page = dir.join(PAGE);
        atomic_file::write_bytes(&page, self.to_html().as_bytes())?;
        Ok(page)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_is_escaped_and_figures_are_inline_and_linked() {
        let mut s = Section::new("A <b> section");
        s.text.push("x < y & z".into());
        s.tables
            .push((vec!["method".into()], vec![vec!["px4 <line>".into()]]));
        s.figure("fig-one", "caption", "<svg id=\"inner\"></svg>".into());
        let r = Report {
            title: "T".into(),
            provenance: vec![("command".into(), "magstand report --out \"x\"".into())],
            sections: vec![s],
        };
        let html = r.to_html();
        assert!(html.contains("A &lt;b&gt; section") && html.contains("x &lt; y &amp; z"));
        assert!(html.contains("px4 &lt;line&gt;") && html.contains("&quot;x&quot;"));
        assert!(html.contains("<svg id=\"inner\"></svg>") && html.contains("href=\"fig-one.svg\""));
        let dir = tempfile::tempdir().unwrap();
        let page = r.write(dir.path()).unwrap();
        assert!(page.exists() && dir.path().join("fig-one.svg").exists());
    }
}

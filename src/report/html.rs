//! A small builder for self-contained HTML reports: every image inline (SVG as markup, PNG as
//! base64 data URIs), one file that opens anywhere, with no network access.

use base64::Engine;

/// Escapes text for HTML content and attribute values.
pub fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

/// A report page being assembled.
pub struct Page {
    title: String,
    body: String,
}

const STYLE: &str = "body{font-family:sans-serif;margin:24px;color:#222;max-width:1200px}\
h1{font-size:22px}h2{font-size:18px;border-bottom:1px solid #ccc;padding-bottom:4px;margin-top:28px}\
table{border-collapse:collapse;margin:8px 0}td,th{border:1px solid #ccc;padding:4px 8px;text-align:right}\
th{background:#f3f3f3}td:first-child,th:first-child{text-align:left}\
.figs{display:flex;flex-wrap:wrap;gap:12px}.figs figure{margin:0;width:min-content}\
figcaption{font-size:12px;color:#555;text-align:center}.bad{color:#b00;font-weight:bold}\
.ok{color:#070;font-weight:bold}.note{font-size:13px;color:#555}.warn{color:#a55a00;font-weight:bold}\
.swatch{display:inline-block;width:24px;height:4px;margin:0 6px 3px 16px}";

impl Page {
    pub fn new(title: &str) -> Page {
        Page {
            title: title.to_string(),
            body: String::new(),
        }
    }

    /// A section heading.
    pub fn heading(&mut self, text: &str) -> &mut Self {
        self.body.push_str(&format!("<h2>{}</h2>\n", escape(text)));
        self
    }

    /// A paragraph of plain text (escaped), with an optional CSS class.
    pub fn paragraph(&mut self, text: &str, class: Option<&str>) -> &mut Self {
        match class {
            Some(c) => self.body.push_str(&format!(
                "<p class=\"{}\">{}</p>\n",
                escape(c),
                escape(text)
            )),
            None => self.body.push_str(&format!("<p>{}</p>\n", escape(text))),
        }
        self
    }

    /// A table: a header row and rows of text cells (escaped).
    pub fn table(&mut self, header: &[&str], rows: &[Vec<String>]) -> &mut Self {
        let rows: Vec<Vec<Cell>> = rows
            .iter()
            .map(|row| row.iter().map(|c| Cell::Text(c.clone())).collect())
            .collect();
        self.table_cells(header, &rows)
    }

    /// A table whose cells may be links.
    pub fn table_cells(&mut self, header: &[&str], rows: &[Vec<Cell>]) -> &mut Self {
        self.body.push_str("<table><tr>");
        for h in header {
            self.body.push_str(&format!("<th>{}</th>", escape(h)));
        }
        self.body.push_str("</tr>\n");
        for row in rows {
            self.body.push_str("<tr>");
            for cell in row {
                let inner = match cell {
                    Cell::Text(text) => escape(text),
                    Cell::Link { href, text } => {
                        format!("<a href=\"{}\">{}</a>", escape(href), escape(text))
                    }
                };
                self.body.push_str(&format!("<td>{inner}</td>"));
            }
            self.body.push_str("</tr>\n");
        }
        self.body.push_str("</table>\n");
        self
    }

    /// A colour legend: a short bar of each colour followed by its label.
    pub fn legend(&mut self, entries: &[(&str, [u8; 3])]) -> &mut Self {
        self.body.push_str("<p class=\"legend\">");
        for (label, [r, g, b]) in entries {
            self.body.push_str(&format!(
                "<span class=\"swatch\" style=\"background:rgb({r},{g},{b})\"></span>{}",
                escape(label)
            ));
        }
        self.body.push_str("</p>\n");
        self
    }

    /// A row of figures: each an inline SVG document or PNG bytes, with a caption.
    pub fn figures(&mut self, figures: &[Figure]) -> &mut Self {
        self.body.push_str("<div class=\"figs\">\n");
        for f in figures {
            let content = match &f.content {
                FigureContent::Svg(svg) => svg.clone(),
                FigureContent::Png(bytes) => format!(
                    "<img alt=\"{}\" src=\"data:image/png;base64,{}\">",
                    escape(&f.caption),
                    base64::engine::general_purpose::STANDARD.encode(bytes)
                ),
            };
            self.body.push_str(&format!(
                "<figure>{content}<figcaption>{}</figcaption></figure>\n",
                escape(&f.caption)
            ));
        }
        self.body.push_str("</div>\n");
        self
    }

    /// The whole document.
    pub fn finish(&self) -> String {
        format!(
            "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{t}</title><style>{STYLE}</style></head>\n<body><h1>{t}</h1>\n{}</body></html>\n",
            self.body,
            t = escape(&self.title)
        )
    }
}

/// A figure's content.
pub enum FigureContent {
    Svg(String),
    Png(Vec<u8>),
}

/// A table cell: text, or a link (relative, e.g. to a case's report).
pub enum Cell {
    Text(String),
    Link { href: String, text: String },
}

/// A captioned figure.
pub struct Figure {
    pub caption: String,
    pub content: FigureContent,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn page_is_self_contained_and_escaped() {
        let mut page = Page::new("case <01>");
        page.heading("metrics")
            .table(
                &["structure", "MASD (mm)"],
                &[vec!["malleus & co".into(), "0.100".into()]],
            )
            .table_cells(
                &["case"],
                &[vec![Cell::Link {
                    href: "a b/report.html".into(),
                    text: "case \"a\"".into(),
                }]],
            )
            .figures(&[Figure {
                caption: "png".into(),
                content: FigureContent::Png(vec![1, 2, 3]),
            }]);
        let html = page.finish();
        assert!(html.contains("<title>case &lt;01&gt;</title>"));
        assert!(html.contains("malleus &amp; co"));
        assert!(html.contains("data:image/png;base64,AQID"));
        assert!(html.contains("<a href=\"a b/report.html\">case &quot;a&quot;</a>"));
        assert!(!html.contains("http"), "no external resource");
    }
}

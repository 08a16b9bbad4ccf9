//! One self-contained HTML page for a report (`mrtwin diagnose --html`): the Markdown
//! report rendered with `pulldown-cmark` (tables on), followed by the plots as inline SVG.
//! Nothing is referenced from outside the file (no scripts, style sheets, fonts or
//! images), so it can be mailed to a colleague and opened offline.

use pulldown_cmark::{html, Options, Parser};

/// A plot for the page: its caption and its SVG text ([`crate::plot::svg_string`]).
#[derive(Debug, Clone)]
pub struct InlineFigure {
    /// Caption under the plot.
    pub caption: String,
    /// The `<svg>` element.
    pub svg: String,
}

/// Style of the page: readable tables and figures that scale down to the window.
const STYLE: &str = "body{font-family:sans-serif;max-width:1100px;margin:2em auto;\
padding:0 1em;color:#222;line-height:1.45}\
table{border-collapse:collapse;margin:1em 0}\
th,td{border:1px solid #bbb;padding:0.25em 0.6em;text-align:left;vertical-align:top}\
th{background:#eee}code{background:#f4f4f4;padding:0 0.2em}\
figure{margin:1.5em 0}figure svg{max-width:100%;height:auto;border:1px solid #ddd}\
figcaption{font-size:0.9em;color:#555}";

/// The page: `title`, the report `markdown` as HTML, then `figures` under a "Plots"
/// heading.
pub fn report_page(title: &str, markdown: &str, figures: &[InlineFigure]) -> String {
    let mut body = String::new();
    html::push_html(&mut body, Parser::new_ext(markdown, Options::ENABLE_TABLES));
    let mut page = format!(
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n\
         <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n\
         <title>{}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n{body}",
        escape(title)
    );
    if !figures.is_empty() {
        page.push_str("<h2>Plots</h2>\n");
    }
    for f in figures {
        page.push_str("<figure>\n");
        page.push_str(without_xml_declaration(&f.svg));
        page.push_str(&format!(
            "\n<figcaption>{}</figcaption>\n</figure>\n",
            escape(&f.caption)
        ));
    }
    page.push_str("</body>\n</html>\n");
    page
}

/// `text` with the characters HTML gives a meaning escaped.
fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// An SVG document's text from its `<svg` element on (an XML declaration is not allowed
/// inside HTML).
fn without_xml_declaration(svg: &str) -> &str {
    svg.find("<svg").map_or(svg, |k| &svg[k..])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_page_holds_the_report_as_html_and_the_plots_inline() {
        let md =
            "# Diagnosis of a&b.csv\n\n| effect | gain |\n|---|---|\n| **field_lag** | 12 % |\n";
        let fig = InlineFigure {
            caption: "loops <F–v>".into(),
            svg: "<?xml version=\"1.0\"?>\n<svg width=\"10\" height=\"10\"><path d=\"M0 0L5 5\"/></svg>"
                .into(),
        };
        let page = report_page("a&b.csv", md, &[fig]);
        assert!(page.starts_with("<!DOCTYPE html>"));
        assert!(page.contains("<title>a&amp;b.csv</title>"));
        assert!(page.contains("<table>") && page.contains("<strong>field_lag</strong>"));
        assert!(page.contains("<figure>\n<svg width=\"10\""));
        assert!(!page.contains("<?xml"));
        assert!(page.contains("<figcaption>loops &lt;F–v&gt;</figcaption>"));
    }
}

//! `report.html`: the Markdown report (`report.md`) as one self-contained page. Every image is
//! embedded as a `data:` URI, so the page can be mailed or archived alone; a click on an image
//! shows it full size over the page (a second click closes it), and tables scroll sideways.
//!
//! It converts exactly the Markdown `report.rs` writes: `#` headings, pipe tables, `- ` lists,
//! paragraphs, and inline `![alt](path)`, `[text](#anchor)`, `**bold**`, `*italic*` and
//! `` `code` ``. Everything else passes through escaped. A general Markdown engine is not needed
//! for one generator's output (and none is in the dependency set).

use std::path::Path;

/// Standard base64 (RFC 4648, with padding).
pub fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            *chunk.get(1).unwrap_or(&0),
            *chunk.get(2).unwrap_or(&0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for (i, shift) in [18, 12, 6, 0].into_iter().enumerate() {
            if i <= chunk.len() {
                out.push(ALPHABET[(n >> shift & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// The anchor of a heading, as GitHub's Markdown makes it (lower case, spaces to `-`,
/// punctuation dropped): the report's contents link to it in both forms.
pub fn anchor(heading: &str) -> String {
    heading
        .to_lowercase()
        .chars()
        .filter(|c| c.is_alphanumeric() || *c == ' ' || *c == '-')
        .map(|c| if c == ' ' { '-' } else { c })
        .collect()
}

fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// Inline Markdown of one line (see module docs); image paths are read relative to `base`
/// (a missing image becomes its path, marked).
fn inline(text: &str, base: &Path) -> String {
    let mut out = String::new();
    let mut rest = text;
    'outer: while let Some(c) = rest.chars().next() {
        // `![alt](path)` and `[text](href)`.
        let link = rest
            .strip_prefix("![")
            .map(|r| (true, r))
            .or_else(|| rest.strip_prefix('[').map(|r| (false, r)));
        if let Some((is_image, after)) = link
            && let Some((label, tail)) = after.split_once("](")
            && let Some((target, tail)) = tail.split_once(')')
        {
            if is_image {
                out.push_str(&image(label, target, base));
            } else {
                out.push_str(&format!(
                    "<a href=\"{}\">{}</a>",
                    escape(target),
                    inline(label, base)
                ));
            }
            rest = tail;
            continue;
        }
        for (mark, tag) in [("**", "strong"), ("`", "code"), ("*", "em")] {
            if let Some((inner, tail)) = rest.strip_prefix(mark).and_then(|r| r.split_once(mark))
                && !inner.is_empty()
            {
                let inner = if tag == "code" {
                    escape(inner)
                } else {
                    inline(inner, base)
                };
                out.push_str(&format!("<{tag}>{inner}</{tag}>"));
                rest = tail;
                continue 'outer;
            }
        }
        out.push_str(&escape(&c.to_string()));
        rest = &rest[c.len_utf8()..];
    }
    out
}

fn image(alt: &str, path: &str, base: &Path) -> String {
    match std::fs::read(base.join(path)) {
        Ok(bytes) => format!(
            "<img alt=\"{}\" title=\"{}\" loading=\"lazy\" src=\"data:image/png;base64,{}\">",
            escape(alt),
            escape(path),
            base64(&bytes)
        ),
        Err(_) => format!(
            "<span class=\"missing\">[missing image {}]</span>",
            escape(path)
        ),
    }
}

/// The page for the Markdown report `md`, whose image paths are relative to `base`.
pub fn report_page(md: &str, base: &Path, title: &str) -> String {
    let mut body = String::new();
    let mut lines = md.lines().peekable();
    while let Some(line) = lines.next() {
        let t = line.trim_end();
        if t.is_empty() {
            continue;
        }
        if let Some(level) =
            (1..=6).find(|&n| t.starts_with(&"#".repeat(n)) && t[n..].starts_with(' '))
        {
            let text = t[level + 1..].trim();
            let id = anchor(text);
            body.push_str(&format!(
                "<h{level} id=\"{id}\">{}</h{level}>\n",
                inline(text, base)
            ));
        } else if t.starts_with('|') {
            let mut rows = vec![t.to_string()];
            while let Some(next) = lines.peek().filter(|l| l.trim_start().starts_with('|')) {
                rows.push(next.trim().to_string());
                lines.next();
            }
            body.push_str("<div class=\"table\"><table>\n");
            let cells = |row: &str| -> Vec<String> {
                row.trim()
                    .trim_matches('|')
                    .split('|')
                    .map(|c| c.trim().to_string())
                    .collect()
            };
            for (i, row) in rows.iter().enumerate() {
                if i == 1 && row.contains("---") {
                    continue;
                }
                let tag = if i == 0 { "th" } else { "td" };
                body.push_str("<tr>");
                for c in cells(row) {
                    body.push_str(&format!("<{tag}>{}</{tag}>", inline(&c, base)));
                }
                body.push_str("</tr>\n");
            }
            body.push_str("</table></div>\n");
        } else if let Some(item) = t.strip_prefix("- ") {
            body.push_str("<ul>\n");
            body.push_str(&format!("<li>{}</li>\n", inline(item, base)));
            while let Some(next) = lines.peek().and_then(|l| l.strip_prefix("- ")) {
                body.push_str(&format!("<li>{}</li>\n", inline(next, base)));
                lines.next();
            }
            body.push_str("</ul>\n");
        } else {
            body.push_str(&format!("<p>{}</p>\n", inline(t, base)));
        }
    }
    format!(
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{title}</title>\n<style>\n{STYLE}</style></head>\n<body>\n{body}<div id=\"zoom\" onclick=\"this.style.display='none'\"></div>\n<script>{SCRIPT}</script>\n</body></html>\n",
        title = escape(title)
    )
}

const STYLE: &str = "body{font:15px/1.45 system-ui,sans-serif;max-width:1400px;margin:2em auto;padding:0 1em;color:#222}
h1,h2,h3{margin-top:1.6em}
.table{overflow-x:auto;margin:1em 0}
table{border-collapse:collapse;font-size:13px}
th,td{border:1px solid #ccc;padding:3px 6px;text-align:right;vertical-align:top}
th:first-child,td:first-child{text-align:left}
tr:nth-child(even){background:#f6f6f6}
img{max-width:100%;cursor:zoom-in;image-rendering:pixelated}
td img{max-width:320px}
code{background:#f0f0f0;padding:0 3px}
.missing{color:#b00}
#zoom{display:none;position:fixed;inset:0;background:rgba(0,0,0,.85);z-index:9;cursor:zoom-out;overflow:auto;text-align:center}
#zoom img{max-width:none;cursor:zoom-out;margin:2em auto}
";

const SCRIPT: &str = "document.querySelectorAll('body > * img').forEach(function(i){i.addEventListener('click',function(){var z=document.getElementById('zoom');z.innerHTML='';var c=i.cloneNode();z.appendChild(c);z.style.display='block';});});";

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_matches_rfc_4648_vectors() {
        for (plain, encoded) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(base64(plain.as_bytes()), encoded, "{plain:?}");
        }
    }

    #[test]
    fn the_report_subset_converts_and_images_are_embedded() {
        let dir = std::env::temp_dir().join(format!("forestlod-html-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("a.png"), [1u8, 2, 3]).unwrap();
        let md = "# Title\n\nSome **bold** and `a<b` and *it*.\n\n| x | y |\n|---|--:|\n| ![](a.png) | [l](#t) |\n\n- one\n- two\n";
        let page = report_page(md, &dir, "t");
        std::fs::remove_dir_all(&dir).ok();
        assert!(page.contains("<h1 id=\"title\">Title</h1>"), "{page}");
        assert!(page.contains("<strong>bold</strong>") && page.contains("<code>a&lt;b</code>"));
        assert!(page.contains("<em>it</em>"));
        assert!(page.contains("<th>x</th><th>y</th>") && !page.contains("---"));
        assert!(
            page.contains("src=\"data:image/png;base64,AQID\""),
            "{page}"
        );
        assert!(page.contains("<a href=\"#t\">l</a>"));
        assert!(page.contains("<li>one</li>\n<li>two</li>"));
        assert!(
            !page.contains("src=\"a.png\""),
            "no image left outside the page"
        );
    }
}

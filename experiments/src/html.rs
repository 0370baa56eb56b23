//! The report's HTML pages (issue 35): the Markdown `report.rs` writes, turned into HTML by
//! `pulldown-cmark` (CommonMark with GitHub tables), in two forms:
//!
//! - [`report_page`]: **one self-contained page** (`report.html`, for mailing or archiving): every
//!   image embedded as a `data:` URI (base64 by the `base64` crate); a PNG plot whose SVG twin
//!   is in the [`Embeds`] too is embedded as that SVG (a quarter of the bytes);
//! - [`linked_page`]: **a page that links its images** (the index and the per-sweep pages): each
//!   image is a lazy-loaded thumbnail that links to the full-size file beside the page, so a page
//!   weighs its text only.
//!
//! In both a click on an image shows it full size over the page (a second click closes it), tables
//! scroll sideways and headings carry the GitHub-style anchors ([`anchor`]) the contents link to.
//!
//! **A report reads only what its generator listed** (issue 28): a page shows an image only when
//! its path, as the Markdown writes it, is a key of the [`Embeds`] the caller checked (a plot or
//! frame its run's manifest names, resolved to a regular file under the run folder); any other
//! image path is shown as not embedded and never opened. Text the generator takes from a manifest
//! goes through [`escape_markdown`] (or [`code_span`]), so it cannot become an image or a link,
//! and paths through [`escape_destination`]. Raw HTML in the Markdown is shown as text, except
//! the `<br>` line breaks the generator writes in table cells.
//!
//! **Bounded** (issue 28, unbounded reads): each embedded image is read through
//! [`forestlod_reference::files`] (regular files only) with a limit of
//! [`MAX_EMBEDDED_IMAGE_BYTES`], and all the images a page embeds, counted at every place the page
//! shows them, may hold at most [`MAX_EMBEDDED_TOTAL_BYTES`]; past either the page is not made
//! and the error names the file and the manifest key that named it ([`Embed::named_by`]).
//! `report.rs` checks the same limits from the files' sizes before anything is read or written,
//! so these are the second line (a file that grew or changed in between).

use std::collections::BTreeMap;
use std::path::PathBuf;

use base64::Engine as _;
use forestlod_reference::InputError;
use forestlod_reference::files::{read_limited, size_text};
use pulldown_cmark::{CowStr, Event, HeadingLevel, Options, Parser, Tag, TagEnd};

/// Largest image a report embeds, bytes: 32 MiB. The sweeps' plots and frames are PNGs of at
/// most a few MB (a 1280x720 frame is under 1 MB, the committed ones at most 0.7 MB); a 4K RGBA
/// frame stored uncompressed would be 33 MB. Base64 makes it 43 MB of page.
pub const MAX_EMBEDDED_IMAGE_BYTES: u64 = 32 << 20;

/// Most bytes of images one report embeds, all together (each image counted every time the page
/// shows it): 256 MiB, a page of about 350 MB, which a browser still opens. The committed run's
/// images are 28 MB in all. Without this bound a manifest listing one large plot thousands of
/// times would make a page of terabytes.
pub const MAX_EMBEDDED_TOTAL_BYTES: u64 = 256 << 20;

/// An image a page may embed: the file it was checked to be, and what named it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Embed {
    /// The file (a regular file under the run folder, checked by the caller).
    pub file: PathBuf,
    /// The link an error about it is reached through, e.g. `run folder R: R/s/sweep.json: key
    /// plots[0][0] = "runtime.png"`.
    pub named_by: String,
}

/// The images a page may embed: each path as the Markdown writes it (unescaped), with the file
/// it was checked to be (`None`: named but absent, shown as a missing image).
pub type Embeds = BTreeMap<String, Option<Embed>>;

/// Characters [`escape_markdown`] escapes: those this converter (or CommonMark) would read as
/// the start or end of an image, link, emphasis, code span, escape or HTML tag.
const MARKDOWN_SPECIAL: &[char] = &['\\', '`', '*', '[', ']', '<'];

fn escape_chars(text: &str, special: &[char]) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '\n' | '\r' => out.push(' '),
            c if special.contains(&c) => {
                out.push('\\');
                out.push(c);
            }
            c => out.push(c),
        }
    }
    out
}

/// `text` (from a manifest or a CSV) as Markdown that shows it literally: every character that
/// could open an image, a link, emphasis or a tag is backslash-escaped, line breaks become
/// spaces. A code span (`` `name` ``) whose content holds none of those characters is kept, as
/// it is literal in every renderer (the built-in sweeps' captions use them).
pub fn escape_markdown(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    while let Some(i) = rest.find('`') {
        out.push_str(&escape_chars(&rest[..i], MARKDOWN_SPECIAL));
        let after = &rest[i + 1..];
        match after.find('`') {
            Some(j)
                if j > 0
                    && !after[..j]
                        .contains(|c| MARKDOWN_SPECIAL.contains(&c) || c == '\n' || c == '\r') =>
            {
                out.push_str(&rest[i..i + j + 2]);
                rest = &after[j + 1..];
            }
            _ => {
                out.push_str("\\`");
                rest = after;
            }
        }
    }
    out.push_str(&escape_chars(rest, MARKDOWN_SPECIAL));
    out
}

/// `text` as a code span when that shows it literally, else [`escape_markdown`]'s plain text.
pub fn code_span(text: &str) -> String {
    if text.contains(|c| MARKDOWN_SPECIAL.contains(&c) || c == '\n' || c == '\r') {
        escape_markdown(text)
    } else {
        format!("`{text}`")
    }
}

/// A path as a link or image destination: `\\`, `(` and `)` escaped, and the whole in angle
/// brackets when it holds a space, a control character or an angle bracket (CommonMark allows
/// those only there, where `<` and `>` are escaped).
pub fn escape_destination(path: &str) -> String {
    if path.contains(|c: char| c == ' ' || c == '<' || c == '>' || c.is_control()) {
        let inner: String = path.chars().filter(|c| !matches!(c, '\n' | '\r')).collect();
        format!("<{}>", escape_chars(&inner, &['\\', '<', '>']))
    } else {
        escape_chars(path, &['\\', '(', ')'])
    }
}

/// Standard base64 (RFC 4648, with padding), by the `base64` crate.
pub fn base64(bytes: &[u8]) -> String {
    base64::engine::general_purpose::STANDARD.encode(bytes)
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

/// How a page shows its images.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Mode {
    /// Embedded as `data:` URIs, at most this many bytes in all.
    Embedded(u64),
    /// Linked: a lazy-loaded thumbnail linking to the full-size file.
    Linked,
}

/// What a page's images have used so far: the bytes embedded, and the first error (after which
/// no image is read).
struct Images<'a> {
    embeds: &'a Embeds,
    mode: Mode,
    total: u64,
    error: Option<InputError>,
}

impl Images<'_> {
    fn image(&mut self, alt: &str, path: &str) -> String {
        if self.error.is_some() {
            return String::new();
        }
        let limit = match self.mode {
            Mode::Embedded(limit) => limit,
            Mode::Linked => return linked_image(alt, path, self.embeds),
        };
        // A PNG whose checked SVG twin is listed too: the twin is embedded (smaller, sharp).
        let twin = path
            .strip_suffix(".png")
            .map(|stem| format!("{stem}.svg"))
            .filter(|svg| matches!(self.embeds.get(svg), Some(Some(_))));
        let path = twin.as_deref().unwrap_or(path);
        image(alt, path, self.embeds, limit, &mut self.total).unwrap_or_else(|e| {
            self.error = Some(e);
            String::new()
        })
    }
}

/// The markup of a path that is not a checked file of the run: named but absent (`Some(None)`),
/// or not listed at all.
fn not_shown(path: &str, embeds: &Embeds) -> String {
    match embeds.get(path) {
        Some(_) => format!(
            "<span class=\"missing\">[missing image {}]</span>",
            escape(path)
        ),
        None => format!(
            "<span class=\"missing\">[image not embedded: {} is not a file of this run's manifests]</span>",
            escape(path)
        ),
    }
}

/// A linked image: a lazy-loaded thumbnail of the checked file `path` (relative to the page),
/// inside a link to it at full size.
fn linked_image(alt: &str, path: &str, embeds: &Embeds) -> String {
    match embeds.get(path) {
        Some(Some(_)) => {
            let href = escape(&percent_path(path));
            format!(
                "<a class=\"full\" href=\"{href}\"><img alt=\"{}\" title=\"{}\" loading=\"lazy\" src=\"{href}\"></a>",
                escape(alt),
                escape(path),
            )
        }
        _ => not_shown(path, embeds),
    }
}

/// `path` as a relative URL: every byte outside the unreserved set and `/` percent-encoded, so
/// a file name with spaces, `#` or `?` still names the file.
fn percent_path(path: &str) -> String {
    let mut out = String::with_capacity(path.len());
    for b in path.bytes() {
        if b.is_ascii_alphanumeric() || b"-._~/".contains(&b) {
            out.push(b as char);
        } else {
            out.push_str(&format!("%{b:02X}"));
        }
    }
    out
}

/// An image: embedded when `path` is one of `embeds` (read within the limits of the module
/// docs, `total` counting the bytes embedded so far), else marked as missing or not embedded.
fn image(
    alt: &str,
    path: &str,
    embeds: &Embeds,
    limit: u64,
    total: &mut u64,
) -> Result<String, InputError> {
    let Some(Some(embed)) = embeds.get(path) else {
        return Ok(not_shown(path, embeds));
    };
    let bytes = read_limited(&embed.file, MAX_EMBEDDED_IMAGE_BYTES)
        .map_err(|e| e.within(embed.named_by.clone()))?;
    *total += bytes.len() as u64;
    if *total > limit {
        let file = embed.file.display().to_string();
        return Err(InputError::new(
            &file,
            "embedded images",
            size_text(*total),
            format!(
                "embedding it brings the report's images over the limit of {} for one report",
                size_text(limit)
            ),
        )
        .within(embed.named_by.clone()));
    }
    let mime = if path.ends_with(".svg") {
        "image/svg+xml"
    } else {
        "image/png"
    };
    Ok(format!(
        "<img alt=\"{}\" title=\"{}\" loading=\"lazy\" src=\"data:{mime};base64,{}\">",
        escape(alt),
        escape(path),
        base64(&bytes)
    ))
}

/// The page for the Markdown report `md`, embedding the images of `embeds` it names; an error
/// when an image is over its limit or cannot be read (module docs).
pub fn report_page(md: &str, embeds: &Embeds, title: &str) -> Result<String, InputError> {
    page(md, embeds, title, MAX_EMBEDDED_TOTAL_BYTES)
}

/// [`report_page`] with `limit` bytes of images in all.
fn page(md: &str, embeds: &Embeds, title: &str, limit: u64) -> Result<String, InputError> {
    convert(md, embeds, title, Mode::Embedded(limit))
}

/// The page for the Markdown `md` whose images (paths relative to the page, those of `embeds`
/// only) are linked, not embedded: lazy-loaded thumbnails linking to the full-size files (module
/// docs). Reads no image, so it cannot fail.
pub fn linked_page(md: &str, embeds: &Embeds, title: &str) -> String {
    convert(md, embeds, title, Mode::Linked)
        .unwrap_or_else(|e| unreachable!("a linked page reads no image, so it has no error: {e}"))
}

/// The plain text of a heading's events (for its anchor).
fn plain_text(events: &[Event]) -> String {
    events
        .iter()
        .filter_map(|e| match e {
            Event::Text(t) | Event::Code(t) => Some(t.as_ref()),
            _ => None,
        })
        .collect()
}

fn convert(md: &str, embeds: &Embeds, title: &str, mode: Mode) -> Result<String, InputError> {
    let mut images = Images {
        embeds,
        mode,
        total: 0,
        error: None,
    };
    let mut events: Vec<Event> = Vec::new();
    let mut parser = Parser::new_ext(md, Options::ENABLE_TABLES);
    while let Some(event) = parser.next() {
        match event {
            // An image: its alt text is the plain text up to its end; the markup is ours.
            Event::Start(Tag::Image { dest_url, .. }) => {
                let mut alt = String::new();
                for inner in parser.by_ref() {
                    match inner {
                        Event::End(TagEnd::Image) => break,
                        Event::Text(t) | Event::Code(t) => alt.push_str(&t),
                        _ => {}
                    }
                }
                events.push(Event::InlineHtml(CowStr::from(
                    images.image(&alt, &dest_url),
                )));
            }
            // A heading gets the anchor of its text.
            Event::Start(Tag::Heading { level, .. }) => {
                let mut inner: Vec<Event> = Vec::new();
                for e in parser.by_ref() {
                    if matches!(e, Event::End(TagEnd::Heading(_))) {
                        break;
                    }
                    inner.push(e);
                }
                let id = anchor(&plain_text(&inner));
                events.push(Event::Html(CowStr::from(format!(
                    "<{} id=\"{}\">",
                    tag_name(level),
                    escape(&id)
                ))));
                // Images inside a heading are not written by the generator: shown as text.
                events.extend(inner.into_iter().map(|e| match e {
                    Event::Html(h) | Event::InlineHtml(h) => Event::Text(h),
                    e => e,
                }));
                events.push(Event::Html(CowStr::from(format!(
                    "</{}>\n",
                    tag_name(level)
                ))));
            }
            // Raw HTML is text, except the generator's `<br>`.
            Event::InlineHtml(h) if h.as_ref() == "<br>" => events.push(Event::InlineHtml(h)),
            Event::Html(h) | Event::InlineHtml(h) => events.push(Event::Text(h)),
            Event::Start(Tag::Table(a)) => {
                events.push(Event::Html(CowStr::from("<div class=\"table\">")));
                events.push(Event::Start(Tag::Table(a)));
            }
            Event::End(TagEnd::Table) => {
                events.push(Event::End(TagEnd::Table));
                events.push(Event::Html(CowStr::from("</div>\n")));
            }
            e => events.push(e),
        }
    }
    if let Some(e) = images.error.take() {
        return Err(e);
    }
    let mut body = String::new();
    pulldown_cmark::html::push_html(&mut body, events.into_iter());
    Ok(format!(
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><meta name=\"viewport\" content=\"width=device-width, initial-scale=1\"><title>{title}</title>\n<style>\n{STYLE}</style></head>\n<body>\n{body}<div id=\"zoom\" onclick=\"this.style.display='none'\"></div>\n<script>{SCRIPT}</script>\n</body></html>\n",
        title = escape(title)
    ))
}

/// `h1` .. `h6`.
fn tag_name(level: HeadingLevel) -> &'static str {
    match level {
        HeadingLevel::H1 => "h1",
        HeadingLevel::H2 => "h2",
        HeadingLevel::H3 => "h3",
        HeadingLevel::H4 => "h4",
        HeadingLevel::H5 => "h5",
        HeadingLevel::H6 => "h6",
    }
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
h1{font-size:1.6em;margin:.4em 0}
a.full img{width:620px;max-width:calc(50% - 8px);margin:0 4px 8px 0;vertical-align:top;image-rendering:auto}
td a.full img{width:auto;max-width:320px;image-rendering:pixelated}
img[src$=\".svg\"]{image-rendering:auto}
code{background:#f0f0f0;padding:0 3px}
.missing{color:#b00}
#zoom{display:none;position:fixed;inset:0;background:rgba(0,0,0,.85);z-index:9;cursor:zoom-out;overflow:auto;text-align:center}
#zoom img{max-width:none;cursor:zoom-out;margin:2em auto}
";

const SCRIPT: &str = "document.querySelectorAll('body > * img').forEach(function(i){if(i.closest('a.full'))return;i.addEventListener('click',function(){var z=document.getElementById('zoom');z.innerHTML='';var c=i.cloneNode();z.appendChild(c);z.style.display='block';});});";

#[cfg(test)]
mod tests {
    use super::*;

    fn embed(file: PathBuf) -> Option<Embed> {
        Some(Embed {
            file,
            named_by: "s/sweep.json: key plots[0][0]".into(),
        })
    }

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
        let embeds = Embeds::from([("a.png".to_string(), (embed(dir.join("a.png"))))]);
        let page = report_page(md, &embeds, "t").unwrap();
        std::fs::remove_dir_all(&dir).ok();
        assert!(page.contains("<h1 id=\"title\">Title</h1>"), "{page}");
        assert!(page.contains("<strong>bold</strong>") && page.contains("<code>a&lt;b</code>"));
        assert!(page.contains("<em>it</em>"));
        assert!(page.contains("<th>x</th>") && page.contains(">y</th>") && !page.contains("---"));
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

    #[test]
    fn only_listed_images_are_embedded_and_escaped_text_stays_text() {
        let dir =
            std::env::temp_dir().join(format!("forestlod-html-hostile-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("listed.png"), [1u8, 2, 3]).unwrap();
        std::fs::write(dir.join("secret"), [4u8, 5, 6]).unwrap();
        let secret = dir.join("secret").display().to_string();
        let embeds = Embeds::from([("listed.png".to_string(), (embed(dir.join("listed.png"))))]);
        // An image the generator did not list is never opened, whatever its path.
        let page = report_page(&format!("![x]({secret}) ![y](listed.png)"), &embeds, "t").unwrap();
        assert!(
            !page.contains("BAUG"),
            "the unlisted file was embedded: {page}"
        );
        assert!(page.contains("base64,AQID"), "{page}");
        assert!(page.contains("[image not embedded: "), "{page}");
        // Manifest text, escaped, is shown literally: no image, no link, no emphasis.
        for hostile in [
            format!("![x]({secret})"),
            format!("[x]({secret})"),
            format!("a\\](x) ![x]({secret})"),
            format!("`a` ![`x`]({secret}) *b* <img src=\"{secret}\">"),
            format!("x`y![x]({secret})"),
        ] {
            let md = escape_markdown(&hostile);
            let page = report_page(&format!("# {md}\n\n{md}\n\n| {md} |\n"), &embeds, "t").unwrap();
            assert!(
                !page.contains("<img") && !page.contains("<a ") && !page.contains("not embedded"),
                "{hostile:?} became markup: {page}"
            );
            assert!(!page.contains("<em>") && !page.contains("<img"), "{page}");
            let code = code_span(&hostile);
            let page = report_page(&format!("- ({code})\n"), &embeds, "t").unwrap();
            assert!(
                !page.contains("<img") && !page.contains("not embedded"),
                "{page}"
            );
        }
        // Destinations round-trip through their escapes.
        std::fs::write(dir.join("a (1).png"), [1u8, 2, 3]).unwrap();
        let embeds = Embeds::from([("a (1).png".to_string(), (embed(dir.join("a (1).png"))))]);
        let page = report_page(
            &format!("![]({})", escape_destination("a (1).png")),
            &embeds,
            "t",
        )
        .unwrap();
        std::fs::remove_dir_all(&dir).ok();
        assert!(page.contains("base64,AQID"), "{page}");
    }

    #[test]
    fn images_are_read_bounded_and_errors_name_the_key() {
        let dir =
            std::env::temp_dir().join(format!("forestlod-html-limits-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        // A special file (here a link to /dev/zero) is refused, naming the key that listed it.
        #[cfg(unix)]
        {
            let zero = dir.join("zero.png");
            let _ = std::fs::remove_file(&zero);
            std::os::unix::fs::symlink("/dev/zero", &zero).unwrap();
            let embeds = Embeds::from([("z.png".to_string(), embed(zero))]);
            let e = report_page("![](z.png)", &embeds, "t")
                .unwrap_err()
                .to_string();
            assert!(
                e.starts_with("s/sweep.json: key plots[0][0]: ") && e.contains("special file"),
                "{e}"
            );
        }
        // One image over the per-image limit.
        let big = dir.join("big.png");
        std::fs::File::create(&big)
            .unwrap()
            .set_len(MAX_EMBEDDED_IMAGE_BYTES + 1)
            .unwrap();
        let embeds = Embeds::from([("big.png".to_string(), embed(big.clone()))]);
        let e = report_page("![](big.png)", &embeds, "t")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("key plots[0][0]") && e.contains("limit of 33554432 bytes"),
            "{e}"
        );
        // An image within its limit, shown so often that the page would pass the total (a
        // total of 1000 bytes here; the real one is checked the same way).
        std::fs::write(&big, [7u8; 100]).unwrap();
        let embeds = Embeds::from([("big.png".to_string(), embed(big))]);
        assert!(page(&"![](big.png) ".repeat(10), &embeds, "t", 1000).is_ok());
        let e = page(&"![](big.png) ".repeat(11), &embeds, "t", 1000)
            .unwrap_err()
            .to_string();
        std::fs::remove_dir_all(&dir).ok();
        assert!(
            e.contains("embedded images: value \"1100 bytes\"")
                && e.contains("limit of 1000 bytes"),
            "{e}"
        );
    }
}

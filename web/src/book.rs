//! The book in the page: the chapters (`docs/*.md`) rendered to HTML when
//! the page is built, with pulldown-cmark, each a `<section>` of the page
//! whose id is the chapter's name (`vga` for `docs/vga.md`), so that the
//! captions' links and the chapters' links to each other work offline in
//! the single file.
//!
//! - Headings get GitHub's anchors (lower case, spaces to hyphens,
//!   punctuation dropped, `-1`, `-2` for repeats) after the chapter's name:
//!   `vga.md#page-flipping-in-vertical-retrace` is
//!   `#vga/page-flipping-in-vertical-retrace` in the page. A chapter's
//!   headings are one level down (its `#` title an `<h2>`): the page has
//!   its own `<h1>`.
//! - Links between chapters are rewritten to those ids; a link to a file
//!   outside the book (`../README.md`) keeps its text, unlinked, with the
//!   path in its title: the page holds no copy of it.
//! - Pictures are `data:` URIs. A PNG with at most 256 colours is written
//!   again with a palette, which keeps every pixel and makes the book's
//!   screenshots (RGB, mostly of two or three colours) several times
//!   smaller.
//! - An inline code span that is one of the page's own URLs (`?modeset=1&ops=3`,
//!   the step-by-step URLs of `vga.md`) is a link that opens the page in
//!   that state: a live figure, one click from the text.

use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use pulldown_cmark::{CowStr, Event, HeadingLevel, Options, Parser, Tag, TagEnd};

/// One chapter, rendered.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Chapter {
    /// The file's name without `.md`: the section's id.
    pub name: String,
    /// The chapter's HTML (no `<section>` around it).
    pub html: String,
}

/// The book, in reading order: the contents (`docs/README.md`) first, then
/// the chapters in the order it lists them, then any it leaves out.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Book {
    /// The chapters.
    pub chapters: Vec<Chapter>,
}

impl Book {
    /// The book as the page holds it: one `<section>` per chapter.
    pub fn html(&self) -> String {
        self.chapters
            .iter()
            .map(|chapter| {
                format!(
                    "<section id=\"{}\" class=\"chapter\">\n{}</section>\n",
                    chapter.name, chapter.html
                )
            })
            .collect()
    }
}

/// Reads and renders every `*.md` in `docs`; a picture that cannot be read
/// is named with its chapter.
pub fn read_book(docs: &Path) -> Result<Book, String> {
    let listing = std::fs::read_dir(docs).map_err(|e| format!("{}: {e}", docs.display()))?;
    let mut sources = BTreeMap::new();
    for entry in listing {
        let path = entry
            .map_err(|e| format!("{}: {e}", docs.display()))?
            .path();
        let Some(name) = path
            .file_name()
            .and_then(|n| n.to_str())
            .and_then(|n| n.strip_suffix(".md"))
        else {
            continue;
        };
        let text =
            std::fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))?;
        sources.insert(name.to_owned(), text);
    }
    let order = reading_order(&sources);
    let names: Vec<&str> = order.iter().map(String::as_str).collect();
    let mut pictures = Pictures::new(docs);
    let mut chapters = Vec::new();
    for name in &order {
        let html = render_chapter(name, &sources[name], &names, &mut |source| {
            pictures.data_uri(source)
        })
        .map_err(|e| format!("docs/{name}.md: {e}"))?;
        chapters.push(Chapter {
            name: name.clone(),
            html,
        });
    }
    Ok(Book { chapters })
}

/// README first, then the chapters as its links name them, then the rest
/// by name.
fn reading_order(sources: &BTreeMap<String, String>) -> Vec<String> {
    let mut order: Vec<String> = Vec::new();
    let mut add = |name: &str| {
        if sources.contains_key(name) && !order.iter().any(|n| n == name) {
            order.push(name.to_owned());
        }
    };
    add("README");
    if let Some(contents) = sources.get("README") {
        for event in Parser::new(contents) {
            if let Event::Start(Tag::Link { dest_url, .. }) = event {
                if let Some(name) = dest_url
                    .split('#')
                    .next()
                    .and_then(|f| f.strip_suffix(".md"))
                {
                    add(name);
                }
            }
        }
    }
    for name in sources.keys() {
        add(name);
    }
    order
}

/// GitHub's anchor for a heading's text: lower case, letters, digits, `-`
/// and `_` kept, each space a hyphen, everything else dropped.
pub fn slug(text: &str) -> String {
    text.trim()
        .to_lowercase()
        .chars()
        .filter_map(|c| match c {
            ' ' => Some('-'),
            c if c.is_alphanumeric() || c == '-' || c == '_' => Some(c),
            _ => None,
        })
        .collect()
}

/// Where a chapter's link goes in the page, or `None` for a file outside
/// the book.
pub fn link_in_page(chapter: &str, dest: &str, chapters: &[&str]) -> Option<String> {
    if dest.contains("://") || dest.starts_with("mailto:") || dest.starts_with('?') {
        return Some(dest.to_owned());
    }
    if let Some(anchor) = dest.strip_prefix('#') {
        return Some(format!("#{chapter}/{anchor}"));
    }
    let (file, anchor) = match dest.split_once('#') {
        Some((file, anchor)) => (file, Some(anchor)),
        None => (dest, None),
    };
    let name = file
        .strip_prefix("./")
        .unwrap_or(file)
        .strip_suffix(".md")?;
    if !chapters.contains(&name) {
        return None;
    }
    Some(match anchor {
        Some(anchor) => format!("#{name}/{anchor}"),
        None => format!("#{name}"),
    })
}

/// Whether an inline code span is one of the page's own URLs: a query the
/// page reads without a complaint (`?modeset=1&ops=3`).
pub fn is_page_url(code: &str) -> bool {
    code.starts_with('?')
        && code.contains('=')
        && !code.contains(char::is_whitespace)
        && crate::url::parse_query(code).1.is_none()
}

/// Text as HTML text or an attribute's value.
pub fn escape_html(text: &str) -> String {
    let mut escaped = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => escaped.push_str("&amp;"),
            '<' => escaped.push_str("&lt;"),
            '>' => escaped.push_str("&gt;"),
            '"' => escaped.push_str("&quot;"),
            '\'' => escaped.push_str("&#39;"),
            c => escaped.push(c),
        }
    }
    escaped
}

fn demoted(level: HeadingLevel) -> HeadingLevel {
    match level {
        HeadingLevel::H1 => HeadingLevel::H2,
        HeadingLevel::H2 => HeadingLevel::H3,
        HeadingLevel::H3 => HeadingLevel::H4,
        HeadingLevel::H4 => HeadingLevel::H5,
        HeadingLevel::H5 | HeadingLevel::H6 => HeadingLevel::H6,
    }
}

/// One chapter's Markdown as the page's HTML; `picture` gives a picture's
/// `data:` URI (and size) from its path as the chapter writes it.
pub fn render_chapter(
    name: &str,
    markdown: &str,
    chapters: &[&str],
    picture: &mut dyn FnMut(&str) -> Result<Picture, String>,
) -> Result<String, String> {
    let options = Options::ENABLE_TABLES | Options::ENABLE_STRIKETHROUGH;
    let mut events: Vec<Event> = Parser::new_ext(markdown, options).collect();
    let mut anchors: HashMap<String, usize> = HashMap::new();
    let mut in_link = false;
    let mut unlinked = false;
    for index in 0..events.len() {
        match &events[index] {
            Event::Start(Tag::Heading { .. }) => {
                let text: String = events[index + 1..]
                    .iter()
                    .take_while(|e| !matches!(e, Event::End(TagEnd::Heading(_))))
                    .filter_map(|e| match e {
                        Event::Text(t) | Event::Code(t) => Some(t.as_ref()),
                        _ => None,
                    })
                    .collect();
                let base = slug(&text);
                let seen = anchors.entry(base.clone()).or_insert(0);
                let anchor = match *seen {
                    0 => base,
                    n => format!("{base}-{n}"),
                };
                *seen += 1;
                if let Event::Start(Tag::Heading { level, id, .. }) = &mut events[index] {
                    *level = demoted(*level);
                    *id = Some(CowStr::from(format!("{name}/{anchor}")));
                }
            }
            Event::End(TagEnd::Heading(level)) => {
                events[index] = Event::End(TagEnd::Heading(demoted(*level)));
            }
            Event::Start(Tag::Link { dest_url, .. }) => {
                in_link = true;
                match link_in_page(name, dest_url, chapters) {
                    Some(target) => {
                        if let Event::Start(Tag::Link { dest_url, .. }) = &mut events[index] {
                            *dest_url = CowStr::from(target);
                        }
                    }
                    None => {
                        let title = format!(
                            "{} in the repository, not in this page",
                            dest_url.trim_start_matches("../")
                        );
                        events[index] = Event::InlineHtml(CowStr::from(format!(
                            "<span class=\"outside\" title=\"{}\">",
                            escape_html(&title)
                        )));
                        unlinked = true;
                    }
                }
            }
            Event::End(TagEnd::Link) => {
                in_link = false;
                if unlinked {
                    events[index] = Event::InlineHtml(CowStr::from("</span>"));
                    unlinked = false;
                }
            }
            Event::Start(Tag::Image {
                dest_url, title, ..
            }) => {
                // The tag written whole, with the picture's size, so that the
                // page is laid out before the pictures decode and an anchor
                // followed stays in view.
                let found = picture(dest_url)?;
                let title = title.to_string();
                let mut alt = String::new();
                let mut inner = index + 1;
                while !matches!(events[inner], Event::End(TagEnd::Image)) {
                    if let Event::Text(text) | Event::Code(text) = &events[inner] {
                        alt.push_str(text);
                    }
                    events[inner] = Event::Text(CowStr::from(""));
                    inner += 1;
                }
                events[inner] = Event::Text(CowStr::from(""));
                let size = found
                    .size
                    .map(|(width, height)| format!(" width=\"{width}\" height=\"{height}\""))
                    .unwrap_or_default();
                let title = if title.is_empty() {
                    String::new()
                } else {
                    format!(" title=\"{}\"", escape_html(&title))
                };
                events[index] = Event::InlineHtml(CowStr::from(format!(
                    "<img src=\"{}\" alt=\"{}\"{size}{title}>",
                    found.uri,
                    escape_html(&alt)
                )));
            }
            Event::Code(code) if !in_link && is_page_url(code) => {
                let code = escape_html(code);
                events[index] = Event::InlineHtml(CowStr::from(format!(
                    "<a class=\"live\" href=\"{code}\" title=\"open the page in this state\"><code>{code}</code></a>"
                )));
            }
            _ => {}
        }
    }
    let mut html = String::new();
    pulldown_cmark::html::push_html(&mut html, events.into_iter());
    Ok(html)
}

/// A picture as the page holds it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Picture {
    /// Its `data:` URI.
    pub uri: String,
    /// Its width and height in pixels, if its format says them in a
    /// header (PNG, GIF).
    pub size: Option<(u32, u32)>,
}

/// The book's pictures as `data:` URIs, each read once.
struct Pictures<'a> {
    docs: &'a Path,
    made: HashMap<String, Picture>,
}

impl<'a> Pictures<'a> {
    fn new(docs: &'a Path) -> Self {
        Pictures {
            docs,
            made: HashMap::new(),
        }
    }

    fn data_uri(&mut self, source: &str) -> Result<Picture, String> {
        if let Some(picture) = self.made.get(source) {
            return Ok(picture.clone());
        }
        let picture = picture_data_uri(self.docs, source)?;
        self.made.insert(source.to_owned(), picture.clone());
        Ok(picture)
    }
}

/// The width and height a PNG's IHDR, a GIF's screen descriptor or an
/// SVG's root element (its `width` and `height` in pixels, else its
/// `viewBox`) gives.
pub fn picture_size(bytes: &[u8]) -> Option<(u32, u32)> {
    let word = |at: usize| -> Option<u32> {
        Some(u32::from_be_bytes(bytes.get(at..at + 4)?.try_into().ok()?))
    };
    let half = |at: usize| -> Option<u32> {
        Some(u32::from(u16::from_le_bytes(
            bytes.get(at..at + 2)?.try_into().ok()?,
        )))
    };
    if bytes.starts_with(b"\x89PNG\r\n\x1a\n") && bytes.get(12..16) == Some(b"IHDR") {
        return Some((word(16)?, word(20)?));
    }
    if bytes.starts_with(b"GIF87a") || bytes.starts_with(b"GIF89a") {
        return Some((half(6)?, half(8)?));
    }
    svg_size(std::str::from_utf8(bytes).ok()?)
}

fn svg_size(text: &str) -> Option<(u32, u32)> {
    let root = &text[text.find("<svg")?..];
    let root = &root[..root.find('>')?];
    let attribute = |name: &str| -> Option<&str> {
        let at = root.find(&format!(" {name}=\""))? + name.len() + 3;
        Some(&root[at..at + root[at..].find('"')?])
    };
    let pixels = |value: &str| -> Option<u32> {
        let number = value.strip_suffix("px").unwrap_or(value);
        number.parse::<f64>().ok().map(|n| n.round() as u32)
    };
    if let (Some(width), Some(height)) = (attribute("width"), attribute("height")) {
        if let (Some(width), Some(height)) = (pixels(width), pixels(height)) {
            return Some((width, height));
        }
    }
    let view: Vec<u32> = attribute("viewBox")?
        .split([' ', ','])
        .filter(|part| !part.is_empty())
        .map(pixels)
        .collect::<Option<_>>()?;
    match view[..] {
        [_, _, width, height] => Some((width, height)),
        _ => None,
    }
}

/// A picture under `docs` (a path relative to it, as a chapter links it)
/// as a `data:` URI, with its size.
pub fn picture_data_uri(docs: &Path, source: &str) -> Result<Picture, String> {
    let relative = Path::new(source);
    if source.contains("://")
        || !relative
            .components()
            .all(|part| matches!(part, std::path::Component::Normal(_)))
    {
        return Err(format!(
            "picture {source:?}: the page holds only pictures under docs/"
        ));
    }
    let path = docs.join(relative);
    let bytes = std::fs::read(&path).map_err(|e| format!("picture {source:?}: {e}"))?;
    let extension = relative
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    let (kind, bytes) = match extension.as_str() {
        "png" => ("image/png", smaller_png(&bytes).unwrap_or(bytes)),
        "gif" => ("image/gif", bytes),
        "svg" => ("image/svg+xml", bytes),
        "jpg" | "jpeg" => ("image/jpeg", bytes),
        _ => return Err(format!("picture {source:?}: not a PNG, GIF, SVG or JPEG")),
    };
    Ok(Picture {
        uri: format!("data:{kind};base64,{}", crate::build::base64(&bytes)),
        size: picture_size(&bytes),
    })
}

/// The PNG again with a palette (1, 2, 4 or 8 bits a pixel), if it has at
/// most 256 colours (alpha included) and comes out smaller; every pixel is
/// kept.
pub fn smaller_png(bytes: &[u8]) -> Option<Vec<u8>> {
    let mut decoder = png::Decoder::new(bytes);
    decoder.set_transformations(png::Transformations::normalize_to_color8());
    let mut reader = decoder.read_info().ok()?;
    let mut buffer = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buffer).ok()?;
    let (width, height) = (info.width as usize, info.height as usize);
    let channels = info.color_type.samples();
    let rgba = |p: &[u8]| -> [u8; 4] {
        match p.len() {
            1 => [p[0], p[0], p[0], 255],
            2 => [p[0], p[0], p[0], p[1]],
            3 => [p[0], p[1], p[2], 255],
            _ => [p[0], p[1], p[2], p[3]],
        }
    };
    let mut palette: Vec<[u8; 4]> = Vec::new();
    let mut index_of: HashMap<[u8; 4], u8> = HashMap::new();
    let mut indices = Vec::with_capacity(width * height);
    for pixel in buffer[..info.buffer_size()].chunks_exact(channels) {
        let colour = rgba(pixel);
        let index = match index_of.get(&colour) {
            Some(&index) => index,
            None => {
                if palette.len() == 256 {
                    return None;
                }
                palette.push(colour);
                let index = (palette.len() - 1) as u8;
                index_of.insert(colour, index);
                index
            }
        };
        indices.push(index);
    }
    let bits = match palette.len() {
        0..=2 => 1,
        3..=4 => 2,
        5..=16 => 4,
        _ => 8,
    };
    let per_byte = 8 / bits;
    let mut packed = Vec::with_capacity(height * width.div_ceil(per_byte));
    for row in indices.chunks(width) {
        for group in row.chunks(per_byte) {
            let mut byte = 0u8;
            for (i, &index) in group.iter().enumerate() {
                byte |= index << (8 - bits * (i + 1));
            }
            packed.push(byte);
        }
    }
    let mut out = Vec::new();
    {
        let mut encoder = png::Encoder::new(&mut out, info.width, info.height);
        encoder.set_color(png::ColorType::Indexed);
        encoder.set_depth(match bits {
            1 => png::BitDepth::One,
            2 => png::BitDepth::Two,
            4 => png::BitDepth::Four,
            _ => png::BitDepth::Eight,
        });
        encoder.set_palette(
            palette
                .iter()
                .flat_map(|c| [c[0], c[1], c[2]])
                .collect::<Vec<u8>>(),
        );
        if palette.iter().any(|c| c[3] != 255) {
            encoder.set_trns(palette.iter().map(|c| c[3]).collect::<Vec<u8>>());
        }
        encoder.set_compression(png::Compression::Best);
        encoder.set_filter(png::FilterType::NoFilter);
        let mut writer = encoder.write_header().ok()?;
        writer.write_image_data(&packed).ok()?;
    }
    (out.len() < bytes.len()).then_some(out)
}

#[cfg(test)]
mod tests;

//! The page's files: the crate built for `wasm32-unknown-unknown` (by the
//! toolchain's own target, from `rust-toolchain.toml`: nothing is
//! downloaded) and deflated, the HTML with the book rendered into it
//! (`book.rs`) and the JavaScript loader; or all three in one
//! self-contained HTML file.

use std::fmt;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The page's HTML: the canvases, buttons and captions.
const INDEX_HTML: &str = include_str!("../page/index.html");
/// The loader: WebAssembly in, key events in, pixels out.
const MODEX_JS: &str = include_str!("../page/modex.js");
/// Where the single-file page's loader finds the module (see `modex.js`).
const INLINE_WASM_ID: &str = "modex-wasm";
/// The module's file beside the page: zlib's format, which the browser's
/// `DecompressionStream("deflate")` reads (see `modex.js`).
const MODULE_FILE: &str = "modex.wasm.deflate";
/// Where the book goes in `index.html`.
const BOOK_MARK: &str = "<!-- the book -->";
/// The page's weight budget, book included: 1 MiB, in either form.
pub const PAGE_BUDGET_BYTES: u64 = 1 << 20;
/// The cargo profile the module is built with (the workspace's Cargo.toml).
const WASM_PROFILE: &str = "web-wasm";
const WASM_TARGET: &str = "wasm32-unknown-unknown";

/// How the page is written.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PageFiles {
    /// One `index.html` with the loader and the module (base64) inside.
    pub single_file: bool,
}

/// What [`build_page`] wrote.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Built {
    /// Each file the page loads, with its size in bytes.
    pub files: Vec<(PathBuf, u64)>,
    /// The bytes of `index.html` that are the book (its sections, pictures
    /// included).
    pub book_bytes: u64,
}

impl Built {
    /// The bytes a browser loads to show the page.
    pub fn weight(&self) -> u64 {
        self.files.iter().map(|(_, bytes)| bytes).sum()
    }
}

/// Why the page was not built.
#[derive(Debug)]
pub enum BuildError {
    /// Cargo did not start.
    Cargo(std::io::Error),
    /// Cargo failed to build the module (its messages went to stderr).
    Compile(std::process::ExitStatus),
    /// A file could not be read or written.
    Io(PathBuf, std::io::Error),
    /// A chapter could not be rendered (a picture missing, say).
    Book(String),
}

impl fmt::Display for BuildError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BuildError::Cargo(e) => write!(f, "cargo did not start: {e}"),
            BuildError::Compile(status) => write!(
                f,
                "cargo could not build the page's WebAssembly ({status}); is the \
                 {WASM_TARGET} target installed (boot/setup.sh, or rustup target add {WASM_TARGET})?"
            ),
            BuildError::Io(path, e) => write!(f, "{}: {e}", path.display()),
            BuildError::Book(problem) => write!(f, "the book: {problem}"),
        }
    }
}

impl std::error::Error for BuildError {}

fn workspace() -> PathBuf {
    // web/ is a member of the workspace at the repository's root.
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("web/ sits in the workspace")
        .to_path_buf()
}

/// Builds the module: `cargo build --lib -p web --target
/// wasm32-unknown-unknown --profile web-wasm`, in a target directory of its
/// own (the cargo that runs this binary may hold the main one's lock).
/// Returns the module's path.
pub fn build_wasm() -> Result<PathBuf, BuildError> {
    let root = workspace();
    let target_dir = root.join("target").join("web-wasm");
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let status = Command::new(cargo)
        .current_dir(&root)
        .args([
            "build",
            "--quiet",
            "--lib",
            "-p",
            "web",
            "--target",
            WASM_TARGET,
        ])
        .args(["--profile", WASM_PROFILE])
        .arg("--target-dir")
        .arg(&target_dir)
        // Flags meant for the host build are not the module's.
        .env_remove("RUSTFLAGS")
        .env_remove("CARGO_ENCODED_RUSTFLAGS")
        .env_remove("CARGO_BUILD_TARGET")
        .status()
        .map_err(BuildError::Cargo)?;
    if !status.success() {
        return Err(BuildError::Compile(status));
    }
    Ok(target_dir
        .join(WASM_TARGET)
        .join(WASM_PROFILE)
        .join("web.wasm"))
}

/// Writes the page into `out` (made if missing): `index.html` (the page
/// and the book), `modex.js` and `modex.wasm.deflate`.
pub fn build_page(out: &Path) -> Result<Built, BuildError> {
    build_page_with(out, PageFiles::default())
}

/// As [`build_page`]; with `single_file`, one `index.html` holding all three.
pub fn build_page_with(out: &Path, files: PageFiles) -> Result<Built, BuildError> {
    let wasm_path = build_wasm()?;
    let wasm = std::fs::read(&wasm_path).map_err(|e| BuildError::Io(wasm_path.clone(), e))?;
    write_page(out, files, &wasm)
}

/// Writes the page's files around an already built module, with the book
/// read from the workspace's `docs/`.
pub fn write_page(out: &Path, files: PageFiles, wasm: &[u8]) -> Result<Built, BuildError> {
    let book = crate::book::read_book(&workspace().join("docs")).map_err(BuildError::Book)?;
    write_page_with_book(out, files, wasm, &book.html())
}

/// Writes the page's files around an already built module and a rendered
/// book.
fn write_page_with_book(
    out: &Path,
    files: PageFiles,
    wasm: &[u8],
    book: &str,
) -> Result<Built, BuildError> {
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |e| BuildError::Io(path, e)
    };
    std::fs::create_dir_all(out).map_err(io(out))?;
    let mut written = Vec::new();
    let mut write = |name: &str, bytes: &[u8]| -> Result<(), BuildError> {
        let path = out.join(name);
        std::fs::write(&path, bytes).map_err(io(&path))?;
        written.push((path, bytes.len() as u64));
        Ok(())
    };
    // The module deflated, to under a third of its size (most of it is
    // tables and zeroed data; docs/web.md has the day's figures).
    let module = deflate(wasm);
    let page = INDEX_HTML.replace(BOOK_MARK, book);
    if files.single_file {
        write("index.html", single_file_html(&page, &module).as_bytes())?;
    } else {
        write("index.html", page.as_bytes())?;
        write("modex.js", MODEX_JS.as_bytes())?;
        write(MODULE_FILE, &module)?;
    }
    Ok(Built {
        files: written,
        book_bytes: book.len() as u64,
    })
}

/// The module in zlib's format, compressed as far as miniz goes.
pub fn deflate(wasm: &[u8]) -> Vec<u8> {
    miniz_oxide::deflate::compress_to_vec_zlib(wasm, 10)
}

/// The page with the loader inline and the deflated module in base64.
fn single_file_html(page: &str, module: &[u8]) -> String {
    let inline = format!(
        "<script type=\"application/octet-stream\" id=\"{INLINE_WASM_ID}\">{}</script>\n<script>\n{MODEX_JS}</script>",
        base64(module)
    );
    page.replace("<script src=\"modex.js\"></script>", &inline)
}

/// Standard base64 with padding (RFC 4648), as the browser's `atob` reads it.
pub fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut text = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let word = u32::from(chunk[0]) << 16
            | u32::from(chunk.get(1).copied().unwrap_or(0)) << 8
            | u32::from(chunk.get(2).copied().unwrap_or(0));
        for (index, shift) in [18, 12, 6, 0].into_iter().enumerate() {
            if index <= chunk.len() {
                text.push(char::from(ALPHABET[(word >> shift) as usize & 63]));
            } else {
                text.push('=');
            }
        }
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_is_rfc_4648s() {
        // RFC 4648's test vectors.
        let vectors = [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ];
        for (plain, encoded) in vectors {
            assert_eq!(base64(plain.as_bytes()), encoded);
        }
        assert_eq!(base64(&[0xFF, 0xEF]), "/+8=");
    }

    #[test]
    fn the_page_files_carry_the_ids_the_tests_drive() {
        for id in [
            "screen",
            "inspector",
            "hover",
            "message",
            "step-frame",
            "step-op",
            "play",
            "record-gif",
            "keypad",
            "lab",
            "lab-registers",
            "lab-restore",
            "lab-export",
            "lab-url",
        ] {
            assert!(INDEX_HTML.contains(&format!("id=\"{id}\"")), "#{id}");
        }
        assert!(MODEX_JS.contains("window.modexPage"));
        // Small: events in, pixels out. The touch, the on-screen keys and
        // the register lab's fields (issue 63) are events too.
        assert!(MODEX_JS.lines().count() < 400, "the loader stays small");
        assert!(INDEX_HTML.contains("<script src=\"modex.js\"></script>"));
    }

    #[test]
    fn the_single_file_holds_the_module_the_loader_and_the_book() {
        let out = std::env::temp_dir().join(format!("web-single-{}", std::process::id()));
        let wasm = b"\0asm\x01\0\0\0 not a real module, not a real module";
        let built = write_page(&out, PageFiles { single_file: true }, wasm).unwrap();
        assert_eq!(built.files.len(), 1);
        let html = std::fs::read_to_string(out.join("index.html")).unwrap();
        assert!(html.contains(&base64(&deflate(wasm))));
        let inflated = miniz_oxide::inflate::decompress_to_vec_zlib(&deflate(wasm)).unwrap();
        assert_eq!(inflated, wasm);
        assert!(html.contains(INLINE_WASM_ID) && MODEX_JS.contains(INLINE_WASM_ID));
        assert!(MODEX_JS.contains(MODULE_FILE) && MODEX_JS.contains("\"deflate\""));
        assert!(!html.contains("src=\"modex.js\"") && !html.contains(BOOK_MARK));
        assert!(html.contains("<section id=\"vga\" class=\"chapter\">"));
        assert_eq!(built.weight(), html.len() as u64);
        assert!(built.book_bytes > 0 && built.book_bytes < built.weight());

        let built = write_page(&out, PageFiles::default(), wasm).unwrap();
        let names: Vec<_> = built
            .files
            .iter()
            .map(|(p, _)| p.file_name().unwrap())
            .collect();
        assert_eq!(names, ["index.html", "modex.js", MODULE_FILE]);
        let html = std::fs::read_to_string(out.join("index.html")).unwrap();
        assert!(html.contains("<section id=\"vga\" class=\"chapter\">"));
        std::fs::remove_dir_all(&out).unwrap();
    }

    /// The values of `attribute="..."` in `html`, `&amp;` decoded.
    fn attribute_values(html: &str, attribute: &str) -> Vec<String> {
        let opening = format!(" {attribute}=\"");
        html.match_indices(&opening)
            .map(|(at, _)| {
                let value = &html[at + opening.len()..];
                value[..value.find('"').expect("a closed attribute")].replace("&amp;", "&")
            })
            .collect()
    }

    /// Every link of the single file, the captions' and the chapters',
    /// lands on an id the file holds (or is a web address, or one of the
    /// page's own URLs); every id is unique; every chapter is there.
    fn assert_links_resolve(html: &str) {
        let ids = attribute_values(html, "id");
        let mut unique = std::collections::BTreeSet::new();
        for id in &ids {
            assert!(unique.insert(id), "the id {id:?} is given twice");
        }
        let mut anchors = 0;
        for href in attribute_values(html, "href") {
            if let Some(anchor) = href.strip_prefix('#') {
                assert!(
                    unique.contains(&anchor.to_owned()),
                    "a link to #{anchor}, which no element has"
                );
                anchors += 1;
            } else if href.starts_with('?') {
                assert!(
                    crate::book::is_page_url(&href),
                    "{href}: not a URL the page reads"
                );
            } else {
                assert!(
                    href.starts_with("https://") || href.starts_with("http://"),
                    "a link to {href:?}, outside the page"
                );
            }
        }
        assert!(anchors > 100, "{anchors} links within the page");
        let docs = workspace().join("docs");
        for entry in std::fs::read_dir(&docs).unwrap() {
            let name = entry.unwrap().file_name().into_string().unwrap();
            if let Some(chapter) = name.strip_suffix(".md") {
                assert!(
                    unique.contains(&chapter.to_owned()),
                    "no section for docs/{name}"
                );
            }
        }
    }

    #[test]
    fn every_link_of_the_single_file_lands_inside_it() {
        let book = crate::book::read_book(&workspace().join("docs")).unwrap();
        let page = INDEX_HTML.replace(BOOK_MARK, &book.html());
        let html = single_file_html(&page, b"module");
        assert_links_resolve(&html);
        // The captions' links among them.
        let captions: Vec<String> = INDEX_HTML
            .split("<figcaption>")
            .skip(1)
            .flat_map(|caption| {
                attribute_values(&caption[..caption.find("</figcaption>").unwrap()], "href")
            })
            .collect();
        assert!(captions.len() >= 5, "{captions:?}");
        assert!(captions.contains(&"#vga/step-by-step-in-the-browser".to_owned()));
    }

    #[test]
    fn a_link_to_a_missing_anchor_is_caught() {
        let book = crate::book::read_book(&workspace().join("docs")).unwrap();
        let page = INDEX_HTML
            .replace(BOOK_MARK, &book.html())
            .replace("href=\"#simulator\"", "href=\"#simulator/no-such-heading\"");
        let html = single_file_html(&page, b"module");
        let caught = std::panic::catch_unwind(|| assert_links_resolve(&html));
        assert!(caught.is_err(), "a dead caption link passed");
    }
}

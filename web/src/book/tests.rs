use super::*;

fn no_pictures(source: &str) -> Result<Picture, String> {
    Err(format!("no picture {source}"))
}

#[test]
fn anchors_are_githubs() {
    for (heading, anchor) in [
        (
            "Page flipping in vertical retrace",
            "page-flipping-in-vertical-retrace",
        ),
        ("Step by step in the browser", "step-by-step-in-the-browser"),
        ("`show_page`: the flip", "show_page-the-flip"),
        (
            "Mode X (320x240, 256 colours)",
            "mode-x-320x240-256-colours",
        ),
        (
            "Index and data ports - 0x3C4/0x3C5",
            "index-and-data-ports---0x3c40x3c5",
        ),
        ("Why? It's Abrash's", "why-its-abrashs"),
    ] {
        assert_eq!(slug(heading), anchor, "{heading}");
    }
}

#[test]
fn a_chapter_renders_with_ids_links_tables_and_live_urls() {
    let markdown = "# Title\n\n## Twice\n\n## Twice\n\nSee [the flip](vga.md#the-flip), \
        [here](#twice), [the sim](simulator.md), [README](../README.md#controls), \
        [a site](https://example.org/) and `?modeset=1&ops=3` (`?keys=xyz`, `x`).\n\n\
        | a | b |\n|---|---|\n| 1 | 2 |\n\n```sh\ncargo run\n```\n";
    let chapters = ["web", "vga", "simulator"];
    let html = render_chapter("web", markdown, &chapters, &mut no_pictures).unwrap();
    for expected in [
        "<h2 id=\"web/title\">Title</h2>",
        "<h3 id=\"web/twice\">Twice</h3>",
        "<h3 id=\"web/twice-1\">Twice</h3>",
        "<a href=\"#vga/the-flip\">the flip</a>",
        "<a href=\"#web/twice\">here</a>",
        "<a href=\"#simulator\">the sim</a>",
        "<span class=\"outside\" title=\"README.md#controls in the repository, not in this page\">README</span>",
        "<a href=\"https://example.org/\">a site</a>",
        "<a class=\"live\" href=\"?modeset=1&amp;ops=3\"",
        "<code>?keys=xyz</code>",
        "<table>",
        "<code class=\"language-sh\">cargo run\n</code>",
    ] {
        assert!(html.contains(expected), "{expected} is not in\n{html}");
    }
    // A link to a chapter the book lacks, or a picture it cannot read, is
    // not a page link.
    let html = render_chapter("web", "[x](nowhere.md)", &chapters, &mut no_pictures).unwrap();
    assert!(!html.contains("href"), "{html}");
    let missing = render_chapter("web", "![p](gone.png)", &chapters, &mut no_pictures);
    assert_eq!(missing, Err("no picture gone.png".into()));
    let mut one = |_: &str| {
        Ok(Picture {
            uri: "data:image/png;base64,AA==".into(),
            size: Some((4, 3)),
        })
    };
    let html = render_chapter("web", "![a \"b\" `c`](p.png \"t\")", &chapters, &mut one).unwrap();
    assert_eq!(
        html,
        "<p><img src=\"data:image/png;base64,AA==\" alt=\"a &quot;b&quot; c\" width=\"4\" height=\"3\" title=\"t\"></p>\n"
    );
}

#[test]
fn pictures_are_data_uris_of_files_under_docs() {
    let docs = std::env::temp_dir().join(format!("web-book-{}", std::process::id()));
    std::fs::create_dir_all(&docs).unwrap();
    std::fs::write(
        docs.join("p.svg"),
        "<svg xmlns=\"http://www.w3.org/2000/svg\"/>",
    )
    .unwrap();
    let svg = picture_data_uri(&docs, "p.svg").unwrap();
    assert!(
        svg.uri.starts_with("data:image/svg+xml;base64,PHN2Zy"),
        "{svg:?}"
    );
    assert_eq!(svg.size, None);
    for (root, size) in [
        (
            "<svg xmlns=\"x\" width=\"320\" height=\"200.4px\">",
            Some((320, 200)),
        ),
        (
            "<svg viewBox=\"0 0 640 480\" width=\"100%\" height=\"auto\">",
            Some((640, 480)),
        ),
        (
            "<?xml version=\"1.0\"?><svg viewBox=\"0,0,8,4\">",
            Some((8, 4)),
        ),
        ("<svg width=\"1em\">", None),
    ] {
        assert_eq!(
            picture_size(format!("{root}</svg>").as_bytes()),
            size,
            "{root}"
        );
    }
    std::fs::write(docs.join("p.gif"), b"GIF89a\x40\x01\xF0\x00rest").unwrap();
    assert_eq!(
        picture_data_uri(&docs, "p.gif").unwrap().size,
        Some((320, 240))
    );
    assert!(picture_data_uri(&docs, "../p.svg")
        .unwrap_err()
        .contains("under docs/"));
    assert!(picture_data_uri(&docs, "gone.png")
        .unwrap_err()
        .contains("gone.png"));
    std::fs::write(docs.join("p.txt"), "text").unwrap();
    assert!(picture_data_uri(&docs, "p.txt")
        .unwrap_err()
        .contains("not a PNG"));
    std::fs::remove_dir_all(&docs).unwrap();
}

/// A PNG's size and pixels as RGBA.
fn decoded(png_bytes: &[u8]) -> (u32, u32, Vec<u8>) {
    let mut decoder = png::Decoder::new(png_bytes);
    decoder.set_transformations(png::Transformations::normalize_to_color8());
    let mut reader = decoder.read_info().unwrap();
    let mut buffer = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buffer).unwrap();
    let channels = info.color_type.samples();
    let rgba = buffer[..info.buffer_size()]
        .chunks_exact(channels)
        .flat_map(|p| match p.len() {
            3 => [p[0], p[1], p[2], 255],
            4 => [p[0], p[1], p[2], p[3]],
            _ => panic!("{channels} channels"),
        })
        .collect();
    (info.width, info.height, rgba)
}

fn encoded(width: u32, height: u32, colour: png::ColorType, pixels: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    let mut encoder = png::Encoder::new(&mut out, width, height);
    encoder.set_color(colour);
    encoder.set_compression(png::Compression::Fast);
    let mut writer = encoder.write_header().unwrap();
    writer.write_image_data(pixels).unwrap();
    writer.finish().unwrap();
    out
}

#[test]
fn a_palette_png_keeps_every_pixel() {
    // Five colours, one half transparent, in a width that is no whole
    // number of 4-bit pixel pairs.
    let (width, height) = (7, 5);
    let colours = [
        [0, 0, 0, 255],
        [255, 0, 0, 255],
        [0, 255, 0, 128],
        [9, 9, 9, 255],
        [1, 2, 3, 255],
    ];
    let pixels: Vec<u8> = (0..width * height)
        .flat_map(|i| colours[(i * 7 % 5) as usize])
        .collect();
    let original = encoded(width, height, png::ColorType::Rgba, &pixels);
    let smaller = smaller_png(&original).expect("smaller with a palette");
    assert!(smaller.len() < original.len());
    assert_eq!(decoded(&smaller), (width, height, pixels));
    // The book's own screenshot, every pixel.
    let crowd = std::fs::read(concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/crowd.png")).unwrap();
    let smaller = smaller_png(&crowd).expect("the crowd has few colours");
    assert!(
        smaller.len() * 4 < crowd.len(),
        "{} of {} bytes",
        smaller.len(),
        crowd.len()
    );
    assert_eq!(decoded(&smaller), decoded(&crowd));
    // More than 256 colours: left as it was.
    let many: Vec<u8> = (0..300u32)
        .flat_map(|i| [i as u8, (i >> 8) as u8, 0])
        .collect();
    assert_eq!(
        smaller_png(&encoded(300, 1, png::ColorType::Rgb, &many)),
        None
    );
}

#[test]
fn the_book_has_every_chapter_and_vgas_step_by_step_urls_are_live() {
    let docs = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../docs"));
    let book = read_book(docs).unwrap();
    assert_eq!(book.chapters[0].name, "README", "the contents first");
    let markdown_files = std::fs::read_dir(docs)
        .unwrap()
        .filter(|e| {
            e.as_ref()
                .unwrap()
                .path()
                .extension()
                .is_some_and(|x| x == "md")
        })
        .count();
    assert_eq!(book.chapters.len(), markdown_files);
    let vga = book.chapters.iter().find(|c| c.name == "vga").unwrap();
    let markdown = std::fs::read_to_string(docs.join("vga.md")).unwrap();
    let section = markdown
        .split("\n## ")
        .find(|s| s.starts_with("Step by step in the browser"))
        .expect("vga.md has its step-by-step section");
    let urls: Vec<&str> = section
        .split('`')
        .skip(1)
        .step_by(2)
        .filter(|code| code.starts_with('?'))
        .collect();
    assert!(urls.len() >= 5, "{urls:?}");
    for url in urls {
        assert!(is_page_url(url), "{url}");
        let link = format!("<a class=\"live\" href=\"{}\"", escape_html(url));
        assert!(
            vga.html.contains(&link),
            "{url} is not a live link in vga's HTML"
        );
    }
    let html = book.html();
    for tag in [
        "<h2 id=\"vga/",
        "<table>",
        "<pre><code",
        "<img src=\"data:image/png;base64,",
    ] {
        assert!(html.contains(tag), "the book has no {tag}");
    }
    // Each picture with its size, so that the page's layout is set before
    // the pictures decode.
    assert!(html.contains(
        "alt=\"The crowd (X, S), under QEMU on the loaded machine\" width=\"640\" height=\"480\">"
    ));
}

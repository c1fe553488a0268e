//! The documentation cannot rot: `README.md`, `CHANGELOG.md` and every
//! `docs/*.md` are checked against the repository and the runner.
//!
//! - every fenced `sh`, `bash` or `console` block parses (`bash -n`);
//! - every `cargo run ... -- OPTIONS` command names only options the runner
//!   accepts (the runner binary's own `--help`), and `cargo run -p sim --
//!   OPTIONS` only the simulator's (its clap fields in `sim/src/main.rs`);
//! - every relative link, and every backticked path that looks like a file
//!   or folder of the repository, exists;
//! - no line is longer than [`MAX_LINE`] characters (tables, links and
//!   program output in `text` blocks excepted), and the README stays short;
//! - the key names in `docs/runner.md` are exactly the runner's table.
//!
//! Host only: no emulator; the checks ran in 0.02 s (`cargo test --test
//! docs`, warm build). The last tests show each check failing on a broken
//! document.

use std::collections::BTreeSet;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// The longest line allowed outside tables, links and program output.
const MAX_LINE: usize = 120;
/// The README is for a user; the rest is in `docs/`.
const README_MAX_LINES: usize = 250;

fn repository() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// README.md, CHANGELOG.md and docs/*.md, as paths relative to the root.
fn documents() -> Vec<PathBuf> {
    let root = repository();
    let mut files = vec![PathBuf::from("README.md"), PathBuf::from("CHANGELOG.md")];
    let mut chapters: Vec<PathBuf> = std::fs::read_dir(root.join("docs"))
        .expect("docs/ exists")
        .map(|entry| entry.expect("docs/ is readable").path())
        .filter(|path| path.extension().is_some_and(|ext| ext == "md"))
        .map(|path| path.strip_prefix(&root).unwrap().to_path_buf())
        .collect();
    chapters.sort();
    assert!(
        chapters.len() >= 5,
        "docs/ should hold the book's chapters, found {chapters:?}"
    );
    files.extend(chapters);
    files
}

/// What the checks compare a document with.
struct Context {
    root: PathBuf,
    runner_options: BTreeSet<String>,
    sim_options: BTreeSet<String>,
}

impl Context {
    fn new() -> Context {
        Context {
            root: repository(),
            runner_options: runner_options(),
            sim_options: sim_options(),
        }
    }
}

/// The long options the runner's `--help` lists (its clap definition).
fn runner_options() -> BTreeSet<String> {
    let output = Command::new(env!("CARGO_BIN_EXE_modex-cube"))
        .arg("--help")
        .output()
        .expect("the runner starts");
    assert!(output.status.success(), "the runner's --help failed");
    let help = String::from_utf8(output.stdout).expect("help is UTF-8");
    let options = long_options_in(&help);
    assert!(
        options.contains("--write-usb") && options.contains("--help"),
        "the runner's --help lists no options: {help}"
    );
    options
}

/// Every `--name` in a help text.
fn long_options_in(help: &str) -> BTreeSet<String> {
    help.split(|c: char| c.is_whitespace() || c == ',' || c == '[' || c == ']')
        .filter(|word| word.starts_with("--") && word.len() > 2)
        .map(|word| {
            let end = word
                .find(|c: char| !(c.is_ascii_alphanumeric() || c == '-') || c == '=')
                .unwrap_or(word.len());
            word[..end].to_string()
        })
        .collect()
}

/// The simulator's long options, from its clap fields (`#[arg(long ...)]`
/// then the field's name, or `long = "name"`), plus clap's own.
fn sim_options() -> BTreeSet<String> {
    let source = std::fs::read_to_string(repository().join("sim/src/main.rs"))
        .expect("sim/src/main.rs exists");
    let mut options: BTreeSet<String> = ["--help", "--version"].map(String::from).into();
    let lines: Vec<&str> = source.lines().collect();
    for (index, line) in lines.iter().enumerate() {
        let line = line.trim();
        if !line.starts_with("#[arg(long") {
            continue;
        }
        if let Some(rest) = line.split("long = \"").nth(1) {
            options.insert(format!("--{}", &rest[..rest.find('"').unwrap()]));
            continue;
        }
        let field = lines[index + 1..]
            .iter()
            .map(|l| l.trim())
            .find(|l| !l.starts_with("#[") && !l.starts_with("///"))
            .and_then(|l| l.split(':').next())
            .expect("a field follows #[arg]");
        let name = field.trim().trim_start_matches("pub ").replace('_', "-");
        options.insert(format!("--{name}"));
    }
    assert!(options.contains("--record"), "no sim options found");
    options
}

/// A fenced block: its language and its lines.
struct Fence {
    language: String,
    first_line: usize,
    text: String,
}

/// A document split into its fenced blocks and its prose (with the fences'
/// lines blanked, so line numbers stay).
fn split_fences(text: &str) -> (Vec<Fence>, Vec<String>) {
    let mut fences = Vec::new();
    let mut prose = Vec::new();
    let mut open: Option<Fence> = None;
    for (number, line) in text.lines().enumerate() {
        let trimmed = line.trim_start();
        if trimmed.starts_with("```") {
            match open.take() {
                Some(fence) => fences.push(fence),
                None => {
                    open = Some(Fence {
                        language: trimmed.trim_start_matches('`').trim().to_string(),
                        first_line: number + 1,
                        text: String::new(),
                    })
                }
            }
            prose.push(String::new());
        } else if let Some(fence) = open.as_mut() {
            fence.text.push_str(line);
            fence.text.push('\n');
            prose.push(String::new());
        } else {
            prose.push(line.to_string());
        }
    }
    if let Some(fence) = open {
        fences.push(Fence {
            language: "unclosed".into(),
            ..fence
        });
    }
    (fences, prose)
}

/// Inline code spans of the prose (they may run across a line break).
fn code_spans(prose: &[String]) -> Vec<(usize, String)> {
    let mut spans = Vec::new();
    let mut current: Option<(usize, String)> = None;
    for (number, line) in prose.iter().enumerate() {
        let mut rest = line.as_str();
        if let Some((_, span)) = current.as_mut() {
            span.push(' ');
        }
        while let Some(tick) = rest.find('`') {
            match current.take() {
                Some((start, mut span)) => {
                    span.push_str(&rest[..tick]);
                    spans.push((start, span));
                }
                None => current = Some((number + 1, String::new())),
            }
            rest = &rest[tick + 1..];
        }
        if let Some((_, span)) = current.as_mut() {
            span.push_str(rest);
        }
        if line.trim().is_empty() {
            // A blank line ends a paragraph: an unmatched backtick is literal.
            current = None;
        }
    }
    spans
}

/// Words of a shell command line, with '...' and "..." quoting.
fn shell_words(line: &str) -> Vec<String> {
    let mut words = Vec::new();
    let mut word = String::new();
    let mut in_word = false;
    let mut quote: Option<char> = None;
    for c in line.chars() {
        match quote {
            Some(q) if c == q => quote = None,
            Some(_) => word.push(c),
            None if c == '\'' || c == '"' => {
                quote = Some(c);
                in_word = true;
            }
            None if c.is_whitespace() => {
                if in_word {
                    words.push(std::mem::take(&mut word));
                    in_word = false;
                }
            }
            None => {
                word.push(c);
                in_word = true;
            }
        }
    }
    if in_word {
        words.push(word);
    }
    words
}

/// Problems with the options of every `cargo run` in `command`.
fn check_cargo_run(context: &Context, command: &str) -> Vec<String> {
    let mut problems = Vec::new();
    // A shell line may chain commands; each `cargo run` is checked alone.
    for part in command.split(['|', ';', '&']) {
        let words = shell_words(part.split('#').next().unwrap_or(""));
        let Some(start) = words
            .windows(2)
            .position(|pair| pair[0] == "cargo" && pair[1] == "run")
        else {
            continue;
        };
        let words = &words[start..];
        let Some(separator) = words.iter().position(|w| w == "--") else {
            continue;
        };
        let cargo_args = &words[..separator];
        let is_sim = cargo_args.windows(2).any(|p| p[0] == "-p" && p[1] == "sim");
        let is_other_package = !is_sim && cargo_args.iter().any(|w| w == "-p");
        if is_other_package {
            problems.push(format!(
                "`{}`: a package the docs test does not know",
                part.trim()
            ));
            continue;
        }
        let (known, program) = if is_sim {
            (&context.sim_options, "the simulator")
        } else {
            (&context.runner_options, "the runner")
        };
        for word in &words[separator + 1..] {
            if !word.starts_with("--") {
                continue;
            }
            let name = word.split('=').next().unwrap();
            if !known.contains(name) {
                problems.push(format!(
                    "`{}`: {program} has no option {name} (it has {})",
                    part.trim(),
                    known.iter().cloned().collect::<Vec<_>>().join(" ")
                ));
            }
        }
    }
    problems
}

/// `bash -n` on a shell block: `None` if it parses, else bash's message.
fn shell_syntax_error(script: &str) -> Option<String> {
    let mut bash = Command::new("bash")
        .arg("-n")
        .stdin(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("bash runs");
    bash.stdin
        .take()
        .unwrap()
        .write_all(script.as_bytes())
        .unwrap();
    let output = bash.wait_with_output().unwrap();
    (!output.status.success()).then(|| String::from_utf8_lossy(&output.stderr).trim().to_string())
}

/// Does this backticked text name a file or folder of the repository?
fn looks_like_repository_path(span: &str) -> bool {
    if span.is_empty()
        || span.contains(char::is_whitespace)
        || !span.contains('/')
        || span.starts_with('/')
        || span.starts_with("target/")
        || span.contains("://")
        || span.contains(['*', '<', '>', '$', '(', '|', ':', '=', ','])
    {
        return false;
    }
    if span.ends_with('/') {
        return span.trim_end_matches('/').split('/').all(|part| {
            !part.is_empty()
                && part
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || "_-.".contains(c))
        });
    }
    let last = span.rsplit('/').next().unwrap();
    match last.rsplit_once('.') {
        Some((stem, extension)) => {
            !stem.is_empty()
                && (1..=5).contains(&extension.len())
                && extension.chars().all(|c| c.is_ascii_alphanumeric())
                && extension.chars().any(|c| c.is_ascii_alphabetic())
        }
        None => false,
    }
}

/// Every `[text](target)` target in a line.
fn link_targets(line: &str) -> Vec<String> {
    let mut targets = Vec::new();
    let mut rest = line;
    while let Some(at) = rest.find("](") {
        rest = &rest[at + 2..];
        if let Some(end) = rest.find(')') {
            targets.push(rest[..end].trim().to_string());
            rest = &rest[end..];
        }
    }
    targets
}

fn is_exempt_from_length(line: &str) -> bool {
    let trimmed = line.trim_start();
    trimmed.starts_with('|') || line.contains("](") || line.contains("://") || line.contains("<!--")
}

/// Every problem in one document: `path` is relative to the root (for links).
fn check_document(context: &Context, path: &Path, text: &str) -> Vec<String> {
    let name = path.display();
    let mut problems = Vec::new();
    let (fences, prose) = split_fences(text);
    let directory = context.root.join(path).parent().unwrap().to_path_buf();

    for fence in &fences {
        let where_ = format!("{name}:{}", fence.first_line);
        match fence.language.as_str() {
            "unclosed" => problems.push(format!("{where_}: a fence is never closed")),
            "sh" | "bash" | "console" => {
                let script = if fence.language == "console" {
                    // Only the commands after a prompt; the rest is output.
                    fence
                        .text
                        .lines()
                        .filter_map(|l| l.strip_prefix("$ "))
                        .collect::<Vec<_>>()
                        .join("\n")
                } else {
                    fence.text.clone()
                };
                if let Some(error) = shell_syntax_error(&script) {
                    problems.push(format!("{where_}: bash -n: {error}"));
                }
                for line in script.lines() {
                    problems.extend(
                        check_cargo_run(context, line)
                            .into_iter()
                            .map(|p| format!("{where_}: {p}")),
                    );
                }
            }
            _ => {}
        }
        if fence.language != "text" {
            for (offset, line) in fence.text.lines().enumerate() {
                if line.chars().count() > MAX_LINE && !line.contains("://") {
                    problems.push(format!(
                        "{name}:{}: {} characters (at most {MAX_LINE})",
                        fence.first_line + 1 + offset,
                        line.chars().count()
                    ));
                }
            }
        }
    }

    for (number, line) in prose.iter().enumerate() {
        let where_ = format!("{name}:{}", number + 1);
        if line.chars().count() > MAX_LINE && !is_exempt_from_length(line) {
            problems.push(format!(
                "{where_}: {} characters (at most {MAX_LINE})",
                line.chars().count()
            ));
        }
        for target in link_targets(line) {
            if target.contains("://") || target.starts_with('#') || target.starts_with("mailto:") {
                continue;
            }
            let file = target.split('#').next().unwrap();
            if !directory.join(file).exists() {
                problems.push(format!("{where_}: the link {target} leads nowhere"));
            }
        }
    }

    for (line, span) in code_spans(&prose) {
        let where_ = format!("{name}:{line}");
        if span.contains("cargo run") {
            problems.extend(
                check_cargo_run(context, &span)
                    .into_iter()
                    .map(|p| format!("{where_}: {p}")),
            );
        }
        if looks_like_repository_path(&span) && !context.root.join(&span).exists() {
            problems.push(format!("{where_}: `{span}` is not in the repository"));
        }
    }
    problems
}

#[test]
fn the_docs_match_the_repository_and_the_runner() {
    let context = Context::new();
    let mut problems = Vec::new();
    for path in documents() {
        let text = std::fs::read_to_string(context.root.join(&path))
            .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        problems.extend(check_document(&context, &path, &text));
    }
    assert!(
        problems.is_empty(),
        "{} problems in the docs:\n{}",
        problems.len(),
        problems.join("\n")
    );
}

#[test]
fn the_readme_fits_on_a_few_screens() {
    let readme = std::fs::read_to_string(repository().join("README.md")).unwrap();
    let lines = readme.lines().count();
    assert!(
        lines <= README_MAX_LINES,
        "README.md has {lines} lines; at most {README_MAX_LINES}: move detail into docs/"
    );
}

/// docs/runner.md lists the key names `--keys` takes: exactly the table's.
#[test]
fn the_runner_chapter_lists_every_key_name() {
    let chapter = std::fs::read_to_string(repository().join("docs/runner.md")).unwrap();
    let listed: Vec<String> = chapter
        .split("\n\n")
        .find(|paragraph| paragraph.starts_with("Key names: "))
        .expect("docs/runner.md has a paragraph starting \"Key names: \"")
        .trim_start_matches("Key names: ")
        .split_whitespace()
        .map(|name| name.trim_matches('`').to_string())
        .collect();
    let table: Vec<&str> = keyboard::keys::names().collect();
    assert_eq!(listed, table);
}

// The checks can fail: each broken document below is caught.

fn problems_in(text: &str) -> Vec<String> {
    check_document(&Context::new(), Path::new("docs/broken.md"), text)
}

#[test]
fn a_broken_link_is_caught() {
    let problems = problems_in("See [the chapter](no-such-chapter.md) and [vga](vga.md).\n");
    assert_eq!(problems.len(), 1, "{problems:?}");
    assert!(problems[0].contains("no-such-chapter.md"), "{problems:?}");
}

#[test]
fn a_missing_repository_path_is_caught() {
    let problems = problems_in("In `modex/src/driver.rs` and `modex/src/no_such_file.rs`.\n");
    assert_eq!(problems.len(), 1, "{problems:?}");
    assert!(problems[0].contains("no_such_file.rs"), "{problems:?}");
}

#[test]
fn an_unknown_runner_option_is_caught() {
    let text = "```sh\ncargo run --release -- --headless --no-such-option\n```\n\
                and `cargo run --release -- --uefi\n--bogus` in prose.\n\
                And `cargo run --release -p sim -- --inspect --headless`.\n";
    let problems = problems_in(text);
    assert_eq!(problems.len(), 3, "{problems:?}");
    assert!(problems[0].contains("--no-such-option"), "{problems:?}");
    assert!(problems[1].contains("--bogus"), "{problems:?}");
    assert!(
        problems[2].contains("simulator has no option --headless"),
        "{problems:?}"
    );
}

#[test]
fn a_shell_syntax_error_is_caught() {
    let problems = problems_in("```sh\nif true; then echo \"unclosed\n```\n");
    assert_eq!(problems.len(), 1, "{problems:?}");
    assert!(problems[0].contains("bash -n"), "{problems:?}");
}

#[test]
fn a_long_line_is_caught_but_not_a_table() {
    let long = "word ".repeat(30);
    let text = format!("{long}\n| {long} |\n```text\n{long}\n```\n");
    let problems = problems_in(&text);
    assert_eq!(problems.len(), 1, "{problems:?}");
    assert!(problems[0].starts_with("docs/broken.md:1:"), "{problems:?}");
}

#[test]
fn paths_are_told_from_other_code() {
    for path in ["modex/src/driver.rs", "kernel/src/bios/", "docs/cube.gif"] {
        assert!(looks_like_repository_path(path), "{path}");
    }
    for text in [
        "x/z",
        "/dev/sdX",
        "target/images/modex-cube.img",
        "PM1a/PM1b",
        "f32/f64",
        "a b/c.rs",
        "machine::protocol",
    ] {
        assert!(!looks_like_repository_path(text), "{text}");
    }
}

//! The documentation cannot rot: `README.md`, `CHANGELOG.md` and every
//! `docs/*.md` are checked against the repository and the runner.
//!
//! - every fenced `sh`, `bash` or `console` block parses (`bash -n`);
//! - every `cargo run ... -- OPTIONS` command names only options the runner
//!   accepts (the runner binary's own `--help`), and `cargo run -p sim --
//!   OPTIONS` only the simulator's (its clap fields in `sim/src/main.rs`);
//! - every relative link, and every backticked path that looks like a file
//!   or folder of the repository, exists, and a link to a heading
//!   (`glossary.md#latch`, `#faults`) names one the page has (GitHub's
//!   anchor for it);
//! - no line is longer than [`MAX_LINE`] characters (tables, links and
//!   program output in `text` blocks excepted), and the README stays short;
//! - the key names in `docs/runner.md` are exactly the runner's table;
//! - a figure followed by a constant's name in parentheses, as in
//!   "5 s (`COMMAND_MICROS`)", quotes that constant: the name must be defined
//!   in the repository's Rust sources and its value (in the unit its name
//!   ends in: `_MICROS`, `_MILLIS`, `_BYTES`, ...) must equal the figure, to
//!   the figure's last digit; a name defined in several files with different
//!   values must be qualified by its module (`xhci::HANDOFF_MICROS`);
//! - a backticked `file.rs:function` (as in the table of
//!   `docs/architecture.md`) names a function defined in that file;
//! - a fenced block whose info string names a source file after the language
//!   (```` ```rust modex/src/draw.rs ````) is a quotation: its lines must
//!   appear in that file, in order and together (indentation aside);
//! - a table headed `| port | register | index | value |` (the mode set in
//!   `docs/vga.md`) lists, row by row, the bus operations `ModeX::program`
//!   makes on the software VGA, in the order it makes them;
//! - the pictures drawn from the code (`docs/vga/*.svg`) are what the code
//!   draws now; `MODEX_CUBE_UPDATE_DOCS_PICTURES=1` remakes them.
//!
//! And the book's lists against what they list:
//!
//! - `docs/runner.md`'s options table against the runner's `--help`, and
//!   each `--option a|b|c` against the values the runner's error for a bad
//!   value lists;
//! - `docs/architecture.md`'s crate table against the workspace's members;
//! - `docs/testing.md`'s table against `tests/*.rs`;
//! - `docs/building.md`'s list against what `boot/setup.sh` installs (and
//!   the components and targets of `rust-toolchain.toml`);
//! - every chapter in `docs/README.md` and in the README's "Read more";
//! - every acronym of the book (2 to 6 capitals and digits, at least two
//!   capitals) in `docs/glossary.md`, as an entry or a row of its
//!   abbreviations, but the few words of [`NOT_ACRONYMS`];
//! - in every chapter, the first use of each term the glossary has an
//!   entry for is a link to it (`glossary.md#anchor`);
//! - a count or a time of tests has the command that measures it in its
//!   paragraph;
//! - every `bench:` line the book quotes is one the kernel's format strings
//!   print.
//!
//! Host only: no emulator. Each check has a test that feeds it a made-up
//! wrong document and sees it fail.

use std::collections::BTreeSet;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use modex::regs::{Crtc, Port};
use modex::soft::{dac_6_to_8, SoftVga};
use modex::{ModeX, Page, VgaBus};

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
    web_options: BTreeSet<String>,
    constants: Vec<Constant>,
    /// The bus operations of the driver's mode set, in order.
    mode_set: Vec<BusOp>,
}

impl Context {
    fn new() -> Context {
        Context {
            root: repository(),
            runner_options: runner_options(),
            sim_options: sim_options(),
            web_options: web_options(),
            constants: constants_in(&repository()),
            mode_set: mode_set_operations(),
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
/// The long options the web page builder's usage text lists
/// (`web/src/main.rs`'s `USAGE`, which its argument parser matches).
fn web_options() -> BTreeSet<String> {
    let source = std::fs::read_to_string(repository().join("web/src/main.rs"))
        .expect("web/src/main.rs exists");
    let usage = source
        .split("const USAGE: &str = \"")
        .nth(1)
        .and_then(|rest| rest.split("\";").next())
        .expect("web/src/main.rs has a USAGE text");
    let options = long_options_in(usage);
    assert!(
        options.contains("--out") && options.contains("--serve"),
        "the web builder's USAGE lists no options: {usage}"
    );
    options
}

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

/// A `const` in the repository's Rust sources.
struct Constant {
    /// The file, relative to the root, with `/` between folders.
    file: String,
    name: String,
    /// The expression after `=`, up to the `;`.
    expression: String,
}

/// Every `const NAME: TYPE = EXPRESSION;` in the repository's `.rs` files
/// (the build's `target/` and hidden folders left out).
fn constants_in(root: &Path) -> Vec<Constant> {
    let mut files = Vec::new();
    let mut folders = vec![root.to_path_buf()];
    while let Some(folder) = folders.pop() {
        for entry in std::fs::read_dir(&folder).expect("the repository is readable") {
            let path = entry.expect("the repository is readable").path();
            let name = path.file_name().unwrap().to_string_lossy().to_string();
            if name.starts_with('.') || (folder == root && name == "target") {
                continue;
            }
            if path.is_dir() {
                folders.push(path);
            } else if name.ends_with(".rs") {
                files.push(path);
            }
        }
    }
    files.sort();
    let mut constants = Vec::new();
    for path in files {
        let Ok(source) = std::fs::read_to_string(&path) else {
            continue;
        };
        let file = path
            .strip_prefix(root)
            .unwrap()
            .to_string_lossy()
            .replace('\\', "/");
        constants.extend(
            constant_definitions(&source)
                .into_iter()
                .map(|(name, expression)| Constant {
                    file: file.clone(),
                    name,
                    expression,
                }),
        );
    }
    constants
}

/// The `(name, expression)` of every `const` item in a Rust source.
fn constant_definitions(source: &str) -> Vec<(String, String)> {
    let mut found = Vec::new();
    let mut rest = source;
    while let Some(at) = rest.find("const ") {
        let before = &rest[..at];
        rest = &rest[at + "const ".len()..];
        // A whole word: `const` after a space, a newline or `)` (`pub(crate)`).
        if !(before.is_empty() || before.ends_with([' ', '\n', '\t', ')'])) {
            continue;
        }
        let Some(colon) = rest.find(':') else { break };
        let name = rest[..colon].trim();
        if name.is_empty() || !name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
            continue;
        }
        let Some(equals) = rest.find('=') else { break };
        let Some(semicolon) = rest[equals..].find(';') else {
            break;
        };
        found.push((
            name.to_string(),
            rest[equals + 1..equals + semicolon].trim().to_string(),
        ));
    }
    found
}

/// The value of a constant's expression: literals (with `_`, `0x`, type
/// suffixes), `+ - * / << >>`, parentheses, `as` casts and other constants
/// of the same file. `None` for anything else.
fn evaluate(expression: &str, file: &str, constants: &[Constant], depth: u32) -> Option<f64> {
    struct Parser<'a> {
        tokens: Vec<String>,
        at: usize,
        file: &'a str,
        constants: &'a [Constant],
        depth: u32,
    }
    impl Parser<'_> {
        fn peek(&self) -> Option<&str> {
            self.tokens.get(self.at).map(String::as_str)
        }
        fn next(&mut self) -> Option<String> {
            self.at += 1;
            self.tokens.get(self.at - 1).cloned()
        }
        fn sum(&mut self) -> Option<f64> {
            let mut value = self.product()?;
            while let Some(op) = self.peek().filter(|t| ["+", "-", "<<", ">>"].contains(t)) {
                let op = op.to_string();
                self.next();
                let right = self.product()?;
                value = match op.as_str() {
                    "+" => value + right,
                    "-" => value - right,
                    "<<" => ((value as i128) << (right as u32)) as f64,
                    _ => ((value as i128) >> (right as u32)) as f64,
                };
            }
            Some(value)
        }
        fn product(&mut self) -> Option<f64> {
            let mut value = self.atom()?;
            while let Some(op) = self.peek().filter(|t| ["*", "/"].contains(t)) {
                let op = op.to_string();
                self.next();
                let right = self.atom()?;
                value = if op == "*" {
                    value * right
                } else {
                    value / right
                };
            }
            Some(value)
        }
        fn atom(&mut self) -> Option<f64> {
            let token = self.next()?;
            let value = if token == "(" {
                let value = self.sum()?;
                (self.next()? == ")").then_some(value)?
            } else if token == "-" {
                -self.atom()?
            } else if token.starts_with(|c: char| c.is_ascii_digit()) {
                number(&token)?
            } else {
                // A constant of the same file, or one a path names
                // (`demo::screens::PANEL_LOG_LINES`).
                let name = token.rsplit("::").next().unwrap();
                let path = token
                    .trim_start_matches("crate::")
                    .trim_start_matches("self::");
                let same_file = self
                    .constants
                    .iter()
                    .find(|c| c.file == self.file && c.name == name);
                let constant = match (path.contains("::"), same_file) {
                    (false, Some(constant)) => constant,
                    _ => match constants_named(self.constants, path).as_slice() {
                        [only] => *only,
                        _ => return None,
                    },
                };
                (self.depth < 8).then_some(())?;
                evaluate(
                    &constant.expression,
                    &constant.file,
                    self.constants,
                    self.depth + 1,
                )?
            };
            while self.peek() == Some("as") {
                self.next();
                self.next()?;
            }
            Some(value)
        }
    }
    fn number(token: &str) -> Option<f64> {
        let digits = token.replace('_', "");
        for suffix in [
            "u8", "u16", "u32", "u64", "u128", "usize", "i8", "i16", "i32", "i64", "i128", "isize",
            "f32", "f64",
        ] {
            if let Some(stripped) = digits.strip_suffix(suffix) {
                if !stripped.starts_with("0x") || !suffix.starts_with('f') {
                    return number(stripped);
                }
            }
        }
        if let Some(hex) = digits.strip_prefix("0x") {
            return u128::from_str_radix(hex, 16).ok().map(|v| v as f64);
        }
        if let Some(binary) = digits.strip_prefix("0b") {
            return u128::from_str_radix(binary, 2).ok().map(|v| v as f64);
        }
        digits.parse().ok()
    }
    let mut tokens = Vec::new();
    let mut chars = expression.chars().peekable();
    while let Some(&c) = chars.peek() {
        if c.is_whitespace() {
            chars.next();
        } else if c.is_ascii_alphanumeric() || c == '_' {
            let mut token = String::new();
            while let Some(&c) = chars.peek() {
                let exponent_sign = (c == '-' || c == '+')
                    && token.starts_with(|d: char| d.is_ascii_digit())
                    && token.ends_with('e');
                let path = c == ':';
                if c.is_ascii_alphanumeric() || c == '_' || c == '.' || exponent_sign || path {
                    token.push(c);
                    chars.next();
                } else {
                    break;
                }
            }
            tokens.push(token);
        } else if c == '<' || c == '>' {
            chars.next();
            (chars.next()? == c).then_some(())?;
            tokens.push(format!("{c}{c}"));
        } else if "+-*/()".contains(c) {
            tokens.push(c.to_string());
            chars.next();
        } else {
            return None;
        }
    }
    let mut parser = Parser {
        tokens,
        at: 0,
        file,
        constants,
        depth,
    };
    let value = parser.sum()?;
    (parser.at == parser.tokens.len()).then_some(value)
}

/// What a figure measures, told by its unit or by a constant's name.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Quantity {
    /// In microseconds.
    Time,
    /// In bytes.
    Size,
    /// In hertz.
    Frequency,
    /// A count (of reads, entries, tries, ...).
    Count,
}

/// A figure's unit: what it measures and its size in the base unit.
fn unit_of_figure(word: &str) -> (Quantity, f64) {
    match word {
        "s" => (Quantity::Time, 1e6),
        "ms" => (Quantity::Time, 1e3),
        "µs" | "us" => (Quantity::Time, 1.0),
        "ns" => (Quantity::Time, 1e-3),
        "B" | "byte" | "bytes" => (Quantity::Size, 1.0),
        "KiB" => (Quantity::Size, 1024.0),
        "MiB" => (Quantity::Size, 1024.0 * 1024.0),
        "GiB" => (Quantity::Size, 1024.0 * 1024.0 * 1024.0),
        "Hz" => (Quantity::Frequency, 1.0),
        "kHz" => (Quantity::Frequency, 1e3),
        "MHz" => (Quantity::Frequency, 1e6),
        _ => (Quantity::Count, 1.0),
    }
}

/// A constant's unit, from the end of its name; `None` if it names none.
fn unit_of_constant(name: &str) -> Option<(Quantity, f64)> {
    [
        ("_MICROS", Quantity::Time, 1.0),
        ("_US", Quantity::Time, 1.0),
        ("_MILLIS", Quantity::Time, 1e3),
        ("_MS", Quantity::Time, 1e3),
        ("_NANOS", Quantity::Time, 1e-3),
        ("_SECS", Quantity::Time, 1e6),
        ("_BYTES", Quantity::Size, 1.0),
        ("_SIZE", Quantity::Size, 1.0),
        ("_KIB", Quantity::Size, 1024.0),
        ("_HZ", Quantity::Frequency, 1.0),
        ("_KHZ", Quantity::Frequency, 1e3),
    ]
    .into_iter()
    .find(|(suffix, _, _)| name.ends_with(suffix))
    .map(|(_, quantity, scale)| (quantity, scale))
}

/// The figure a text ends with, as in "... given up after 5 s": its number,
/// the unit word after it (if any) and half its last digit (the rounding a
/// quoted figure may carry).
fn trailing_figure(text: &str) -> Option<(f64, String, f64)> {
    let words: Vec<&str> = text.split_whitespace().rev().take(2).collect();
    let parse = |word: &str| -> Option<(f64, f64)> {
        let word = word.trim_start_matches(['(', '~']);
        if !word.starts_with(|c: char| c.is_ascii_digit()) {
            return None;
        }
        if let Some(hex) = word.strip_prefix("0x") {
            return Some((u64::from_str_radix(hex, 16).ok()? as f64, 0.5));
        }
        let plain = word.replace(',', "");
        let decimals = plain.split_once('.').map_or(0, |(_, d)| d.len());
        Some((plain.parse().ok()?, 0.5 / 10f64.powi(decimals as i32)))
    };
    match words.as_slice() {
        [last, ..] if parse(last).is_some() => {
            let (value, half) = parse(last)?;
            Some((value, String::new(), half))
        }
        [unit, number] if unit.chars().all(|c| c.is_alphabetic() || c == 'µ') => {
            let (value, half) = parse(number)?;
            Some((value, unit.to_string(), half))
        }
        _ => None,
    }
}

/// Is this backticked text a constant's name, bare or with its module path
/// (`COMMAND_MICROS`, `xhci::HANDOFF_MICROS`)?
fn is_constant_name(span: &str) -> bool {
    let mut parts: Vec<&str> = span.split("::").collect();
    let name = parts.pop().unwrap();
    name.len() > 1
        && name.starts_with(|c: char| c.is_ascii_uppercase())
        && name
            .chars()
            .all(|c| c.is_ascii_uppercase() || c.is_ascii_digit() || c == '_')
        && parts.iter().all(|part| {
            !part.is_empty()
                && part
                    .chars()
                    .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_')
        })
}

/// The constants a qualified name can mean: `a::b::NAME` is a `NAME`
/// defined in a file whose path holds the folders or file stems `a` and
/// `b` (a crate's `-` read as `_`).
fn constants_named<'a>(constants: &'a [Constant], span: &str) -> Vec<&'a Constant> {
    let mut parts: Vec<&str> = span.split("::").collect();
    let name = parts.pop().unwrap();
    constants
        .iter()
        .filter(|constant| constant.name == name)
        .filter(|constant| {
            let segments: Vec<String> = constant
                .file
                .trim_end_matches(".rs")
                .split('/')
                .map(|s| s.replace('-', "_"))
                .collect();
            parts.iter().all(|part| segments.iter().any(|s| s == part))
        })
        .collect()
}

/// Problems with every constant the prose quotes: "FIGURE (`NAME`)".
fn check_constants(constants: &[Constant], name: &str, prose: &[String]) -> Vec<String> {
    let mut problems = Vec::new();
    let text = prose.join("\n");
    let mut from = 0;
    while let Some(at) = text[from..].find("(`") {
        let open = from + at;
        from = open + 2;
        let Some(close) = text[from..].find("`)") else {
            break;
        };
        let span = &text[from..from + close];
        if !is_constant_name(span) {
            continue;
        }
        // The figure sits just before the parenthesis, on the same line or
        // the one before (text is wrapped).
        let line_start = text[..open].rfind('\n').map_or(0, |n| n + 1);
        let previous_start = text[..line_start.saturating_sub(1)]
            .rfind('\n')
            .map_or(0, |n| n + 1);
        let Some((figure, unit, half_digit)) = trailing_figure(&text[previous_start..open]) else {
            continue;
        };
        let where_ = format!("{name}:{}", text[..open].matches('\n').count() + 1);
        let candidates = constants_named(constants, span);
        let values: Vec<(String, Option<f64>)> = candidates
            .iter()
            .map(|c| {
                (
                    c.file.clone(),
                    evaluate(&c.expression, &c.file, constants, 0),
                )
            })
            .collect();
        let Some((file, value)) = values.first().cloned() else {
            problems.push(format!(
                "{where_}: `{span}`, quoted as {figure} {unit}, is defined nowhere in the sources"
            ));
            continue;
        };
        if values.iter().any(|(_, v)| *v != value) {
            let files: Vec<&str> = values.iter().map(|(f, _)| f.as_str()).collect();
            problems.push(format!(
                "{where_}: `{span}` has different values in {files:?}: qualify it (`module::NAME`)"
            ));
            continue;
        }
        let Some(value) = value else {
            problems.push(format!(
                "{where_}: `{span}` in {file} is not a value the docs test can evaluate"
            ));
            continue;
        };
        let (figure_quantity, figure_scale) = unit_of_figure(&unit);
        let (constant_quantity, constant_scale) = match unit_of_constant(span) {
            Some(unit) => unit,
            None if figure_quantity == Quantity::Time => {
                problems.push(format!(
                    "{where_}: `{span}` is quoted as a time, but its name says no unit (_MICROS, _MILLIS, ...)"
                ));
                continue;
            }
            None => (figure_quantity, 1.0),
        };
        let (figure_quantity, figure_scale) =
            if figure_quantity == Quantity::Count && constant_quantity != Quantity::Count {
                // "16 reports", "1,024 bytes of descriptor": a plain count
                // beside a constant of a unit is in that unit's base.
                (constant_quantity, 1.0)
            } else {
                (figure_quantity, figure_scale)
            };
        if figure_quantity != constant_quantity {
            problems.push(format!(
                "{where_}: `{span}` ({file}) is a {constant_quantity:?}, quoted as {figure} {unit}"
            ));
            continue;
        }
        let quoted = figure * figure_scale;
        let actual = value * constant_scale;
        if (quoted - actual).abs() > half_digit * figure_scale + 1e-9 * actual.abs() {
            problems.push(format!(
                "{where_}: `{span}` is quoted as {figure} {unit}, but {file} defines {} ({})",
                value, candidates[0].expression
            ));
        }
    }
    problems
}

/// Problems with every backticked `file.rs:function`: the file must define
/// the function (`fn NAME`; for `Type::method`, the method).
fn check_functions(root: &Path, name: &str, prose: &[String]) -> Vec<String> {
    let mut problems = Vec::new();
    for (line, span) in code_spans(prose) {
        let Some((file, function)) = span.split_once(".rs:") else {
            continue;
        };
        let file = format!("{file}.rs");
        if !looks_like_repository_path(&file)
            || function.is_empty()
            || !function
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == ':')
        {
            continue;
        }
        let where_ = format!("{name}:{line}");
        let Ok(source) = std::fs::read_to_string(root.join(&file)) else {
            problems.push(format!("{where_}: `{span}`: there is no file {file}"));
            continue;
        };
        if let Ok(number) = function.parse::<usize>() {
            // `file.rs:33`, a line.
            if number == 0 || number > source.lines().count() {
                problems.push(format!("{where_}: `{span}`: {file} has no line {number}"));
            }
            continue;
        }
        let method = function.rsplit("::").next().unwrap();
        let defined = [format!("fn {method}("), format!("fn {method}<")]
            .iter()
            .any(|definition| source.contains(definition.as_str()));
        let type_named = match function.rsplit_once("::") {
            // `Type::method`: an `impl` (or the trait) of that type.
            Some((owner, _)) => {
                let owner = owner.rsplit("::").next().unwrap();
                source.lines().map(str::trim_start).any(|line| {
                    (line.starts_with("impl") || line.starts_with("pub trait"))
                        && line
                            .split(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
                            .any(|word| word == owner)
                })
            }
            None => true,
        };
        if !defined || !type_named {
            problems.push(format!("{where_}: `{span}`: {file} defines no {function}"));
        }
    }
    problems
}

/// A problem with a quoted block (```` ```rust FILE ````), if its lines are
/// not in that file, together and in order (indentation aside).
fn check_quotation(root: &Path, where_: &str, file: &str, quoted: &str) -> Option<String> {
    let Ok(source) = std::fs::read_to_string(root.join(file)) else {
        return Some(format!("{where_}: the quoted file {file} does not exist"));
    };
    let block: Vec<&str> = quoted.lines().collect();
    let code: Vec<&str> = source.lines().collect();
    // A doc test's lines are quoted without their `/// ` or `//! `.
    let doc_tests: Vec<&str> = code
        .iter()
        .map(|line| {
            let line = line.trim_start();
            ["/// ", "//! ", "///", "//!"]
                .iter()
                .find_map(|prefix| line.strip_prefix(prefix))
                .unwrap_or(line)
        })
        .collect();
    let found = [code, doc_tests]
        .iter()
        .any(|source| quotation_is_in(&block, source));
    (!found).then(|| {
        let first = block.iter().find(|line| !line.trim().is_empty());
        format!(
            "{where_}: the quoted code is not in {file} as it stands (its first line: {})",
            first.map_or("", |line| line.trim())
        )
    })
}

/// Whether `block`'s lines are in `source`, together and in order
/// (indentation aside).
fn quotation_is_in(block: &[&str], source: &[&str]) -> bool {
    let Some(first) = block.iter().find(|line| !line.trim().is_empty()) else {
        return true;
    };
    let block_indent = first.len() - first.trim_start().len();
    (0..source.len()).any(|start| {
        let Some(line) = source.get(start + block.iter().position(|l| l == first).unwrap()) else {
            return false;
        };
        if line.trim_start() != first.trim_start() {
            return false;
        }
        let indent = (line.len() - line.trim_start().len()) as isize - block_indent as isize;
        block.len() + start <= source.len()
            && block
                .iter()
                .zip(&source[start..])
                .all(|(quoted, original)| {
                    if quoted.trim().is_empty() {
                        original.trim().is_empty()
                    } else if indent >= 0 {
                        original
                            .get(..indent as usize)
                            .is_some_and(|p| p.trim().is_empty())
                            && &original[indent as usize..] == *quoted
                    } else {
                        quoted
                            .get(..(-indent) as usize)
                            .is_some_and(|p| p.trim().is_empty())
                            && &quoted[(-indent) as usize..] == *original
                    }
                })
    })
}

/// A fenced block: its language and its lines.
struct Fence {
    language: String,
    /// The source file a quoted block is taken from (the info string's
    /// second word).
    source: Option<String>,
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
                    let mut info = trimmed.trim_start_matches('`').split_whitespace();
                    open = Some(Fence {
                        language: info.next().unwrap_or("").to_string(),
                        source: info.next().map(String::from),
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
        let package = |name: &str| cargo_args.windows(2).any(|p| p[0] == "-p" && p[1] == name);
        let (is_sim, is_web) = (package("sim"), package("web"));
        let is_other_package = !is_sim && !is_web && cargo_args.iter().any(|w| w == "-p");
        if is_other_package {
            problems.push(format!(
                "`{}`: a package the docs test does not know",
                part.trim()
            ));
            continue;
        }
        let (known, program) = if is_sim {
            (&context.sim_options, "the simulator")
        } else if is_web {
            (&context.web_options, "the web page builder")
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
        if let Some(file) = &fence.source {
            problems.extend(check_quotation(&context.root, &where_, file, &fence.text));
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
            if target.contains("://") || target.starts_with("mailto:") {
                continue;
            }
            let (file, fragment) = match target.split_once('#') {
                Some((file, fragment)) => (file, Some(fragment)),
                None => (target.as_str(), None),
            };
            let linked = directory.join(file);
            if !file.is_empty() && !linked.exists() {
                problems.push(format!("{where_}: the link {target} leads nowhere"));
                continue;
            }
            // A heading's anchor, in this page or another chapter.
            let Some(fragment) = fragment else { continue };
            let linked_text = if file.is_empty() {
                text.to_string()
            } else if file.ends_with(".md") {
                std::fs::read_to_string(&linked).unwrap_or_default()
            } else {
                continue;
            };
            if !heading_anchors(&linked_text).contains(fragment) {
                problems.push(format!(
                    "{where_}: the link {target} leads to no heading (#{fragment})"
                ));
            }
        }
    }

    problems.extend(check_constants(
        &context.constants,
        &name.to_string(),
        &prose,
    ));
    problems.extend(check_functions(&context.root, &name.to_string(), &prose));
    problems.extend(check_mode_set_tables(
        &context.mode_set,
        &name.to_string(),
        &prose,
    ));
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

// The book as a whole: its lists and tables against what they describe.

/// The book's documents, as `(path, text)`: README.md and docs/*.md
/// (CHANGELOG.md is history: its figures and lines are of their day).
fn book() -> Vec<(String, String)> {
    documents()
        .into_iter()
        .filter(|path| path != Path::new("CHANGELOG.md"))
        .map(|path| {
            let text = std::fs::read_to_string(repository().join(&path)).unwrap();
            (path.display().to_string(), text)
        })
        .collect()
}

fn read(file: &str) -> String {
    std::fs::read_to_string(repository().join(file)).unwrap_or_else(|e| panic!("{file}: {e}"))
}

/// The part of a Markdown text under the heading `heading` (the whole line,
/// as `## Options`), up to the next heading of the same level or higher.
fn section<'a>(text: &'a str, heading: &str) -> Option<&'a str> {
    let level = heading.chars().take_while(|&c| c == '#').count();
    let start = text.find(&format!("{heading}\n"))? + heading.len() + 1;
    let rest = &text[start..];
    let end = rest
        .match_indices('\n')
        .map(|(at, _)| at + 1)
        .find(|&at| {
            let hashes = rest[at..].chars().take_while(|&c| c == '#').count();
            (1..=level).contains(&hashes) && rest[at + hashes..].starts_with(' ')
        })
        .unwrap_or(rest.len());
    Some(&rest[..end])
}

/// The backticked spans of a table's rows (`|` lines), by row and column.
fn table_cells(text: &str) -> Vec<Vec<Vec<String>>> {
    text.lines()
        .filter(|line| line.trim_start().starts_with('|') && !line.contains("|---"))
        .map(|line| {
            // `\|` inside a cell is a literal bar.
            let line = line.replace("\\|", "\u{1}");
            line.trim()
                .trim_matches('|')
                .split('|')
                .map(|cell| {
                    code_spans(&[cell.replace('\u{1}', "|")])
                        .into_iter()
                        .map(|(_, span)| span)
                        .collect()
                })
                .collect()
        })
        .collect()
}

/// The values a runner option takes, as its own error for a bad value
/// lists them ("one of: a, b" or clap's "[possible values: a, b]").
fn runner_values(option: &str) -> Option<BTreeSet<String>> {
    let output = Command::new(env!("CARGO_BIN_EXE_modex-cube"))
        .args([option, "not-a-value"])
        .output()
        .expect("the runner starts");
    assert!(!output.status.success(), "{option} not-a-value was taken");
    values_in_usage_error(&String::from_utf8_lossy(&output.stderr))
}

fn values_in_usage_error(error: &str) -> Option<BTreeSet<String>> {
    let list = ["one of: ", "[possible values: "]
        .iter()
        .find_map(|marker| error.split(marker).nth(1))?;
    let list = list.split(['\n', ']']).next().unwrap();
    Some(
        list.split(',')
            .map(|value| value.trim().trim_start_matches("or ").trim().to_string())
            .filter(|value| !value.is_empty())
            .collect(),
    )
}

/// Problems with `docs/runner.md`'s table of options: a row for every
/// option of the runner's `--help` (but `--help` and `--version`), none for
/// an option it lacks, and every `--option a|b|c` giving exactly the values
/// the runner takes.
fn check_runner_table(
    chapter: &str,
    options: &BTreeSet<String>,
    values_of: &dyn Fn(&str) -> Option<BTreeSet<String>>,
) -> Vec<String> {
    let Some(table) = section(chapter, "## Options") else {
        return vec!["docs/runner.md has no \"## Options\" section".into()];
    };
    let mut problems = Vec::new();
    let mut listed = BTreeSet::new();
    for row in table_cells(table) {
        for span in row.first().into_iter().flatten() {
            let words: Vec<&str> = span.split_whitespace().collect();
            for (index, word) in words.iter().enumerate() {
                if !word.starts_with("--") {
                    continue;
                }
                listed.insert(word.to_string());
                let Some(values) = words.get(index + 1).filter(|w| w.contains('|')) else {
                    continue;
                };
                let documented: BTreeSet<String> = values.split('|').map(String::from).collect();
                match values_of(word) {
                    Some(taken) if taken == documented => {}
                    Some(taken) => problems.push(format!(
                        "docs/runner.md: `{word} {values}`, but the runner takes {}",
                        taken.into_iter().collect::<Vec<_>>().join("|")
                    )),
                    None => problems.push(format!(
                        "docs/runner.md: `{word} {values}`: the runner's error for a bad value lists none"
                    )),
                }
            }
        }
    }
    for option in options {
        if !listed.contains(option) && option != "--help" && option != "--version" {
            problems.push(format!(
                "docs/runner.md's options table has no row for {option}"
            ));
        }
    }
    for option in &listed {
        if !options.contains(option) {
            problems.push(format!(
                "docs/runner.md's options table lists {option}, which the runner lacks"
            ));
        }
    }
    problems
}

#[test]
fn the_runner_chapter_lists_every_option_and_its_values() {
    let problems = check_runner_table(&read("docs/runner.md"), &runner_options(), &runner_values);
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

#[test]
fn a_runner_option_left_out_or_a_value_list_cut_short_is_caught() {
    let options = runner_options();
    let mut made_up = String::from("## Options\n\n| option | what |\n|---|---|\n");
    for option in &options {
        let row = match option.as_str() {
            "--usb-keyboard" | "--help" | "--version" => continue,
            "--usb-stick" => "`--usb-stick xhci\\|ehci`".to_string(),
            other => format!("`{other}`"),
        };
        made_up.push_str(&format!("| {row} | it |\n"));
    }
    made_up.push_str("| `--no-such-option` | none |\n");
    let problems = check_runner_table(&made_up, &options, &runner_values);
    assert_eq!(problems.len(), 3, "{problems:?}");
    assert!(
        problems[0].contains("ehci|ich9|ohci|uhci|xhci"),
        "{problems:?}"
    );
    assert!(
        problems[1].contains("no row for --usb-keyboard"),
        "{problems:?}"
    );
    assert!(problems[2].contains("--no-such-option"), "{problems:?}");
}

/// The workspace's members, from the root `Cargo.toml`.
fn workspace_members(manifest: &str) -> Vec<String> {
    let list = manifest
        .split("\nmembers = [")
        .nth(1)
        .and_then(|rest| rest.split(']').next())
        .expect("Cargo.toml lists the workspace's members");
    list.split(',')
        .map(|member| member.trim().trim_matches('"').to_string())
        .filter(|member| !member.is_empty())
        .collect()
}

/// Problems with `docs/architecture.md`'s crate table: every workspace
/// member must be in it, as `member/`.
fn check_crate_table(chapter: &str, members: &[String]) -> Vec<String> {
    let Some(table) = section(chapter, "## The crates") else {
        return vec!["docs/architecture.md has no \"## The crates\" section".into()];
    };
    let named: BTreeSet<String> = table_cells(table).into_iter().flatten().flatten().collect();
    members
        .iter()
        .filter(|member| !named.contains(&format!("{member}/")))
        .map(|member| format!("docs/architecture.md's crate table leaves out `{member}/`"))
        .collect()
}

#[test]
fn the_architecture_chapter_lists_every_crate() {
    let members = workspace_members(&read("Cargo.toml"));
    assert!(members.len() > 10, "{members:?}");
    let problems = check_crate_table(&read("docs/architecture.md"), &members);
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

#[test]
fn a_crate_left_out_of_the_architecture_chapter_is_caught() {
    let members = workspace_members("[workspace]\nmembers = [\n    \"modex\",\n    \"web\",\n]\n");
    assert_eq!(members, ["modex", "web"]);
    let made_up = "## The crates\n\n| crate | holds |\n|---|---|\n| `modex/` | the driver |\n\n## Next\n\n`web/`\n";
    assert_eq!(
        check_crate_table(made_up, &members),
        ["docs/architecture.md's crate table leaves out `web/`"]
    );
}

/// Problems with `docs/testing.md`'s table of what each test proves: a row
/// for every `tests/*.rs`.
fn check_test_table(chapter: &str, files: &[String]) -> Vec<String> {
    let Some(table) = section(chapter, "## What each test proves") else {
        return vec!["docs/testing.md has no \"## What each test proves\" section".into()];
    };
    let rows: BTreeSet<String> = table_cells(table)
        .into_iter()
        .filter_map(|row| row.into_iter().next())
        .flatten()
        .collect();
    files
        .iter()
        .filter(|file| !rows.contains(*file))
        .map(|file| format!("docs/testing.md's table has no row for tests/{file}"))
        .collect()
}

/// The test files of the root package: `tests/*.rs`.
fn test_files() -> Vec<String> {
    let mut files: Vec<String> = std::fs::read_dir(repository().join("tests"))
        .unwrap()
        .map(|entry| entry.unwrap().file_name().to_string_lossy().to_string())
        .filter(|name| name.ends_with(".rs"))
        .collect();
    files.sort();
    files
}

#[test]
fn the_testing_chapter_has_a_row_for_every_test_file() {
    let files = test_files();
    assert!(files.contains(&"docs.rs".to_string()), "{files:?}");
    let problems = check_test_table(&read("docs/testing.md"), &files);
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

#[test]
fn a_test_file_without_a_row_is_caught() {
    let made_up =
        "## What each test proves\n\n| file | proves |\n|---|---|\n| `boot.rs` | boots |\n";
    let files = ["boot.rs".to_string(), "usb_hosts.rs".to_string()];
    assert_eq!(
        check_test_table(made_up, &files),
        ["docs/testing.md's table has no row for tests/usb_hosts.rs"]
    );
}

/// What `boot/setup.sh` installs: the Debian packages it adds to
/// `missing`, the ones it downloads, what pip installs, and the components
/// and targets `rust-toolchain.toml` names (which rustup installs).
fn setup_installs(script: &str, toolchain: &str) -> BTreeSet<String> {
    let mut installs = BTreeSet::new();
    for line in script
        .lines()
        .filter(|line| !line.trim_start().starts_with('#'))
    {
        for part in line.split("missing+=(").skip(1) {
            installs.insert(part.split(')').next().unwrap().to_string());
        }
        for marker in ["apt-get download -q ", "pip\" install -q "] {
            if let Some(rest) = line.split(marker).nth(1) {
                let names = rest.split([')', '>', '&', '|']).next().unwrap();
                installs.extend(names.split_whitespace().map(String::from));
            }
        }
    }
    for key in ["components", "targets"] {
        let list = toolchain
            .lines()
            .find_map(|line| line.strip_prefix(&format!("{key} = [")))
            .unwrap_or_else(|| panic!("rust-toolchain.toml has no {key}"));
        installs.extend(
            list.trim_end_matches(']')
                .split(',')
                .map(|name| name.trim().trim_matches('"').to_string())
                .filter(|name| !name.is_empty()),
        );
    }
    installs
}

/// Problems with `docs/building.md`'s list of what `boot/setup.sh`
/// installs: each thing must be named there, backticked.
fn check_setup_list(chapter: &str, installs: &BTreeSet<String>) -> Vec<String> {
    let Some(list) = section(chapter, "## What `boot/setup.sh` installs") else {
        return vec!["docs/building.md has no \"## What `boot/setup.sh` installs\"".into()];
    };
    let lines: Vec<String> = list.lines().map(String::from).collect();
    let named: BTreeSet<String> = code_spans(&lines).into_iter().map(|(_, s)| s).collect();
    installs
        .iter()
        .filter(|thing| !named.contains(*thing))
        .map(|thing| format!("docs/building.md does not say that boot/setup.sh installs `{thing}`"))
        .collect()
}

#[test]
fn the_building_chapter_lists_what_setup_installs() {
    let installs = setup_installs(&read("boot/setup.sh"), &read("rust-toolchain.toml"));
    for expected in [
        "qemu-system-x86",
        "shim-signed",
        "virt-firmware",
        "x86_64-unknown-none",
    ] {
        assert!(
            installs.contains(expected),
            "{expected} not read from {installs:?}"
        );
    }
    let problems = check_setup_list(&read("docs/building.md"), &installs);
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

#[test]
fn a_package_setup_installs_but_the_chapter_omits_is_caught() {
    let script = "command -v nasm >/dev/null || missing+=(nasm)\n\
                  command -v sign-efi-sig-list >/dev/null || missing+=(efitools)\n";
    let toolchain = "components = [\"rust-src\"]\ntargets = [\"wasm32-unknown-unknown\"]\n";
    let installs = setup_installs(script, toolchain);
    let made_up =
        "## What `boot/setup.sh` installs\n\n| what |\n|---|\n| `nasm` |\n| `rust-src` |\n";
    assert_eq!(
        check_setup_list(made_up, &installs),
        [
            "docs/building.md does not say that boot/setup.sh installs `efitools`",
            "docs/building.md does not say that boot/setup.sh installs `wasm32-unknown-unknown`",
        ]
    );
}

/// Problems with the book's contents: `contents` (docs/README.md) must
/// link every chapter, and `read_more` (the README's "Read more") too, as
/// `docs/NAME.md`.
fn check_contents(contents: &str, read_more: &str, chapters: &[String]) -> Vec<String> {
    let targets = |text: &str| -> BTreeSet<String> {
        text.lines()
            .flat_map(link_targets)
            .map(|target| target.split('#').next().unwrap().to_string())
            .collect()
    };
    let (in_contents, in_read_more) = (targets(contents), targets(read_more));
    let mut problems = Vec::new();
    for chapter in chapters {
        if !in_contents.contains(chapter) {
            problems.push(format!("docs/README.md does not list {chapter}"));
        }
        if !in_read_more.contains(&format!("docs/{chapter}")) {
            problems.push(format!(
                "README.md's \"Read more\" does not list docs/{chapter}"
            ));
        }
    }
    problems
}

/// The chapters: docs/*.md but the contents page.
fn chapters() -> Vec<String> {
    documents()
        .into_iter()
        .filter_map(|path| {
            let name = path
                .strip_prefix("docs")
                .ok()?
                .to_string_lossy()
                .to_string();
            (name != "README.md").then_some(name)
        })
        .collect()
}

#[test]
fn the_contents_and_the_readme_list_every_chapter() {
    let readme = read("README.md");
    let read_more = section(&readme, "## Read more").expect("README.md has \"## Read more\"");
    let problems = check_contents(&read("docs/README.md"), read_more, &chapters());
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

#[test]
fn a_chapter_left_out_of_the_contents_is_caught() {
    let chapters = ["vga.md".to_string(), "web.md".to_string()];
    let contents = "1. [Mode X and the VGA](vga.md#the-hardware): the driver.\n";
    let read_more = "- [Mode X](docs/vga.md), [the page](docs/web.md);\n";
    assert_eq!(
        check_contents(contents, read_more, &chapters),
        ["docs/README.md does not list web.md"]
    );
    assert_eq!(
        check_contents(
            "[a](vga.md) [b](web.md)",
            "[Mode X](docs/vga.md)",
            &chapters
        ),
        ["README.md's \"Read more\" does not list docs/web.md"]
    );
}

/// A document's prose for word checks: fences blanked, and inline code,
/// URLs, link targets, HTML comments and headings blanked too (each
/// character a space, so columns stay). Link texts stay.
fn plain_prose(text: &str) -> Vec<String> {
    let (_, prose) = split_fences(text);
    let mut in_span = false;
    let mut in_comment = false;
    prose
        .iter()
        .map(|line| {
            if line.trim().is_empty() {
                in_span = false;
            }
            if line.starts_with('#') {
                return " ".repeat(line.len());
            }
            let mut out = String::new();
            // Blank up to this byte (a link's target, a URL).
            let mut blank_until = 0;
            for (at, c) in line.char_indices() {
                let rest = &line[at..];
                let blank = if at < blank_until {
                    true
                } else if in_comment {
                    if rest.starts_with("-->") {
                        in_comment = false;
                        blank_until = at + 3;
                    }
                    true
                } else if rest.starts_with("<!--") {
                    in_comment = true;
                    true
                } else if c == '`' {
                    in_span = !in_span;
                    true
                } else if in_span {
                    true
                } else if rest.starts_with("](") {
                    blank_until = at + rest.find(')').map_or(rest.len(), |end| end + 1);
                    true
                } else if rest.starts_with("http://") || rest.starts_with("https://") {
                    blank_until = at + rest.find(char::is_whitespace).unwrap_or(rest.len());
                    true
                } else {
                    false
                };
                if blank {
                    out.push_str(&" ".repeat(c.len_utf8()));
                } else {
                    out.push(c);
                }
            }
            out
        })
        .collect()
}

/// The words of a text that look like acronyms: 2 to 6 characters, capital
/// letters and digits, at least two capitals, first a capital (`ACPI`,
/// `PS2` no: `PS/2` gives `PS`; `E820` and `S5` are names, not acronyms).
fn acronyms_in(line: &str) -> Vec<(usize, String)> {
    let mut found = Vec::new();
    let mut start = None;
    let chars: Vec<char> = line.chars().collect();
    for index in 0..=chars.len() {
        let is_word = chars
            .get(index)
            .is_some_and(|c| c.is_alphanumeric() || *c == '_');
        match (start, is_word) {
            (None, true) => start = Some(index),
            (Some(from), false) => {
                let word: String = chars[from..index].iter().collect();
                let capitals = word.chars().filter(|c| c.is_ascii_uppercase()).count();
                if (2..=6).contains(&word.len())
                    && capitals >= 2
                    && word.starts_with(|c: char| c.is_ascii_uppercase())
                    && word
                        .chars()
                        .all(|c| c.is_ascii_uppercase() || c.is_ascii_digit())
                {
                    found.push((from, word));
                }
                start = None;
            }
            _ => {}
        }
    }
    found
}

/// Capitalised words that are not acronyms, each with why.
const NOT_ACRONYMS: &[(&str, &str)] = &[
    ("BOOT", "a folder's name in a firmware path, \\EFI\\BOOT"),
    ("II", "a roman numeral: EDK II, the UEFI project's name"),
    (
        "NOT",
        "emphasis in a quoted log line (`vga: Mode X NOT verified`)",
    ),
    ("OK", "a word, as said aloud"),
    ("README", "a file's name"),
];

/// The glossary's entries: each `## ` heading's anchor and the terms it
/// defines (`## SMI, SMM` defines both), and the abbreviations of its
/// table (`| CPU | ... |` rows under `## Abbreviations`).
struct Glossary {
    entries: Vec<(String, Vec<String>)>,
    abbreviations: BTreeSet<String>,
}

/// GitHub's anchor for a heading: lower case, spaces as `-`, punctuation
/// but `-` and `_` dropped.
fn anchor(heading: &str) -> String {
    heading
        .trim()
        .to_lowercase()
        .chars()
        .filter(|c| c.is_alphanumeric() || *c == ' ' || *c == '-' || *c == '_')
        .map(|c| if c == ' ' { '-' } else { c })
        .collect()
}

/// The anchors GitHub gives a document's headings (those outside fences);
/// a repeated heading's anchor gets `-1`, `-2`, ... after it.
fn heading_anchors(text: &str) -> BTreeSet<String> {
    let (_, prose) = split_fences(text);
    let mut anchors = BTreeSet::new();
    for line in &prose {
        let Some(heading) = line
            .strip_prefix('#')
            .map(|rest| rest.trim_start_matches('#'))
            .and_then(|rest| rest.strip_prefix(' '))
        else {
            continue;
        };
        let base = anchor(heading);
        let mut unique = base.clone();
        let mut repeat = 0;
        while !anchors.insert(unique.clone()) {
            repeat += 1;
            unique = format!("{base}-{repeat}");
        }
    }
    anchors
}

fn glossary_of(text: &str) -> Glossary {
    let mut entries = Vec::new();
    for heading in text.lines().filter_map(|line| line.strip_prefix("## ")) {
        if heading == "Abbreviations" {
            continue;
        }
        let terms = heading
            .split(", ")
            .map(|term| term.trim().to_string())
            .collect();
        entries.push((anchor(heading), terms));
    }
    let abbreviations = section(text, "## Abbreviations")
        .map(|table| {
            table
                .lines()
                .filter(|line| line.starts_with('|') && !line.starts_with("|---"))
                .filter_map(|line| line.trim_matches('|').split('|').next())
                .flat_map(|cell| cell.split(',').map(|name| name.trim().to_string()))
                .collect()
        })
        .unwrap_or_default();
    Glossary {
        entries,
        abbreviations,
    }
}

impl Glossary {
    /// Is `word` defined: an abbreviation, a term of an entry, or one of
    /// those with a number after it (`BAR0`, `SSE2`) or a part of one
    /// (`PS` of `PS/2`, `PM` of `PM timer`)?
    fn defines(&self, word: &str) -> bool {
        let bare = word.trim_end_matches(|c: char| c.is_ascii_digit());
        [word, bare]
            .into_iter()
            .any(|word| self.defines_exactly(word))
    }

    fn defines_exactly(&self, word: &str) -> bool {
        self.abbreviations
            .iter()
            .any(|name| name.split(['/', ' ']).any(|part| part == word))
            || self.entries.iter().any(|(_, terms)| {
                terms
                    .iter()
                    .any(|term| term.split(['/', ' ']).any(|w| w == word))
            })
    }
}

/// Problems with the acronyms of the book: each one used in `documents`
/// must be defined in the glossary (an entry or a row of its
/// abbreviations) or be one of [`NOT_ACRONYMS`].
fn check_acronyms(documents: &[(String, String)], glossary: &Glossary) -> Vec<String> {
    let mut problems = Vec::new();
    let mut reported = BTreeSet::new();
    for (name, text) in documents {
        for (number, line) in plain_prose(text).iter().enumerate() {
            for (_, word) in acronyms_in(line) {
                if glossary.defines(&word)
                    || NOT_ACRONYMS.iter().any(|(not, _)| *not == word)
                    || !reported.insert(word.clone())
                {
                    continue;
                }
                problems.push(format!(
                    "{name}:{}: {word} is not in docs/glossary.md",
                    number + 1
                ));
            }
        }
    }
    problems
}

#[test]
fn every_acronym_of_the_book_is_in_the_glossary() {
    let glossary = glossary_of(&read("docs/glossary.md"));
    let problems = check_acronyms(&book(), &glossary);
    assert!(
        problems.is_empty(),
        "{} acronyms:\n{}",
        problems.len(),
        problems.join("\n")
    );
}

#[test]
fn an_acronym_the_glossary_lacks_is_caught() {
    let glossary = glossary_of(
        "# Glossary\n\n## SMI, SMM\n\nSystem Management Interrupt.\n\n## Abbreviations\n\n\
         | abbreviation | meaning |\n|---|---|\n| CPU | the processor |\n",
    );
    let made_up = "The CPU enters SMM on an SMI; the BAR says where (`MMIO` in code is\n\
                   not prose) and [a link](https://example.com/PCH) neither.\n";
    let problems = check_acronyms(&[("docs/made-up.md".into(), made_up.into())], &glossary);
    assert_eq!(
        problems,
        ["docs/made-up.md:1: BAR is not in docs/glossary.md"]
    );
}

/// Does `term` occur in `line` at `at`, as a whole word (a plural `s`
/// allowed)? All-capital terms match only in capitals; the others in
/// either case.
fn term_at(line: &str, at: usize, term: &str) -> bool {
    let Some(candidate) = line.get(at..at + term.len()) else {
        return false;
    };
    let has_lower_case = term.chars().any(|c| c.is_lowercase());
    let same = if has_lower_case {
        candidate.eq_ignore_ascii_case(term)
    } else {
        candidate == term
    };
    let mut rest = &line[at + term.len()..];
    if has_lower_case {
        // "latches", "write modes"
        rest = rest
            .strip_prefix("es")
            .or_else(|| rest.strip_prefix('s'))
            .unwrap_or(rest);
    }
    let is_word = |c: Option<char>| c.is_some_and(|c| c.is_alphanumeric() || c == '_');
    same && !is_word(line[..at].chars().next_back()) && !is_word(rest.chars().next())
}

/// The spans of a prose line that are the texts of links, with their
/// targets (the line as written, not blanked).
fn link_texts(line: &str) -> Vec<(usize, usize, String)> {
    let mut links = Vec::new();
    let mut from = 0;
    while let Some(open) = line[from..].find('[') {
        let open = from + open;
        let Some(close) = line[open..].find("](") else {
            break;
        };
        let close = open + close;
        let Some(end) = line[close..].find(')') else {
            break;
        };
        let target = line[close + 2..close + end].to_string();
        links.push((open + 1, close, target));
        from = close + end;
    }
    links
}

/// Problems with a chapter's glossary links: for every term the glossary
/// defines in an entry of its own, the term's first use in the chapter's
/// prose (outside code, headings, URLs and the texts of links to other
/// pages) must be the text of a link to its entry, `glossary.md#ANCHOR`.
fn check_glossary_links(name: &str, text: &str, glossary: &Glossary) -> Vec<String> {
    let (_, raw) = split_fences(text);
    let plain = plain_prose(text);
    let mut problems = Vec::new();
    for (anchor, terms) in &glossary.entries {
        let target = format!("glossary.md#{anchor}");
        let mut first: Option<(usize, usize, &str)> = None;
        'lines: for (number, (line, written)) in plain.iter().zip(&raw).enumerate() {
            let links = link_texts(written);
            for at in (0..line.len()).filter(|&at| line.is_char_boundary(at)) {
                let Some(term) = terms.iter().find(|term| term_at(line, at, term)) else {
                    continue;
                };
                let in_link = links
                    .iter()
                    .find(|(start, end, _)| (*start..*end).contains(&at));
                match in_link {
                    Some((_, _, to)) if to.ends_with(&target) => {
                        first = None;
                        break 'lines;
                    }
                    // The title of another page, as [Mode X and the VGA](vga.md).
                    Some(_) => continue,
                    None => {
                        first = Some((number + 1, at, term));
                        break 'lines;
                    }
                }
            }
        }
        if let Some((line, _, term)) = first {
            problems.push(format!(
                "{name}:{line}: the first use of \"{term}\" is not a link to {target}"
            ));
        }
    }
    problems
}

#[test]
fn every_chapter_links_the_glossary_at_the_first_use_of_a_term() {
    let glossary = glossary_of(&read("docs/glossary.md"));
    assert!(glossary.entries.len() > 40, "{}", glossary.entries.len());
    let mut problems = Vec::new();
    for (name, text) in book() {
        if name == "docs/glossary.md" || !name.starts_with("docs/") {
            continue;
        }
        problems.extend(check_glossary_links(&name, &text, &glossary));
    }
    assert!(
        problems.is_empty(),
        "{} unlinked:\n{}",
        problems.len(),
        problems.join("\n")
    );
}

#[test]
fn a_term_first_used_without_its_glossary_link_is_caught() {
    let glossary =
        glossary_of("## TCG\n\nQEMU's translator.\n\n## Vertical retrace\n\nThe beam.\n");
    let linked = "See [Mode X and TCG](vga.md). Under [TCG](glossary.md#tcg), then TCG;\n\
                  in [vertical retraces](glossary.md#vertical-retrace).\n";
    assert_eq!(
        check_glossary_links("docs/a.md", linked, &glossary),
        Vec::<String>::new()
    );
    let unlinked = "## TCG\n\n`TCG` in code; under TCG the\n\
                    guest is slow, and [TCG](glossary.md#tcg) later is too late.\n\
                    Vertical retrace is unlinked.\n";
    assert_eq!(
        check_glossary_links("docs/a.md", unlinked, &glossary),
        [
            "docs/a.md:3: the first use of \"TCG\" is not a link to glossary.md#tcg",
            "docs/a.md:5: the first use of \"Vertical retrace\" is not a link to glossary.md#vertical-retrace",
        ]
    );
}

/// A paragraph of prose with the line it starts on; a table is one
/// paragraph with the paragraph that introduces it.
fn paragraphs(prose: &[String]) -> Vec<(usize, String)> {
    let mut paragraphs: Vec<(usize, String)> = Vec::new();
    let mut current: Option<(usize, String)> = None;
    let mut previous_was_table = false;
    for (number, line) in prose.iter().enumerate() {
        if line.trim().is_empty() {
            if let Some(paragraph) = current.take() {
                paragraphs.push(paragraph);
            }
            continue;
        }
        let is_table = line.trim_start().starts_with('|');
        match current.as_mut() {
            Some((_, text)) => {
                text.push('\n');
                text.push_str(line);
            }
            None if is_table && !previous_was_table && !paragraphs.is_empty() => {
                // The table joins the paragraph before it.
                let (start, mut text) = paragraphs.pop().unwrap();
                text.push('\n');
                text.push_str(line);
                current = Some((start, text));
            }
            None => current = Some((number + 1, line.clone())),
        }
        previous_was_table = is_table;
    }
    paragraphs.extend(current);
    paragraphs
}

/// The figures of a paragraph that count tests or time them: "33 tests",
/// or a duration ("351 s", "2.5 min") in a sentence (or a table's row)
/// about tests. A duration that quotes a constant ("5 s
/// (`TRANSFER_MICROS`)") is the constant check's.
fn test_figures(paragraph: &str) -> Vec<String> {
    let mut sentences = Vec::new();
    let mut header: Option<&str> = None;
    for line in paragraph.lines() {
        if line.trim_start().starts_with('|') {
            // A row is read with its table's header ("| test | time |").
            let header = *header.get_or_insert(line);
            sentences.push(format!("{header}\n{line}"));
        } else {
            header = None;
            match sentences.last_mut() {
                Some(last) if !last.trim_start().starts_with('|') => {
                    last.push('\n');
                    last.push_str(line);
                }
                _ => sentences.push(line.to_string()),
            }
        }
    }
    sentences
        .iter()
        .flat_map(|text| {
            text.split(". ")
                .flat_map(|s| s.split(".\n"))
                .map(test_figures_of_sentence)
                .collect::<Vec<_>>()
        })
        .flatten()
        .collect()
}

fn test_figures_of_sentence(sentence: &str) -> Vec<String> {
    let words: Vec<&str> = sentence.split_whitespace().collect();
    let about_tests = words.iter().any(|word| {
        let word = word
            .trim_matches(|c: char| !c.is_alphanumeric())
            .to_lowercase();
        word == "test" || word == "tests" || word == "suite"
    });
    let mut figures = Vec::new();
    for (index, pair) in words.windows(2).enumerate() {
        let number = pair[0].trim_start_matches(['(', '~', '|']);
        if !number.starts_with(|c: char| c.is_ascii_digit())
            || !number
                .trim_end_matches(['%'])
                .chars()
                .all(|c| c.is_ascii_digit() || c == ',' || c == '.' || c == '-')
        {
            continue;
        }
        let unit = pair[1].trim_end_matches([',', '.', ';', ':', ')']);
        let quotes_constant = words
            .get(index + 2)
            .is_some_and(|next| next.starts_with("(`"));
        let is_count = unit == "tests" || unit == "test";
        let is_time = ["s", "ms", "min", "minutes", "seconds", "hours"].contains(&unit);
        if is_count || (is_time && about_tests && !quotes_constant) {
            figures.push(format!("{number} {unit}"));
        }
    }
    figures
}

/// Does the paragraph give a command to run: a backticked `cargo ...`,
/// `bash ...`, `target/release/modex-cube ...` or `node ...`?
fn has_command(paragraph: &str) -> bool {
    let lines: Vec<String> = paragraph.lines().map(String::from).collect();
    code_spans(&lines).iter().any(|(_, span)| {
        ["cargo ", "bash ", "target/release/modex-cube ", "node "]
            .iter()
            .any(|program| span.trim_start().starts_with(program))
    })
}

/// Problems with the test counts and times of a document: each must have,
/// in its paragraph (or its table's), the command that measures it.
fn check_test_figures(name: &str, text: &str) -> Vec<String> {
    let (_, prose) = split_fences(text);
    paragraphs(&prose)
        .into_iter()
        .filter(|(_, paragraph)| !has_command(paragraph))
        .flat_map(|(line, paragraph)| {
            test_figures(&paragraph).into_iter().map(move |figure| {
                format!(
                    "{name}:{line}: \"{figure}\" of tests, but no command beside it measures it"
                )
            })
        })
        .collect()
}

#[test]
fn every_test_count_and_time_has_its_command() {
    let problems: Vec<String> = book()
        .iter()
        .flat_map(|(name, text)| check_test_figures(name, text))
        .collect();
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

#[test]
fn a_test_time_without_its_command_is_caught() {
    let made_up = "The suite passed: 707 tests in 1,024 s.\n\n\
                   The tests give up after 5 s (`TRANSFER_MICROS`); a test takes 3 ms.\n\
                   A frame takes 2 ms.\n\n\
                   Its 8 tests take 6 s (`cargo test --test web_page`).\n\n\
                   Measured once:\n\n| test | time |\n|---|---|\n| `clock.rs` | 74 s |\n";
    let problems = check_test_figures("docs/made-up.md", made_up);
    assert_eq!(
        problems,
        [
            "docs/made-up.md:1: \"707 tests\" of tests, but no command beside it measures it",
            "docs/made-up.md:1: \"1,024 s\" of tests, but no command beside it measures it",
            "docs/made-up.md:3: \"3 ms\" of tests, but no command beside it measures it",
            "docs/made-up.md:8: \"74 s\" of tests, but no command beside it measures it",
        ]
    );
}

/// A format string's or a quotation's pieces: literal characters, and
/// `None` for text that may be anything (a `{}` of a format string, a
/// `...` of a quotation).
fn pattern(text: &str, is_format: bool) -> Vec<Option<char>> {
    let mut pieces = Vec::new();
    let mut chars = text.chars().peekable();
    while let Some(c) = chars.next() {
        if is_format && c == '{' && chars.peek() == Some(&'{') {
            chars.next();
            pieces.push(Some('{'));
        } else if is_format && c == '}' && chars.peek() == Some(&'}') {
            chars.next();
            pieces.push(Some('}'));
        } else if is_format && c == '{' {
            for c in chars.by_ref() {
                if c == '}' {
                    break;
                }
            }
            pieces.push(None);
        } else if !is_format && c == '.' && text.contains("...") && chars.peek() == Some(&'.') {
            chars.next();
            chars.next();
            pieces.push(None);
        } else {
            pieces.push(Some(c));
        }
    }
    pieces
}

/// Can one line match both a format string's pattern `a` and a
/// quotation's `b`? A `{}` stands for one value (letters, digits and
/// `._-/%`, no spaces); a `...` for anything.
fn patterns_meet(a: &[Option<char>], b: &[Option<char>]) -> bool {
    let is_value = |c: Option<char>| c.is_none_or(|c| c.is_alphanumeric() || "._-/%".contains(c));
    // reachable[i][j]: a[..i] and b[..j] can produce the same text.
    let mut reachable = vec![vec![false; b.len() + 1]; a.len() + 1];
    reachable[0][0] = true;
    for i in 0..=a.len() {
        for j in 0..=b.len() {
            if !reachable[i][j] {
                continue;
            }
            if i < a.len() && a[i].is_none() {
                reachable[i + 1][j] = true;
                if j < b.len() && is_value(b[j]) {
                    reachable[i][j + 1] = true;
                }
            }
            if j < b.len() && b[j].is_none() {
                reachable[i][j + 1] = true;
                if i < a.len() {
                    reachable[i + 1][j] = true;
                }
            }
            if i < a.len() && j < b.len() && a[i].is_some() && a[i] == b[j] {
                reachable[i + 1][j + 1] = true;
            }
        }
    }
    reachable[a.len()][b.len()]
}

/// The kernel's `bench:` format strings (string literals that start with
/// `bench: `, their `\` line continuations joined).
fn bench_formats(source: &str) -> Vec<String> {
    let mut formats = Vec::new();
    for part in source.split("\"bench: ").skip(1) {
        let mut format = String::from("bench: ");
        let mut chars = part.chars();
        while let Some(c) = chars.next() {
            match c {
                '"' => break,
                '\\' => match chars.next() {
                    Some('\n') => {
                        let rest: String = chars.clone().collect();
                        let skipped = rest.len() - rest.trim_start().len();
                        for _ in 0..rest[..skipped].chars().count() {
                            chars.next();
                        }
                    }
                    Some(other) => format.push(other),
                    None => break,
                },
                other => format.push(other),
            }
        }
        formats.push(format);
    }
    formats
}

/// Problems with the `bench:` lines a document quotes (backticked, `...`
/// for what is left out, the rest of the line too): each must be a line
/// one of the kernel's format strings can print.
fn check_bench_lines(name: &str, text: &str, formats: &[String]) -> Vec<String> {
    let (_, prose) = split_fences(text);
    let formats: Vec<Vec<Option<char>>> =
        formats.iter().map(|format| pattern(format, true)).collect();
    code_spans(&prose)
        .into_iter()
        .filter(|(_, span)| span.starts_with("bench:"))
        .filter(|(_, span)| {
            let mut quoted = pattern(span, false);
            // A quotation may stop before the line's end.
            quoted.push(None);
            !formats.iter().any(|format| patterns_meet(format, &quoted))
        })
        .map(|(line, span)| format!("{name}:{line}: `{span}` is no line the kernel's bench prints"))
        .collect()
}

/// The `bench:` format strings of the kernel's sources.
fn kernel_bench_formats() -> Vec<String> {
    let mut formats = Vec::new();
    let mut folders = vec![repository().join("kernel/src")];
    while let Some(folder) = folders.pop() {
        for entry in std::fs::read_dir(folder).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                folders.push(path);
            } else if path.extension().is_some_and(|ext| ext == "rs") {
                formats.extend(bench_formats(&std::fs::read_to_string(path).unwrap()));
            }
        }
    }
    formats
}

#[test]
fn every_bench_line_the_book_quotes_is_printed_by_the_kernel() {
    let formats = kernel_bench_formats();
    assert!(formats.len() > 5, "{formats:?}");
    let problems: Vec<String> = book()
        .iter()
        .flat_map(|(name, text)| check_bench_lines(name, text, &formats))
        .collect();
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

#[test]
fn a_bench_line_the_kernel_no_longer_prints_is_caught() {
    let source = "serial_println!(\n    \"bench: phases of the {} (us/frame): motion {}, \\\n     \
                  bus writes {}\",\n);\nserial_println!(\"bench: USB poll: none\");\n";
    let formats = bench_formats(source);
    assert_eq!(
        formats,
        [
            "bench: phases of the {} (us/frame): motion {}, bus writes {}",
            "bench: USB poll: none"
        ]
    );
    let made_up = "`bench: phases of the cube (us/frame): ...`, `bench: ... bus writes 3`,\n\
                   `bench: USB ...`, and `bench: xHCI poll ...` and `bench: phases of the cube: 4`.\n";
    assert_eq!(
        check_bench_lines("docs/made-up.md", made_up, &formats),
        [
            "docs/made-up.md:2: `bench: xHCI poll ...` is no line the kernel's bench prints",
            "docs/made-up.md:2: `bench: phases of the cube: 4` is no line the kernel's bench prints",
        ]
    );
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
fn a_link_to_a_heading_that_does_not_exist_is_caught() {
    let text = "# A page\n\n## The start address\n\n```sh\n# Not a heading\n```\n\n\
                [Here](#the-start-address), [the CRTC](glossary.md#crtc) and\n\
                [a latch](glossary.md#latches), [code](#not-a-heading) and\n\
                [VGA](vga.md#planar-memory).\n";
    assert_eq!(
        problems_in(text),
        [
            "docs/broken.md:10: the link glossary.md#latches leads to no heading (#latches)",
            "docs/broken.md:10: the link #not-a-heading leads to no heading (#not-a-heading)",
        ]
    );
}

#[test]
fn repeated_headings_get_numbered_anchors() {
    let anchors = heading_anchors("# Odd/even\n## Faults\n### Faults\n## `show_page`, again\n");
    let expected = ["oddeven", "faults", "faults-1", "show_page-again"];
    assert_eq!(anchors, expected.into_iter().map(String::from).collect());
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

#[test]
fn a_quoted_constant_must_match_the_code() {
    // usb/src/xhci/host.rs: COMMAND_MICROS = 5_000_000.
    let right = "A command is given up after 5 s (`COMMAND_MICROS`), or\n\
                 5,000 ms (`COMMAND_MICROS`), and a port reset after 0.8 s\n\
                 (`enumeration::HUB_RESET_MICROS`); Linux's name (`XHCI_CMD_DEFAULT_TIMEOUT`) is not ours.\n";
    assert_eq!(problems_in(right), Vec::<String>::new());
    let made_up = "A command is given up after 0.3 s (`COMMAND_MICROS`).\n";
    let problems = problems_in(made_up);
    assert_eq!(problems.len(), 1, "{problems:?}");
    assert!(
        problems[0].contains("COMMAND_MICROS") && problems[0].contains("5_000_000"),
        "{problems:?}"
    );
}

#[test]
fn a_quoted_constant_that_does_not_exist_is_caught() {
    let problems = problems_in("Given up after 5 s (`NO_SUCH_TIMEOUT_MICROS`).\n");
    assert_eq!(problems.len(), 1, "{problems:?}");
    assert!(problems[0].contains("defined nowhere"), "{problems:?}");
}

#[test]
fn a_count_a_size_and_a_qualified_name_are_checked() {
    // MAX_RECOVERIES = 8, MAX_DESCRIPTOR_BYTES = 1024,
    // xhci::HANDOFF_MICROS = 1_000_000.
    let right = "More than 8 failures (`MAX_RECOVERIES`), 1 KiB (`MAX_DESCRIPTOR_BYTES`),\n\
                 1 s (`xhci::HANDOFF_MICROS`).\n";
    assert_eq!(problems_in(right), Vec::<String>::new());
    let wrong = "After 9 failures (`MAX_RECOVERIES`), 2 KiB (`MAX_DESCRIPTOR_BYTES`),\n\
                 1 s (`enumeration::HANDOFF_MICROS`), 5 bytes (`COMMAND_MICROS`).\n";
    let problems = problems_in(wrong);
    assert_eq!(problems.len(), 4, "{problems:?}");
    assert!(problems[0].contains("MAX_RECOVERIES"), "{problems:?}");
    assert!(problems[1].contains("MAX_DESCRIPTOR_BYTES"), "{problems:?}");
    assert!(problems[2].contains("defined nowhere"), "{problems:?}");
    assert!(problems[3].contains("Time"), "{problems:?}");
}

#[test]
fn constant_expressions_are_evaluated() {
    let constants = [
        ("A", "1 << 20"),
        ("B", "(A + 0x10) * 2_u64"),
        ("C", "B as usize / 4"),
    ]
    .map(|(name, expression)| Constant {
        file: "x.rs".into(),
        name: name.into(),
        expression: expression.into(),
    });
    let value = |name: &str| {
        let c = constants.iter().find(|c| c.name == name).unwrap();
        evaluate(&c.expression, "x.rs", &constants, 0)
    };
    assert_eq!(value("A"), Some(1048576.0));
    assert_eq!(value("B"), Some(2097184.0));
    assert_eq!(value("C"), Some(524296.0));
    assert_eq!(
        evaluate("Duration::from_secs(1)", "x.rs", &constants, 0),
        None
    );
    assert_eq!(
        constant_definitions("pub(crate) const X: u8 = 3;\nconst Y: [u8; 2] = [1, 2];"),
        vec![("X".into(), "3".into()), ("Y".into(), "[1, 2]".into())]
    );
}

#[test]
fn a_function_the_file_does_not_define_is_caught() {
    let text = "| mode set | `modex/src/mode.rs:set_mode` |\n\
                | flip | `modex/src/page.rs:no_such_function` |\n\
                | gone | `modex/src/no_such_file.rs:flip` |\n";
    let problems = problems_in(text);
    assert_eq!(problems.len(), 2, "{problems:?}");
    assert!(problems[0].contains("no_such_function"), "{problems:?}");
    assert!(problems[1].contains("no_such_file.rs"), "{problems:?}");
}

#[test]
fn a_quotation_that_no_longer_matches_its_source_is_caught() {
    let source = std::fs::read_to_string(repository().join("modex/src/page.rs")).unwrap();
    let lines: Vec<&str> = source.lines().collect();
    let start = lines
        .iter()
        .position(|line| line.contains("fn "))
        .expect("page.rs has a function");
    let quoted: String = lines[start..start + 4]
        .iter()
        .map(|line| format!("{}\n", line.strip_prefix("    ").unwrap_or(line)))
        .collect();
    let right = format!("```rust modex/src/page.rs\n{quoted}```\n");
    assert_eq!(problems_in(&right), Vec::<String>::new());
    let changed = format!("```rust modex/src/page.rs\n{quoted}    let made_up = 1;\n```\n");
    let problems = problems_in(&changed);
    assert_eq!(problems.len(), 1, "{problems:?}");
    assert!(
        problems[0].contains("not in modex/src/page.rs"),
        "{problems:?}"
    );
}

// The mode-set table of docs/vga.md: the driver's own bus operations.

/// One bus operation, as a row of the mode-set table lists it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum BusOp {
    /// An 8-bit OUT.
    Out8(u16, u8),
    /// A 16-bit OUT to an index port: the index in the low byte, the value
    /// (for the data port after it) in the high byte.
    Out16(u16, u16),
    /// An 8-bit IN.
    In8(u16),
}

impl std::fmt::Display for BusOp {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match *self {
            BusOp::Out8(port, value) => write!(f, "OUT {port:#05X}, {value:#04X}"),
            BusOp::Out16(port, value) => {
                let [index, data] = value.to_le_bytes();
                write!(f, "OUT {port:#05X}, index {index:#04X} value {data:#04X}")
            }
            BusOp::In8(port) => write!(f, "IN {port:#05X}"),
        }
    }
}

/// The software VGA, logging the port operations made inside `ModeX::program`.
struct ModeSetLog {
    soft: Box<SoftVga>,
    calls: Vec<&'static str>,
    operations: Vec<BusOp>,
}

impl ModeSetLog {
    fn log(&mut self, operation: BusOp) {
        if self.calls.contains(&"ModeX::program") {
            self.operations.push(operation);
        }
    }
}

impl VgaBus for ModeSetLog {
    fn write_port8(&mut self, port: Port, value: u8) {
        self.log(BusOp::Out8(port.number(), value));
        self.soft.write_port8(port, value);
    }
    fn write_port16(&mut self, port: Port, value: u16) {
        self.log(BusOp::Out16(port.number(), value));
        self.soft.write_port16(port, value);
    }
    fn read_port8(&mut self, port: Port) -> u8 {
        self.log(BusOp::In8(port.number()));
        self.soft.read_port8(port)
    }
    fn write_vram8(&mut self, offset: u16, value: u8) {
        self.soft.write_vram8(offset, value);
    }
    fn read_vram8(&mut self, offset: u16) -> u8 {
        self.soft.read_vram8(offset)
    }
    fn enter(&mut self, function: &'static str) {
        self.calls.push(function);
    }
    fn leave(&mut self) {
        self.calls.pop();
    }
}

/// The port operations of Mode X's register programming, from power-on.
fn mode_set_operations() -> Vec<BusOp> {
    let mut vga = ModeX::new(ModeSetLog {
        soft: Box::new(SoftVga::new()),
        calls: Vec::new(),
        operations: Vec::new(),
    });
    vga.set_mode();
    let operations = vga.into_bus().operations;
    assert!(operations.len() > 40, "ModeX::program made {operations:?}");
    operations
}

/// The header that marks a mode-set table.
const MODE_SET_TABLE_HEADER: &str = "| port | register | index | value |";

/// The numbers of a cell: `0x3C4`, `0x00-0x05` (each in turn) or `—` (none).
fn cell_numbers(cell: &str) -> Result<Vec<u16>, String> {
    let hex = |text: &str| {
        text.strip_prefix("0x")
            .and_then(|digits| u16::from_str_radix(digits, 16).ok())
            .ok_or_else(|| format!("`{text}` is not a number like 0x3C4"))
    };
    let mut numbers = Vec::new();
    for word in cell.split_whitespace() {
        let word = word.trim_matches(['`', ',']);
        if word.is_empty() || word == "—" {
            continue;
        }
        match word.split_once('-') {
            Some((first, last)) => {
                let (first, last) = (hex(first)?, hex(last)?);
                if last < first {
                    return Err(format!("the range `{word}` runs backwards"));
                }
                numbers.extend(first..=last);
            }
            None => numbers.push(hex(word)?),
        }
    }
    Ok(numbers)
}

/// The bus operations a row of the mode-set table stands for. An index
/// port (0x3C4, 0x3CE, 0x3D4) takes index and value in one 16-bit OUT; the
/// Attribute Controller (0x3C0) takes them in two OUTs; a value `read` is an
/// IN. One value for several indices is written to each.
fn row_operations(row: &str) -> Result<Vec<BusOp>, String> {
    let cells: Vec<&str> = row
        .trim()
        .trim_matches('|')
        .split('|')
        .map(str::trim)
        .collect();
    let [port, _register, index, value, ..] = cells.as_slice() else {
        return Err("a row needs a port, a register, an index and a value".into());
    };
    let port = match cell_numbers(port.split_whitespace().next().unwrap_or(""))?.as_slice() {
        [port] => *port,
        _ => return Err(format!("`{port}` is not one port")),
    };
    if value.trim_matches('`') == "read" {
        return Ok(vec![BusOp::In8(port)]);
    }
    let indices = cell_numbers(index)?;
    let values = cell_numbers(value)?;
    let byte = |n: u16| u8::try_from(n).map_err(|_| format!("{n:#X} is not a byte"));
    if indices.is_empty() {
        return values
            .into_iter()
            .map(|v| Ok(BusOp::Out8(port, byte(v)?)))
            .collect();
    }
    let values = match values.as_slice() {
        [one] => vec![*one; indices.len()],
        _ if values.len() == indices.len() => values,
        _ => {
            return Err(format!(
                "{} indices but {} values",
                indices.len(),
                values.len()
            ))
        }
    };
    let mut operations = Vec::new();
    for (index, value) in indices.into_iter().zip(values) {
        let (index, value) = (byte(index)?, byte(value)?);
        if port == Port::ATTRIBUTE_INDEX.number() {
            operations.push(BusOp::Out8(port, index));
            operations.push(BusOp::Out8(port, value));
        } else {
            operations.push(BusOp::Out16(port, u16::from_le_bytes([index, value])));
        }
    }
    Ok(operations)
}

/// Problems with every mode-set table: it must list the driver's
/// operations, all of them, in order.
fn check_mode_set_tables(driver: &[BusOp], name: &str, prose: &[String]) -> Vec<String> {
    let mut problems = Vec::new();
    let mut tables: Vec<(usize, Vec<(usize, BusOp)>)> = Vec::new();
    let mut in_table = false;
    for (number, line) in prose.iter().enumerate() {
        let line = line.trim();
        if line.starts_with(MODE_SET_TABLE_HEADER) {
            tables.push((number + 1, Vec::new()));
            in_table = true;
            continue;
        }
        if !in_table || !line.starts_with('|') {
            in_table = false;
            continue;
        }
        if line.starts_with("|---") || line.starts_with("| ---") {
            continue;
        }
        let (_, rows) = tables.last_mut().unwrap();
        match row_operations(line) {
            Ok(operations) => rows.extend(operations.into_iter().map(|op| (number + 1, op))),
            Err(error) => problems.push(format!("{name}:{}: mode-set table: {error}", number + 1)),
        }
    }
    for (header, listed) in tables {
        for (at, actual) in driver.iter().enumerate() {
            match listed.get(at) {
                Some((_, op)) if op == actual => continue,
                Some((line, op)) => problems.push(format!(
                    "{name}:{line}: the mode-set table lists {op}, but the driver's operation {} \
                     is {actual}",
                    at + 1
                )),
                None => problems.push(format!(
                    "{name}:{header}: the mode-set table stops after {} operations; the \
                     driver goes on with {actual} ({} in all)",
                    listed.len(),
                    driver.len()
                )),
            }
            break;
        }
        if let Some((line, op)) = listed.get(driver.len()) {
            problems.push(format!(
                "{name}:{line}: the mode-set table lists {op} after the driver's last operation"
            ));
        }
    }
    problems
}

#[test]
fn a_mode_set_table_that_differs_from_the_driver_is_caught() {
    let chapter = std::fs::read_to_string(repository().join("docs/vga.md")).unwrap();
    let table: Vec<&str> = chapter
        .lines()
        .skip_while(|line| !line.starts_with(MODE_SET_TABLE_HEADER))
        .take_while(|line| line.starts_with('|'))
        .collect();
    assert!(table.len() > 10, "docs/vga.md has no mode-set table");
    assert_eq!(problems_in(&table.join("\n")), Vec::<String>::new());
    // Memory Mode with chain-4 still on: the driver writes 0x06.
    let chained = table
        .join("\n")
        .replace("| 0x04 | 0x06 |", "| 0x04 | 0x0E |");
    let problems = problems_in(&chained);
    assert_eq!(problems.len(), 1, "{problems:?}");
    assert!(
        problems[0].contains("index 0x04 value 0x0E"),
        "{problems:?}"
    );
    // A row left out.
    let short = table[..table.len() - 1].join("\n");
    let problems = problems_in(&short);
    assert_eq!(problems.len(), 1, "{problems:?}");
    assert!(problems[0].contains("stops after"), "{problems:?}");
}

// Pictures the book shows, drawn from the code by this test.

/// Set to 1, the picture test writes the pictures instead of comparing.
const UPDATE_PICTURES: &str = "MODEX_CUBE_UPDATE_DOCS_PICTURES";

/// A problem if the committed picture is not the one drawn now.
fn picture_problem(file: &str, committed: Option<&str>, drawn: &str) -> Option<String> {
    let remake = format!(
        "remake it with `{UPDATE_PICTURES}=1 cargo test --test docs pictures`, look at it, \
         and commit it"
    );
    match committed {
        Some(committed) if committed == drawn => None,
        Some(_) => Some(format!("{file} is not what the code draws now: {remake}")),
        None => Some(format!("{file} is missing: {remake}")),
    }
}

/// The DAC's colour of an index, as `#rrggbb`, and a text colour legible on it.
fn dac_colour(soft: &SoftVga, index: u8) -> (String, &'static str) {
    let [r, g, b] = soft.dac_entry(index).map(dac_6_to_8);
    let light = 299 * u32::from(r) + 587 * u32::from(g) + 114 * u32::from(b) > 128_000;
    (
        format!("#{r:02x}{g:02x}{b:02x}"),
        if light { "black" } else { "white" },
    )
}

/// Four planes, one byte address and the four pixels it holds: twelve
/// pixels of line 0 drawn by the driver, then the planes' bytes as the
/// software VGA holds them and which pixel its scan-out shows each as.
fn planes_picture() -> String {
    const PIXELS: u8 = 12;
    const SHOWN: usize = 1;
    let mut soft = Box::new(SoftVga::new());
    let mut vga = ModeX::new(&mut *soft);
    vga.set_mode();
    for x in 0..PIXELS {
        vga.put_pixel(Page::Zero, i32::from(x), 0, x + 1);
    }
    let mut screen = vec![0u8; 320 * 240];
    soft.scanout_indices(&mut screen);
    let line = &screen[..usize::from(PIXELS)];
    let addresses = usize::from(PIXELS) / 4;
    let (left, pixel, cell) = (70, 36, 144);
    let mut svg = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{}\" height=\"330\" \
         font-family=\"sans-serif\" font-size=\"12\">\n\
         <rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n\
         <text x=\"{left}\" y=\"18\">The screen, line 0: pixels x = 0 to {} (the colour index in each)</text>\n",
        left + addresses * cell + 140,
        PIXELS - 1
    );
    for (x, &index) in line.iter().enumerate() {
        let (fill, ink) = dac_colour(&soft, index);
        let at = left + x * pixel;
        svg += &format!(
            "<rect x=\"{at}\" y=\"28\" width=\"{}\" height=\"32\" fill=\"{fill}\" stroke=\"black\"/>\n\
             <text x=\"{}\" y=\"49\" text-anchor=\"middle\" fill=\"{ink}\">{index}</text>\n\
             <text x=\"{}\" y=\"76\" text-anchor=\"middle\">x={x}</text>\n",
            pixel - 4,
            at + pixel / 2 - 2,
            at + pixel / 2 - 2
        );
    }
    svg += &format!(
        "<text x=\"{left}\" y=\"104\">Video memory: byte addresses 0 to {} of each plane, and the pixel the \
         scan-out shows each byte as</text>\n",
        addresses - 1
    );
    for plane in 0..4 {
        let y = 116 + plane * 48;
        svg += &format!("<text x=\"8\" y=\"{}\">plane {plane}</text>\n", y + 26);
        for address in 0..addresses {
            let value = soft.plane(plane)[address];
            let (fill, ink) = dac_colour(&soft, value);
            let shown_at = line.iter().position(|&index| index == value);
            let shown_at = shown_at.map_or("not shown".into(), |x| format!("pixel x={x}"));
            let at = left + address * cell;
            svg += &format!(
                "<rect x=\"{at}\" y=\"{y}\" width=\"{}\" height=\"40\" fill=\"{fill}\" stroke=\"black\"/>\n\
                 <text x=\"{}\" y=\"{}\" fill=\"{ink}\">address {address}: {value}</text>\n\
                 <text x=\"{}\" y=\"{}\" fill=\"{ink}\">{shown_at}</text>\n",
                cell - 4,
                at + 8,
                y + 16,
                at + 8,
                y + 32
            );
        }
    }
    let at = left + SHOWN * cell - 3;
    svg += &format!(
        "<rect x=\"{at}\" y=\"24\" width=\"{cell}\" height=\"{}\" fill=\"none\" stroke=\"#d00000\" \
         stroke-width=\"3\" stroke-dasharray=\"6 4\"/>\n\
         <text x=\"{left}\" y=\"322\" fill=\"#d00000\">Byte address {SHOWN} holds pixels {} to {}, \
         one in each plane: x mod 4 is the plane, x / 4 the address.</text>\n</svg>\n",
        116 + 4 * 48 - 24 + 2,
        SHOWN * 4,
        SHOWN * 4 + 3
    );
    svg
}

/// One frame of Mode X as the CRTC's registers time it: the display, the
/// blanking around it, vertical retrace, and the Input Status 1 bits.
fn frame_picture() -> String {
    let mut soft = Box::new(SoftVga::new());
    ModeX::new(&mut *soft).set_mode();
    let timing = soft.timing();
    let scans_per_row =
        u64::from(soft.crtc(Crtc::MaximumScanLine) & modex::regs::crtc::MAXIMUM_SCAN_LINE_MASK) + 1;
    let dots_per_line = timing.characters_per_line * timing.dots_per_character;
    let hertz = timing.dot_clock_hz as f64 / (dots_per_line * timing.lines_per_frame) as f64;
    let (left, top, per_character) = (50, 40, 4);
    let width = timing.characters_per_line * per_character;
    let display_width = timing.display_characters * per_character;
    let height = timing.lines_per_frame;
    let retrace_end = timing.retrace_start_line + timing.retrace_lines;
    let label = left + width + 12;
    let mut svg = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{}\" height=\"{}\" \
         font-family=\"sans-serif\" font-size=\"12\">\n\
         <rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n\
         <text x=\"{left}\" y=\"18\">One Mode X frame: {} characters of {} dots by {} lines at {} MHz: \
         {hertz:.2} Hz</text>\n",
        label + 330,
        top + height + 30,
        timing.characters_per_line,
        timing.dots_per_character,
        timing.lines_per_frame,
        timing.dot_clock_hz as f64 / 1e6
    );
    // The whole frame is blanking (grey) but for the display (white) and
    // retrace (red).
    svg += &format!(
        "<rect x=\"{left}\" y=\"{top}\" width=\"{width}\" height=\"{height}\" fill=\"#b0b0b0\" stroke=\"black\"/>\n\
         <rect x=\"{left}\" y=\"{top}\" width=\"{display_width}\" height=\"{}\" fill=\"#e8f0ff\" stroke=\"black\"/>\n\
         <rect x=\"{left}\" y=\"{}\" width=\"{width}\" height=\"{}\" fill=\"#d00000\"/>\n",
        timing.display_lines,
        top + timing.retrace_start_line,
        timing.retrace_lines
    );
    let middle = top + timing.display_lines / 2;
    svg += &format!(
        "<text x=\"{}\" y=\"{}\" text-anchor=\"middle\">display: {} x {} dots</text>\n\
         <text x=\"{}\" y=\"{}\" text-anchor=\"middle\">{} rows, each scanned {scans_per_row} times</text>\n\
         <text x=\"{}\" y=\"{}\" text-anchor=\"middle\">Input Status 1 bits 0 and 3 clear:</text>\n\
         <text x=\"{}\" y=\"{}\" text-anchor=\"middle\">write the start address here</text>\n",
        left + display_width / 2,
        middle - 30,
        timing.display_characters * timing.dots_per_character,
        timing.display_lines,
        left + display_width / 2,
        middle - 12,
        timing.display_lines / scans_per_row,
        left + display_width / 2,
        middle + 20,
        left + display_width / 2,
        middle + 36,
    );
    let lines = [
        (
            4,
            "line 0: the scan-out starts at the latched address".to_string(),
        ),
        (
            timing.display_lines - 2,
            format!(
                "line {}: display ends; bit 0 set (display disabled) to the end",
                timing.display_lines
            ),
        ),
        (
            timing.retrace_start_line + 10,
            format!(
                "lines {}-{}: vertical retrace, bit 3 set;",
                timing.retrace_start_line,
                retrace_end - 1
            ),
        ),
        (
            timing.retrace_start_line + 24,
            "the new start address is latched as it begins".to_string(),
        ),
        (
            timing.lines_per_frame + 10,
            format!("line {}: the next frame starts", timing.lines_per_frame),
        ),
    ];
    for (line, text) in lines {
        svg += &format!("<text x=\"{label}\" y=\"{}\">{text}</text>\n", top + line);
    }
    svg += &format!(
        "<text x=\"{}\" y=\"{}\" text-anchor=\"middle\" transform=\"rotate(-90 {} {})\">\
         {} characters of blanking: bit 0 set</text>\n</svg>\n",
        left + display_width + (width - display_width) / 2 + 4,
        middle,
        left + display_width + (width - display_width) / 2 + 4,
        middle,
        timing.characters_per_line - timing.display_characters
    );
    svg
}

#[test]
fn pictures_are_what_the_code_draws() {
    let update = std::env::var_os(UPDATE_PICTURES).is_some_and(|v| v == "1");
    let mut problems = Vec::new();
    for (file, drawn) in [
        ("docs/vga/planes.svg", planes_picture()),
        ("docs/vga/frame.svg", frame_picture()),
    ] {
        let path = repository().join(file);
        if update {
            std::fs::create_dir_all(path.parent().unwrap()).unwrap();
            std::fs::write(&path, &drawn).unwrap();
        }
        let committed = std::fs::read_to_string(&path).ok();
        problems.extend(picture_problem(file, committed.as_deref(), &drawn));
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

#[test]
fn pictures_a_stale_picture_is_caught() {
    let drawn = planes_picture();
    assert_eq!(picture_problem("p.svg", Some(&drawn), &drawn), None);
    let stale = drawn.replace("address 1: 5", "address 1: 6");
    assert_ne!(
        stale, drawn,
        "the picture shows address 1 of plane 0 holding 5"
    );
    let problem = picture_problem("p.svg", Some(&stale), &drawn).unwrap();
    assert!(problem.contains(UPDATE_PICTURES), "{problem}");
    assert!(picture_problem("p.svg", None, &drawn).is_some());
}

#[test]
fn a_quoted_doc_test_is_checked_without_its_comment_marks() {
    // modex/src/draw.rs: fill_rect's example, as `/// ` lines.
    let right = "```rust modex/src/draw.rs\n\
                 vga.set_mode();\n\
                 let before = vga.bus().counts();\n```\n";
    assert_eq!(problems_in(right), Vec::<String>::new());
    let changed = right.replace("counts()", "count()");
    let problems = problems_in(&changed);
    assert_eq!(problems.len(), 1, "{problems:?}");
    assert!(
        problems[0].contains("not in modex/src/draw.rs"),
        "{problems:?}"
    );
}

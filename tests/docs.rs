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
//!   appear in that file, in order and together (indentation aside).
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
    web_options: BTreeSet<String>,
    constants: Vec<Constant>,
}

impl Context {
    fn new() -> Context {
        Context {
            root: repository(),
            runner_options: runner_options(),
            sim_options: sim_options(),
            web_options: web_options(),
            constants: constants_in(&repository()),
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
    let source: Vec<&str> = source.lines().collect();
    let first = block.iter().find(|line| !line.trim().is_empty())?;
    let block_indent = first.len() - first.trim_start().len();
    let found = (0..source.len()).any(|start| {
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
    });
    (!found).then(|| {
        format!(
            "{where_}: the quoted code is not in {file} as it stands (its first line: {})",
            first.trim()
        )
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
            if target.contains("://") || target.starts_with('#') || target.starts_with("mailto:") {
                continue;
            }
            let file = target.split('#').next().unwrap();
            if !directory.join(file).exists() {
                problems.push(format!("{where_}: the link {target} leads nowhere"));
            }
        }
    }

    problems.extend(check_constants(
        &context.constants,
        &name.to_string(),
        &prose,
    ));
    problems.extend(check_functions(&context.root, &name.to_string(), &prose));
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

//! `cargo run --release -p web -- --out DIR [--single-file]`: builds the web
//! page (the demo compiled to WebAssembly, its HTML with the book, and its
//! loader) into DIR;
//! `-- --serve [--port N]` builds it into a temporary directory (or DIR)
//! and serves it on 127.0.0.1, printing `serving http://127.0.0.1:PORT/`.

use std::path::PathBuf;
use std::process::ExitCode;

const USAGE: &str = "\
usage: web --out DIR [--single-file]
       web --serve [--port N] [--out DIR] [--single-file]

Builds the modex-cube web page, with the book (docs/) in it: DIR/index.html,
DIR/modex.js, DIR/modex.wasm.deflate (with --single-file, one self-contained
DIR/index.html). --serve serves it on 127.0.0.1 (port 0, the default: any free
port) and prints its address.";

#[derive(Debug, Default)]
struct Args {
    out: Option<PathBuf>,
    single_file: bool,
    serve: bool,
    port: u16,
}

fn parse(mut words: impl Iterator<Item = String>) -> Result<Args, String> {
    let mut args = Args::default();
    while let Some(word) = words.next() {
        match word.as_str() {
            "--out" => {
                let dir = words.next().ok_or("--out needs a directory")?;
                args.out = Some(PathBuf::from(dir));
            }
            "--single-file" => args.single_file = true,
            "--serve" => args.serve = true,
            "--port" => {
                let port = words.next().ok_or("--port needs a number")?;
                args.port = port
                    .parse()
                    .map_err(|_| format!("--port {port:?}: not a port number (0-65535)"))?;
            }
            "-h" | "--help" => return Err(USAGE.to_string()),
            other => return Err(format!("unknown argument {other:?}\n{USAGE}")),
        }
    }
    if args.out.is_none() && !args.serve {
        return Err(format!("give --out DIR or --serve\n{USAGE}"));
    }
    Ok(args)
}

fn main() -> ExitCode {
    let args = match parse(std::env::args().skip(1)) {
        Ok(args) => args,
        Err(message) => {
            eprintln!("{message}");
            return ExitCode::from(2);
        }
    };
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| std::env::temp_dir().join(format!("modex-web-{}", std::process::id())));
    let files = web::PageFiles {
        single_file: args.single_file,
    };
    let built = match web::build_page_with(&out, files) {
        Ok(built) => built,
        Err(error) => {
            eprintln!("error: {error}");
            return ExitCode::FAILURE;
        }
    };
    // With --serve, stdout carries the one line a test waits for.
    let report = format!(
        "Wrote the page to {} ({} bytes in all, {} of them the book: {})",
        out.display(),
        built.weight(),
        built.book_bytes,
        built
            .files
            .iter()
            .map(|(path, bytes)| format!(
                "{} {bytes}",
                path.file_name().unwrap_or_default().to_string_lossy()
            ))
            .collect::<Vec<_>>()
            .join(", ")
    );
    if !args.serve {
        println!("{report}");
        return ExitCode::SUCCESS;
    }
    eprintln!("{report}");
    match web::serve(&out, args.port) {
        Ok(server) => {
            println!("serving {}", server.url());
            server.wait();
            ExitCode::SUCCESS
        }
        Err(error) => {
            eprintln!("error: cannot serve on 127.0.0.1:{}: {error}", args.port);
            ExitCode::FAILURE
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn words(line: &str) -> impl Iterator<Item = String> + '_ {
        line.split_whitespace().map(String::from)
    }

    #[test]
    fn arguments() {
        let args = parse(words("--out page --single-file")).unwrap();
        assert_eq!(args.out, Some(PathBuf::from("page")));
        assert!(args.single_file && !args.serve);
        let args = parse(words("--serve --port 8080")).unwrap();
        assert!(args.serve && args.port == 8080 && args.out.is_none());
        assert!(parse(words("")).unwrap_err().starts_with("give --out DIR"));
        assert!(parse(words("--serve --port http"))
            .unwrap_err()
            .contains("\"http\""));
        assert!(parse(words("--out")).is_err());
        assert!(parse(words("--bogus")).unwrap_err().contains("\"--bogus\""));
    }
}

//! Demo's modules import one another without a circle, and a frame's data
//! goes one way: the scene and the depth policy never reach each other.
//!
//! Every file under `demo/src` is parsed (with `syn`) and every path that
//! names another of the crate's top-level modules — `use crate::…`,
//! `crate::…` in code or in a macro's tokens, `super::…` climbing out of the
//! module — becomes an edge from the file's top-level module to that one
//! (a file in `scene/` belongs to `scene`). Doc comments are not code and
//! are left out. The test fails on any circle and names it.

use proc_macro2::{TokenStream, TokenTree};
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use syn::visit::Visit;

/// Top-level module -> the top-level modules it names.
type Graph = BTreeMap<String, BTreeSet<String>>;

/// Walks one file, knowing which module (as a path from the crate root) each
/// item is in, and collects the top-level modules its paths lead to.
struct Imports {
    /// The module being walked, from the crate root.
    module: Vec<String>,
    /// Top-level modules named.
    named: BTreeSet<String>,
}

impl Imports {
    /// Resolves a path's leading segments (`crate`, `super`, `self`, then
    /// names) to the top-level module it lands in, if it stays inside the
    /// crate and leaves the crate root.
    fn resolve(&mut self, segments: &[String]) {
        let mut at: Vec<String>;
        let mut rest = segments;
        match segments.first().map(String::as_str) {
            Some("crate") => {
                at = Vec::new();
                rest = &segments[1..];
            }
            Some("super") | Some("self") => {
                at = self.module.clone();
                while let Some(first) = rest.first() {
                    match first.as_str() {
                        "super" => {
                            at.pop();
                        }
                        "self" => {}
                        _ => break,
                    }
                    rest = &rest[1..];
                }
            }
            // A name of this module, an extern crate's or a prelude's.
            _ => return,
        }
        if let Some(next) = rest.first() {
            at.push(next.clone());
        }
        if let Some(top) = at.first() {
            self.named.insert(top.clone());
        }
    }

    /// A `use` tree: each leaf's full path is resolved.
    fn use_tree(&mut self, prefix: &mut Vec<String>, tree: &syn::UseTree) {
        match tree {
            syn::UseTree::Path(path) => {
                prefix.push(path.ident.to_string());
                self.use_tree(prefix, &path.tree);
                prefix.pop();
            }
            syn::UseTree::Name(name) => {
                prefix.push(name.ident.to_string());
                self.resolve(prefix);
                prefix.pop();
            }
            syn::UseTree::Rename(rename) => {
                prefix.push(rename.ident.to_string());
                self.resolve(prefix);
                prefix.pop();
            }
            syn::UseTree::Glob(_) => self.resolve(prefix),
            syn::UseTree::Group(group) => {
                for item in &group.items {
                    self.use_tree(prefix, item);
                }
            }
        }
    }

    /// A macro's tokens are not parsed as code: look in them for `crate ::
    /// name` and `super :: name` sequences.
    fn tokens(&mut self, tokens: TokenStream) {
        let trees: Vec<TokenTree> = tokens.into_iter().collect();
        for (index, tree) in trees.iter().enumerate() {
            match tree {
                TokenTree::Group(group) => self.tokens(group.stream()),
                TokenTree::Ident(ident) if ident == "crate" || ident == "super" => {
                    let mut segments = vec![ident.to_string()];
                    let mut next = index + 1;
                    while let [TokenTree::Punct(a), TokenTree::Punct(b), TokenTree::Ident(name), ..] =
                        &trees[next..]
                    {
                        if a.as_char() != ':' || b.as_char() != ':' {
                            break;
                        }
                        segments.push(name.to_string());
                        next += 3;
                    }
                    self.resolve(&segments);
                }
                _ => {}
            }
        }
    }
}

impl<'ast> Visit<'ast> for Imports {
    fn visit_item_use(&mut self, item: &'ast syn::ItemUse) {
        self.use_tree(&mut Vec::new(), &item.tree);
    }

    fn visit_path(&mut self, path: &'ast syn::Path) {
        let segments: Vec<String> = path.segments.iter().map(|s| s.ident.to_string()).collect();
        self.resolve(&segments);
        syn::visit::visit_path(self, path);
    }

    fn visit_item_mod(&mut self, item: &'ast syn::ItemMod) {
        self.module.push(item.ident.to_string());
        syn::visit::visit_item_mod(self, item);
        self.module.pop();
    }

    fn visit_macro(&mut self, mac: &'ast syn::Macro) {
        self.tokens(mac.tokens.clone());
        syn::visit::visit_macro(self, mac);
    }

    // Doc comments and other attributes are not code.
    fn visit_attribute(&mut self, _attribute: &'ast syn::Attribute) {}
}

/// The module a file is, as a path from the crate root: `scene/mod.rs` is
/// `scene`, `scene/crowd.rs` is `scene::crowd`, `lib.rs` the root.
fn module_of(relative: &Path) -> Vec<String> {
    let mut module: Vec<String> = relative
        .with_extension("")
        .components()
        .map(|part| part.as_os_str().to_string_lossy().into_owned())
        .collect();
    if matches!(module.last().map(String::as_str), Some("mod" | "lib")) {
        module.pop();
    }
    module
}

/// The top-level modules `source` (the file at `module`) names, other than
/// its own.
fn named_by(module: &[String], source: &str) -> Result<BTreeSet<String>, syn::Error> {
    let file = syn::parse_file(source)?;
    let mut imports = Imports {
        module: module.to_vec(),
        named: BTreeSet::new(),
    };
    imports.visit_file(&file);
    if let Some(own) = module.first() {
        imports.named.remove(own);
    }
    Ok(imports.named)
}

fn rust_files(directory: &Path, found: &mut Vec<PathBuf>) {
    let entries = std::fs::read_dir(directory)
        .unwrap_or_else(|error| panic!("reading {}: {error}", directory.display()));
    for entry in entries {
        let path = entry.expect("a directory entry").path();
        if path.is_dir() {
            rust_files(&path, found);
        } else if path.extension().is_some_and(|ext| ext == "rs") {
            found.push(path);
        }
    }
}

/// Demo's import graph among its top-level modules.
fn demo_graph() -> Graph {
    let source = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&source, &mut files);
    let mut graph = Graph::new();
    for file in files {
        let relative = file.strip_prefix(&source).expect("under src");
        let module = module_of(relative);
        let Some(top) = module.first() else {
            continue; // lib.rs: it declares the modules, it uses none of them
        };
        let text = std::fs::read_to_string(&file)
            .unwrap_or_else(|error| panic!("reading {}: {error}", file.display()));
        let named = named_by(&module, &text)
            .unwrap_or_else(|error| panic!("parsing {}: {error}", file.display()));
        graph.entry(top.clone()).or_default().extend(named);
    }
    graph
}

/// A circle of modules, each naming the next and the last the first, if
/// there is one.
fn find_circle(graph: &Graph) -> Option<Vec<String>> {
    #[derive(Clone, Copy, PartialEq)]
    enum State {
        Open,
        Done,
    }
    fn visit(
        graph: &Graph,
        node: &str,
        state: &mut BTreeMap<String, State>,
        trail: &mut Vec<String>,
    ) -> Option<Vec<String>> {
        match state.get(node) {
            Some(State::Done) => return None,
            Some(State::Open) => {
                let start = trail.iter().position(|n| n == node).expect("on the trail");
                return Some(trail[start..].to_vec());
            }
            None => {}
        }
        state.insert(node.to_owned(), State::Open);
        trail.push(node.to_owned());
        for next in graph.get(node).into_iter().flatten() {
            if let Some(circle) = visit(graph, next, state, trail) {
                return Some(circle);
            }
        }
        trail.pop();
        state.insert(node.to_owned(), State::Done);
        None
    }
    let mut state = BTreeMap::new();
    graph
        .keys()
        .find_map(|node| visit(graph, node, &mut state, &mut Vec::new()))
}

/// Every module `from` leads to, directly or through others.
fn reachable(graph: &Graph, from: &str) -> BTreeSet<String> {
    let mut seen = BTreeSet::new();
    let mut todo = vec![from.to_owned()];
    while let Some(node) = todo.pop() {
        for next in graph.get(&node).into_iter().flatten() {
            if seen.insert(next.clone()) {
                todo.push(next.clone());
            }
        }
    }
    seen
}

fn set(names: &[&str]) -> BTreeSet<String> {
    names.iter().map(|name| name.to_string()).collect()
}

#[test]
fn demo_modules_import_one_another_without_a_circle() {
    let graph = demo_graph();
    // The walk saw the modules this test is about, and their imports.
    for module in ["depth", "faces", "frame", "scene", "screen"] {
        assert!(
            graph.contains_key(module),
            "{module} missing from {graph:?}"
        );
    }
    assert!(graph["frame"].contains("depth") && graph["frame"].contains("scene"));
    if let Some(circle) = find_circle(&graph) {
        panic!(
            "demo's modules import in a circle: {} -> {}",
            circle.join(" -> "),
            circle[0]
        );
    }
}

#[test]
fn a_frames_data_goes_one_way() {
    let graph = demo_graph();
    let from_scene = reachable(&graph, "scene");
    let from_depth = reachable(&graph, "depth");
    assert!(
        !from_scene.contains("depth"),
        "scene reaches depth: {from_scene:?}"
    );
    assert!(
        !from_depth.contains("scene"),
        "depth reaches scene: {from_depth:?}"
    );
    for plain in ["faces", "screen"] {
        let from = reachable(&graph, plain);
        for module in ["scene", "depth", "frame"] {
            assert!(!from.contains(module), "{plain} reaches {module}: {from:?}");
        }
    }
}

#[test]
fn the_walk_sees_every_kind_of_path_and_only_those() {
    let source = r#"
        //! A doc link to [`crate::doc_only`] is not an import.
        use crate::a::Thing;
        use crate::{b, c::{self, Other}};
        use super::sibling_of_file;
        use self::inner::Item;
        mod inner {
            use super::super::super::d;
            use super::super::own_too;
        }
        fn f() {
            let _ = crate::e::value();
            assert_eq!(crate::f::VALUE, super::g::VALUE);
            let _ = std::mem::size_of::<u8>();
        }
        #[cfg(test)]
        mod tests {
            use super::*;
            use crate::h;
        }
    "#;
    // As the file `own/part.rs`: `super` is `own`, `super::super` the root.
    let module = vec!["own".to_owned(), "part".to_owned()];
    let named = named_by(&module, source).expect("parses");
    assert_eq!(named, set(&["a", "b", "c", "d", "e", "f", "h"]));
    assert_eq!(module_of(Path::new("scene/mod.rs")), vec!["scene"]);
    assert_eq!(
        module_of(Path::new("scene/crowd.rs")),
        vec!["scene", "crowd"]
    );
    assert_eq!(module_of(Path::new("lib.rs")), Vec::<String>::new());
}

#[test]
fn a_circle_is_found_and_named() {
    let graph = |edges: &[(&str, &str)]| {
        let mut graph = Graph::new();
        for (from, to) in edges {
            graph
                .entry(from.to_string())
                .or_default()
                .insert(to.to_string());
        }
        graph
    };
    let one_way = graph(&[("frame", "depth"), ("frame", "scene"), ("depth", "faces")]);
    assert_eq!(find_circle(&one_way), None);
    // Issue 33's circle: depth -> frame -> scene -> depth.
    let circled = graph(&[
        ("depth", "frame"),
        ("frame", "scene"),
        ("scene", "depth"),
        ("frame", "depth"),
    ]);
    let circle = find_circle(&circled).expect("a circle");
    assert_eq!(circle.len(), 2, "{circle:?}"); // depth <-> frame first
    assert!(circle.contains(&"depth".to_owned()) && circle.contains(&"frame".to_owned()));
    let three = graph(&[("depth", "scene"), ("scene", "frame"), ("frame", "depth")]);
    assert_eq!(find_circle(&three).expect("a circle").len(), 3);
    assert_eq!(
        reachable(&three, "depth"),
        set(&["depth", "frame", "scene"])
    );
}

//! `cargo xtask imports`: no two files of a module import each other, directly or around a
//! loop, in any crate of the repository.
//!
//! The rule ("imports point down"): in every directory module (a crate's `src/`, or a
//! directory with a `mod.rs`), the files and the sub-directories form the nodes of a graph, a
//! sub-directory counting as one node with everything below it. There is an edge `A → B` when
//! code in `A` names an item defined in `B`: a `use` of it, or a path such as `super::b::x`,
//! `crate::m::b::x` or `self::b::x` anywhere in the code (types, calls, patterns, macros'
//! paths). A name that the module's `mod.rs` re-exports from a child (`pub use child::x`)
//! counts as the child's. What does not count: the `mod` declarations and the `pub use`
//! re-exports of a `mod.rs` (the module's public face, not a dependency), and items under
//! `#[cfg(test)]` or `#[cfg(doc)]` (tests and doc links may look anywhere). The graph must
//! have no cycle; each cycle is reported with one line naming each of its edges.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, anyhow};
use syn::visit::Visit;

/// The crates whose sources are checked, relative to the repository root: the core, the
/// firmware's application crate, the host crate and xtask itself.
pub const CRATES: [&str; 4] = ["src", "firmware/app/src", "host-tests/src", "xtask/src"];

/// One reference from a file to a module path, with where it was written.
#[derive(Debug, Clone)]
struct Reference {
    /// Absolute module path of what is named (crate-relative segments).
    path: Vec<String>,
    /// Line of the reference in its file.
    line: usize,
}

/// A parsed source file of a crate.
#[derive(Debug)]
struct SourceFile {
    /// Path relative to the crate's source directory.
    rel: PathBuf,
    /// The module path of the file (`klt::kernel::lanes` for `klt/kernel/lanes/mod.rs`).
    module: Vec<String>,
    /// What the file's code names, resolved to absolute paths.
    refs: Vec<Reference>,
    /// Names re-exported by this file from its child modules: name → child.
    reexports: BTreeMap<String, String>,
}

/// An edge of a module's graph and the first place that makes it.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord)]
struct Edge {
    from: String,
    to: String,
    at: String,
}

/// Checks every crate of [`CRATES`] under `root`; the error lists every cycle found.
pub fn check(root: &Path) -> Result<()> {
    let mut problems = Vec::new();
    for krate in CRATES {
        let dir = root.join(krate);
        for cycle in cycles_in(&dir).with_context(|| format!("reading {}", dir.display()))? {
            problems.push(format!("{krate}: {cycle}"));
        }
    }
    if problems.is_empty() {
        println!(
            "imports: no cycle between the files of any module ({})",
            CRATES.join(", ")
        );
        Ok(())
    } else {
        Err(anyhow!(
            "import cycles between the files of a module (each edge: file → file, at the place that makes it):\n  {}",
            problems.join("\n  ")
        ))
    }
}

/// Every cycle of every directory module of the crate whose sources are in `src`, one string
/// each.
fn cycles_in(src: &Path) -> Result<Vec<String>> {
    let files = parse_crate(src)?;
    let mut out = Vec::new();
    let dirs: BTreeSet<Vec<String>> = files.iter().map(dir_module).collect();
    for dir in dirs {
        let edges = edges_of(&dir, &files);
        for cycle in find_cycles(&edges) {
            let names = cycle
                .iter()
                .map(|e| format!("{} → {} ({})", e.from, e.to, e.at))
                .collect::<Vec<_>>()
                .join(", ");
            let module = if dir.is_empty() {
                "crate root".to_string()
            } else {
                dir.join("::")
            };
            out.push(format!("module {module}: {names}"));
        }
    }
    Ok(out)
}

/// The directory module a file is a node of: the module itself for a `mod.rs`/`lib.rs`/
/// `main.rs`, its parent otherwise.
fn dir_module(f: &SourceFile) -> Vec<String> {
    if is_dir_root(&f.rel) {
        f.module.clone()
    } else {
        f.module[..f.module.len().saturating_sub(1)].to_vec()
    }
}

fn is_dir_root(rel: &Path) -> bool {
    matches!(
        rel.file_name().and_then(|n| n.to_str()),
        Some("mod.rs" | "lib.rs" | "main.rs")
    )
}

/// The node of directory module `dir` that the module path `module` lies in: the child's
/// name, or `mod.rs` for the directory module itself; `None` outside `dir`.
fn node_of(dir: &[String], module: &[String]) -> Option<String> {
    if !module.starts_with(dir) {
        return None;
    }
    Some(match module.get(dir.len()) {
        Some(child) => child.clone(),
        None => "mod.rs".to_string(),
    })
}

/// The edges between the nodes of directory module `dir`.
fn edges_of(dir: &[String], files: &[SourceFile]) -> Vec<Edge> {
    let children: BTreeSet<String> = files
        .iter()
        .filter_map(|f| match node_of(dir, &f.module)? {
            n if n == "mod.rs" => None,
            n => Some(n),
        })
        .collect();
    let reexports = files
        .iter()
        .find(|f| f.module == dir && is_dir_root(&f.rel))
        .map(|f| f.reexports.clone())
        .unwrap_or_default();
    let mut seen = BTreeMap::new();
    for f in files {
        let Some(from) = node_of(dir, &f.module) else {
            continue;
        };
        for r in &f.refs {
            if !r.path.starts_with(dir) {
                continue;
            }
            let to = match r.path.get(dir.len()) {
                Some(s) if children.contains(s) => s.clone(),
                Some(s) => reexports
                    .get(s)
                    .cloned()
                    .unwrap_or_else(|| "mod.rs".to_string()),
                None => continue,
            };
            if to == from {
                continue;
            }
            seen.entry((from.clone(), to.clone()))
                .or_insert_with(|| Edge {
                    from: from.clone(),
                    to,
                    at: format!("{}:{}", f.rel.display(), r.line),
                });
        }
    }
    seen.into_values().collect()
}

/// Every elementary cycle through the strongly connected components of the graph, one
/// shortest cycle per component: enough to name what must change.
fn find_cycles(edges: &[Edge]) -> Vec<Vec<Edge>> {
    let mut adj: BTreeMap<&str, Vec<&Edge>> = BTreeMap::new();
    for e in edges {
        adj.entry(&e.from).or_default().push(e);
    }
    let mut out = Vec::new();
    let mut reported: BTreeSet<BTreeSet<String>> = BTreeSet::new();
    for start in adj.keys() {
        // Breadth-first from `start` back to itself: the shortest cycle through it.
        let mut prev: BTreeMap<&str, &Edge> = BTreeMap::new();
        let mut queue = std::collections::VecDeque::from([*start]);
        let mut found = None;
        while let Some(n) = queue.pop_front() {
            for e in adj.get(n).into_iter().flatten() {
                if e.to == *start {
                    found = Some(*e);
                    break;
                }
                if !prev.contains_key(e.to.as_str()) {
                    prev.insert(&e.to, e);
                    queue.push_back(&e.to);
                }
            }
            if found.is_some() {
                break;
            }
        }
        let Some(last) = found else { continue };
        let mut cycle = vec![last.clone()];
        let mut at = last.from.as_str();
        while at != *start {
            let e = prev[at];
            cycle.push(e.clone());
            at = &e.from;
        }
        cycle.reverse();
        let nodes: BTreeSet<String> = cycle.iter().map(|e| e.from.clone()).collect();
        if reported.insert(nodes) {
            out.push(cycle);
        }
    }
    out
}

/// Parses every `.rs` file below `src`.
fn parse_crate(src: &Path) -> Result<Vec<SourceFile>> {
    let mut paths = Vec::new();
    collect(src, &mut paths)?;
    paths.sort();
    let mut out = Vec::new();
    for path in paths {
        let rel = path.strip_prefix(src)?.to_path_buf();
        // `src/bin/*.rs` are crates of their own.
        if rel.starts_with("bin") {
            continue;
        }
        let text = std::fs::read_to_string(&path)?;
        let ast = syn::parse_file(&text).with_context(|| format!("parsing {}", path.display()))?;
        let module = module_path(&rel);
        let mut v = Refs {
            module: &module,
            is_root: is_dir_root(&rel),
            children: child_mods(&ast),
            refs: Vec::new(),
            reexports: BTreeMap::new(),
        };
        v.visit_file(&ast);
        let (refs, reexports) = (v.refs, v.reexports);
        out.push(SourceFile {
            rel,
            module,
            refs,
            reexports,
        });
    }
    Ok(out)
}

fn collect(dir: &Path, out: &mut Vec<PathBuf>) -> Result<()> {
    for entry in std::fs::read_dir(dir)? {
        let path = entry?.path();
        if path.is_dir() {
            collect(&path, out)?;
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
    Ok(())
}

/// `klt/kernel/mod.rs` → `[klt, kernel]`, `klt/lk.rs` → `[klt, lk]`, `lib.rs` → `[]`.
fn module_path(rel: &Path) -> Vec<String> {
    let mut parts: Vec<String> = rel
        .iter()
        .map(|p| p.to_string_lossy().trim_end_matches(".rs").to_string())
        .collect();
    if is_dir_root(rel) {
        parts.pop();
    }
    parts
}

/// The modules a file declares (`mod x;` or `mod x { .. }`), but those only for tests or
/// docs: a path that starts with one of them is a path into it.
fn child_mods(ast: &syn::File) -> BTreeSet<String> {
    ast.items
        .iter()
        .filter_map(|i| match i {
            syn::Item::Mod(m) if !test_or_doc_only(&m.attrs) => Some(m.ident.to_string()),
            _ => None,
        })
        .collect()
}

/// Collects the paths a file names.
struct Refs<'m> {
    module: &'m [String],
    is_root: bool,
    /// Modules the file declares.
    children: BTreeSet<String>,
    refs: Vec<Reference>,
    reexports: BTreeMap<String, String>,
}

impl Refs<'_> {
    /// The absolute module path of `segments` written in this file, when it starts with
    /// `crate`, `super`, `self` or a module the file declares.
    fn resolve(&self, segments: &[String]) -> Option<Vec<String>> {
        let mut base: Vec<String> = self.module.to_vec();
        let mut rest = segments;
        match rest.first().map(String::as_str) {
            Some("crate") => {
                base.clear();
                rest = &rest[1..];
            }
            Some("self") => rest = &rest[1..],
            Some("super") => {
                while rest.first().map(String::as_str) == Some("super") {
                    base.pop()?;
                    rest = &rest[1..];
                }
            }
            Some(first) if self.children.contains(first) => {}
            _ => return None,
        }
        base.extend(rest.iter().cloned());
        Some(base)
    }

    fn push(&mut self, segments: &[String], line: usize) {
        if let Some(path) = self.resolve(segments) {
            self.refs.push(Reference { path, line });
        }
    }

    /// Every leaf path of a `use` tree.
    fn use_paths(tree: &syn::UseTree, prefix: &mut Vec<String>, out: &mut Vec<Vec<String>>) {
        match tree {
            syn::UseTree::Path(p) => {
                prefix.push(p.ident.to_string());
                Self::use_paths(&p.tree, prefix, out);
                prefix.pop();
            }
            syn::UseTree::Name(n) => {
                let mut v = prefix.clone();
                if n.ident != "self" {
                    v.push(n.ident.to_string());
                }
                out.push(v);
            }
            syn::UseTree::Rename(r) => {
                let mut v = prefix.clone();
                v.push(r.ident.to_string());
                out.push(v);
            }
            syn::UseTree::Glob(_) => out.push(prefix.clone()),
            syn::UseTree::Group(g) => {
                for t in &g.items {
                    Self::use_paths(t, prefix, out);
                }
            }
        }
    }
}

/// `#[cfg(test)]`, `#[cfg(doc)]` and their `any(...)`/`all(...)` forms that only hold in
/// tests or docs.
fn test_or_doc_only(attrs: &[syn::Attribute]) -> bool {
    attrs.iter().any(|a| {
        a.path().is_ident("cfg") && {
            let text = a
                .meta
                .require_list()
                .map(|l| l.tokens.to_string())
                .unwrap_or_default();
            text == "test" || text == "doc"
        }
    })
}

fn line_of(span: proc_macro2::Span) -> usize {
    span.start().line
}

impl<'ast> Visit<'ast> for Refs<'_> {
    fn visit_item(&mut self, item: &'ast syn::Item) {
        let attrs: &[syn::Attribute] = match item {
            syn::Item::Mod(m) => &m.attrs,
            syn::Item::Use(u) => &u.attrs,
            syn::Item::Fn(f) => &f.attrs,
            syn::Item::Impl(i) => &i.attrs,
            syn::Item::Struct(s) => &s.attrs,
            syn::Item::Enum(e) => &e.attrs,
            syn::Item::Const(c) => &c.attrs,
            syn::Item::Static(s) => &s.attrs,
            syn::Item::Trait(t) => &t.attrs,
            syn::Item::Type(t) => &t.attrs,
            syn::Item::Macro(m) => &m.attrs,
            _ => &[],
        };
        if test_or_doc_only(attrs) {
            return;
        }
        syn::visit::visit_item(self, item);
    }

    fn visit_item_use(&mut self, u: &'ast syn::ItemUse) {
        let mut leaves = Vec::new();
        Self::use_paths(&u.tree, &mut Vec::new(), &mut leaves);
        let public = matches!(
            u.vis,
            syn::Visibility::Public(_) | syn::Visibility::Restricted(_)
        );
        let line = line_of(syn::spanned::Spanned::span(&u.use_token));
        for leaf in leaves {
            // A re-export from a child by a module's root file: the module's face, not a
            // dependency; remember which child each name comes from.
            let child = leaf.first().map(String::as_str);
            let from_child = match child {
                Some("self") => leaf.get(1),
                Some("crate" | "super") => None,
                _ => leaf.first(),
            };
            if self.is_root
                && public
                && leaf.len() >= 2
                && let (Some(child), Some(name)) = (from_child, leaf.last())
                && self.children.contains(child)
            {
                self.reexports.insert(name.clone(), child.clone());
                continue;
            }
            self.push(&leaf, line);
        }
    }

    fn visit_path(&mut self, p: &'ast syn::Path) {
        let segments: Vec<String> = p.segments.iter().map(|s| s.ident.to_string()).collect();
        if let Some(first) = p.segments.first() {
            self.push(&segments, line_of(first.ident.span()));
        }
        syn::visit::visit_path(self, p);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(dir: &Path, files: &[(&str, &str)]) {
        for (name, text) in files {
            let path = dir.join(name);
            std::fs::create_dir_all(path.parent().unwrap()).unwrap();
            std::fs::write(path, text).unwrap();
        }
    }

    fn tmp(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("xtask-imports-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        dir
    }

    #[test]
    fn a_cycle_between_siblings_is_found_and_named() {
        let dir = tmp("cycle");
        write(
            &dir,
            &[
                ("lib.rs", "mod a;\nmod b;\n"),
                ("a.rs", "use crate::b::B;\npub struct A;\n"),
                ("b.rs", "pub struct B;\nfn f() -> super::a::A { todo!() }\n"),
            ],
        );
        let cycles = cycles_in(&dir).unwrap();
        assert_eq!(cycles.len(), 1, "{cycles:?}");
        assert!(
            cycles[0].contains("a → b (a.rs:1)") && cycles[0].contains("b → a (b.rs:2)"),
            "{cycles:?}"
        );
    }

    #[test]
    fn a_cycle_through_a_parent_and_a_subdirectory_is_found() {
        let dir = tmp("nested");
        write(
            &dir,
            &[
                ("lib.rs", "mod k;\n"),
                // The parent calls into the child (not a re-export) ...
                (
                    "k/mod.rs",
                    "mod inner;\npub fn go() { inner::deep::run() }\npub struct Cfg;\n",
                ),
                ("k/inner/mod.rs", "pub mod deep;\n"),
                // ... and the child, two levels down, names an item of the parent.
                (
                    "k/inner/deep.rs",
                    "pub fn run() { let _ = super::super::Cfg; }\n",
                ),
            ],
        );
        let cycles = cycles_in(&dir).unwrap();
        assert_eq!(cycles.len(), 1, "{cycles:?}");
        assert!(cycles[0].starts_with("module k:"), "{cycles:?}");
    }

    #[test]
    fn reexports_tests_and_layered_imports_are_not_cycles() {
        let dir = tmp("clean");
        write(
            &dir,
            &[
                ("lib.rs", "mod m;\npub use m::Thing;\n"),
                // mod.rs re-exports its children and defines an item they use.
                (
                    "m/mod.rs",
                    "mod low;\nmod high;\npub use high::Thing;\npub use self::low::Low;\npub struct Cfg;\n\
                     #[cfg(test)]\nmod tests { use super::high::Thing; }\n",
                ),
                ("m/low.rs", "use super::Cfg;\npub struct Low(pub Cfg);\n"),
                // `Low` through the parent's re-export is `low`'s: high → low, not high → mod.rs.
                ("m/high.rs", "use super::Low;\npub struct Thing(pub Low);\n"),
            ],
        );
        assert_eq!(cycles_in(&dir).unwrap(), Vec::<String>::new());
        // A re-export does not hide a real cycle: low now names high's item.
        write(
            &dir,
            &[(
                "m/low.rs",
                "use super::Cfg;\npub struct Low(pub Cfg, super::high::Thing);\n",
            )],
        );
        let cycles = cycles_in(&dir).unwrap();
        assert_eq!(cycles.len(), 1, "{cycles:?}");
    }
}

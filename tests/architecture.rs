//! The shape of the code, checked: no import cycle among the library's
//! modules, the shells (CLI, bench, app) never import one another, no
//! source file passes 1 000 lines, and no work-log numbering in the sources.
//!
//! The module graph is read from the sources themselves: every `use` tree
//! and every inline `crate::`/`super::`/`self::`/child-module path outside
//! comments and test modules is resolved to the module that *defines* the
//! item, following `pub use` re-exports (a facade that only re-exports an
//! item is not a dependency of it; one that also uses it is).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

type ModPath = Vec<String>;

struct Module {
    /// Code without comments and without `#[cfg(test)] mod tests`.
    code: String,
    /// Child modules declared here (`mod name;` / `pub mod name;`).
    children: BTreeSet<String>,
}

fn module_path(src: &Path, file: &Path) -> ModPath {
    let rel = file.strip_prefix(src).unwrap();
    let mut parts: Vec<String> = rel
        .iter()
        .map(|p| p.to_string_lossy().into_owned())
        .collect();
    let last = parts.pop().unwrap();
    let stem = last.trim_end_matches(".rs");
    if stem != "mod" && stem != "lib" {
        parts.push(stem.to_string());
    }
    parts
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The text without `//` comments, string contents and the unit-test
/// module (tests may reach anywhere).
fn code_of(text: &str) -> String {
    let test_module = text.match_indices("#[cfg(test)]\n").find(|(at, marker)| {
        let next = text[at + marker.len()..].lines().next().unwrap_or_default();
        next.trim_start_matches("pub(super) ")
            .starts_with("mod tests")
    });
    let text = match test_module {
        Some((at, _)) => &text[..at],
        None => text,
    };
    let mut out = String::with_capacity(text.len());
    for line in text.lines() {
        let mut in_string = false;
        let mut prev = ' ';
        let mut kept = String::new();
        let chars: Vec<char> = line.chars().collect();
        let mut i = 0;
        while i < chars.len() {
            let c = chars[i];
            if in_string {
                if c == '"' && prev != '\\' {
                    in_string = false;
                    kept.push('"');
                }
                prev = if prev == '\\' && c == '\\' { ' ' } else { c };
                i += 1;
                continue;
            }
            if c == '"' {
                in_string = true;
                kept.push('"');
            } else if c == '/' && chars.get(i + 1) == Some(&'/') {
                break;
            } else {
                kept.push(c);
            }
            prev = c;
            i += 1;
        }
        out.push_str(&kept);
        out.push('\n');
    }
    out
}

fn is_ident_char(c: char) -> bool {
    c.is_ascii_alphanumeric() || c == '_'
}

/// Expands a `use` tree (`a::{b, c::{d, e as f}}`) into its paths.
fn expand_use(tree: &str, prefix: &str, out: &mut Vec<String>) {
    let tree = tree.trim();
    if let Some(open) = tree.find('{') {
        let head = format!("{prefix}{}", &tree[..open]);
        let inner = &tree[open + 1..tree.rfind('}').unwrap()];
        let mut depth = 0;
        let mut start = 0;
        for (i, c) in inner.char_indices() {
            match c {
                '{' => depth += 1,
                '}' => depth -= 1,
                ',' if depth == 0 => {
                    expand_use(&inner[start..i], &head, out);
                    start = i + 1;
                }
                _ => {}
            }
        }
        expand_use(&inner[start..], &head, out);
    } else if !tree.is_empty() {
        let path = tree.split(" as ").next().unwrap().trim();
        out.push(format!("{prefix}{path}"));
    }
}

/// Whether a `use` after `before` starts a statement (not `fn reuse`).
fn starts_statement(before: &str) -> bool {
    before
        .chars()
        .last()
        .is_none_or(|c| c.is_whitespace() || c == ';' || c == '{' || c == '}')
}

/// The `use` statements of `code`: (is `pub use`, expanded paths).
fn use_statements(code: &str) -> Vec<(bool, Vec<String>)> {
    let mut found = Vec::new();
    let mut rest = code;
    while let Some(at) = rest.find("use ") {
        let before = &rest[..at];
        let starts_statement = starts_statement(before);
        let after = &rest[at + 4..];
        if !starts_statement {
            rest = after;
            continue;
        }
        let line_start = before.rfind('\n').map_or(0, |i| i + 1);
        let is_pub = before[line_start..].trim_start().starts_with("pub");
        let end = after.find(';').unwrap_or(after.len());
        let mut paths = Vec::new();
        expand_use(&after[..end].replace('\n', " "), "", &mut paths);
        found.push((is_pub, paths));
        rest = &after[end..];
    }
    found
}

/// `code` without its `use` statements.
fn without_uses(code: &str) -> String {
    let mut out = String::with_capacity(code.len());
    let mut rest = code;
    while let Some(at) = rest.find("use ") {
        let before = &rest[..at];
        let starts_statement = starts_statement(before);
        if !starts_statement {
            out.push_str(&rest[..at + 4]);
            rest = &rest[at + 4..];
            continue;
        }
        out.push_str(before);
        let end = rest[at..].find(';').map_or(rest.len(), |e| at + e + 1);
        rest = &rest[end..];
    }
    out.push_str(rest);
    out
}

/// Every inline path of `code` (outside `use` statements) that starts at
/// `crate`, `super`, `self` or one of `children`.
fn inline_paths(code: &str, children: &BTreeSet<String>) -> Vec<String> {
    let code = without_uses(code);
    let chars: Vec<char> = code.chars().collect();
    let mut found = Vec::new();
    let mut i = 0;
    while i < chars.len() {
        if is_ident_char(chars[i])
            && (i == 0 || !is_ident_char(chars[i - 1]) && chars[i - 1] != ':')
        {
            let mut j = i;
            while j < chars.len() && (is_ident_char(chars[j]) || chars[j] == ':') {
                j += 1;
            }
            let path: String = chars[i..j].iter().collect();
            let first = path.split("::").next().unwrap();
            if path.contains("::")
                && (["crate", "super", "self"].contains(&first) || children.contains(first))
            {
                found.push(path.trim_end_matches(':').to_string());
            }
            i = j;
        } else {
            i += 1;
        }
    }
    found
}

struct Graph {
    modules: BTreeMap<ModPath, Module>,
    /// (module, name) → the module an item `pub use`d there comes from.
    reexports: BTreeMap<(ModPath, String), ModPath>,
}

impl Graph {
    fn load() -> Self {
        let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
        let mut files = Vec::new();
        rust_files(&src, &mut files);
        let mut modules = BTreeMap::new();
        for file in files {
            if file.file_name().unwrap() == "main.rs" {
                continue; // the binary: a crate of its own
            }
            let text = std::fs::read_to_string(&file).unwrap();
            let code = code_of(&text);
            let children = code
                .lines()
                .filter_map(|l| {
                    let l = l.trim();
                    let l = l.strip_prefix("pub ").unwrap_or(l);
                    let name = l.strip_prefix("mod ")?.strip_suffix(';')?;
                    Some(name.trim().to_string())
                })
                .collect();
            modules.insert(module_path(&src, &file), Module { code, children });
        }
        let mut graph = Graph {
            modules,
            reexports: BTreeMap::new(),
        };
        // Re-exports may chain: resolve until nothing changes.
        for _ in 0..4 {
            let mut reexports = BTreeMap::new();
            for (path, module) in &graph.modules {
                for (is_pub, uses) in use_statements(&module.code) {
                    if !is_pub {
                        continue;
                    }
                    for used in uses {
                        let name = used.rsplit("::").next().unwrap().to_string();
                        if let Some(target) = graph.resolve(path, &used) {
                            reexports.insert((path.clone(), name), target);
                        }
                    }
                }
            }
            graph.reexports = reexports;
        }
        graph
    }

    /// The module defining what `path`, written in module `from`, names;
    /// `None` for other crates.
    fn resolve(&self, from: &ModPath, path: &str) -> Option<ModPath> {
        let mut segments = path.split("::").filter(|s| !s.is_empty()).peekable();
        let mut at: ModPath = match *segments.peek()? {
            "crate" => {
                segments.next();
                Vec::new()
            }
            "self" => {
                segments.next();
                from.clone()
            }
            "super" => {
                let mut at = from.clone();
                while segments.peek() == Some(&"super") {
                    segments.next();
                    at.pop();
                }
                at
            }
            first if self.modules.get(from)?.children.contains(first) => from.clone(),
            _ => return None,
        };
        for segment in segments {
            let module = self.modules.get(&at)?;
            if module.children.contains(segment) {
                at.push(segment.to_string());
            } else {
                if let Some(target) = self.reexports.get(&(at.clone(), segment.to_string())) {
                    return Some(target.clone());
                }
                return Some(at);
            }
        }
        Some(at)
    }

    /// Module → the modules it uses (re-exports and itself left out).
    fn edges(&self) -> BTreeMap<ModPath, BTreeSet<ModPath>> {
        let mut edges = BTreeMap::new();
        for (path, module) in &self.modules {
            let mut paths = Vec::new();
            // A re-export is a dependency where the module itself uses
            // the name it re-exports.
            let own_code = without_uses(&module.code);
            let identifiers: BTreeSet<&str> = own_code
                .split(|c: char| !is_ident_char(c))
                .filter(|w| !w.is_empty())
                .collect();
            for (is_pub, uses) in use_statements(&module.code) {
                for used in uses {
                    let name = used.rsplit("::").next().unwrap_or_default();
                    if !is_pub || identifiers.contains(name) {
                        paths.push(used);
                    }
                }
            }
            paths.extend(inline_paths(&module.code, &module.children));
            let targets: BTreeSet<ModPath> = paths
                .iter()
                .filter_map(|p| self.resolve(path, p))
                .filter(|t| t != path && self.modules.contains_key(t))
                .collect();
            edges.insert(path.clone(), targets);
        }
        edges
    }
}

fn name(path: &ModPath) -> String {
    if path.is_empty() {
        "crate".into()
    } else {
        path.join("::")
    }
}

/// Strongly connected components with more than one module (Tarjan).
fn cycles(edges: &BTreeMap<ModPath, BTreeSet<ModPath>>) -> Vec<Vec<String>> {
    struct State<'a> {
        edges: &'a BTreeMap<ModPath, BTreeSet<ModPath>>,
        index: BTreeMap<&'a ModPath, usize>,
        low: BTreeMap<&'a ModPath, usize>,
        stack: Vec<&'a ModPath>,
        on_stack: BTreeSet<&'a ModPath>,
        next: usize,
        found: Vec<Vec<String>>,
    }
    fn visit<'a>(s: &mut State<'a>, v: &'a ModPath) {
        s.index.insert(v, s.next);
        s.low.insert(v, s.next);
        s.next += 1;
        s.stack.push(v);
        s.on_stack.insert(v);
        for w in &s.edges[v] {
            if !s.index.contains_key(w) {
                visit(s, w);
                let low = s.low[v].min(s.low[w]);
                s.low.insert(v, low);
            } else if s.on_stack.contains(w) {
                let low = s.low[v].min(s.index[w]);
                s.low.insert(v, low);
            }
        }
        if s.low[v] == s.index[v] {
            let mut component = Vec::new();
            loop {
                let w = s.stack.pop().unwrap();
                s.on_stack.remove(w);
                component.push(name(w));
                if w == v {
                    break;
                }
            }
            if component.len() > 1 {
                component.sort();
                s.found.push(component);
            }
        }
    }
    let mut s = State {
        edges,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on_stack: BTreeSet::new(),
        next: 0,
        found: Vec::new(),
    };
    for v in edges.keys() {
        if !s.index.contains_key(v) {
            visit(&mut s, v);
        }
    }
    s.found
}

#[test]
fn the_module_graph_has_no_cycle() {
    let graph = Graph::load();
    let edges = graph.edges();
    let found = cycles(&edges);
    let report: Vec<String> = found
        .iter()
        .map(|component| {
            let members: BTreeSet<&String> = component.iter().collect();
            let inner: Vec<String> = edges
                .iter()
                .filter(|(from, _)| members.contains(&name(from)))
                .flat_map(|(from, to)| {
                    to.iter()
                        .filter(|t| members.contains(&name(t)))
                        .map(move |t| format!("{} → {}", name(from), name(t)))
                })
                .collect();
            format!("{{{}}}: {}", component.join(", "), inner.join("; "))
        })
        .collect();
    assert!(found.is_empty(), "import cycles:\n{}", report.join("\n"));
}

#[test]
fn the_shells_do_not_import_one_another() {
    let graph = Graph::load();
    let shells = ["app", "bench", "cli"];
    let mut found = Vec::new();
    for (from, to) in graph.edges() {
        let Some(shell) = from.first().filter(|s| shells.contains(&s.as_str())) else {
            continue;
        };
        for target in to {
            if let Some(other) = target.first().filter(|t| shells.contains(&t.as_str())) {
                if other != shell {
                    found.push(format!("{} → {}", name(&from), name(&target)));
                }
            }
        }
    }
    assert!(found.is_empty(), "shells importing shells: {found:?}");
}

#[test]
fn no_source_file_passes_a_thousand_lines() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let long: Vec<String> = files
        .iter()
        .filter_map(|f| {
            let lines = std::fs::read_to_string(f).unwrap().lines().count();
            let name = f.strip_prefix(root).unwrap().display();
            (lines > 1000).then(|| format!("{name} ({lines})"))
        })
        .collect();
    assert!(long.is_empty(), "files over 1 000 lines: {long:?}");
}

#[test]
fn the_graph_reader_sees_known_edges() {
    // The checker itself can fail: a known dependency must show up.
    let graph = Graph::load();
    let edges = graph.edges();
    let render: ModPath = vec!["render".into()];
    let atmosphere: ModPath = vec!["atmosphere".into()];
    let all: BTreeSet<&ModPath> = edges.values().flatten().collect();
    assert!(all.contains(&atmosphere), "nobody uses atmosphere?");
    assert!(
        edges.keys().any(|k| k.first() == render.first()),
        "no render modules found"
    );
    let mut cyclic = BTreeMap::new();
    cyclic.insert(
        vec!["a".to_string()],
        BTreeSet::from([vec!["b".to_string()]]),
    );
    cyclic.insert(
        vec!["b".to_string()],
        BTreeSet::from([vec!["a".to_string()]]),
    );
    assert_eq!(
        cycles(&cyclic),
        vec![vec!["a".to_string(), "b".to_string()]]
    );
}

#[test]
fn no_work_log_numbering_in_the_sources_or_the_readme() {
    // "session 17", "sessions 16 and 18": references to a work log a
    // newcomer does not have. Words split across lines count too.
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut files = Vec::new();
    rust_files(&root.join("src"), &mut files);
    files.push(root.join("README.md"));
    let mut found = Vec::new();
    for file in files {
        let text = std::fs::read_to_string(&file).unwrap().to_lowercase();
        let words: Vec<&str> = text.split_whitespace().collect();
        for pair in words.windows(2) {
            let number = pair[1].trim_start_matches(['(', '#']);
            if (pair[0] == "session" || pair[0] == "sessions")
                && number.starts_with(|c: char| c.is_ascii_digit())
            {
                found.push(format!("{}: {} {}", file.display(), pair[0], pair[1]));
            }
        }
    }
    assert!(found.is_empty(), "work-log references: {found:?}");
}

#[test]
fn top_level_modules_import_only_layers_below() {
    // The layers from the bottom up; a module may use its own layer and
    // those below. The shells (cli, bench, app) share the top layer but
    // not one another (checked above).
    const LAYERS: [&[&str]; 10] = [
        &["error", "data", "rng"],
        &["physics"],
        &["atmosphere", "spectrum"],
        &["plan"],
        &["scene"],
        &["output"],
        &["render"],
        &["lighting"],
        &["export"],
        &["cli", "bench", "app"],
    ];
    let layer = |m: &str| LAYERS.iter().position(|l| l.contains(&m));
    let graph = Graph::load();
    let mut found = Vec::new();
    for (from, to) in graph.edges() {
        let Some(a) = from.first() else { continue };
        for target in to {
            let Some(b) = target.first() else { continue };
            let (Some(la), Some(lb)) = (layer(a), layer(b)) else {
                found.push(format!("{a} or {b} is in no layer"));
                continue;
            };
            if lb > la {
                found.push(format!("{} → {}", name(&from), name(&target)));
            }
        }
    }
    found.sort();
    found.dedup();
    assert!(found.is_empty(), "imports of a layer above: {found:?}");
}

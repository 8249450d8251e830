//! The layering check: no import loop inside any crate of the workspace, and crate
//! dependencies only along the layering table below.
//!
//! **Module loops.** For every crate target of every workspace member (`src/lib.rs`,
//! `src/main.rs`, `src/bin/*.rs`), the modules are found by following the `mod` declarations
//! from the root file; a module is a file (`src/a.rs` or `src/a/mod.rs` is `a`, `src/a/b.rs`
//! is `a::b`, the root file is `crate`). Module A depends on module B when A's non-test code
//! names B:
//! - a `use` leaf (grouped ones too: `use crate::{b, c::d}`) or a path in code
//!   (`crate::b::f()`) starting with `crate::`, `super::` or `self::`, or with the name of a
//!   child module of A (`child::f()`);
//! - a path through a re-export resolves to the module that defines the item
//!   (`crate::Type` with `pub use module::Type` in `lib.rs` is `module`);
//! - a module never depends on its own descendants (declaring `mod child`, re-exporting or
//!   using a child's items: the crate root and a folder's `mod.rs` are its layout), while a
//!   child using its parent's own items through `super::` or `crate::` depends on the parent.
//!   So the loops found are between siblings (and cousins): two files of one folder that
//!   import each other, directly or around a cycle.
//!
//! Test code is left out: items under `#[cfg(test)]` (or `cfg(all(test, ..))`) and `#[test]`,
//! the files of `#[cfg(test)] mod name;`, and the crate's `tests/` folder. A strongly connected
//! component of more than one module is a loop; the test lists each with the lines that make
//! its edges.
//!
//! **Crate layering.** The `[dependencies]` (not dev-dependencies) of each member on other
//! members must be in [`ALLOWED`], which only points down the layers of [`LAYERS`].

use std::collections::{BTreeMap, BTreeSet, VecDeque};
use std::path::{Path, PathBuf};

/// The layers of the workspace, lowest first: a crate may depend only on crates of lower
/// layers (ARCHITECTURE.md, "Crates").
const LAYERS: &[&[&str]] = &[
    // Scene files and images; the kd-tree (which knows nothing about files).
    &["scenes", "kdtree"],
    // Ray groups over the kd-tree; the wide BVHs.
    &["packets", "mbvh"],
    // Techniques over packets.
    &["cones", "edgewidth"],
    // The tracing interface: every technique as a registered method.
    &["trace"],
    // Other tracers as registered methods; the conformance harness (test support).
    &["baselines", "conformance"],
    // The measurements.
    &["experiments"],
    // The command line and the viewer.
    &["rttest", "viewer"],
];

/// Which workspace crates each member may name in its `[dependencies]`: the graph of the
/// manifests when this test was written. A new dependency between members is added here, and
/// only downwards (see [`LAYERS`]).
const ALLOWED: &[(&str, &[&str])] = &[
    ("scenes", &[]),
    ("kdtree", &[]),
    ("packets", &["kdtree", "scenes"]),
    ("mbvh", &["kdtree"]),
    ("cones", &["kdtree", "packets", "scenes"]),
    ("edgewidth", &["kdtree", "packets", "scenes"]),
    ("trace", &["cones", "edgewidth", "kdtree", "mbvh", "packets", "scenes"]),
    ("baselines", &["cones", "kdtree", "scenes", "trace"]),
    ("conformance", &["cones", "kdtree", "scenes", "trace"]),
    ("experiments", &["baselines", "cones", "edgewidth", "kdtree", "mbvh", "packets", "scenes", "trace"]),
    ("rttest", &["baselines", "cones", "edgewidth", "experiments", "kdtree", "packets", "scenes", "trace"]),
    ("viewer", &["baselines", "cones", "edgewidth", "kdtree", "scenes", "trace"]),
];

// ---------------------------------------------------------------------------------------------
// Lexing: identifiers, `::` and punctuation, with line numbers; comments, strings, character
// literals, lifetimes and numbers are dropped.

/// A token of Rust source.
#[derive(Clone, Debug, PartialEq)]
enum Tok {
    /// An identifier or keyword (raw identifiers without their `r#`).
    Ident(String),
    /// `::`.
    PathSep,
    /// Any other punctuation character.
    Punct(char),
}

/// A token and the line it starts on (1-based).
#[derive(Clone, Debug)]
struct Token {
    tok: Tok,
    line: usize,
}

fn is_ident_start(c: char) -> bool {
    c == '_' || c.is_alphabetic()
}

fn is_ident_char(c: char) -> bool {
    c == '_' || c.is_alphanumeric()
}

/// Skips a quoted string whose opening `"` is at `i`; returns the index after the closing one.
fn skip_string(chars: &[char], mut i: usize, line: &mut usize) -> usize {
    i += 1;
    while i < chars.len() {
        match chars[i] {
            '\\' => {
                if chars.get(i + 1) == Some(&'\n') {
                    *line += 1;
                }
                i += 2;
                continue;
            }
            '"' => return i + 1,
            '\n' => *line += 1,
            _ => {}
        }
        i += 1;
    }
    i
}

/// Skips a raw string whose first `#` or `"` (after the `r`) is at `i`.
fn skip_raw_string(chars: &[char], mut i: usize, line: &mut usize) -> usize {
    let mut hashes = 0;
    while chars.get(i) == Some(&'#') {
        hashes += 1;
        i += 1;
    }
    i += 1; // the opening quote
    while i < chars.len() {
        if chars[i] == '\n' {
            *line += 1;
        }
        if chars[i] == '"' && (1..=hashes).all(|k| chars.get(i + k) == Some(&'#')) {
            return i + 1 + hashes;
        }
        i += 1;
    }
    i
}

/// Skips a character literal or a lifetime starting with the `'` at `i`.
fn skip_quote(chars: &[char], i: usize) -> usize {
    if chars.get(i + 1) == Some(&'\\') {
        // An escaped character literal: '\n', '\'', '\u{..}'.
        let mut j = i + 3;
        while j < chars.len() && chars[j] != '\'' {
            j += 1;
        }
        return j + 1;
    }
    if chars.get(i + 2) == Some(&'\'') {
        return i + 3; // 'x'
    }
    // A lifetime or label: skip its name.
    let mut j = i + 1;
    while j < chars.len() && is_ident_char(chars[j]) {
        j += 1;
    }
    j
}

/// The tokens of `src`.
fn lex(src: &str) -> Vec<Token> {
    let chars: Vec<char> = src.chars().collect();
    let mut out = Vec::new();
    let (mut i, mut line) = (0, 1);
    while i < chars.len() {
        let c = chars[i];
        let next = chars.get(i + 1).copied();
        if c == '\n' {
            line += 1;
            i += 1;
        } else if c.is_whitespace() {
            i += 1;
        } else if c == '/' && next == Some('/') {
            while i < chars.len() && chars[i] != '\n' {
                i += 1;
            }
        } else if c == '/' && next == Some('*') {
            // Block comments nest.
            let mut depth = 0;
            while i < chars.len() {
                if chars[i] == '/' && chars.get(i + 1) == Some(&'*') {
                    depth += 1;
                    i += 2;
                } else if chars[i] == '*' && chars.get(i + 1) == Some(&'/') {
                    depth -= 1;
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    if chars[i] == '\n' {
                        line += 1;
                    }
                    i += 1;
                }
            }
        } else if c == '"' {
            i = skip_string(&chars, i, &mut line);
        } else if c == '\'' {
            i = skip_quote(&chars, i);
        } else if is_ident_start(c) {
            let start = i;
            while i < chars.len() && is_ident_char(chars[i]) {
                i += 1;
            }
            let word: String = chars[start..i].iter().collect();
            let (after, after2) = (chars.get(i).copied(), chars.get(i + 1).copied());
            match (word.as_str(), after) {
                ("r" | "br" | "cr", Some('"')) => i = skip_raw_string(&chars, i, &mut line),
                ("r" | "br" | "cr", Some('#')) if matches!(after2, Some('"' | '#')) => {
                    i = skip_raw_string(&chars, i, &mut line)
                }
                ("b" | "c", Some('"')) => i = skip_string(&chars, i, &mut line),
                ("b", Some('\'')) => i = skip_quote(&chars, i),
                ("r", Some('#')) => {
                    // A raw identifier: r#name.
                    let start = i + 1;
                    i = start;
                    while i < chars.len() && is_ident_char(chars[i]) {
                        i += 1;
                    }
                    out.push(Token { tok: Tok::Ident(chars[start..i].iter().collect()), line });
                }
                _ => out.push(Token { tok: Tok::Ident(word), line }),
            }
        } else if c.is_ascii_digit() {
            // Numbers (with suffixes, exponents and fractions) carry no names.
            while i < chars.len()
                && (is_ident_char(chars[i])
                    || (chars[i] == '.' && chars.get(i + 1).is_some_and(|d| d.is_ascii_digit())))
            {
                i += 1;
            }
        } else if c == ':' && next == Some(':') {
            out.push(Token { tok: Tok::PathSep, line });
            i += 2;
        } else {
            out.push(Token { tok: Tok::Punct(c), line });
            i += 1;
        }
    }
    out
}

// ---------------------------------------------------------------------------------------------
// Scanning one file: its `mod` declarations, `use` leaves, paths in code and the names it
// defines, all before any resolution.

/// One name brought in by a `use` (a leaf of its tree).
#[derive(Clone, Debug, PartialEq)]
struct UseLeaf {
    /// The inline module (`mod name { .. }`) it sits in, relative to the file's module.
    scope: Vec<String>,
    /// The path as written, e.g. `["super", "shapes", "Part"]` (a `self` leaf is dropped).
    path: Vec<String>,
    /// The name it binds (an alias if renamed); `None` for a glob.
    name: Option<String>,
    /// `pub` or `pub(..)`: a re-export.
    public: bool,
    /// The line of its last segment.
    line: usize,
}

/// A path in code, as written (at least two segments).
#[derive(Clone, Debug, PartialEq)]
struct PathRef {
    scope: Vec<String>,
    segments: Vec<String>,
    line: usize,
}

/// What one file says about its dependencies.
#[derive(Clone, Debug, Default)]
struct FileFacts {
    /// `mod name;` declarations outside test code: (inline scope, name).
    mod_files: Vec<(Vec<String>, String)>,
    /// Inline modules outside test code (`mod name { .. }`), as scopes.
    inline_mods: Vec<Vec<String>>,
    /// Names of the items defined anywhere in the file.
    defines: BTreeSet<String>,
    uses: Vec<UseLeaf>,
    paths: Vec<PathRef>,
    /// Identifiers in code that are not a path's later segment, a field or a method, with the
    /// line of their first appearance: to find a module's uses of names it re-exports.
    idents: BTreeMap<String, usize>,
}

const ITEM_KEYWORDS: &[&str] = &["fn", "struct", "enum", "union", "trait", "type", "const", "static"];

fn ident(tokens: &[Token], i: usize) -> Option<&str> {
    match tokens.get(i).map(|t| &t.tok) {
        Some(Tok::Ident(s)) => Some(s),
        _ => None,
    }
}

fn is_punct(tokens: &[Token], i: usize, c: char) -> bool {
    matches!(tokens.get(i).map(|t| &t.tok), Some(Tok::Punct(p)) if *p == c)
}

fn is_path_sep(tokens: &[Token], i: usize) -> bool {
    matches!(tokens.get(i).map(|t| &t.tok), Some(Tok::PathSep))
}

/// Reads the attribute whose `#` is at `i`: (index after its `]`, inner `#!`, test only).
fn attribute(tokens: &[Token], i: usize) -> (usize, bool, bool) {
    let inner = is_punct(tokens, i + 1, '!');
    let open = if inner { i + 2 } else { i + 1 };
    if !is_punct(tokens, open, '[') {
        return (i + 1, false, false);
    }
    let mut depth = 0;
    let mut j = open;
    let mut words = Vec::new();
    while j < tokens.len() {
        match &tokens[j].tok {
            Tok::Punct('[') => depth += 1,
            Tok::Punct(']') => {
                depth -= 1;
                if depth == 0 {
                    break;
                }
            }
            Tok::Ident(s) => words.push(s.as_str()),
            _ => {}
        }
        j += 1;
    }
    let cfg_test =
        words.first() == Some(&"cfg") && words.contains(&"test") && !words.contains(&"not") && !words.contains(&"any");
    let test_fn = words == ["test"];
    (j + 1, inner, cfg_test || test_fn)
}

/// Skips the item starting at `i` (its further attributes included): to the `;` or the closing
/// `}` at its own level. Returns the index after it.
fn skip_item(tokens: &[Token], mut i: usize) -> usize {
    while is_punct(tokens, i, '#') {
        i = attribute(tokens, i).0;
    }
    let mut depth = 0usize;
    while i < tokens.len() {
        match tokens[i].tok {
            Tok::Punct('{' | '(' | '[') => depth += 1,
            Tok::Punct(c @ ('}' | ')' | ']')) => {
                depth = depth.saturating_sub(1);
                if depth == 0 && c == '}' {
                    return i + 1;
                }
            }
            Tok::Punct(';') if depth == 0 => return i + 1,
            _ => {}
        }
        i += 1;
    }
    i
}

/// Whether the `use` at `i` is `pub` or `pub(..)`.
fn is_pub_use(tokens: &[Token], i: usize) -> bool {
    if i >= 1 && ident(tokens, i - 1) == Some("pub") {
        return true;
    }
    if i >= 1 && is_punct(tokens, i - 1, ')') {
        // pub(crate), pub(super), pub(in path)
        let mut j = i - 1;
        while j > 0 && !is_punct(tokens, j, '(') {
            j -= 1;
        }
        return j >= 1 && ident(tokens, j - 1) == Some("pub");
    }
    false
}

/// Reads one use tree at `i` under `prefix`, pushing its leaves; returns the index after it.
fn use_tree(
    tokens: &[Token],
    mut i: usize,
    prefix: &[String],
    leaf: &dyn Fn(Vec<String>, Option<String>, usize) -> UseLeaf,
    out: &mut Vec<UseLeaf>,
) -> usize {
    let mut path = prefix.to_vec();
    while i < tokens.len() {
        let line = tokens[i].line;
        match &tokens[i].tok {
            Tok::Ident(s) => {
                path.push(s.clone());
                i += 1;
                if is_path_sep(tokens, i) {
                    i += 1;
                    continue;
                }
                let mut name = s.clone();
                if ident(tokens, i) == Some("as") {
                    name = ident(tokens, i + 1).unwrap_or("_").to_string();
                    i += 2;
                }
                if path.last().map(String::as_str) == Some("self") {
                    path.pop();
                    if name == "self" {
                        name = path.last().cloned().unwrap_or_default();
                    }
                }
                out.push(leaf(path, Some(name), line));
                return i;
            }
            Tok::Punct('*') => {
                out.push(leaf(path, None, line));
                return i + 1;
            }
            Tok::Punct('{') => {
                i += 1;
                while i < tokens.len() && !is_punct(tokens, i, '}') {
                    let before = i;
                    i = use_tree(tokens, i, &path, leaf, out);
                    if is_punct(tokens, i, ',') {
                        i += 1;
                    }
                    if i == before {
                        i += 1; // not a tree: step over it
                    }
                }
                return i + 1;
            }
            // A leading `::` (an extern crate path): kept, so the path never resolves locally.
            Tok::PathSep => {
                path.push("::".to_string());
                i += 1;
            }
            _ => return i,
        }
    }
    i
}

/// The facts of one file's tokens.
fn scan(tokens: &[Token]) -> FileFacts {
    let mut facts = FileFacts::default();
    let mut scope: Vec<String> = Vec::new();
    let mut scope_depths: Vec<usize> = Vec::new();
    let mut depth = 0usize;
    let mut i = 0;
    while i < tokens.len() {
        let line = tokens[i].line;
        match &tokens[i].tok {
            Tok::Punct('#') => {
                let (end, inner, test_only) = attribute(tokens, i);
                if test_only && inner {
                    // #![cfg(test)]: the rest of the file, or of the inline module, is test code.
                    let Some(&open) = scope_depths.last() else { return FileFacts::default() };
                    // Up to the inline module's closing brace, which then closes its scope.
                    let (mut j, mut d) = (end, depth);
                    while j < tokens.len() {
                        match tokens[j].tok {
                            Tok::Punct('{') => d += 1,
                            Tok::Punct('}') if d == open + 1 => break,
                            Tok::Punct('}') => d -= 1,
                            _ => {}
                        }
                        j += 1;
                    }
                    i = j;
                    continue;
                }
                i = if test_only { skip_item(tokens, end) } else { end };
                continue;
            }
            Tok::Punct('{') => depth += 1,
            Tok::Punct('}') => {
                depth = depth.saturating_sub(1);
                if scope_depths.last() == Some(&depth) {
                    scope_depths.pop();
                    scope.pop();
                }
            }
            Tok::Ident(word) if word == "mod" => {
                if let Some(name) = ident(tokens, i + 1) {
                    if is_punct(tokens, i + 2, ';') {
                        facts.mod_files.push((scope.clone(), name.to_string()));
                        i += 3;
                        continue;
                    }
                    if is_punct(tokens, i + 2, '{') {
                        scope.push(name.to_string());
                        facts.inline_mods.push(scope.clone());
                        scope_depths.push(depth);
                        depth += 1;
                        i += 3;
                        continue;
                    }
                }
            }
            Tok::Ident(word) if word == "use" => {
                let public = is_pub_use(tokens, i);
                let here = scope.clone();
                let leaf = |path: Vec<String>, name: Option<String>, line: usize| UseLeaf {
                    scope: here.clone(),
                    path,
                    name,
                    public,
                    line,
                };
                i = use_tree(tokens, i + 1, &[], &leaf, &mut facts.uses);
                continue;
            }
            Tok::Ident(word) if ITEM_KEYWORDS.contains(&word.as_str()) || word == "macro_rules" => {
                let at = if word == "macro_rules" { i + 2 } else { i + 1 };
                // `const fn f`, `static mut X`: the name comes after the second keyword.
                let named = ident(tokens, at).filter(|n| !ITEM_KEYWORDS.contains(n) && !["mut", "unsafe"].contains(n));
                if let Some(name) = named {
                    facts.defines.insert(name.to_string());
                    i = at + 1;
                    continue;
                }
            }
            Tok::Ident(word) => {
                let after_sep = i >= 1 && is_path_sep(tokens, i - 1);
                let after_dot = i >= 1 && is_punct(tokens, i - 1, '.');
                // `pub(in crate::a)` is a visibility, not a dependency.
                let restricted = i >= 1 && ident(tokens, i - 1) == Some("in");
                if !after_sep && !after_dot && !restricted {
                    let mut segments = vec![word.clone()];
                    let mut j = i + 1;
                    while is_path_sep(tokens, j) {
                        match ident(tokens, j + 1) {
                            Some(s) => segments.push(s.to_string()),
                            None => break,
                        }
                        j += 2;
                    }
                    if segments.len() >= 2 {
                        facts.paths.push(PathRef { scope: scope.clone(), segments, line });
                        i = j;
                        continue;
                    }
                    facts.idents.entry(word.clone()).or_insert(line);
                }
            }
            _ => {}
        }
        i += 1;
    }
    facts
}

// ---------------------------------------------------------------------------------------------
// Modules of a crate target, and the graph between them.

/// One module (file) of a crate target.
#[derive(Debug)]
struct Module {
    /// Its path from the crate root (empty for the root).
    path: Vec<String>,
    /// The file, as shown in messages.
    file: String,
    facts: FileFacts,
}

/// The module graph of one crate target.
#[derive(Debug)]
struct ModuleGraph {
    modules: Vec<Module>,
    /// from -> to -> the (file, line)s that make the edge.
    edges: BTreeMap<usize, BTreeMap<usize, BTreeSet<(String, usize)>>>,
}

/// A module's name as shown in messages.
fn module_name(path: &[String]) -> String {
    if path.is_empty() { "crate".to_string() } else { path.join("::") }
}

/// Follows the `mod` declarations from `root` (a crate root file), reading files with `read`;
/// `label` turns a file path into the name shown in messages.
fn discover(
    root: &Path,
    read: &dyn Fn(&Path) -> Option<String>,
    label: &dyn Fn(&Path) -> String,
) -> Result<Vec<Module>, String> {
    let mut modules = Vec::new();
    let mut queue: VecDeque<(Vec<String>, PathBuf, bool)> = VecDeque::from([(Vec::new(), root.to_path_buf(), true)]);
    while let Some((path, file, mod_rs)) = queue.pop_front() {
        let text = read(&file).ok_or_else(|| format!("cannot read {}", label(&file)))?;
        let facts = scan(&lex(&text));
        let parent = file.parent().unwrap_or(Path::new(""));
        let dir = if mod_rs { parent.to_path_buf() } else { parent.join(file.file_stem().unwrap_or_default()) };
        for (scope, name) in &facts.mod_files {
            let mut base = dir.clone();
            base.extend(scope);
            let flat = base.join(format!("{name}.rs"));
            let nested = base.join(name).join("mod.rs");
            let mut child = path.clone();
            child.extend(scope.iter().cloned());
            child.push(name.clone());
            if read(&flat).is_some() {
                queue.push_back((child, flat, false));
            } else if read(&nested).is_some() {
                queue.push_back((child, nested, true));
            } else {
                return Err(format!(
                    "{}: `mod {name};` has neither {} nor {}",
                    label(&file),
                    label(&flat),
                    label(&nested)
                ));
            }
        }
        modules.push(Module { path, file: label(&file), facts });
    }
    Ok(modules)
}

impl ModuleGraph {
    /// The graph of `modules` (from [`discover`]).
    fn new(modules: Vec<Module>) -> ModuleGraph {
        let mut graph = ModuleGraph { modules, edges: BTreeMap::new() };
        let resolver = Resolver::new(&graph.modules);
        let mut edges: Vec<(usize, usize, (String, usize))> = Vec::new();
        let modules = &graph.modules;
        for (from, module) in modules.iter().enumerate() {
            let at = |line: usize| (module.file.clone(), line);
            let mut add = |target: Option<usize>, line: usize| {
                // A module using its own descendants (a folder's `mod.rs`, the crate root) is
                // the folder's layout, not a dependency that can close a loop.
                if let Some(to) = target.filter(|&to| to != from && !modules[to].path.starts_with(&module.path)) {
                    edges.push((from, to, at(line)));
                }
            };
            for leaf in &module.facts.uses {
                let scope = [module.path.as_slice(), &leaf.scope].concat();
                let Some(target) = resolver.absolute(&scope, &leaf.path) else { continue };
                if leaf.public && target.starts_with(&module.path) {
                    // A facade re-export of this module's own descendants: an edge only where
                    // the module's code uses the name.
                    if let Some(&line) = leaf.name.as_ref().and_then(|name| module.facts.idents.get(name)) {
                        add(resolver.resolve(&target, 0), line);
                    }
                    continue;
                }
                add(resolver.resolve(&target, 0), leaf.line);
            }
            for path in &module.facts.paths {
                let scope = [module.path.as_slice(), &path.scope].concat();
                if let Some(target) = resolver.absolute(&scope, &path.segments) {
                    add(resolver.resolve(&target, 0), path.line);
                }
            }
        }
        for (from, to, at) in edges {
            graph.edges.entry(from).or_default().entry(to).or_default().insert(at);
        }
        graph
    }

    /// The strongly connected components of more than one module (Tarjan), each sorted.
    fn loops(&self) -> Vec<Vec<usize>> {
        struct Tarjan<'g> {
            graph: &'g ModuleGraph,
            index: Vec<Option<usize>>,
            low: Vec<usize>,
            on_stack: Vec<bool>,
            stack: Vec<usize>,
            next: usize,
            out: Vec<Vec<usize>>,
        }
        impl Tarjan<'_> {
            fn visit(&mut self, v: usize) {
                self.index[v] = Some(self.next);
                self.low[v] = self.next;
                self.next += 1;
                self.stack.push(v);
                self.on_stack[v] = true;
                let targets: Vec<usize> =
                    self.graph.edges.get(&v).map(|m| m.keys().copied().collect()).unwrap_or_default();
                for w in targets {
                    match self.index[w] {
                        None => {
                            self.visit(w);
                            self.low[v] = self.low[v].min(self.low[w]);
                        }
                        Some(iw) if self.on_stack[w] => self.low[v] = self.low[v].min(iw),
                        Some(_) => {}
                    }
                }
                if Some(self.low[v]) == self.index[v] {
                    let mut component = Vec::new();
                    while let Some(w) = self.stack.pop() {
                        self.on_stack[w] = false;
                        component.push(w);
                        if w == v {
                            break;
                        }
                    }
                    if component.len() > 1 {
                        component.sort_unstable();
                        self.out.push(component);
                    }
                }
            }
        }
        let n = self.modules.len();
        let mut t = Tarjan {
            graph: self,
            index: vec![None; n],
            low: vec![0; n],
            on_stack: vec![false; n],
            stack: Vec::new(),
            next: 0,
            out: Vec::new(),
        };
        for v in 0..n {
            if t.index[v].is_none() {
                t.visit(v);
            }
        }
        t.out.sort();
        t.out
    }

    fn name(&self, m: usize) -> String {
        module_name(&self.modules[m].path)
    }

    /// A shortest cycle through the first module of `component`, as names.
    fn a_cycle(&self, component: &[usize]) -> Vec<String> {
        let start = component[0];
        let inside: BTreeSet<usize> = component.iter().copied().collect();
        let mut previous: BTreeMap<usize, usize> = BTreeMap::new();
        let mut queue = VecDeque::from([start]);
        while let Some(v) = queue.pop_front() {
            for &w in self.edges.get(&v).into_iter().flat_map(|m| m.keys()) {
                if !inside.contains(&w) {
                    continue;
                }
                if w == start {
                    let mut cycle = vec![v];
                    while let Some(&p) = cycle.last().and_then(|c| previous.get(c)) {
                        cycle.push(p);
                    }
                    cycle.reverse();
                    cycle.push(start);
                    return cycle.into_iter().map(|m| self.name(m)).collect();
                }
                if w != start && !previous.contains_key(&w) {
                    previous.insert(w, v);
                    queue.push_back(w);
                }
            }
        }
        Vec::new()
    }

    /// Each loop with a cycle through it and every edge inside it with its lines.
    fn describe_loops(&self) -> Vec<String> {
        self.loops()
            .iter()
            .map(|component| {
                let names: Vec<String> = component.iter().map(|&m| self.name(m)).collect();
                let mut text =
                    format!("loop among {{{}}}, e.g. {}\n", names.join(", "), self.a_cycle(component).join(" -> "));
                for &from in component {
                    for (to, lines) in self.edges.get(&from).into_iter().flatten() {
                        if component.contains(to) {
                            let lines: Vec<String> = lines.iter().map(|(f, l)| format!("{f}:{l}")).collect();
                            text += &format!("    {} -> {}: {}\n", self.name(from), self.name(*to), lines.join(", "));
                        }
                    }
                }
                text
            })
            .collect()
    }

    /// The `file:line`s of the edge `from -> to`, by module names (for the tests of this file).
    fn edge(&self, from: &str, to: &str) -> Vec<String> {
        let find = |name: &str| (0..self.modules.len()).find(|&m| self.name(m) == name);
        let lines = find(from).zip(find(to)).and_then(|(f, t)| self.edges.get(&f)?.get(&t));
        lines.into_iter().flatten().map(|(file, line)| format!("{file}:{line}")).collect()
    }
}

/// Turns paths as written into modules, through imports and re-exports.
struct Resolver<'m> {
    modules: &'m [Module],
    /// Every module path, file or inline, to the file module it belongs to.
    namespaces: BTreeMap<Vec<String>, usize>,
}

impl<'m> Resolver<'m> {
    fn new(modules: &'m [Module]) -> Resolver<'m> {
        let mut namespaces = BTreeMap::new();
        for (m, module) in modules.iter().enumerate() {
            namespaces.insert(module.path.clone(), m);
            for inline in &module.facts.inline_mods {
                namespaces.insert([module.path.as_slice(), inline].concat(), m);
            }
        }
        Resolver { modules, namespaces }
    }

    /// The absolute path (from the crate root) of `segments` written in module `scope`, or
    /// `None` when it does not start in this crate (`std::`, `glam::`, a type's `Vec3::new`).
    fn absolute(&self, scope: &[String], segments: &[String]) -> Option<Vec<String>> {
        let first = segments.first()?.as_str();
        match first {
            "crate" => Some(segments[1..].to_vec()),
            "self" => Some([scope, &segments[1..]].concat()),
            "super" => {
                let mut base = scope.to_vec();
                let mut k = 0;
                while segments.get(k).map(String::as_str) == Some("super") {
                    base.pop()?;
                    k += 1;
                }
                Some([base.as_slice(), &segments[k..]].concat())
            }
            _ => {
                let child = [scope, &segments[..1]].concat();
                self.namespaces.contains_key(&child).then(|| [scope, segments].concat())
            }
        }
    }

    /// The module that defines what the absolute path `path` names: the longest module prefix,
    /// followed through the imports (re-exports or private `use`s) of that module. `None` when
    /// it leads out of the crate.
    fn resolve(&self, path: &[String], depth: usize) -> Option<usize> {
        let k = (0..=path.len()).rev().find(|&k| self.namespaces.contains_key(&path[..k]))?;
        let (namespace, rest) = path.split_at(k);
        let module = self.namespaces[namespace];
        let Some(name) = rest.first() else { return Some(module) };
        if depth > 16 {
            return Some(module);
        }
        let facts = &self.modules[module].facts;
        let file_path = &self.modules[module].path;
        let in_namespace = |leaf: &UseLeaf| [file_path.as_slice(), &leaf.scope].concat() == namespace;
        // A name the namespace imports resolves to its source.
        if let Some(leaf) = facts.uses.iter().find(|l| l.name.as_ref() == Some(name) && in_namespace(l)) {
            let source = self.absolute(namespace, &leaf.path)?;
            return self.resolve(&[source.as_slice(), &rest[1..]].concat(), depth + 1);
        }
        if facts.defines.contains(name) {
            return Some(module);
        }
        // A glob import that brings the name.
        for leaf in facts.uses.iter().filter(|l| l.name.is_none() && in_namespace(l)) {
            let Some(source) = self.absolute(namespace, &leaf.path) else { continue };
            let Some(&m) = self.namespaces.get(&source) else { continue };
            let from = &self.modules[m].facts;
            if from.defines.contains(name) || from.uses.iter().any(|l| l.name.as_ref() == Some(name)) {
                return self.resolve(&[source.as_slice(), rest].concat(), depth + 1);
            }
        }
        Some(module)
    }
}

// ---------------------------------------------------------------------------------------------
// The workspace: members, their crate targets and manifests.

fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").canonicalize().expect("the workspace root")
}

fn read_text(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The quoted strings of the `members = [..]` array of a workspace manifest.
fn members(manifest: &str) -> Vec<String> {
    let start = manifest
        .match_indices("members")
        .map(|(at, _)| at)
        .find(|&at| at == 0 || manifest[..at].ends_with('\n'))
        .expect("a `members` key");
    let open = start + manifest[start..].find('[').expect("members = [");
    let close = open + manifest[open..].find(']').expect("members = [..]");
    manifest[open + 1..close]
        .split(',')
        .map(|s| s.trim().trim_matches('"').to_string())
        .filter(|s| !s.is_empty())
        .collect()
}

/// The package name and the dependency names (as packages) of a member manifest: the
/// `[dependencies]` and `[target.'..'.dependencies]` tables, not dev- or build-dependencies.
fn manifest_deps(manifest: &str) -> (String, Vec<String>) {
    let mut section = String::new();
    let mut name = String::new();
    let mut deps = Vec::new();
    for line in manifest.lines() {
        let line = line.trim();
        if line.starts_with('[') {
            section = line.trim_matches(|c| c == '[' || c == ']').to_string();
            continue;
        }
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let Some((key, value)) = line.split_once('=') else { continue };
        let key = key.trim();
        if section == "package" && key == "name" {
            name = value.trim().trim_matches('"').to_string();
        }
        if section == "dependencies" || (section.starts_with("target.") && section.ends_with(".dependencies")) {
            let dep = key.split('.').next().unwrap_or(key).trim().to_string();
            // `alias = { package = "real", .. }`
            let package = value
                .split_once("package")
                .and_then(|(_, rest)| rest.split('"').nth(1))
                .map(str::to_string)
                .unwrap_or(dep);
            deps.push(package);
        }
    }
    (name, deps)
}

/// The crate root files of a member: `src/lib.rs`, `src/main.rs`, `src/bin/*.rs`.
fn crate_roots(member: &Path) -> Vec<PathBuf> {
    let src = member.join("src");
    let mut roots: Vec<PathBuf> = ["lib.rs", "main.rs"].iter().map(|f| src.join(f)).filter(|p| p.is_file()).collect();
    if let Ok(entries) = std::fs::read_dir(src.join("bin")) {
        let mut bins: Vec<PathBuf> = entries.flatten().map(|e| e.path()).filter(|p| p.is_file()).collect();
        bins.sort();
        roots.extend(bins);
    }
    roots
}

#[test]
fn no_import_loop_inside_any_crate() {
    let root = workspace_root();
    let read = |p: &Path| std::fs::read_to_string(p).ok();
    let label = |p: &Path| p.strip_prefix(&root).unwrap_or(p).display().to_string();
    let mut failures = Vec::new();
    let mut found: BTreeMap<String, Vec<String>> = BTreeMap::new();
    for member in members(&read_text(&root.join("Cargo.toml"))) {
        let dir = root.join(&member);
        let (package, _) = manifest_deps(&read_text(&dir.join("Cargo.toml")));
        let roots = crate_roots(&dir);
        assert!(!roots.is_empty(), "{member}: no src/lib.rs or src/main.rs");
        for crate_root in roots {
            let modules = discover(&crate_root, &read, &label).unwrap_or_else(|e| panic!("{e}"));
            let graph = ModuleGraph::new(modules);
            let target = format!("{package} ({})", label(&crate_root));
            for text in graph.describe_loops() {
                found.entry(package.clone()).or_default().push(format!("{target}: {text}"));
            }
        }
    }
    for loops in found.values() {
        failures.push(loops.concat());
    }
    assert!(failures.is_empty(), "module loops (see rttest/tests/layering.rs):\n{}", failures.concat());
}

#[test]
fn crate_dependencies_follow_the_layering_table() {
    let root = workspace_root();
    let manifests: Vec<(String, Vec<String>)> = members(&read_text(&root.join("Cargo.toml")))
        .iter()
        .map(|member| manifest_deps(&read_text(&root.join(member).join("Cargo.toml"))))
        .collect();
    let names: BTreeSet<&str> = manifests.iter().map(|(name, _)| name.as_str()).collect();
    let mut failures = Vec::new();
    for (name, deps) in &manifests {
        let Some((_, allowed)) = ALLOWED.iter().find(|(crate_name, _)| crate_name == name) else {
            failures.push(format!("{name} is not in ALLOWED (nor in LAYERS)"));
            continue;
        };
        for dep in deps.iter().filter(|d| names.contains(d.as_str())) {
            if !allowed.contains(&dep.as_str()) {
                failures.push(format!("{name} depends on {dep}, which ALLOWED does not let it"));
            }
        }
    }
    for (name, _) in ALLOWED {
        if !names.contains(name) {
            failures.push(format!("ALLOWED names {name}, which is not a workspace member"));
        }
    }
    assert!(failures.is_empty(), "crate layering:\n{}", failures.join("\n"));
}

#[test]
fn the_layering_table_only_points_down() {
    let layer = |name: &str| LAYERS.iter().position(|layer| layer.contains(&name));
    for (name, allowed) in ALLOWED {
        let from = layer(name).unwrap_or_else(|| panic!("{name} is in no layer"));
        for dep in *allowed {
            let to = layer(dep).unwrap_or_else(|| panic!("{dep} is in no layer"));
            assert!(to < from, "{name} (layer {from}) may not depend on {dep} (layer {to})");
        }
    }
    let layered: usize = LAYERS.iter().map(|l| l.len()).sum();
    assert_eq!(layered, ALLOWED.len(), "every crate in exactly one layer and in ALLOWED");
}

// ---------------------------------------------------------------------------------------------
// Tests of the scanner and the graph on small sources.

/// The graph of a crate made of `files` (`("src/lib.rs", source)`, ...).
fn graph_of(files: &[(&str, &str)]) -> ModuleGraph {
    let sources: BTreeMap<PathBuf, String> = files.iter().map(|(p, s)| (PathBuf::from(p), s.to_string())).collect();
    let read = |p: &Path| sources.get(p).cloned();
    let label = |p: &Path| p.display().to_string();
    ModuleGraph::new(discover(Path::new("src/lib.rs"), &read, &label).unwrap())
}

/// The edges of `graph` as `from -> to` strings.
fn edge_names(graph: &ModuleGraph) -> Vec<String> {
    let mut out = Vec::new();
    for (from, targets) in &graph.edges {
        for to in targets.keys() {
            out.push(format!("{} -> {}", graph.name(*from), graph.name(*to)));
        }
    }
    out
}

#[test]
fn grouped_uses_give_one_edge_per_leaf_at_its_line() {
    let graph = graph_of(&[
        ("src/lib.rs", "mod a;\nmod b;\nmod c;\nmod d;\n"),
        ("src/a.rs", "use crate::{\n    b,\n    c::{self as see, Thing},\n};\nuse std::fmt;\n"),
        ("src/b.rs", ""),
        ("src/c.rs", "pub struct Thing;"),
        ("src/d/mod.rs", "pub use crate::b::*;"),
    ]);
    assert_eq!(edge_names(&graph), ["a -> b", "a -> c", "d -> b"]);
    assert_eq!(graph.edge("a", "b"), ["src/a.rs:2"]);
    assert_eq!(graph.edge("a", "c"), ["src/a.rs:3"]);
    assert!(graph.loops().is_empty());
}

#[test]
fn paths_in_code_count_and_comments_strings_and_lifetimes_do_not() {
    let graph = graph_of(&[
        ("src/lib.rs", "mod a;\nmod b;\nmod c;\n"),
        (
            "src/a.rs",
            "// crate::c::x\n/* crate::c /* nested */ crate::c */\n\
             fn f<'a>(x: &'a str) -> char { let _ = r#\"crate::c\"#; let _ = \"crate::c\"; '{' }\n\
             fn g() { if true { { crate::b::h(1.0e-3) } } }\n",
        ),
        ("src/b.rs", "pub fn h(_: f64) {}"),
        ("src/c.rs", ""),
    ]);
    assert_eq!(edge_names(&graph), ["a -> b"]);
    assert_eq!(graph.edge("a", "b"), ["src/a.rs:4"]);
}

#[test]
fn test_code_is_skipped() {
    let graph = graph_of(&[
        ("src/lib.rs", "mod a;\nmod b;\n#[cfg(test)]\nmod test_support;\npub fn c() {}\n"),
        (
            "src/a.rs",
            "pub fn f() {}\n#[cfg(test)]\nmod tests {\n    use crate::b::g;\n    fn h() { if true { crate::b::g() } }\n}\n\
             #[test]\nfn t() { crate::b::g(); }\n#[cfg(all(test, feature = \"x\"))]\nuse crate::b::G;\n",
        ),
        (
            "src/b.rs",
            "pub fn g() { crate::a::f() }\n#[cfg(any(test, feature = \"y\"))]\nfn y() {}\n\
             mod inner {\n    #![cfg(test)]\n    use crate::a::f;\n    fn z() { if true {} }\n}\nfn after() { super::c() }\n",
        ),
        // Not read: its declaration is test code (and it would make a loop).
        ("src/test_support.rs", "use crate::a::f; use crate::b::g;"),
    ]);
    // `super::c()` after the test-only inline module is read in `b` again (its parent is the
    // root); the inline module's `use crate::a::f` (line 6) is not read.
    assert_eq!(edge_names(&graph), ["b -> crate", "b -> a"]);
    assert_eq!(graph.edge("b", "a"), ["src/b.rs:1"]);
    assert_eq!(graph.modules.len(), 3);
}

#[test]
fn super_reaches_siblings_and_the_parent_and_child_paths_count() {
    let graph = graph_of(&[
        ("src/lib.rs", "pub mod top;\n"),
        (
            "src/top/mod.rs",
            "mod left;\nmod right;\npub use left::Left;\npub(crate) fn helper() {}\n\
             pub fn run() { right::go() }\n",
        ),
        ("src/top/left.rs", "use super::right::Right;\npub struct Left;\n"),
        ("src/top/right.rs", "pub struct Right;\npub fn go() { super::helper() }\n"),
    ]);
    // The declarations, the re-export of `Left` and the parent's `right::go()` are its layout,
    // no edges; a sibling's `super::right` and a child's `super::helper()` are.
    assert_eq!(edge_names(&graph), ["top::left -> top::right", "top::right -> top"]);
    assert!(graph.loops().is_empty());
}

#[test]
fn re_exports_resolve_to_the_defining_module() {
    let graph = graph_of(&[
        ("src/lib.rs", "mod inner;\npub mod shapes;\npub mod user;\npub use shapes::{Cube, Sphere as Ball};\n"),
        ("src/shapes/mod.rs", "mod cube;\npub use cube::Cube;\npub struct Sphere;\n"),
        ("src/shapes/cube.rs", "pub struct Cube;\n"),
        ("src/user.rs", "use crate::{Ball, Cube};\nfn f() -> crate::shapes::Cube { todo!() }\n"),
        ("src/inner.rs", "use super::user;\n"),
    ]);
    assert_eq!(edge_names(&graph), ["inner -> user", "user -> shapes", "user -> shapes::cube"]);
    assert_eq!(graph.edge("user", "shapes::cube"), ["src/user.rs:1", "src/user.rs:2"]);
}

#[test]
fn a_parent_using_its_child_is_its_layout_not_a_loop() {
    let graph = graph_of(&[
        ("src/lib.rs", "pub mod scenes;\n"),
        ("src/scenes/mod.rs", "mod atrium;\npub use atrium::atrium;\npub fn by_name() { atrium() }\nfn view() {}\n"),
        ("src/scenes/atrium.rs", "use super::view;\npub fn atrium() { view() }\n"),
    ]);
    assert_eq!(edge_names(&graph), ["scenes::atrium -> scenes"]);
    assert!(graph.loops().is_empty());
}

#[test]
fn a_three_cycle_is_found_with_its_lines() {
    let graph = graph_of(&[
        ("src/lib.rs", "mod a;\nmod b;\nmod c;\nmod d;\npub use a::A;\n"),
        ("src/a.rs", "pub struct A;\nfn f() -> crate::b::B { todo!() }\n"),
        ("src/b.rs", "pub struct B;\nuse super::c::C;\n"),
        ("src/c.rs", "pub struct C;\n\nuse crate::A;\n"),
        ("src/d.rs", "use crate::{a::A, b::B};\n"),
    ]);
    let loops = graph.loops();
    assert_eq!(loops.len(), 1);
    assert_eq!(loops[0].iter().map(|&m| graph.name(m)).collect::<Vec<_>>(), ["a", "b", "c"]);
    let text = graph.describe_loops().concat();
    assert!(text.contains("loop among {a, b, c}, e.g. a -> b -> c -> a"), "{text}");
    for line in ["a -> b: src/a.rs:2", "b -> c: src/b.rs:2", "c -> a: src/c.rs:3"] {
        assert!(text.contains(line), "{line} missing from\n{text}");
    }
    assert!(!text.contains("d ->"), "{text}");
}

#[test]
fn manifests_give_members_and_normal_dependencies() {
    let root = "[workspace]\nmembers = [\"a\",\n  \"b\"]\n[workspace.dependencies]\na = { path = \"a\" }\n";
    assert_eq!(members(root), ["a", "b"]);
    let member = "[package]\nname = \"b\"\n\n[dependencies]\na.workspace = true\n# c\nglam = \"0.30\"\n\
                  renamed = { package = \"zed\", version = \"1\" }\n\
                  [target.'cfg(unix)'.dependencies]\nunixy = \"1\"\n[dev-dependencies]\nc.workspace = true\n";
    assert_eq!(manifest_deps(member), ("b".to_string(), vec!["a".into(), "glam".into(), "zed".into(), "unixy".into()]));
}

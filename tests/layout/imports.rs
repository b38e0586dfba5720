//! The import graph among one crate's files, read from its source text.
//!
//! A file imports another when it names an item of that file's module through `crate::`,
//! `super::` or `self::` (in a `use` or inline). A name that a module only imports (`use` or
//! `pub use`) leads on to the module that defines it, so a re-export hides no circle. A module's
//! own children are its parts: the arrows from a module to the modules below it are left out,
//! so a child reaching up to its parent is no circle; test code (`#[cfg(test)]` items and
//! files) is left out too.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// One crate's module tree: each module's path (`[]` is the crate root) and its file.
pub struct Crate {
    pub modules: BTreeMap<Vec<String>, PathBuf>,
    /// The code of each module's file, comments, strings and test code blanked out.
    code: BTreeMap<Vec<String>, String>,
    /// The names each module imports, with the path each stands for.
    imported: BTreeMap<Vec<String>, BTreeMap<String, Vec<String>>>,
}

impl Crate {
    /// Reads the crate whose root file is `root` (`src/lib.rs` or `src/main.rs`).
    pub fn read(root: &Path) -> Crate {
        let mut krate = Crate { modules: BTreeMap::new(), code: BTreeMap::new(), imported: BTreeMap::new() };
        krate.add(Vec::new(), root.to_path_buf(), true);
        let imported = krate.code.iter().map(|(m, code)| (m.clone(), krate.imported_names(m, code))).collect();
        krate.imported = imported;
        krate
    }

    fn add(&mut self, path: Vec<String>, file: PathBuf, owns_folder: bool) {
        let text = std::fs::read_to_string(&file).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
        let code = strip_tests(&blank_comments_and_strings(&text));
        let dir = if owns_folder {
            file.parent().expect("a file has a folder").to_path_buf()
        } else {
            file.with_extension("")
        };
        for (name, explicit) in child_modules(&code) {
            let (child, child_owns) = match explicit {
                Some(p) => (file.parent().expect("a file has a folder").join(p), true),
                None if dir.join(format!("{name}.rs")).exists() => (dir.join(format!("{name}.rs")), false),
                None => (dir.join(&name).join("mod.rs"), true),
            };
            let mut child_path = path.clone();
            child_path.push(name);
            self.add(child_path, child, child_owns);
        }
        self.modules.insert(path.clone(), file);
        self.code.insert(path, code);
    }

    /// For each module, the modules its file imports (never itself or one below it).
    pub fn imports(&self) -> BTreeMap<Vec<String>, BTreeSet<Vec<String>>> {
        let mut graph = BTreeMap::new();
        for (module, code) in &self.code {
            let mut to = BTreeSet::new();
            for path in referenced_paths(code) {
                if let Some(target) = self.resolve(module, &path)
                    && !target.starts_with(module)
                {
                    to.insert(target);
                }
            }
            graph.insert(module.clone(), to);
        }
        graph
    }

    /// The names `module`'s `use` declarations bring in, each with its path from `module`
    /// (`crate::…`, `super::…` or `self::…`; paths into other crates are left out).
    fn imported_names(&self, module: &[String], code: &str) -> BTreeMap<String, Vec<String>> {
        let mut names = BTreeMap::new();
        for (mut path, alias) in use_declarations(code) {
            let first = path.first().cloned().unwrap_or_default();
            let mut child = module.to_vec();
            child.push(first.clone());
            if self.modules.contains_key(&child) && !["crate", "super", "self"].contains(&first.as_str()) {
                path.insert(0, "self".to_owned());
            }
            if ["crate", "super", "self"].contains(&path[0].as_str())
                && let Some(name) = alias.or_else(|| path.last().cloned())
                && name != "self"
                && name != "*"
            {
                names.insert(name, path);
            }
        }
        names
    }

    /// The module of this crate that defines what `path` (from inside `from`) names: the
    /// deepest module it walks through, or where that module's import of the next name leads.
    fn resolve(&self, from: &[String], path: &[String]) -> Option<Vec<String>> {
        self.resolve_within(from, path, 8)
    }

    fn resolve_within(&self, from: &[String], path: &[String], hops: u32) -> Option<Vec<String>> {
        let mut at: Vec<String> = from.to_vec();
        let mut rest = path;
        match rest.first().map(String::as_str) {
            Some("crate") => {
                at.clear();
                rest = &rest[1..];
            }
            Some("self") => rest = &rest[1..],
            Some("super") => {
                while rest.first().map(String::as_str) == Some("super") {
                    at.pop()?;
                    rest = &rest[1..];
                }
            }
            _ => return None,
        }
        let mut walked = 0;
        for segment in rest {
            let mut next = at.clone();
            next.push(segment.clone());
            if !self.modules.contains_key(&next) {
                break;
            }
            at = next;
            walked += 1;
        }
        if let Some(name) = rest.get(walked)
            && hops > 0
            && let Some(import) = self.imported.get(&at).and_then(|names| names.get(name))
            && let Some(defined) = self.resolve_within(&at, import, hops - 1)
        {
            return Some(defined);
        }
        Some(at)
    }
}

/// The circles of `graph`: its strongly connected sets of more than one module (Tarjan).
pub fn circles(graph: &BTreeMap<Vec<String>, BTreeSet<Vec<String>>>) -> Vec<Vec<Vec<String>>> {
    struct State<'a> {
        graph: &'a BTreeMap<Vec<String>, BTreeSet<Vec<String>>>,
        index: BTreeMap<&'a Vec<String>, usize>,
        low: BTreeMap<&'a Vec<String>, usize>,
        stack: Vec<&'a Vec<String>>,
        on_stack: BTreeSet<&'a Vec<String>>,
        found: Vec<Vec<Vec<String>>>,
    }
    fn visit<'a>(s: &mut State<'a>, v: &'a Vec<String>) {
        let n = s.index.len();
        s.index.insert(v, n);
        s.low.insert(v, n);
        s.stack.push(v);
        s.on_stack.insert(v);
        for w in s.graph.get(v).into_iter().flatten() {
            let Some((w, _)) = s.graph.get_key_value(w) else { continue };
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
            let mut set = Vec::new();
            while let Some(w) = s.stack.pop() {
                s.on_stack.remove(w);
                set.push(w.clone());
                if w == v {
                    break;
                }
            }
            if set.len() > 1 {
                set.sort();
                s.found.push(set);
            }
        }
    }
    let mut s = State {
        graph,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on_stack: BTreeSet::new(),
        found: Vec::new(),
    };
    for v in graph.keys() {
        if !s.index.contains_key(v) {
            visit(&mut s, v);
        }
    }
    s.found
}

/// The `mod name;` declarations of a file (test modules left out), with their `#[path]`.
fn child_modules(code: &str) -> Vec<(String, Option<String>)> {
    let mut out = Vec::new();
    let mut attrs: Vec<String> = Vec::new();
    for line in code.lines().map(str::trim) {
        let mut line = line;
        while line.starts_with("#[") {
            let end = line.find(']').map_or(line.len(), |e| e + 1);
            attrs.push(line[..end].to_owned());
            line = line[end..].trim_start();
        }
        if line.is_empty() && !attrs.is_empty() {
            continue;
        }
        let decl = line.strip_prefix("pub ").or_else(|| strip_restricted_pub(line)).unwrap_or(line);
        if let Some(name) = decl.strip_prefix("mod ").and_then(|d| d.strip_suffix(';'))
            && !attrs.iter().any(|a| a.starts_with("#[cfg(test)]"))
        {
            // The path attribute's value is blanked with the strings: read it from the attribute
            // only when the file keeps it (the test modules use it, and they are left out).
            let path = attrs.iter().find_map(|a| a.strip_prefix("#[path = \"")?.strip_suffix("\"]").map(str::to_owned));
            out.push((name.trim().to_owned(), path));
        }
        if !line.is_empty() {
            attrs.clear();
        }
    }
    out
}

/// `rest` of `pub(…) rest`.
fn strip_restricted_pub(line: &str) -> Option<&str> {
    let rest = line.strip_prefix("pub(")?;
    let close = rest.find(')')?;
    Some(rest[close + 1..].trim_start())
}

/// Every `use` declaration of the code, expanded: each path with its `as` name, if any.
fn use_declarations(code: &str) -> Vec<(Vec<String>, Option<String>)> {
    let mut out = Vec::new();
    let mut from = 0;
    while let Some(at) = code[from..].find("use ").map(|a| from + a) {
        let b = code.as_bytes();
        let starts_word = at == 0 || !(b[at - 1].is_ascii_alphanumeric() || b[at - 1] == b'_');
        let end = code[at..].find(';').map_or(code.len(), |e| at + e);
        if starts_word {
            let mut trees = Vec::new();
            expand_use_tree_named(&code[at + 4..end], &mut Vec::new(), &mut trees);
            out.extend(trees);
        }
        from = end.max(at + 4);
    }
    out
}

/// Every `crate::…`, `super::…` and `self::…` path the code names, `use` trees expanded.
fn referenced_paths(code: &str) -> Vec<Vec<String>> {
    let mut out = Vec::new();
    let bytes = code.as_bytes();
    let mut i = 0;
    while i < bytes.len() {
        let starts_word =
            i == 0 || !(bytes[i - 1].is_ascii_alphanumeric() || bytes[i - 1] == b'_' || bytes[i - 1] == b'$');
        if starts_word && code[i..].starts_with("use ") {
            let end = code[i..].find(';').map_or(code.len(), |e| i + e);
            expand_use_tree(&code[i + 4..end], &mut Vec::new(), &mut out);
            i = end;
            continue;
        }
        if starts_word
            && ["crate::", "super::", "self::"].iter().any(|p| code[i..].starts_with(p))
            && !(i >= 2 && &code[i - 2..i] == "::")
        {
            let mut end = i;
            while end < bytes.len() && (bytes[end].is_ascii_alphanumeric() || bytes[end] == b'_' || bytes[end] == b':')
            {
                end += 1;
            }
            out.push(code[i..end].split("::").filter(|s| !s.is_empty()).map(str::to_owned).collect());
            i = end;
            continue;
        }
        i += 1;
    }
    out
}

/// Expands a `use` tree (`a::{b, c::{d, self}}`) after `prefix` into whole paths.
fn expand_use_tree(tree: &str, prefix: &mut Vec<String>, out: &mut Vec<Vec<String>>) {
    let mut named = Vec::new();
    expand_use_tree_named(tree, prefix, &mut named);
    out.extend(named.into_iter().map(|(path, _)| path));
}

/// [`expand_use_tree`], each path with its `as` name.
fn expand_use_tree_named(tree: &str, prefix: &mut Vec<String>, out: &mut Vec<(Vec<String>, Option<String>)>) {
    let tree = tree.trim();
    let (head, group) = match tree.find('{') {
        Some(open) if tree.ends_with('}') => (&tree[..open], Some(&tree[open + 1..tree.len() - 1])),
        _ => (tree, None),
    };
    let depth = prefix.len();
    let mut split = head.split(" as ");
    let head = split.next().unwrap_or(head);
    let alias = split.next().map(|a| a.trim().to_owned());
    prefix.extend(head.split("::").map(str::trim).filter(|s| !s.is_empty() && *s != "*").map(str::to_owned));
    match group {
        None => out.push((prefix.clone(), alias)),
        Some(group) => {
            for part in split_top_level(group) {
                if part.trim() == "self" {
                    out.push((prefix.clone(), None));
                } else if !part.trim().is_empty() {
                    expand_use_tree_named(part, prefix, out);
                }
            }
        }
    }
    prefix.truncate(depth);
}

/// `group` split at the commas outside braces.
fn split_top_level(group: &str) -> Vec<&str> {
    let (mut parts, mut depth, mut start) = (Vec::new(), 0, 0);
    for (i, c) in group.char_indices() {
        match c {
            '{' => depth += 1,
            '}' => depth -= 1,
            ',' if depth == 0 => {
                parts.push(&group[start..i]);
                start = i + 1;
            }
            _ => {}
        }
    }
    parts.push(&group[start..]);
    parts
}

/// `text` with every comment and the inside of every string and char literal replaced by
/// spaces (line breaks kept), so that no path or brace in them is read as code. An attribute
/// `#[path = "…"]` keeps its string.
fn blank_comments_and_strings(text: &str) -> String {
    let b = text.as_bytes();
    let mut out = b.to_vec();
    let blank = |out: &mut Vec<u8>, from: usize, to: usize| {
        for c in &mut out[from..to] {
            if *c != b'\n' {
                *c = b' ';
            }
        }
    };
    let mut i = 0;
    while i < b.len() {
        if b[i..].starts_with(b"//") {
            let end = text[i..].find('\n').map_or(b.len(), |e| i + e);
            blank(&mut out, i, end);
            i = end;
        } else if b[i..].starts_with(b"/*") {
            let (mut depth, mut j) = (1, i + 2);
            while j < b.len() && depth > 0 {
                if b[j..].starts_with(b"/*") {
                    depth += 1;
                    j += 2;
                } else if b[j..].starts_with(b"*/") {
                    depth -= 1;
                    j += 2;
                } else {
                    j += 1;
                }
            }
            blank(&mut out, i, j);
            i = j;
        } else if b[i] == b'r' && (b.get(i + 1) == Some(&b'"') || b.get(i + 1) == Some(&b'#')) && !ident_before(b, i) {
            let hashes = b[i + 1..].iter().take_while(|&&c| c == b'#').count();
            if b.get(i + 1 + hashes) != Some(&b'"') {
                i += 1;
                continue;
            }
            let close = format!("\"{}", "#".repeat(hashes));
            let body = i + 2 + hashes;
            let end = text[body..].find(&close).map_or(b.len(), |e| body + e + close.len());
            blank(&mut out, body, end.saturating_sub(close.len()).max(body));
            i = end;
        } else if b[i] == b'"' {
            let mut j = i + 1;
            while j < b.len() && b[j] != b'"' {
                j += if b[j] == b'\\' { 2 } else { 1 };
            }
            let line_start = text[..i].rfind('\n').map_or(0, |s| s + 1);
            if !text[line_start..i].trim_start().starts_with("#[path") {
                blank(&mut out, i + 1, j.min(b.len()));
            }
            i = j + 1;
        } else if b[i] == b'\'' {
            // A char literal ('a', '\n', '\u{..}'), not a lifetime ('a without a closing quote).
            let end = if b.get(i + 1) == Some(&b'\\') {
                text[i + 2..].find('\'').map(|e| i + 2 + e)
            } else {
                text[i + 1..].chars().next().map(|c| i + 1 + c.len_utf8()).filter(|&e| b.get(e) == Some(&b'\''))
            };
            match end {
                Some(e) => {
                    blank(&mut out, i + 1, e);
                    i = e + 1;
                }
                None => i += 1,
            }
        } else {
            i += 1;
        }
    }
    String::from_utf8(out).expect("only ASCII bytes were replaced")
}

fn ident_before(b: &[u8], i: usize) -> bool {
    i > 0 && (b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'_')
}

/// `code` without its `#[cfg(test)]` items (an inline module, a `use`, a function: to the `;`
/// or the matching brace, whichever ends the item); `mod x;` declarations stay for
/// [`child_modules`], which leaves the test ones out.
fn strip_tests(code: &str) -> String {
    const ATTR: &str = "#[cfg(test)]";
    let mut out = code.to_owned();
    let mut from = 0;
    while let Some(at) = out[from..].find(ATTR).map(|a| from + a) {
        let item = at + ATTR.len();
        let (semi, brace) = (out[item..].find(';'), out[item..].find('{'));
        let end = match (semi, brace) {
            (Some(s), b) if b.is_none_or(|b| s < b) => {
                let decl = out[item..item + s].trim();
                let decl = decl.rsplit(']').next().unwrap_or(decl).trim();
                if decl.starts_with("mod ") || decl.contains(" mod ") {
                    from = item;
                    continue;
                }
                item + s + 1
            }
            (_, Some(b)) => {
                let open = item + b;
                let mut depth = 0;
                let mut end = out.len();
                for (i, c) in out[open..].char_indices() {
                    match c {
                        '{' => depth += 1,
                        '}' => {
                            depth -= 1;
                            if depth == 0 {
                                end = open + i + 1;
                                break;
                            }
                        }
                        _ => {}
                    }
                }
                end
            }
            _ => out.len(),
        };
        out.replace_range(at..end, &"\n".repeat(out[at..end].matches('\n').count()));
        from = at;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn use_trees_expand_into_paths() {
        let mut out = Vec::new();
        expand_use_tree("crate::a::{b, c::{d, self}, e as f}", &mut Vec::new(), &mut out);
        let joined: Vec<String> = out.iter().map(|p| p.join("::")).collect();
        assert_eq!(joined, ["crate::a::b", "crate::a::c::d", "crate::a::c", "crate::a::e"]);
    }

    #[test]
    fn comments_strings_and_tests_are_not_code() {
        let code = "use crate::a; // crate::b\nlet s = \"crate::c\";\n#[cfg(test)]\nmod tests {\n use crate::d;\n}\nfn f<'a>(x: &'a str) -> char { 'x' }\n";
        let paths: Vec<String> =
            referenced_paths(&strip_tests(&blank_comments_and_strings(code))).iter().map(|p| p.join("::")).collect();
        assert_eq!(paths, ["crate::a"]);
    }

    #[test]
    fn a_re_export_leads_on_to_the_module_that_defines_the_name() {
        let dir = tempdir();
        let write = |path: &str, text: &str| {
            let file = dir.join(path);
            std::fs::create_dir_all(file.parent().unwrap()).unwrap();
            std::fs::write(file, text).unwrap();
        };
        write("lib.rs", "mod p;\nmod x;\n");
        write("p/mod.rs", "mod c;\npub use c::Thing;\n");
        write("p/c.rs", "use crate::x::Other;\npub struct Thing;\n");
        write("x.rs", "use crate::p::Thing;\npub struct Other;\n#[cfg(test)] use crate::p::c::Thing as T;\n");
        let krate = Crate::read(&dir.join("lib.rs"));
        let m = |s: &str| s.split('/').filter(|x| !x.is_empty()).map(str::to_owned).collect::<Vec<_>>();
        assert_eq!(circles(&krate.imports()), vec![vec![m("p/c"), m("x")]]);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// A fresh folder of this test's own under the system's temporary folder.
    fn tempdir() -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("risktwin-layout-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn a_two_file_circle_is_found_and_a_parent_child_pair_is_not() {
        let m = |s: &str| s.split('/').filter(|x| !x.is_empty()).map(str::to_owned).collect::<Vec<_>>();
        let graph: BTreeMap<Vec<String>, BTreeSet<Vec<String>>> =
            [(m(""), BTreeSet::new()), (m("a"), [m("b")].into()), (m("b"), [m("a")].into()), (m("c"), [m("")].into())]
                .into();
        assert_eq!(circles(&graph), vec![vec![m("a"), m("b")]]);
    }
}

//! The `cell` crate's layering, read from its source: the stages depend on each other in one
//! direction only (`plan` ← `run` ← `record` ← `sim` ← `predict` ← `verify`; `lathe` on none of them), no
//! production module of `plan`, `run` or `record` reaches a simulator, and no two modules import
//! each other through a chain (docs/ARCHITECTURE.md, "Crates and dependency direction").
//!
//! The test reads `crate::…` paths in code (comments and doc comments left out, and each file's
//! `#[cfg(test)]` module, which may drive a simulator), so a `use` line, a path written inline and
//! a grouped import all count.

use std::collections::{BTreeMap, BTreeSet};
use std::fs;
use std::path::{Path, PathBuf};

/// The stages in dependency order: each may use only those before it.
const STAGES: [&str; 6] = ["plan", "run", "record", "sim", "predict", "verify"];

fn src() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The module a source file defines, as a path under the crate root (`run::coordinator`,
/// `run::coordinator::discrete`, `cli::run`).
fn module_of(file: &Path) -> String {
    let rel = file.strip_prefix(src()).unwrap();
    let mut parts: Vec<String> = rel
        .iter()
        .map(|p| p.to_string_lossy().into_owned())
        .collect();
    let last = parts.pop().unwrap();
    let stem = last.trim_end_matches(".rs");
    if stem != "mod" && stem != "lib" && stem != "main" {
        parts.push(stem.to_string());
    }
    parts.join("::")
}

/// The code of a file without comments and without its test module.
fn production_code(text: &str) -> String {
    let mut code = String::new();
    for line in text.lines() {
        if line.trim_start().starts_with("#[cfg(test)]") {
            break;
        }
        let line = match line.find("//") {
            Some(i) => &line[..i],
            None => line,
        };
        code.push_str(line);
        code.push('\n');
    }
    code
}

/// Every module path the code names after `prefix` (`crate::` in the library, `cell::` in the
/// command line), grouped imports expanded one level (`crate::run::{device, journal}`).
fn referenced_modules(code: &str, prefix: &str, known: &BTreeSet<String>) -> BTreeSet<String> {
    let mut found = BTreeSet::new();
    let mut rest = code;
    while let Some(i) = rest.find(prefix) {
        let before = rest[..i].chars().last();
        rest = &rest[i + prefix.len()..];
        if before.is_some_and(|c| c.is_alphanumeric() || c == '_') {
            continue;
        }
        let path: String = rest
            .chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_' || *c == ':')
            .collect();
        let path = path.trim_end_matches(':');
        let mut candidates = vec![path.to_string()];
        let after = &rest[path.len()..];
        if let Some(group) = after.strip_prefix("::{") {
            let end = group.find('}').unwrap_or(group.len());
            for name in group[..end].split(',') {
                let name = name.split_whitespace().next().unwrap_or("");
                if !name.is_empty() && name != "self" {
                    candidates.push(format!("{path}::{name}"));
                }
            }
        }
        for candidate in candidates {
            // The longest prefix of the path that is a module of the crate.
            let segments: Vec<&str> = candidate.split("::").collect();
            for n in (1..=segments.len()).rev() {
                let m = segments[..n].join("::");
                if known.contains(&m) {
                    found.insert(m);
                    break;
                }
            }
        }
    }
    found
}

struct Crate {
    /// Module → the modules its production code names.
    uses: BTreeMap<String, BTreeSet<String>>,
    /// Module → its production code.
    code: BTreeMap<String, String>,
}

fn read_crate() -> Crate {
    let mut files = Vec::new();
    rust_files(&src(), &mut files);
    let known: BTreeSet<String> = files.iter().map(|f| module_of(f)).collect();
    let mut uses = BTreeMap::new();
    let mut code = BTreeMap::new();
    for file in &files {
        let module = module_of(file);
        let text = production_code(&fs::read_to_string(file).unwrap());
        let prefix = if module == "cli" || module.starts_with("cli::") || module.is_empty() {
            "cell::"
        } else {
            "crate::"
        };
        let mut named = referenced_modules(&text, prefix, &known);
        named.extend(referenced_modules(&text, "crate::", &known));
        named.remove(&module);
        named.remove("");
        uses.insert(module.clone(), named);
        code.insert(module, text);
    }
    Crate { uses, code }
}

fn stage_of(module: &str) -> &str {
    module.split("::").next().unwrap_or("")
}

#[test]
fn the_modules_are_found_and_read() {
    let c = read_crate();
    // The reader sees the imports it is meant to police: the coordinator's devices and journal.
    let coordinator = &c.uses["run::coordinator"];
    assert!(coordinator.contains("run::device"), "{coordinator:?}");
    assert!(coordinator.contains("run::journal"), "{coordinator:?}");
    assert!(c.uses["predict"].contains("sim"), "{:?}", c.uses["predict"]);
    for stage in STAGES.iter().chain(&["lathe"]) {
        assert!(c.uses.contains_key(*stage), "no module {stage}");
    }
}

#[test]
fn stages_depend_in_one_direction() {
    let c = read_crate();
    let mut wrong = Vec::new();
    for (module, named) in &c.uses {
        let from = stage_of(module);
        let Some(rank) = STAGES.iter().position(|s| *s == from) else {
            if from == "lathe" {
                for n in named {
                    if STAGES.contains(&stage_of(n)) {
                        wrong.push(format!("{module} uses {n}"));
                    }
                }
            }
            continue;
        };
        for n in named {
            let to = stage_of(n);
            if to == "lathe" || to == "cli" {
                wrong.push(format!("{module} uses {n}"));
            }
            if STAGES
                .iter()
                .position(|s| *s == to)
                .is_some_and(|r| r > rank)
            {
                wrong.push(format!("{module} ({from}) uses {n} ({to})"));
            }
        }
    }
    assert!(
        wrong.is_empty(),
        "stage order broken:\n{}",
        wrong.join("\n")
    );
}

#[test]
fn no_production_module_before_the_simulated_cell_reaches_a_simulator() {
    let c = read_crate();
    let mut wrong = Vec::new();
    for (module, code) in &c.code {
        if !["plan", "run", "record"].contains(&stage_of(module)) {
            continue;
        }
        for simulator in ["asea_protocol::sim", "mandrel_drive::sim", "crate::sim"] {
            if code.contains(simulator) {
                wrong.push(format!("{module} names {simulator}"));
            }
        }
    }
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
}

#[test]
fn no_import_cycles_between_modules() {
    let c = read_crate();
    // Depth-first search for a back edge; a module's own submodules (and its parent) are one unit,
    // as `super::` and the parent's items are one module's inside.
    let unit = |m: &str| -> String {
        let s: Vec<&str> = m.split("::").collect();
        match s.as_slice() {
            ["run", "coordinator", ..] => "run::coordinator".to_string(),
            _ => m.to_string(),
        }
    };
    let mut graph: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for (m, named) in &c.uses {
        let from = unit(m);
        let entry = graph.entry(from.clone()).or_default();
        for n in named {
            let to = unit(n);
            // A module naming its parent's re-exports (`crate::sim` from `sim::wiretap`) is
            // inside that module.
            if to != from && !from.starts_with(&format!("{to}::")) {
                entry.insert(to);
            }
        }
    }
    fn visit(
        m: &str,
        graph: &BTreeMap<String, BTreeSet<String>>,
        state: &mut BTreeMap<String, u8>,
        stack: &mut Vec<String>,
    ) -> Option<Vec<String>> {
        match state.get(m) {
            Some(2) => return None,
            Some(1) => {
                let start = stack.iter().position(|s| s == m).unwrap();
                let mut cycle = stack[start..].to_vec();
                cycle.push(m.to_string());
                return Some(cycle);
            }
            _ => {}
        }
        state.insert(m.to_string(), 1);
        stack.push(m.to_string());
        for n in graph.get(m).into_iter().flatten() {
            if let Some(cycle) = visit(n, graph, state, stack) {
                return Some(cycle);
            }
        }
        stack.pop();
        state.insert(m.to_string(), 2);
        None
    }
    let mut state = BTreeMap::new();
    for m in graph.keys() {
        let mut stack = Vec::new();
        if let Some(cycle) = visit(m, &graph, &mut state, &mut stack) {
            panic!("import cycle: {}", cycle.join(" → "));
        }
    }
}

#[test]
fn the_cycle_finder_finds_a_cycle() {
    // The reader on a made-up pair that names each other: both edges are seen.
    let known: BTreeSet<String> = ["run", "run::device", "sim"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    let a = referenced_modules(
        "use crate::run::{device, journal};\nlet x = crate::sim::Thing;",
        "crate::",
        &known,
    );
    assert_eq!(
        a,
        ["run", "run::device", "sim"]
            .iter()
            .map(|s| s.to_string())
            .collect()
    );
    let b = referenced_modules("// crate::sim\n", "crate::", &known);
    assert!(
        b.contains("sim"),
        "comments are removed by production_code, not here"
    );
    assert!(
        production_code("let a = 1; // crate::sim\n")
            .find("crate::sim")
            .is_none()
    );
}

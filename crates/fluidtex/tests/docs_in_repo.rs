//! The repository documents itself: no file may send a reader to a document
//! that is not in it, and the docs' own links and section citations must
//! resolve.
//!
//! Checked over every text file of the repository (tracked, plus new files
//! not ignored, through `git ls-files`; without git, a walk that skips build
//! output and tool caches):
//!
//! - no citation of the design, evaluation or style notes that lived outside
//!   the repository, and no path into the folder beside it that held them
//!   and the papers (the needles are assembled at run time, so this file
//!   does not match itself);
//! - every relative markdown link in `README.md` and `docs/` names a file
//!   or folder that exists (anchors are not checked);
//! - every citation of a section of `docs/design.md` (the page, a comma,
//!   the section name in asterisks) names one of its `##` headings, so
//!   renaming a section cannot strand its citations (the citation pattern
//!   is assembled at run time too).

#![allow(clippy::unwrap_used)]

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The workspace root: this crate lives in `crates/fluidtex`.
fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .canonicalize()
        .unwrap()
}

/// Strings that point outside the repository. Built with `concat!` so that
/// none of them appears verbatim in this file.
fn needles() -> [&'static str; 6] {
    [
        concat!("DESIGN", " §"),
        concat!("DESIGN", ".md"),
        concat!("EVALUATION", ".md"),
        concat!("STYLE", ".md"),
        concat!("..", "/shared"),
        concat!("shared", "/papers"),
    ]
}

/// Folders a directory walk never enters: build output, VCS data, caches
/// and tools installed by `.ci/run`, none of them part of the sources.
const SKIPPED_DIRS: &[&str] = &[
    "target",
    ".git",
    ".tools",
    ".venv",
    "node_modules",
    "__pycache__",
    "out",
    "fluidtex-demo",
];

/// Repository files, relative to `root`: from git when it answers (tracked
/// and untracked-but-not-ignored, so a new file is checked before it is
/// committed), else from a walk.
fn repo_files(root: &Path) -> Vec<PathBuf> {
    let listed = Command::new("git")
        .arg("-C")
        .arg(root)
        .args([
            "ls-files",
            "-z",
            "--cached",
            "--others",
            "--exclude-standard",
        ])
        .output();
    if let Ok(out) = listed
        && out.status.success()
        && !out.stdout.is_empty()
    {
        return out
            .stdout
            .split(|&b| b == 0)
            .filter(|name| !name.is_empty())
            .map(|name| PathBuf::from(String::from_utf8_lossy(name).into_owned()))
            // A tracked file deleted in the work tree is not there to read.
            .filter(|rel| root.join(rel).is_file())
            .collect();
    }
    let mut files = Vec::new();
    walk(root, Path::new(""), &mut files);
    files
}

fn walk(root: &Path, rel: &Path, files: &mut Vec<PathBuf>) {
    let mut entries: Vec<_> = std::fs::read_dir(root.join(rel))
        .unwrap()
        .map(|e| e.unwrap())
        .collect();
    entries.sort_by_key(|e| e.file_name());
    for entry in entries {
        let name = entry.file_name();
        let path = rel.join(&name);
        let kind = entry.file_type().unwrap();
        if kind.is_dir() {
            if !SKIPPED_DIRS.iter().any(|s| name == *s) {
                walk(root, &path, files);
            }
        } else if kind.is_file() {
            files.push(path);
        }
    }
}

/// The file's text, or `None` for binary content (images, EXR, state
/// files): a NUL byte or invalid UTF-8.
fn text(path: &Path) -> Option<String> {
    let bytes = std::fs::read(path).unwrap();
    if bytes.contains(&0) {
        return None;
    }
    String::from_utf8(bytes).ok()
}

/// Every text file of the repository with its path relative to the root.
fn text_files(root: &Path) -> Vec<(PathBuf, String)> {
    let files: Vec<_> = repo_files(root)
        .into_iter()
        .filter_map(|rel| text(&root.join(&rel)).map(|t| (rel, t)))
        .collect();
    // A listing that lost the sources would pass every check below.
    assert!(
        files
            .iter()
            .any(|(rel, _)| rel == Path::new("crates/fluidtex/src/lib.rs")),
        "the repository listing from {} misses the library's sources",
        root.display()
    );
    files
}

/// `(line number, needle)` of every outside reference in `text`.
fn outside_references(text: &str) -> Vec<(usize, &'static str)> {
    let needles = needles();
    text.lines()
        .enumerate()
        .flat_map(|(i, line)| {
            needles
                .into_iter()
                .filter(move |n| line.contains(n))
                .map(move |n| (i + 1, n))
        })
        .collect()
}

/// Relative link targets of a markdown text, outside code: `[text](target)`
/// and `![alt](target)`, without their `#anchor` or title. External links
/// (`http:`, `https:`, `mailto:`) and pure anchors are left out.
fn relative_links(markdown: &str) -> Vec<(usize, String)> {
    let mut links = Vec::new();
    let mut fenced = false;
    for (i, line) in markdown.lines().enumerate() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
            continue;
        }
        if fenced {
            continue;
        }
        // Inline code spans are not links: drop every other backtick run.
        let prose: String = line.split('`').step_by(2).collect::<Vec<_>>().join(" ");
        let mut rest = prose.as_str();
        while let Some(at) = rest.find("](") {
            rest = &rest[at + 2..];
            let end = rest.find(')').unwrap_or(rest.len());
            let inside = rest[..end].trim();
            rest = &rest[end..];
            let target = inside
                .split_whitespace()
                .next()
                .unwrap_or("")
                .trim_start_matches('<')
                .trim_end_matches('>');
            let path = target.split('#').next().unwrap_or("");
            let external = ["http://", "https://", "mailto:"]
                .iter()
                .any(|scheme| target.starts_with(scheme));
            if !external && !path.is_empty() {
                links.push((i + 1, path.replace("%20", " ")));
            }
        }
    }
    links
}

/// The markdown files whose links are checked: the README and `docs/`.
fn is_checked_markdown(rel: &Path) -> bool {
    rel.extension().is_some_and(|e| e == "md")
        && (rel == Path::new("README.md") || rel.starts_with("docs"))
}

/// `text` with comment continuations joined, so that a citation wrapped
/// over two comment lines reads as one: each line loses its indentation
/// and its `//!`, `///` or `//` marker.
fn joined_prose(text: &str) -> String {
    text.lines()
        .map(|line| {
            let line = line.trim_start();
            let line = ["//!", "///", "//"]
                .iter()
                .find_map(|marker| line.strip_prefix(marker))
                .unwrap_or(line);
            line.trim()
        })
        .collect::<Vec<_>>()
        .join(" ")
}

/// The section names cited in `text` as the design page, a comma and the
/// name in asterisks.
fn design_citations(text: &str) -> Vec<String> {
    const CITE: &str = concat!("docs/design.md", ", *");
    let prose = joined_prose(text);
    let mut names = Vec::new();
    let mut rest = prose.as_str();
    while let Some(at) = rest.find(CITE) {
        rest = &rest[at + CITE.len()..];
        if let Some(end) = rest.find('*') {
            names.push(rest[..end].to_string());
            rest = &rest[end..];
        }
    }
    names
}

/// The `##` headings of a markdown text.
fn headings(markdown: &str) -> BTreeSet<String> {
    markdown
        .lines()
        .filter_map(|l| l.strip_prefix("## "))
        .map(|h| h.trim().to_string())
        .collect()
}

#[test]
fn no_file_cites_a_document_outside_the_repository() {
    let root = repo_root();
    let mut found = Vec::new();
    for (rel, text) in text_files(&root) {
        for (line, needle) in outside_references(&text) {
            found.push(format!("{}:{line}: {needle:?}", rel.display()));
        }
    }
    assert!(
        found.is_empty(),
        "these cite documents that are not in the repository (point to \
         docs/design.md or another page under docs/ instead):\n{}",
        found.join("\n")
    );
}

#[test]
fn relative_links_in_the_readme_and_docs_resolve() {
    let root = repo_root();
    let mut broken = Vec::new();
    let mut checked = 0;
    for (rel, text) in text_files(&root) {
        if !is_checked_markdown(&rel) {
            continue;
        }
        let dir = root.join(&rel).parent().unwrap().to_path_buf();
        for (line, target) in relative_links(&text) {
            checked += 1;
            if !dir.join(&target).exists() {
                broken.push(format!("{}:{line}: {target}", rel.display()));
            }
        }
    }
    assert!(checked > 0, "no relative link found: is the parser broken?");
    assert!(
        broken.is_empty(),
        "broken relative links:\n{}",
        broken.join("\n")
    );
}

#[test]
fn design_citations_name_sections_of_the_design_page() {
    let root = repo_root();
    let design = std::fs::read_to_string(root.join("docs/design.md")).unwrap();
    let sections = headings(&design);
    let mut cited = 0;
    let mut unknown = Vec::new();
    for (rel, text) in text_files(&root) {
        for name in design_citations(&text) {
            cited += 1;
            if !sections.contains(&name) {
                unknown.push(format!("{}: *{name}*", rel.display()));
            }
        }
    }
    assert!(
        cited > 0,
        "no docs/design.md citation found: is the parser broken?"
    );
    assert!(
        unknown.is_empty(),
        "citations of sections docs/design.md does not have (its sections: \
         {sections:?}):\n{}",
        unknown.join("\n")
    );
}

#[test]
fn the_checks_see_what_they_look_for() {
    // The needles, the link parser and the citation parser on known input,
    // so a check that silently finds nothing cannot pass for a clean tree.
    let cited = format!("see {} for r", needles()[1]);
    assert_eq!(outside_references(&cited), vec![(1, needles()[1])]);
    let good = concat!("see docs/design.md", ", *Time*");
    assert!(outside_references(good).is_empty());

    let md = "[a](x.md#top) ![b](img/p.png \"t\") [c](https://e.org) [d](#here)\n\
              `[e](not/a/link.md)`\n```\n[f](code.md)\n```\n";
    let links: Vec<String> = relative_links(md).into_iter().map(|(_, t)| t).collect();
    assert_eq!(links, ["x.md", "img/p.png"]);

    let wrapped = concat!(
        "/// the bound (docs/design.md",
        ", *Triangle\n/// distortion*) and\n"
    );
    assert_eq!(design_citations(wrapped), ["Triangle distortion"]);
}

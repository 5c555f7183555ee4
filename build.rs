//! Embeds where the binaries come from: the git revision they are built
//! from (`DUALPHOTON_REVISION`, 12 hex digits, or "unknown") and whether the
//! tracked files outside `results/` matched it (`DUALPHOTON_TREE_CLEAN`:
//! "true", "false" or "unknown"). Every run's `manifest.json` records both
//! (see `src/io/manifest.rs`). Without git, or outside a repository (a
//! crate unpacked from an archive), both are "unknown": never a build failure.
//!
//! When it reruns: cargo rebuilds the whole package (library and every
//! binary) whenever this script reruns, so it watches only what can change
//! its answer for the code: the git HEAD, the branch's ref (and
//! packed-refs), the index (staging or committing), and the sources that
//! make the binaries (`src/`, `experiments/`, `Cargo.toml`, `Cargo.lock`,
//! this file). Editing a test or a doc does not rebuild the library; the
//! price is that an unstaged edit there, made after the last build, is not
//! seen as dirty until the next commit, `git add` or source edit (the
//! binary's own code is still exactly the revision's). A new commit always
//! rebuilds everything once: the revision is part of the binaries.

use std::path::{Path, PathBuf};
use std::process::Command;

/// The sources the binaries are built from, relative to the manifest.
const SOURCES: [&str; 5] = ["src", "experiments", "build.rs", "Cargo.toml", "Cargo.lock"];

fn main() {
    let root = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").unwrap_or_else(|_| ".".into()));
    for s in SOURCES {
        if root.join(s).exists() {
            println!("cargo:rerun-if-changed={s}");
        }
    }
    let git = |args: &[&str]| -> Option<String> {
        // No optional locks: `git status` would otherwise refresh the index
        // of a fresh clone, and the index is watched, so the next build
        // would rebuild the whole package once more for nothing.
        let out = Command::new("git").env("GIT_OPTIONAL_LOCKS", "0").arg("-C").arg(&root).args(args).output().ok()?;
        out.status.success().then(|| String::from_utf8_lossy(&out.stdout).trim().to_string())
    };
    let revision = git(&["rev-parse", "--short=12", "HEAD"]).filter(|r| !r.is_empty());
    let clean = match &revision {
        Some(_) => git(&["status", "--porcelain", "--untracked-files=no", "--", ".", ":(exclude)results"])
            .map(|s| s.is_empty()),
        None => None,
    };
    if revision.is_some() {
        for file in git_files(&root, &git) {
            println!("cargo:rerun-if-changed={}", file.display());
        }
    }
    println!("cargo:rustc-env=DUALPHOTON_REVISION={}", revision.as_deref().unwrap_or("unknown"));
    println!("cargo:rustc-env=DUALPHOTON_TREE_CLEAN={}", clean.map_or("unknown".into(), |c| c.to_string()));
}

/// The git files whose change can change the answer: HEAD and the index (in
/// the worktree's own git directory: `.git/` of a clone, or
/// `.git/worktrees/<name>/` where `.git` is a file), the checked-out
/// branch's ref and packed-refs (in the common directory). Only those that
/// exist: cargo reruns a script on every build while a watched path is missing.
fn git_files(root: &Path, git: &dyn Fn(&[&str]) -> Option<String>) -> Vec<PathBuf> {
    let absolute = |p: String| if Path::new(&p).is_absolute() { PathBuf::from(p) } else { root.join(p) };
    let mut files = vec![];
    if let Some(dir) = git(&["rev-parse", "--git-dir"]).map(absolute) {
        files.push(dir.join("HEAD"));
        files.push(dir.join("index"));
    }
    if let Some(common) = git(&["rev-parse", "--git-common-dir"]).map(absolute) {
        if let Some(branch) = git(&["symbolic-ref", "-q", "HEAD"]) {
            files.push(common.join(branch));
        }
        files.push(common.join("packed-refs"));
    }
    files.retain(|f| f.exists());
    files
}

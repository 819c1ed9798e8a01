//! Names the commit a build came from, for every binary's `--version`
//! (`RICOCHET_COMMIT`: `git describe`'s short hash, with `-dirty` for uncommitted changes;
//! `unknown` outside a git checkout, e.g. a source archive).

use std::process::Command;

fn main() {
    let commit = Command::new("git")
        .args(["describe", "--always", "--dirty", "--abbrev=10"])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .and_then(|o| String::from_utf8(o.stdout).ok())
        .map(|s| s.trim().to_string())
        .filter(|s| !s.is_empty())
        .unwrap_or_else(|| "unknown".to_string());
    println!("cargo:rustc-env=RICOCHET_COMMIT={commit}");
    // Again when HEAD moves or the index changes (a commit, a checkout, a staged edit).
    for path in ["../.git/HEAD", "../.git/index"] {
        println!("cargo:rerun-if-changed={path}");
    }
}

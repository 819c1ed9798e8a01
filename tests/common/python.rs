//! Which Python the tests run: `$PYTHON` when set, else the virtual environment
//! `.ci/install` makes (`$RICOCHET_VENV`, by default `~/.cache/ricochet-venv`), else
//! `python3`. Shared by the tests of every package (included by path where `common` is
//! not a module).

use std::path::PathBuf;

/// The virtual environment `.ci/install` makes and fills.
pub fn venv() -> PathBuf {
    match std::env::var_os("RICOCHET_VENV") {
        Some(dir) => PathBuf::from(dir),
        None => {
            PathBuf::from(std::env::var_os("HOME").unwrap_or_default()).join(".cache/ricochet-venv")
        }
    }
}

/// The interpreter to run Python with.
pub fn python() -> PathBuf {
    if let Some(p) = std::env::var_os("PYTHON") {
        return PathBuf::from(p);
    }
    let bin = venv().join("bin/python");
    if bin.exists() {
        return bin;
    }
    PathBuf::from("python3")
}

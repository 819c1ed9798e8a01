//! The server's scenes directory: what a `load` command from the network may read. A
//! name flows in; a path inside the directory, or a refusal that names the scene as asked
//! and nothing else, flows out. Also the input logs of headless runs (`--inputs`).

use std::path::{Path, PathBuf};

use ricochet_engine::world::short;

/// The largest scene file `load` reads, in bytes.
pub const MAX_SCENE_FILE_BYTES: u64 = 1 << 20;

/// The scene file `name` under `dir`: a plain name or relative path that stays inside
/// `dir` once every link is resolved, naming a regular file of at most
/// [`MAX_SCENE_FILE_BYTES`]. Refusals name the scene as asked, never the reason the
/// operating system gave nor any of the file's contents.
pub fn resolve_scene(dir: &Path, name: &str) -> Result<PathBuf, String> {
    let shown = short(name, 64);
    let missing = || format!("no scene `{shown}` in the server's scenes directory");
    if name.is_empty() || Path::new(name).is_absolute() {
        return Err(missing());
    }
    let root = dir
        .canonicalize()
        .map_err(|_| "the server has no scenes directory".to_string())?;
    let path = root.join(name).canonicalize().map_err(|_| missing())?;
    if !path.starts_with(&root) {
        return Err(missing());
    }
    let meta = std::fs::metadata(&path).map_err(|_| missing())?;
    if !meta.is_file() {
        return Err(format!("scene `{shown}` is not a regular file"));
    }
    if meta.len() > MAX_SCENE_FILE_BYTES {
        return Err(format!(
            "scene `{shown}` is {} bytes, over the {MAX_SCENE_FILE_BYTES} a scene may have",
            meta.len()
        ));
    }
    Ok(path)
}

/// Reads at most [`MAX_SCENE_FILE_BYTES`] of a resolved scene file as text.
pub fn read_scene(path: &Path, shown: &str) -> Result<String, String> {
    use std::io::Read;
    let mut text = String::new();
    std::fs::File::open(path)
        .and_then(|f| f.take(MAX_SCENE_FILE_BYTES).read_to_string(&mut text))
        .map_err(|_| format!("scene `{shown}` cannot be read as text"))?;
    Ok(text)
}

/// Reads an input log (`simulate --inputs`, the lab's `tradeoff --inputs`), its errors
/// naming the file and line.
pub fn read_inputs(path: &Path) -> anyhow::Result<Vec<ricochet_protocol::command::TimedAction>> {
    use anyhow::Context;
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read inputs {}", path.display()))?;
    ricochet_protocol::command::parse_input_log(&text)
        .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))
}

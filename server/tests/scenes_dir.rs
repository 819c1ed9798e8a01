//! The scenes directory: names that stay inside it resolve, everything else is refused
//! without saying why the operating system refused it.

use std::path::Path;

use ricochet_server::scenes::{resolve_scene, MAX_SCENE_FILE_BYTES};

#[test]
fn only_regular_files_inside_the_directory_resolve() {
    let dir = tempfile::tempdir().unwrap();
    let scenes = dir.path().join("scenes");
    std::fs::create_dir_all(scenes.join("sub")).unwrap();
    std::fs::write(scenes.join("a.toml"), "").unwrap();
    std::fs::write(scenes.join("sub/b.toml"), "").unwrap();
    std::fs::write(dir.path().join("secret.toml"), "").unwrap();
    std::os::unix::fs::symlink(dir.path().join("secret.toml"), scenes.join("out.toml")).unwrap();
    std::os::unix::fs::symlink(scenes.join("a.toml"), scenes.join("in.toml")).unwrap();
    let big = std::fs::File::create(scenes.join("big.toml")).unwrap();
    big.set_len(MAX_SCENE_FILE_BYTES + 1).unwrap();

    for ok in [
        "a.toml",
        "sub/b.toml",
        "./a.toml",
        "sub/../a.toml",
        "in.toml",
    ] {
        let p = resolve_scene(&scenes, ok).unwrap_or_else(|e| panic!("{ok}: {e}"));
        assert!(
            p.starts_with(scenes.canonicalize().unwrap()),
            "{ok}: {}",
            p.display()
        );
    }
    for (bad, needle) in [
        ("../secret.toml", "no scene"),
        ("out.toml", "no scene"),
        ("/etc/passwd", "no scene"),
        ("", "no scene"),
        ("missing.toml", "no scene"),
        ("sub", "not a regular file"),
        ("big.toml", "bytes"),
    ] {
        let e = resolve_scene(&scenes, bad).unwrap_err();
        assert!(e.contains(needle), "{bad}: {e}");
        assert!(
            !e.contains("os error") && !e.contains("No such file"),
            "{bad}: {e}"
        );
    }
    assert!(resolve_scene(Path::new("/nonexistent-dir"), "a.toml").is_err());
}

//! The `ricochet` Python package (python/) against real servers on loopback: installed by
//! pip into a fresh virtual environment, its quick start strikes a body and watches 120
//! frames; a refused command raises `CommandRefused` with the server's reason; a world
//! nobody serves is a one-line error that says how long was waited; and the numpy arrays
//! of `frames()` are the server's own state (`run --dump`) within the bounds the frame
//! layout states. README.md's Python quick start is the example file, word for word.

mod common;

use std::path::Path;
use std::process::{Command as Process, Output};
use std::time::Instant;

use common::*;
use ricochet_protocol::dump::read_dump;
use ricochet_protocol::frame::{FINE, PARTICLE_BOUND, POS_BOUND};

/// `python` running `code` with the repository's package first on its path.
fn run_code(code: &str, args: &[&str]) -> Output {
    Process::new(python())
        .env("PYTHONPATH", root().join("python/src"))
        .args(["-c", code])
        .args(args)
        .output()
        .expect("python runs")
}

#[test]
fn pip_installs_the_package_in_a_fresh_venv_and_the_quick_start_strikes_and_watches() {
    let dir = temp_dir();
    let venv = dir.path().join("venv");
    ok(&Process::new(python())
        .args(["-m", "venv"])
        .arg(&venv)
        .output()
        .unwrap());
    let py = venv.join("bin/python");
    // A fresh environment sees nothing installed elsewhere.
    let bare = Process::new(&py)
        .args(["-c", "import numpy"])
        .output()
        .unwrap();
    assert!(!bare.status.success(), "numpy is seen from a fresh venv");
    ok(&Process::new(&py)
        .args(["-m", "pip", "install", "-q", "--disable-pip-version-check"])
        .arg(root().join("python"))
        .output()
        .unwrap());
    let server = Server::start("emitters.toml", "default", &[]);
    // Run from the temporary directory: the package imported is the installed one.
    let out = Process::new(&py)
        .current_dir(dir.path())
        .arg(root().join("python/examples/quickstart.py"))
        .arg(&server.endpoint)
        .output()
        .unwrap();
    let out = ok(&out);
    let lines: Vec<&str> = out.lines().collect();
    assert!(lines[0].starts_with("120 frames, "), "{out}");
    let span: Vec<u64> = lines[0]
        .trim_start_matches("120 frames, ")
        .split(" to ")
        .map(|n| n.parse().unwrap())
        .collect();
    assert_eq!(span[1] - span[0], 119, "consecutive frames: {out}");
    // Struck at 40 units/s along x for 2 s of frames: it moved well along x.
    let moved: f64 = lines[1]
        .trim_start_matches("ball moved ")
        .trim_end_matches(" units along x")
        .parse()
        .unwrap();
    assert!(moved > 20.0, "{out}");
    let where_from = Process::new(&py)
        .current_dir(dir.path())
        .args(["-c", "import ricochet; print(ricochet.__file__)"])
        .output()
        .unwrap();
    assert!(ok(&where_from).starts_with(venv.to_str().unwrap()));
}

const REFUSED: &str = r#"
import sys, ricochet
with ricochet.World.connect(sys.argv[1], world="refusing") as world:
    try:
        world.impulse("nobody", [1, 0])
        print("accepted")
    except ricochet.CommandRefused as e:
        print(e.command, "|", e.reason, "|", e.reply["ok"])
    print(world.spawn(body={"id": "b", "shape": "circle", "radius": 1, "pos": [50, 50], "mass": 1}))
"#;

#[test]
fn a_refused_command_raises_command_refused_with_the_servers_reason() {
    let server = Server::start("emitters.toml", "refusing", &[]);
    let out = ok(&run_code(REFUSED, &[&server.endpoint]));
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(
        lines[0], "impulse | no body `nobody` in this world | False",
        "{out}"
    );
    assert_eq!(lines[1], "b", "{out}");
}

#[test]
fn a_world_nobody_serves_is_one_line_that_says_how_long_was_waited() {
    let endpoint = free_endpoint();
    let began = Instant::now();
    let out = Process::new(python())
        .arg(root().join("assets/scripts/ricochet_client.py"))
        .args(["--connect", &endpoint, "--timeout", "1", "send", "pause"])
        .output()
        .unwrap();
    assert!(began.elapsed().as_secs_f64() >= 1.0);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("Traceback"), "{err}");
    assert!(
        err.contains(&format!(
            "error: no server of world 'default' seen through {endpoint} in 1."
        )),
        "{err}"
    );
}

const FRAMES: &str = r#"
import json, sys, ricochet
with ricochet.World.connect(sys.argv[1], world="dumped") as world:
    world.resume()
    for f in world.frames(120):
        assert f.particles.pos.dtype.name == "float32" and f.particles.pos.shape == (len(f.particles), 2)
        print(json.dumps({"frame": f.number, "ids": f.bodies.ids, "bodies": f.bodies.pos.tolist(),
                          "particles": f.particles.pos.tolist(), "sizes": f.particles.size.tolist()}))
"#;

#[test]
fn frames_arrays_are_the_servers_dump_within_the_stated_bounds() {
    let dir = temp_dir();
    let dump = dir.path().join("served.jsonl");
    let server = Server::start(
        "emitters.toml",
        "dumped",
        &["--paused", "--dump", dump.to_str().unwrap()],
    );
    let out = ok(&run_code(FRAMES, &[&server.endpoint]));
    let decoded: Vec<serde_json::Value> = out
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(decoded.len(), 120);
    drop(server);
    let served = read_dump(&std::fs::read_to_string(&dump).unwrap()).unwrap();
    let (mut compared, mut particles) = (0, 0);
    for d in &decoded {
        let frame = d["frame"].as_u64().unwrap();
        let Some(record) = served.iter().find(|r| r.frame == frame) else {
            continue;
        };
        compared += 1;
        let ids = d["ids"].as_array().unwrap();
        for (id, pos) in ids.iter().zip(d["bodies"].as_array().unwrap()) {
            let r = record.bodies.iter().find(|b| b.id == id.as_str().unwrap());
            let r = r.unwrap_or_else(|| panic!("frame {frame}: body {id} not served"));
            for (got, was) in pos.as_array().unwrap().iter().zip([r.x, r.y]) {
                let got = got.as_f64().unwrap();
                assert!(
                    (got - was).abs() <= POS_BOUND + FINE / 2.0,
                    "frame {frame}: body {id} at {pos}, served at ({}, {})",
                    r.x,
                    r.y
                );
            }
        }
        let got = d["particles"].as_array().unwrap();
        assert_eq!(
            got.len(),
            record.particles.len(),
            "frame {frame}: particles"
        );
        particles += got.len();
        for (k, (pos, r)) in got.iter().zip(&record.particles).enumerate() {
            for (got, was) in pos.as_array().unwrap().iter().zip([r.x, r.y]) {
                let got = got.as_f64().unwrap();
                assert!(
                    (got - was as f64).abs() <= PARTICLE_BOUND + 1e-6,
                    "frame {frame}: particle {k} at {pos}, served at ({}, {})",
                    r.x,
                    r.y
                );
            }
            let size = d["sizes"][k].as_f64().unwrap() as f32;
            assert!((size - r.size).abs() <= 1e-5 * r.size.abs().max(1.0));
        }
    }
    assert!(compared >= 100, "{compared} of 120 frames compared");
    assert!(particles > 0, "no particle compared");
}

/// Every command the protocol knows is named by the package, and no other: `send`
/// refuses a name outside `ricochet.COMMANDS` before sending it.
#[test]
fn the_package_names_every_command_of_the_protocol() {
    use ricochet_protocol::command::{Action, SERVER_COMMANDS};
    let out = ok(&run_code(
        "import json, ricochet; print(json.dumps(list(ricochet.COMMANDS)))",
        &[],
    ));
    let mut python: Vec<String> = serde_json::from_str(out.trim()).unwrap();
    let mut rust: Vec<String> = SERVER_COMMANDS
        .iter()
        .chain(Action::NAMES)
        .map(|s| s.to_string())
        .collect();
    python.sort();
    rust.sort();
    assert_eq!(python, rust);
}

/// The code block under README.md's `### Quick start: Python as a library`.
fn readme_quick_start(readme: &str) -> Option<String> {
    let section = readme
        .split("### Quick start: Python as a library")
        .nth(1)?;
    let block = section.split("```python\n").nth(1)?;
    Some(block.split("```").next()?.to_string())
}

#[test]
fn the_readmes_python_quick_start_is_the_example_file() {
    let readme = std::fs::read_to_string(root().join("README.md")).unwrap();
    let example =
        std::fs::read_to_string(Path::new(&root()).join("python/examples/quickstart.py")).unwrap();
    let block = readme_quick_start(&readme)
        .expect("README.md has `### Quick start: Python as a library` with a ```python block");
    assert_eq!(
        block, example,
        "README.md's Python quick start differs from python/examples/quickstart.py"
    );
}

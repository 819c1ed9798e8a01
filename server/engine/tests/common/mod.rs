//! Helpers shared by the engine's integration tests: scenes from text or from the shipped
//! files, whole-state text, `set` actions.
#![allow(dead_code)]

use std::path::Path;

use ricochet_engine::prelude::*;
use ricochet_engine::scene;

pub fn scene(text: &str) -> World {
    scene::parse(text, Path::new("test.toml"), &[]).unwrap_or_else(|e| panic!("{e}"))
}

pub fn asset(name: &str) -> World {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../assets/scenes")
        .join(name);
    scene::load(&path).unwrap_or_else(|e| panic!("{e}"))
}

/// A world's whole state, every float printed to the bit (Debug prints the shortest text
/// that reads back to the same f64).
pub fn state(w: &World) -> String {
    format!(
        "{} {:?} {:?} {:?} {:?} {:?}",
        w.frame(),
        w.time(),
        w.bodies(),
        w.infos(),
        w.particles(),
        w.emitters()
    )
}

/// A `set` action from `name=value` text, as the command line writes it.
pub fn set(assignment: &str) -> Action {
    Action::Set(Setting::parse(assignment).unwrap_or_else(|e| panic!("{e}")))
}

pub fn body<'a>(world: &'a World, id: &str) -> &'a ricochet_engine::dynamics::Body {
    world.body(id).unwrap_or_else(|| panic!("no body {id}"))
}

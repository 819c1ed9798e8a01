//! A suite scene as every engine of the benchmark sees it: its text parsed into Ricochet's
//! world (under Ricochet's default), its criteria, and the facts a peer needs to build the
//! same scene: which bodies are dynamic, and which groups collide (as bit masks).

use std::path::{Path, PathBuf};

use anyhow::{bail, ensure, Context, Result};
use ricochet_engine::criteria::Criteria;
use ricochet_engine::dynamics::body::Body;
use ricochet_engine::world::{Side, World};

/// One scene file of the suite, read and checked.
pub struct Scene {
    /// The file name without `.toml` (`pyramid-100`).
    pub name: String,
    pub path: PathBuf,
    text: String,
    /// `[world]` overrides Ricochet parses the scene under (`--set`); a peer follows those
    /// it has a counterpart of (sleeping).
    overrides: Vec<String>,
    pub criteria: Criteria,
    /// The scene as parsed once: what the peers translate and the monitor is built from.
    pub world: World,
    /// Each body's collision filter (same order as the world's bodies).
    pub filters: Vec<CollisionFilter>,
}

/// Which groups a body belongs to and collides with, one bit per group of the scene:
/// a pair collides when each one's mask holds the other's category.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CollisionFilter {
    pub category: u32,
    pub mask: u32,
}

impl Scene {
    /// Reads, parses and checks the scene at `path`: it must state criteria, accelerate
    /// bodies classically (`mass_scaled_acceleration = false`), give no body a gravity of
    /// its own and use at most 32 groups.
    pub fn load(path: &Path, overrides: &[String]) -> Result<Scene> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("reading the scene {}", path.display()))?;
        let world = ricochet_engine::scene::parse(&text, path, overrides)
            .with_context(|| format!("parsing the scene {}", path.display()))?;
        let criteria = ricochet_engine::scene::criteria(&text, path)
            .with_context(|| format!("reading the criteria of {}", path.display()))?
            .with_context(|| format!("{} states no [criteria]", path.display()))?;
        let name = path
            .file_stem()
            .and_then(|s| s.to_str())
            .with_context(|| format!("{} has no file name", path.display()))?
            .to_string();
        ensure!(
            !world.config.mass_scaled_acceleration,
            "{name}: mass_scaled_acceleration = true has no counterpart in Box2D or rapier"
        );
        for body in world.bodies() {
            if let Some(g) = body.gravity {
                ensure!(
                    g == world.config.gravity,
                    "{name}: a body with a gravity of its own ({g}) has no counterpart in the peers"
                );
            }
        }
        let filters = collision_filters(&name, &world)?;
        Ok(Scene {
            name,
            path: path.to_path_buf(),
            text,
            overrides: overrides.to_vec(),
            criteria,
            world,
            filters,
        })
    }

    /// A fresh Ricochet world of the scene, before its first step.
    pub fn fresh_world(&self) -> Result<World> {
        ricochet_engine::scene::parse(&self.text, &self.path, &self.overrides)
            .with_context(|| format!("parsing the scene {}", self.path.display()))
    }

    /// The scene's bodies, as parsed.
    pub fn bodies(&self) -> &[Body] {
        self.world.bodies()
    }

    /// Steps of the judged run.
    pub fn steps(&self) -> u64 {
        self.criteria.steps
    }

    /// Dynamic bodies of the scene.
    pub fn dynamic_count(&self) -> usize {
        self.bodies().iter().filter(|b| !b.is_static()).count()
    }
}

/// Every body's filter: group k (by first appearance among the bodies) is bit k; a group's
/// mask holds every group an interaction with `resolve = true` pairs it with. Interactions
/// that only flag (`resolve = false`) collide in no engine of the benchmark.
fn collision_filters(name: &str, world: &World) -> Result<Vec<CollisionFilter>> {
    let mut groups: Vec<u16> = Vec::new();
    for body in world.bodies() {
        if !groups.contains(&body.group) {
            groups.push(body.group);
        }
    }
    if groups.len() > 32 {
        bail!(
            "{name}: {} groups, more than the 32 a filter holds",
            groups.len()
        );
    }
    let bit = |g: u16| groups.iter().position(|&h| h == g).map(|k| 1u32 << k);
    let mut masks = vec![0u32; groups.len()];
    for inter in world.interactions() {
        if let (Side::Group(a), Side::Group(b), true) = (inter.a, inter.b, inter.resolve) {
            let (Some(ba), Some(bb)) = (bit(a), bit(b)) else {
                continue; // a group without bodies
            };
            masks[ba.trailing_zeros() as usize] |= bb;
            masks[bb.trailing_zeros() as usize] |= ba;
        }
    }
    Ok(world
        .bodies()
        .iter()
        .map(|b| {
            let k = groups
                .iter()
                .position(|&h| h == b.group)
                .expect("every body's group");
            CollisionFilter {
                category: 1 << k,
                mask: masks[k],
            }
        })
        .collect())
}

/// The scene files under `dir` whose file name contains `only` (all with `None`), by name.
pub fn scene_files(dir: &Path, only: Option<&str>) -> Result<Vec<PathBuf>> {
    let mut files = Vec::new();
    for entry in std::fs::read_dir(dir)
        .with_context(|| format!("listing the scenes in {}", dir.display()))?
    {
        let path = entry?.path();
        let name = path
            .file_name()
            .and_then(|n| n.to_str())
            .unwrap_or_default();
        if name.ends_with(".toml") && only.is_none_or(|o| name.contains(o)) {
            files.push(path);
        }
    }
    files.sort();
    ensure!(!files.is_empty(), "no scene in {} matches", dir.display());
    Ok(files)
}

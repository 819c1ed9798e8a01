//! The scene in Box2D v3 (boxdd's bundled source): 4 sub-steps a step, one worker (no task
//! system), sleeping as Ricochet's setting of the scene (its own default tolerances: 0.05
//! units/s for 0.5 s, as Ricochet's), continuous collision as Box2D's default, rotation locked both by
//! the motion lock and by a zero rotational inertia, restitution mixed as Ricochet's
//! minimum.

use anyhow::{Context, Result};
use boxdd::{
    shapes, BodyId, BodyType, Filter, Foundation, MassData, MaterialMixInput, MixerId, MotionLocks,
    Position, ShapeDef, SurfaceMaterial, Vec2, WorkerCount, World, WorldScalar,
};
use glam::DVec2;
use ricochet_engine::criteria::Monitor;
use ricochet_engine::geometry::Shape;

use crate::engine::{observe_dynamic, Engine};
use crate::scene::Scene;

/// Sub-steps of Box2D's soft step per step.
pub const SUB_STEPS: i32 = 4;

/// Box2D's cap on a body's speed (its default is 400 units/s; the bullets fly at 600).
pub const MAX_LINEAR_SPEED: f32 = 1.0e5;

/// Whether Box2D's positions are f64 (the `double` feature).
pub const DOUBLE_PRECISION: bool = cfg!(feature = "double");

/// The scene built in a Box2D world.
pub struct Box2dScene {
    world: World,
    dt: f32,
    /// Each Ricochet body's Box2D body (by index among the world's bodies).
    bodies: Vec<Option<BodyId>>,
    states: Vec<(DVec2, DVec2)>,
}

/// Box2D's version, as its bundled source reports it ("3.2.0").
pub fn version() -> Result<String> {
    foundation()?;
    let v = boxdd::version().context("asking Box2D its version")?;
    Ok(format!("{}.{}.{}", v.major, v.minor, v.revision))
}

fn foundation() -> Result<&'static Foundation> {
    match Foundation::get() {
        Some(f) => Ok(f),
        None => Foundation::initialize_default().context("initialising Box2D"),
    }
}

impl Box2dScene {
    pub fn build(scene: &Scene) -> Result<Box2dScene> {
        let config = &scene.world.config;
        let foundation = foundation()?;
        let def = foundation
            .world_builder()
            .gravity(Vec2::new(config.gravity.x as f32, config.gravity.y as f32))
            .enable_sleep(config.sleeping)
            .enable_continuous(true)
            .maximum_linear_speed(MAX_LINEAR_SPEED)
            .worker_count(WorkerCount::new(1)?)
            .build()
            .context("a Box2D world definition")?;
        let mut world = foundation
            .create_world(def)
            .context("creating a Box2D world")?;
        // Ricochet combines restitutions as their minimum (Box2D: maximum). Friction is
        // sqrt(fa * fb) in both, Box2D's default.
        world
            .set_restitution_callback(
                MixerId::from_bytes(*b"ricochet/restitution=min(ea,eb)."),
                |a: MaterialMixInput, b: MaterialMixInput| a.coefficient.min(b.coefficient),
            )
            .context("setting Box2D's restitution mixing")?;
        let mut bodies = Vec::with_capacity(scene.bodies().len());
        for (body, filter) in scene.bodies().iter().zip(&scene.filters) {
            let dynamic = !body.is_static();
            let def = world
                .body_builder()
                .body_type(if dynamic {
                    BodyType::Dynamic
                } else {
                    BodyType::Static
                })
                .position(Position::new(
                    body.pos.x as WorldScalar,
                    body.pos.y as WorldScalar,
                ))
                .linear_velocity(Vec2::new(body.vel.x as f32, body.vel.y as f32))
                .enable_sleep(config.sleeping)
                .motion_locks(MotionLocks::new(false, false, true))
                .build()
                .context("a Box2D body definition")?;
            let id = world.create_body(def).context("creating a Box2D body")?;
            let shape_def = ShapeDef::builder()
                .material(
                    SurfaceMaterial::new()
                        .with_friction(body.friction as f32)?
                        .with_restitution(body.restitution as f32)?,
                )
                .filter(Filter {
                    category_bits: filter.category as u64,
                    mask_bits: filter.mask as u64,
                    group_index: 0,
                })
                .enable_contact_events(false)
                .build()
                .context("a Box2D shape definition")?;
            let mut b = world.body(id)?;
            match body.shape {
                Shape::Rect { half } => {
                    let polygon = shapes::box_polygon(half.x as f32, half.y as f32)?;
                    b.create_polygon(&shape_def, &polygon)?;
                }
                Shape::Circle { radius } => {
                    b.create_circle(&shape_def, &shapes::circle([0.0, 0.0], radius as f32)?)?;
                }
            }
            if dynamic {
                // The motion lock only zeroes the angular velocity; without a zero inertia
                // the solver still lets contacts turn the bodies and stacks go soft.
                b.set_mass_data(MassData::new(body.mass() as f32, Vec2::new(0.0, 0.0), 0.0)?)?;
            }
            bodies.push(dynamic.then_some(id));
        }
        Ok(Box2dScene {
            world,
            dt: config.dt as f32,
            bodies,
            states: Vec::new(),
        })
    }
}

impl Engine for Box2dScene {
    fn step(&mut self) -> Result<()> {
        // A failure found after the native step (a mixing callback's) is an error too.
        let done = self
            .world
            .step(self.dt, SUB_STEPS)
            .context("stepping Box2D")?;
        drop(done.into_result().context("after a Box2D step")?);
        Ok(())
    }

    fn observe(&mut self, monitor: &mut Monitor) -> Result<()> {
        let world = &mut self.world;
        observe_dynamic(monitor, &self.bodies, &mut self.states, |id| {
            let body = world.body(id)?;
            let (p, v) = (body.position()?, body.linear_velocity()?);
            Ok(([p.x as f64, p.y as f64], [v.x as f64, v.y as f64]))
        })
    }
}

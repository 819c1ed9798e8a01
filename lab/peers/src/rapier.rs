//! The scene in rapier2d (f32, one thread): 4 solver iterations, sleeping as Ricochet's
//! setting of the scene (rapier's own thresholds), rotation
//! locked, masses set on the colliders, friction combined as the geometric mean and
//! restitution as the minimum (Ricochet's rules), CCD on every dynamic body (Box2D's
//! default continuous collision against static bodies; Ricochet needs none at the suite's
//! speeds).

use anyhow::Result;
use glam::DVec2;
use rapier2d::prelude::{
    CoefficientCombineRule, ColliderBuilder, Group, InteractionGroups, InteractionTestMode,
    PhysicsWorld, Real, RigidBodyBuilder, RigidBodyHandle, Vector,
};
use ricochet_engine::criteria::Monitor;
use ricochet_engine::geometry::Shape;

use crate::engine::{observe_dynamic, Engine};
use crate::scene::Scene;

/// rapier's solver iterations per step.
pub const SOLVER_ITERATIONS: usize = 4;

/// The scene built in a rapier world.
pub struct RapierScene {
    world: PhysicsWorld,
    /// Each Ricochet body's rapier body (by index among the world's bodies).
    bodies: Vec<Option<RigidBodyHandle>>,
    states: Vec<(DVec2, DVec2)>,
}

fn vector(v: DVec2) -> Vector {
    Vector::new(v.x as Real, v.y as Real)
}

impl RapierScene {
    pub fn build(scene: &Scene) -> RapierScene {
        let config = &scene.world.config;
        let mut world = PhysicsWorld::new();
        world.gravity = vector(config.gravity);
        let params = &mut world.integration_parameters;
        params.dt = config.dt as Real;
        params.num_solver_iterations = SOLVER_ITERATIONS;
        // rapier caps speeds at 400 units/s by default; the bullets fly at 600.
        params.normalized_max_linear_velocity = Real::MAX;
        let mut bodies = Vec::with_capacity(scene.bodies().len());
        for (body, filter) in scene.bodies().iter().zip(&scene.filters) {
            let dynamic = !body.is_static();
            let rigid = if dynamic {
                RigidBodyBuilder::dynamic()
                    .lock_rotations()
                    .can_sleep(config.sleeping)
                    .ccd_enabled(true)
                    .linvel(vector(body.vel))
            } else {
                RigidBodyBuilder::fixed()
            }
            .translation(vector(body.pos));
            let collider = match body.shape {
                Shape::Rect { half } => ColliderBuilder::cuboid(half.x as Real, half.y as Real),
                Shape::Circle { radius } => ColliderBuilder::ball(radius as Real),
            }
            .friction(body.friction as Real)
            .friction_combine_rule(CoefficientCombineRule::GeometricMean)
            .restitution(body.restitution as Real)
            .restitution_combine_rule(CoefficientCombineRule::Min)
            .collision_groups(InteractionGroups::new(
                Group::from_bits_retain(filter.category),
                Group::from_bits_retain(filter.mask),
                InteractionTestMode::And,
            ));
            let collider = if dynamic {
                collider.mass(body.mass() as Real)
            } else {
                collider
            };
            let (handle, _) = world.insert(rigid, collider);
            bodies.push(dynamic.then_some(handle));
        }
        RapierScene {
            world,
            bodies,
            states: Vec::new(),
        }
    }
}

impl Engine for RapierScene {
    fn step(&mut self) -> Result<()> {
        self.world.step();
        Ok(())
    }

    fn observe(&mut self, monitor: &mut Monitor) -> Result<()> {
        let bodies = &self.world.bodies;
        observe_dynamic(monitor, &self.bodies, &mut self.states, |h| {
            let (p, v) = (bodies[h].translation(), bodies[h].linvel());
            Ok(([p.x as f64, p.y as f64], [v.x as f64, v.y as f64]))
        })
    }
}

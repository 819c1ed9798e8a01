//! The chapter demo's game rules, which the step calls at two named points
//! ([`HookPoint`]), as rapier calls its `PhysicsHooks`: behaviours steer the hero, the
//! patrolling minions and the homing dye packs before the bodies move; dye packs touching
//! the hero explode into emitters once they moved.

use glam::DVec2;

use crate::behavior::{self, Behavior};
use crate::dynamics::body::BodyKey;
use crate::geometry::collide;
use crate::particles::Emitter;

use super::World;

/// The points of a step where the game rules run (see [`World::step`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum HookPoint {
    /// Before the bodies move: behaviours set velocities and fly dye packs; expired packs
    /// are removed.
    BeforeMotion,
    /// Once the bodies moved (see [`World::rigid_stage`] for when that is) and before the
    /// particles move: dye packs touching the hero are removed and start emitters.
    AfterMotion,
}

impl World {
    /// The chapter demo's rules at `point` (nothing for a world without its actors).
    pub(super) fn game_rules(&mut self, point: HookPoint) {
        match point {
            HookPoint::BeforeMotion => self.run_behaviors(),
            HookPoint::AfterMotion => self.explode_dye_packs_on_hero(),
        }
    }

    /// The first hero's index.
    pub(super) fn hero(&self) -> Option<usize> {
        self.behaving
            .iter()
            .map(|&i| i as usize)
            .find(|&i| matches!(self.infos[i].behavior, Behavior::Hero { .. }))
    }

    pub(super) fn hero_pos(&self) -> Option<DVec2> {
        self.hero().map(|i| self.bodies[i].pos)
    }

    fn run_behaviors(&mut self) {
        let dt = self.config.dt;
        let hero = self.hero_pos();
        let mut expired_packs = false;
        for &i in &self.behaving {
            let b = &mut self.bodies[i as usize];
            let movable = !b.is_static();
            match &mut self.infos[i as usize].behavior {
                Behavior::None | Behavior::DumbMinion => {}
                Behavior::Hero { held } => {
                    if movable {
                        b.vel += held.push() * dt;
                    }
                }
                Behavior::Patrol { speed, dir } => {
                    // A collision that reversed the motion turns the patrol back.
                    if b.vel.x != 0.0 && b.vel.x.signum() != *dir {
                        *dir = b.vel.x.signum();
                    }
                    b.vel = DVec2::new(*dir * *speed, 0.0);
                }
                Behavior::DyePack { heading, life } => {
                    if let Some(target) = hero {
                        *heading = behavior::turn_toward(
                            *heading,
                            target - b.pos,
                            behavior::DYE_PACK_TURN_RATE,
                        );
                    }
                    b.pos += *heading * (behavior::DYE_PACK_SPEED * dt);
                    *life = life.saturating_sub(1);
                    expired_packs |= *life == 0;
                }
            }
        }
        if expired_packs {
            self.remove_bodies(|_, info| {
                matches!(info.behavior, Behavior::DyePack { life: 0, .. })
            });
        }
    }

    /// Dye packs touching the hero are removed, each starting an explosion where it was.
    fn explode_dye_packs_on_hero(&mut self) {
        let Some(hero) = self.hero() else {
            return;
        };
        let (hero_shape, hero_pos) = (self.bodies[hero].shape, self.bodies[hero].pos);
        let hits: Vec<BodyKey> = self
            .behaving
            .iter()
            .map(|&i| i as usize)
            .filter(|&i| matches!(self.infos[i].behavior, Behavior::DyePack { .. }))
            .map(|i| &self.bodies[i])
            .filter(|b| collide(&hero_shape, hero_pos, &b.shape, b.pos).is_some())
            .map(|b| b.key)
            .collect();
        if hits.is_empty() {
            return;
        }
        for key in &hits {
            let pos = self.body_by_key(*key).expect("hit is alive").pos;
            // An explosion is skipped where the world's limits leave no room for it.
            if self
                .presets
                .get(behavior::DYE_PACK_EXPLOSION_PRESET)
                .is_some()
                && self.check_new_emitter(behavior::DYE_PACK_EXPLOSION).is_ok()
            {
                self.emitters.push(Emitter {
                    pos: pos.as_vec2(),
                    remaining: behavior::DYE_PACK_EXPLOSION,
                    preset: behavior::DYE_PACK_EXPLOSION_PRESET.to_string(),
                });
            }
        }
        self.remove_bodies(|b, _| hits.contains(&b.key));
    }
}

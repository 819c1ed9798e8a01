//! The chapter demo's behaviours, run by the step: the hero steered by held directions,
//! patrolling minions, homing dye packs that explode into emitters on touching the hero.

use glam::DVec2;

use crate::behavior::{self, Behavior};
use crate::dynamics::body::BodyKey;
use crate::geometry::collide;
use crate::particles::Emitter;

use super::World;

impl World {
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

    pub(super) fn run_behaviors(&mut self) {
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
    pub(super) fn explode_dye_packs_on_hero(&mut self) {
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

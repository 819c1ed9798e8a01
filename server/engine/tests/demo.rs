//! The chapter demo's behaviours and actions through the public API: the hero, patrolling
//! minions, dye packs, emitters, particles against shapes, dumb minions.

mod common;

use common::*;
use glam::DVec2;
use ricochet_engine::behavior::{Behavior, Direction};
use ricochet_engine::prelude::*;

fn demo_with_particles() -> World {
    asset("emitters.toml")
}

#[test]
fn the_hero_is_pushed_while_a_direction_is_held_and_not_after_release() {
    let mut w = asset("impulse.toml");
    w.step_n(120); // land on the floor
    let v0 = body(&w, "hero").vel.x;
    w.apply(&Action::Press {
        dir: Direction::Right,
    })
    .unwrap();
    w.step_n(10);
    let v1 = body(&w, "hero").vel.x;
    assert!(v1 > v0 + 3.0, "held right: vx {v0} -> {v1}");
    w.apply(&Action::Release {
        dir: Direction::Right,
    })
    .unwrap();
    w.step_n(10);
    let v2 = body(&w, "hero").vel.x;
    assert!(v2 < v1, "released: friction slows it ({v1} -> {v2})");
    assert!(v2 >= 0.0, "friction never reverses motion");
}

#[test]
fn minions_patrol_and_turn_back_on_collision() {
    let mut w = asset("impulse.toml");
    let start = body(&w, "minion/0").vel.x;
    assert_eq!(start, 5.0);
    let mut turned = false;
    for _ in 0..60 * 30 {
        w.step();
        let m = body(&w, "minion/0");
        // The patrol sets |vx| = 5 before each step; a collision may slow it within one.
        assert!(
            m.vel.x.abs() <= 5.0 && m.vel.x != 0.0,
            "patrol speed {}",
            m.vel.x
        );
        turned |= m.vel.x < 0.0;
    }
    assert!(turned, "minion/0 never turned back at a platform");
    assert!(body(&w, "minion/0").pos.x > 90.0 && body(&w, "minion/0").pos.x < 150.0);
}

#[test]
fn a_dye_pack_homes_on_the_hero_and_explodes_into_an_emitter() {
    let mut w = demo_with_particles();
    w.step_n(300); // let the scene's own emitter finish and the hero land
    let hero = body(&w, "hero").pos;
    let out = w
        .apply(&Action::FireDyePack {
            at: [hero.x + 40.0, hero.y + 30.0],
        })
        .unwrap();
    assert_eq!(out.ids.len(), 1);
    let id = out.ids[0].clone();
    let mut exploded_at = None;
    for k in 0..300 {
        w.step();
        if w.body(&id).is_none() {
            exploded_at = Some(k);
            break;
        }
    }
    let k = exploded_at.expect("the dye pack never reached the hero");
    assert!(k < 299, "it exploded, not expired");
    assert_eq!(w.emitters().len(), 1, "an explosion emitter started");
    let mut total = w.particles().len();
    while !w.emitters().is_empty() {
        let before = w.particles().len();
        w.step();
        total += w.particles().len().saturating_sub(before);
    }
    assert!(total >= 150, "the explosion made {total} particles");
}

#[test]
fn a_dye_pack_that_never_reaches_the_hero_expires_after_300_updates() {
    let mut w = scene(
        r#"
[[body]]
id = "hero"
group = "hero"
behavior = "hero"
shape = "rect"
size = [16, 22]
pos = [100, 100]
mass = 0
"#,
    );
    let id = w
        .apply(&Action::FireDyePack {
            at: [-1000.0, 100.0],
        })
        .unwrap()
        .ids
        .remove(0);
    w.step_n(299);
    assert!(w.body(&id).is_some());
    w.step();
    assert!(w.body(&id).is_none());
    assert!(w.emitters().is_empty(), "an expired pack does not explode");
}

#[test]
fn an_emitter_releases_exactly_its_count_and_its_particles_expire() {
    let mut w = scene(
        r#"
[[emitter]]
preset = "fire"
count = 200
pos = [100, 60]
"#,
    );
    let mut released = 0;
    let mut steps = 0;
    while !w.emitters().is_empty() {
        let before = w.particles().len();
        let old_lives: Vec<f32> = w.particles().life.clone();
        w.step();
        steps += 1;
        // Fire lives at least 30 updates: nothing expires during the first emissions.
        let expired = old_lives.iter().filter(|&&l| l - 1.0 < 0.0).count();
        released += w.particles().len() + expired - before;
    }
    assert_eq!(released, 200);
    assert!(steps > 5, "emission spreads over updates ({steps})");
    // Fire lives under 230 updates: all gone after 231 more.
    w.step_n(231);
    assert_eq!(w.particles().len(), 0);
}

#[test]
fn particles_collide_with_the_shapes_of_their_interactions() {
    let mut w = scene(
        r#"
[world]
particle_gravity = [0, -50]
[[body]]
id = "floor"
group = "platforms"
shape = "rect"
size = [200, 4]
pos = [100, 0]
mass = 0
[[particle]]
pos = [100, 10]
life = 600
[[interact]]
a = "particles"
b = "platforms"
"#,
    );
    w.step_n(300);
    let y = w.particles().y[0];
    assert!(
        (y - 2.0).abs() < 1e-4,
        "particle should rest on the floor top, at {y}"
    );
}

#[test]
fn dumb_minions_spawn_get_selected_dragged_agitated_and_cleared() {
    let mut w = asset("impulse.toml");
    let mut ids = Vec::new();
    for k in 0..6 {
        let out = w
            .apply(&Action::SpawnDumbMinion {
                at: [80.0 + 20.0 * k as f64, 60.0],
            })
            .unwrap();
        ids.extend(out.ids);
    }
    assert_eq!(ids.len(), 6);
    for id in &ids {
        assert!(matches!(w.info(id).unwrap().behavior, Behavior::DumbMinion));
    }
    w.step_n(240);
    // They settle on platforms: nothing fell out of the world or blew up.
    for id in &ids {
        let b = body(&w, id);
        assert!(
            b.pos.y > 0.0 && b.pos.y < 112.0 && b.pos.is_finite(),
            "{id} at {}",
            b.pos
        );
    }
    let target = body(&w, &ids[2]).pos;
    let sel = w
        .apply(&Action::Select {
            at: target.into(),
            group: Some("dumb_minions".into()),
        })
        .unwrap();
    assert_eq!(sel.ids, vec![ids[2].clone()]);
    w.apply(&Action::Drag { to: [100.0, 90.0] }).unwrap();
    assert_eq!(body(&w, &ids[2]).pos, DVec2::new(100.0, 90.0));
    let kicked = w.apply(&Action::Agitate { strength: None }).unwrap();
    assert_eq!(kicked.ids.len(), 6);
    w.step_n(600);
    for id in &ids {
        assert!(body(&w, id).pos.is_finite());
    }
    let cleared = w
        .apply(&Action::Clear {
            group: "dumb_minions".into(),
        })
        .unwrap();
    assert_eq!(cleared.ids.len(), 6);
    assert!(ids.iter().all(|id| w.body(id).is_none()));
    assert_eq!(w.selected(), None);
    w.step();
}

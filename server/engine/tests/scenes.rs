//! Scene files: defaults, generators, and bad scenes refused with file, line and field.

use std::path::Path;

use glam::DVec2;
use ricochet_engine::geometry::Shape;
use ricochet_engine::scene::{self, SceneError};

fn parse(text: &str) -> Result<ricochet_engine::world::World, SceneError> {
    scene::parse(text, Path::new("bad.toml"), &[])
}

/// Asserts the scene is refused at `line` for `field`, with `needle` in the message.
fn refused(text: &str, line: usize, field: &str, needle: &str) {
    let e = parse(text)
        .err()
        .unwrap_or_else(|| panic!("accepted:\n{text}"));
    assert_eq!(e.file, Path::new("bad.toml"));
    assert_eq!((e.line, e.field.as_str()), (line, field), "{e}");
    assert!(
        e.message.contains(needle),
        "`{}` should contain `{needle}`",
        e.message
    );
    let shown = e.to_string();
    assert!(
        shown.starts_with(&format!("bad.toml:{line}: {field}")),
        "{shown}"
    );
}

#[test]
fn left_out_fields_take_the_chapters_defaults() {
    let w = parse("[[body]]\nid = \"b\"\nshape = \"circle\"\nradius = 2\n").unwrap();
    let b = w.body("b").unwrap();
    assert_eq!((b.inv_mass, b.restitution, b.friction), (1.0, 0.8, 0.3));
    assert_eq!(w.config.relaxation_iterations, 15);
    assert_eq!(w.config.gravity, DVec2::new(0.0, -50.0));
    assert_eq!(b.shape, Shape::circle(2.0));
}

#[test]
fn generators_name_their_bodies_after_themselves() {
    let w = parse(
        r#"
[[generate]]
kind = "pyramid"
id = "p"
shape = "rect"
size = [2, 1]
base = [10, 0]
levels = 3
gap = 0.5
"#,
    )
    .unwrap();
    let ids: Vec<&str> = w.infos().iter().map(|b| b.id.as_str()).collect();
    assert_eq!(ids, ["p/0", "p/1", "p/2", "p/3", "p/4", "p/5"]);
    // Bottom row of 3 centred on x = 10, 2.5 apart; the top one at the centre.
    assert_eq!(w.body("p/0").unwrap().pos, DVec2::new(7.5, 0.5));
    assert_eq!(w.body("p/2").unwrap().pos, DVec2::new(12.5, 0.5));
    assert_eq!(w.body("p/5").unwrap().pos, DVec2::new(10.0, 3.5));
}

#[test]
fn overrides_apply_after_the_file() {
    let w = scene::parse(
        "[world]\nrelaxation_iterations = 4\n",
        Path::new("s.toml"),
        &["relaxation_iterations=30".into(), "gravity=[0,-10]".into()],
    )
    .unwrap();
    assert_eq!(w.config.relaxation_iterations, 30);
    assert_eq!(w.config.gravity, DVec2::new(0.0, -10.0));
    let e = scene::parse("", Path::new("s.toml"), &["dt=-1".into()])
        .err()
        .unwrap();
    assert_eq!(e.field, "dt");
}

#[test]
fn a_typo_in_a_field_name_is_refused_at_its_line() {
    refused(
        "[[body]]\nid = \"a\"\nshape = \"rect\"\nsiz = [1, 2]\n",
        4,
        "body[0].siz",
        "unknown field `siz`",
    );
}

#[test]
fn a_value_of_the_wrong_type_is_refused_at_its_line() {
    refused(
        "[world]\nseed = 1\ngravity = \"down\"\n",
        3,
        "world.gravity",
        "invalid type",
    );
}

#[test]
fn a_broken_file_is_refused_at_its_line() {
    refused("[world]\ndt = 0.01\n\n[[body]\nid = 1\n", 4, "[[body]", "");
}

#[test]
fn bad_numbers_are_refused_with_the_field_at_fault() {
    refused(
        "[world]\nseed = 1\ndt = 0\n",
        3,
        "world.dt",
        "from 0.00001 to 1",
    );
    refused(
        "[[body]]\nid = \"a\"\nshape = \"circle\"\nradius = -1\n",
        4,
        "body[0].radius",
        "above 0",
    );
    refused(
        "[[body]]\nid = \"a\"\nshape = \"rect\"\nsize = [1, 1]\n\n[[body]]\nid = \"b\"\nshape = \"rect\"\nsize = [1, 1]\nmass = -3\n",
        10,
        "body[1].mass",
        "-3",
    );
    refused(
        "[[body]]\nid = \"a\"\nshape = \"rect\"\nsize = [1, 1]\npos = [nan, 0]\n",
        5,
        "body[0].pos",
        "finite",
    );
    refused(
        "[[body]]\nid = \"a\"\nshape = \"rect\"\nsize = [1e300, 1]\n",
        4,
        "body[0].size",
        "at most",
    );
}

#[test]
fn a_missing_shape_size_is_refused_at_the_table() {
    refused(
        "[world]\nseed = 2\n\n[[body]]\nid = \"a\"\nshape = \"rect\"\n",
        4,
        "body[0].size",
        "size = [width, height]",
    );
}

#[test]
fn duplicate_ids_unknown_presets_and_particle_pairs_are_refused() {
    refused(
        "[[body]]\nid = \"a\"\nshape = \"circle\"\nradius = 1\n[[body]]\nid = \"a\"\nshape = \"circle\"\nradius = 1\n",
        6,
        "body[1].id",
        "already exists",
    );
    refused(
        "[[emitter]]\npreset = \"smoke\"\ncount = 3\npos = [0, 0]\n",
        2,
        "emitter[0].preset",
        "smoke",
    );
    refused(
        "[[interact]]\na = \"particles\"\nb = \"particles\"\n",
        3,
        "interact[0].b",
        "each other",
    );
    refused(
        "[[particle]]\npos = [0, 0]\nlife = -4\n",
        3,
        "particle[0].life",
        "0 or more",
    );
}

#[test]
fn an_unreadable_file_is_named() {
    let e = scene::load(Path::new("/nonexistent/scene.toml"))
        .err()
        .unwrap();
    assert_eq!(e.file, Path::new("/nonexistent/scene.toml"));
    assert_eq!(e.field, "file");
}

#[test]
fn inline_presets_add_to_the_built_in_ones() {
    let w = parse(
        r#"
[preset.spark]
life = 10
color = [1, 1, 0, 1]
final_color = [1, 1, 0, 0]
size = { base = 1, rand = [1] }
size_delta = 1
vel = [0, { base = 5, rand = [5] }]
drag = 1

[[emitter]]
preset = "spark"
count = 10
pos = [0, 0]
"#,
    )
    .unwrap();
    assert!(w.presets().get("spark").is_some() && w.presets().get("fire").is_some());
    assert_eq!(w.emitters().len(), 1);
}

#[test]
fn a_scene_over_its_limits_is_refused_at_the_field_that_asks_too_much() {
    let pile = "[limits]\nbodies = 10\n\n[[generate]]\nkind = \"stack\"\nid = \"s\"\nshape = \"rect\"\nsize = [1, 1]\ncount = 11\n";
    refused(pile, 9, "generate[0].count", "limits.bodies");
    assert!(scene::parse(
        &pile.replace("count = 11", "count = 10"),
        Path::new("t.toml"),
        &[]
    )
    .is_ok());
    // A scene may lower a limit, never raise it above the runner's.
    refused("[limits]\nbodies = 1e12\n", 2, "limits.bodies", "");
    refused(
        "[limits]\nbodies = 200000\n",
        2,
        "limits.bodies",
        "may only lower",
    );
    refused("[limits]\nnope = 3\n", 2, "limits.nope", "unknown");
    // Emitters and presets count against theirs.
    refused(
        "[limits]\nparticles = 100\n\n[[emitter]]\npreset = \"fire\"\ncount = 101\npos = [0, 0]\n",
        6,
        "emitter[0].count",
        "limits.particles",
    );
    refused(
        "[limits]\nrand_terms = 2\n\n[preset.spark]\nlife = { base = 1, rand = [1, 2, 3] }\ncolor = [1, 1, 1, 1]\nfinal_color = [1, 1, 1, 1]\nsize = 1\nsize_delta = 1\nvel = [0, 0]\ndrag = 1\n",
        4,
        "preset.spark.rand",
        "3 random terms",
    );
}

#[test]
fn a_scene_whose_step_would_cost_more_than_its_work_limit_is_refused() {
    let pile = |broad_phase: &str| {
        format!(
            "[world]\nbroad_phase = \"{broad_phase}\"\n\n[limits]\nstep_work = 1e6\n\n[[generate]]\nkind = \"grid\"\nid = \"g\"\ngroup = \"g\"\nshape = \"rect\"\nsize = [1, 1]\ncols = 50\nrows = 50\n\n[[interact]]\na = \"g\"\nb = \"g\"\n"
        )
    };
    // 2 500 bodies: all pairs is 3.1e6 tests times 15 passes; the sweep a few per body.
    let e = scene::parse(&pile("all_pairs"), Path::new("t.toml"), &[]).unwrap_err();
    assert_eq!(e.field, "world.solver");
    assert!(e.message.contains("step_work"), "{e}");
    scene::parse(&pile("sweep"), Path::new("t.toml"), &[]).unwrap();
}

/// A file that is not a scene (a secret, a journal, another tool's config) named as one:
/// the error names the file, the line and a field or `scene`, never its text.
#[test]
fn a_refusal_never_quotes_the_files_text() {
    for (text, secret) in [
        (
            "{\n  \"user\": \"admin\",\n  \"password\": \"hunter2-secret\"\n}\n",
            "hunter2",
        ),
        ("password hunter2-secret\n", "hunter2"),
        ("[world]\ndt = \"hunter2-secret\"\n", "hunter2"),
        ("[world]\ngravity = [0, \"hunter2-secret\"]\n", "hunter2"),
        (
            "[[body]]\nid = 'x'\nshape = \"hunter2-secret\"\n",
            "hunter2",
        ),
    ] {
        let e = scene::parse(text, Path::new("secrets.json"), &[]).unwrap_err();
        let shown = e.to_string();
        assert!(!shown.contains(secret), "{shown}");
        assert!(shown.starts_with("secrets.json:"), "{shown}");
        assert!(e.line >= 1, "{shown}");
    }
}

/// A ball over the ground, and an interaction between them named by `b`.
fn ball_over_ground(groups: &str, b: &str) -> String {
    format!(
        r#"{groups}
[[body]]
id = "ground"
group = "ground"
shape = "rect"
size = [40, 2]
pos = [0, -1]
mass = 0

[[body]]
id = "ball"
group = "ball"
shape = "circle"
radius = 1
pos = [0, 10]

[[interact]]
a = "ball"
b = "{b}"
"#
    )
}

#[test]
fn an_interaction_naming_a_group_no_body_is_in_is_refused() {
    let text = ball_over_ground("", "grund");
    let e = parse(&text).unwrap_err();
    let line = text.lines().position(|l| l == "b = \"grund\"").unwrap() + 1;
    assert_eq!(
        (e.line, e.column, e.field.as_str()),
        (line, 5, "interact[0].b"),
        "{e}"
    );
    assert!(e.message.contains("`grund`"), "{e}");
    assert_eq!(e.help(), Some("did you mean `ground`?"));
    // The same name listed as a group joined at run time loads; the right name keeps
    // the ball on the ground.
    parse(&ball_over_ground("groups = [\"grund\"]", "grund")).unwrap();
    let mut w = parse(&ball_over_ground("", "ground")).unwrap();
    for _ in 0..120 {
        w.step();
    }
    assert!(w.body("ball").unwrap().pos.y > 0.5, "fell through");
    // `particles` names the particle side, and needs no body.
    parse(&ball_over_ground("", "particles")).unwrap();
    let e = parse(&ball_over_ground("", "bal")).unwrap_err();
    assert_eq!(e.help(), Some("did you mean `ball`?"));
    let e = parse(&ball_over_ground("", "nothing-near")).unwrap_err();
    assert!(e.help().unwrap().contains("groups = ["));
}

#[test]
fn the_local_report_shows_the_value_with_a_caret_and_a_suggestion() {
    let text = "[[body]]\nid = \"a\"\nshape = \"rec\"\nsize = [1, 2]\n";
    let e = parse(text).unwrap_err();
    assert_eq!(
        (e.line, e.column, e.field.as_str()),
        (3, 9, "body[0].shape")
    );
    // The short form, as a network client gets it, quotes no value of the file.
    assert!(!e.to_string().contains("rec`"), "{e}");
    let report = e.report(text);
    for needle in [
        "bad.toml:3:9",
        "shape = \"rec\"",
        "^^^^^",
        "unknown variant `rec`",
        "help: did you mean `rect`?",
    ] {
        assert!(report.contains(needle), "`{needle}` missing from\n{report}");
    }
    // The user's own value, shown in their own report.
    let text = "[[body]]\nshape = \"circle\"\nradius = \"big\"\n";
    let e = parse(text).unwrap_err();
    assert!(!e.to_string().contains("big"), "{e}");
    assert!(
        e.report(text).contains("string \"big\""),
        "{}",
        e.report(text)
    );
}

#[test]
fn a_typo_keeps_its_table_and_gets_a_suggestion() {
    let text =
        "[[body]]\nshape = \"circle\"\nradius = 1\n\n[[body]]\nshape = \"rect\"\nsiz = [1, 2]\n";
    let e = parse(text).unwrap_err();
    assert_eq!((e.line, e.field.as_str()), (7, "body[1].siz"), "{e}");
    assert_eq!(e.help(), Some("did you mean `size`?"));
    // Every `[world]` field in the local report; the short form is cut.
    let text = "[world]\ngravty = [0, -10]\n";
    let e = parse(text).unwrap_err();
    assert_eq!(e.field, "world.gravty");
    assert_eq!(e.help(), Some("did you mean `gravity`?"));
    assert!(e.message.len() <= 310, "{}", e.message);
    let report = e.report(text);
    assert!(report.contains("`accuracy`"), "{report}");
    assert!(!e.to_string().contains("accuracy"), "{e}");
}

#[test]
fn a_syntax_error_reads_on_one_line() {
    let text = "[world]\ndt = 0.01\n\n[[body]\nid = 1\n";
    let e = parse(text).unwrap_err();
    assert!(!e.message.contains("\\n"), "{e}");
    assert!(!e.message.contains('\n'), "{e}");
    assert!(e.report(text).contains("[[body]"), "{}", e.report(text));
}

/// Names reach `info` replies, frames and viewers' labels: an escape sequence or a newline
/// in one (sent by `load text=`) would be read there as something else than a name.
#[test]
fn names_with_control_characters_are_refused_naming_the_field() {
    let body = |id: &str, group: &str| {
        format!("[[body]]\nid = \"{id}\"\ngroup = \"{group}\"\nshape = \"rect\"\nsize = [1, 1]\n")
    };
    refused(&body("a", "red\\u001b[2J"), 3, "body[0].group", "U+001B");
    refused(&body("a\\nb", "boxes"), 2, "body[0].id", "U+000A");
    refused(
        "[[generate]]\nkind = \"row\"\nid = \"row\"\ngroup = \"x\\ty\"\nshape = \"rect\"\nsize = [1, 1]\ncount = 2\n",
        4,
        "generate[0].group",
        "U+0009",
    );
    refused(
        &(body("a", "boxes") + "[[interact]]\na = \"boxes\"\nb = \"\\u0007\"\n"),
        8,
        "interact[0].b",
        "U+0007",
    );
    // Any other character is a name: accents, symbols, emoji.
    assert!(parse(&body("é/1", "boîtes ✓")).is_ok());
}

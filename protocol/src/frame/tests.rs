//! The codec, encoder to decoder: deltas, key frames, resync, statics and garbage.

use super::*;

/// Seconds a frame stands for in these tests.
const DT: f64 = 1.0 / 60.0;

fn body(key: u32, id: &str, pos: [f64; 2]) -> BodyIn<'_> {
    BodyIn {
        key,
        id,
        group: "g",
        circle: key.is_multiple_of(2),
        size: [2.0, 3.0],
        pos,
        vel: [0.0, 0.0],
        collided: false,
    }
}

#[derive(Default)]
struct Cloud {
    id: Vec<u32>,
    x: Vec<f32>,
    y: Vec<f32>,
    vx: Vec<f32>,
    vy: Vec<f32>,
    ax: Vec<f32>,
    ay: Vec<f32>,
    drag: Vec<f32>,
    life: Vec<f32>,
    initial_life: Vec<f32>,
    size: Vec<f32>,
    size_delta: Vec<f32>,
    color: Vec<[f32; 4]>,
    color_delta: Vec<[f32; 4]>,
}

impl Cloud {
    fn push(&mut self, id: u32, x: f32, y: f32) {
        self.id.push(id);
        self.x.push(x);
        self.y.push(y);
        self.vx.push(0.0);
        self.vy.push(0.0);
        self.ax.push(0.0);
        self.ay.push(0.0);
        self.drag.push(1.0);
        self.life.push(10.0);
        self.initial_life.push(10.0);
        self.size.push(2.0);
        self.size_delta.push(0.5);
        self.color.push([1.0, 0.0, 0.0, 1.0]);
        self.color_delta.push([0.3, 0.0, 0.0, -0.05]);
    }
    fn view(&self) -> ParticlesIn<'_> {
        ParticlesIn {
            id: &self.id,
            x: &self.x,
            y: &self.y,
            vx: &self.vx,
            vy: &self.vy,
            ax: &self.ax,
            ay: &self.ay,
            drag: &self.drag,
            life: &self.life,
            initial_life: &self.initial_life,
            size: &self.size,
            size_delta: &self.size_delta,
            color: &self.color,
            color_delta: &self.color_delta,
        }
    }
}

#[test]
fn deltas_rebuild_the_state_and_resting_things_cost_next_to_nothing() {
    let mut enc = FrameEncoder::new(60);
    let mut dec = FrameDecoder::new();
    let mut cloud = Cloud::default();
    cloud.push(3, 10.0, 20.0);
    cloud.push(7, 11.0, 21.0);
    let bodies = [
        body(0, "a", [1.0, 2.0]),
        body(1, "b", [5.0, 5.0]),
        body(4, "c", [9.0, 9.0]),
    ];
    let f0 = enc.encode(
        0,
        0.0,
        DT,
        &FrameStats::default(),
        &[],
        &bodies,
        &cloud.view(),
    );
    assert_eq!(dec.apply(&f0).unwrap().kind, KIND_KEY);
    assert_eq!(dec.bodies.len(), 3);
    assert_eq!(dec.body("c").unwrap().pos(), [9.0, 9.0]);
    assert_eq!(dec.particles.len(), 2);

    // Nothing changes: a delta frame of the header, three empty sections and the motion
    // of three bodies at rest, in no bytes at all (the coder's last value is 0).
    let f1 = enc.encode(
        1,
        0.1,
        DT,
        &FrameStats::default(),
        &[],
        &bodies,
        &cloud.view(),
    );
    assert_eq!(f1.len(), HEADER_BYTES + 4);
    dec.apply(&f1).unwrap();

    // b moves, a is removed, d is new; particle 3 moves, 7 expires, 9 is born.
    let moved = [
        body(1, "b", [5.5, 5.0]),
        body(4, "c", [9.0, 9.0]),
        body(6, "d", [0.0, 0.0]),
    ];
    let mut cloud2 = Cloud::default();
    cloud2.push(3, 10.5, 20.0);
    cloud2.push(9, 0.0, 0.0);
    let f2 = enc.encode(
        2,
        0.2,
        DT,
        &FrameStats::default(),
        &[EmitterIn {
            x: 1.0,
            y: 2.0,
            remaining: 7,
        }],
        &moved,
        &cloud2.view(),
    );
    dec.apply(&f2).unwrap();
    let ids: Vec<&str> = dec.bodies.iter().map(|b| b.id.as_str()).collect();
    assert_eq!(ids, ["b", "c", "d"]);
    assert_eq!(dec.body("b").unwrap().pos(), [5.5, 5.0]);
    assert_eq!(
        dec.particles.iter().map(|p| p.id).collect::<Vec<_>>(),
        [3, 9]
    );
    assert_eq!(dec.particles[0].pos(), [10.5, 20.0]);
    assert_eq!(
        dec.emitters,
        [EmitterIn {
            x: 1.0,
            y: 2.0,
            remaining: 7
        }]
    );
}

#[test]
fn particle_colour_and_size_follow_from_the_birth_record() {
    let mut enc = FrameEncoder::new(60);
    let mut dec = FrameDecoder::new();
    let mut cloud = Cloud::default();
    cloud.push(1, 0.0, 0.0);
    cloud.life[0] = 6.0; // born 4 updates ago
    cloud.size[0] = 2.0;
    dec.apply(&enc.encode(
        100,
        0.0,
        DT,
        &FrameStats::default(),
        &[],
        &[],
        &cloud.view(),
    ))
    .unwrap();
    let p = &dec.particles[0];
    // Colour at frame 100 = start + delta * age(4); final = start + delta * 10.
    let c = p.color_at(100);
    assert!(
        (c[0] - 2.2).abs() < 0.02 && (c[3] - 0.8).abs() < 0.02,
        "{c:?}"
    );
    let c = p.color_at(106);
    assert!(
        (c[0] - 4.0).abs() < 0.02 && (c[3] - 0.5).abs() < 0.02,
        "{c:?}"
    );
    assert_eq!(p.size_at(102), 0.5);
}

#[test]
fn a_missed_frame_waits_for_the_next_key_frame() {
    let mut enc = FrameEncoder::new(3);
    let mut dec = FrameDecoder::new();
    let cloud = Cloud::default();
    let frames: Vec<Vec<u8>> = (0..7)
        .map(|k| {
            enc.encode(
                k,
                0.0,
                DT,
                &FrameStats::default(),
                &[],
                &[body(0, "a", [k as f64, 0.0])],
                &cloud.view(),
            )
        })
        .collect();
    let kinds: Vec<u8> = frames
        .iter()
        .map(|f| peek_header(f).unwrap().kind)
        .collect();
    assert_eq!(
        kinds,
        [KIND_KEY, KIND_DELTA, KIND_DELTA, KIND_KEY, KIND_DELTA, KIND_DELTA, KIND_KEY]
    );
    dec.apply(&frames[0]).unwrap();
    // Frame 1 is lost: frame 2 is refused, frame 3 (key) resynchronises.
    assert_eq!(
        dec.apply(&frames[2]),
        Err(DecodeError::OutOfSync {
            held: 0,
            follows: 1
        })
    );
    assert!(!dec.synced);
    dec.apply(&frames[3]).unwrap();
    dec.apply(&frames[4]).unwrap();
    assert_eq!(dec.body("a").unwrap().pos(), [4.0, 0.0]);
}

#[test]
fn a_late_joiner_resyncs_from_the_encoders_state_and_follows_the_deltas() {
    let mut enc = FrameEncoder::new(1000);
    let mut early = FrameDecoder::new();
    let mut cloud = Cloud::default();
    cloud.push(1, 0.0, 0.0);
    assert!(enc.resync_frame().is_none());
    let mut frames = Vec::new();
    for k in 0..10u64 {
        cloud.x[0] = k as f32;
        cloud.life[0] = 10.0 - k as f32;
        cloud.size[0] = 2.0 * 0.5f32.powi(k as i32);
        frames.push(enc.encode(
            k,
            k as f64,
            DT,
            &FrameStats::default(),
            &[],
            &[body(0, "a", [k as f64, 1.0])],
            &cloud.view(),
        ));
        early.apply(frames.last().unwrap()).unwrap();
    }
    // Joining after frame 9: the resync frame, then frame 9 again (stale) is ignored.
    let mut late = FrameDecoder::new();
    late.apply(&enc.resync_frame().unwrap()).unwrap();
    assert_eq!(late.apply(&frames[9]), Err(DecodeError::Stale { frame: 9 }));
    assert_eq!(late.apply(&frames[8]), Err(DecodeError::Stale { frame: 8 }));
    assert!(late.synced);
    cloud.x[0] = 10.0;
    let next = enc.encode(
        10,
        10.0,
        DT,
        &FrameStats::default(),
        &[],
        &[body(0, "a", [10.0, 1.0])],
        &cloud.view(),
    );
    early.apply(&next).unwrap();
    late.apply(&next).unwrap();
    assert_eq!(late.bodies, early.bodies);
    assert_eq!(late.particles[0].pos, early.particles[0].pos);
    assert_eq!(
        late.particles[0].color_at(10),
        early.particles[0].color_at(10)
    );
    assert_eq!(
        late.particles[0].size_at(10),
        early.particles[0].size_at(10)
    );
}

#[test]
fn statics_are_a_snapshot_of_their_own() {
    let statics = [body(2, "floor", [0.0, 0.0]), body(5, "wall", [100.0, 50.0])];
    let snap = encode_statics(12, 0.2, &statics);
    let mut dec = FrameDecoder::new();
    assert_eq!(dec.apply(&snap).unwrap().kind, KIND_STATICS);
    assert_eq!(dec.statics.len(), 2);
    assert_eq!(dec.body("wall").unwrap().pos(), [100.0, 50.0]);
    assert!(dec.bodies.is_empty());
}

#[test]
fn garbage_is_refused_without_panicking() {
    let mut dec = FrameDecoder::new();
    let good = FrameEncoder::new(1).encode(
        0,
        0.0,
        DT,
        &FrameStats::default(),
        &[],
        &[body(0, "a", [1.0, 1.0])],
        &Cloud::default().view(),
    );
    for cut in 0..good.len() {
        assert!(
            dec.apply(&good[..cut]).is_err(),
            "a frame cut at {cut} was accepted"
        );
    }
    let mut bad_version = good.clone();
    bad_version[3] = 9;
    assert_eq!(dec.apply(&bad_version), Err(DecodeError::Version(9)));
    let mut huge_count = good[..HEADER_BYTES].to_vec();
    huge_count.extend_from_slice(&[0xff, 0xff, 0xff, 0xff, 0x0f]);
    assert!(matches!(
        dec.apply(&huge_count),
        Err(DecodeError::Malformed(_))
    ));
    dec.apply(&good).unwrap();
}

#[test]
fn a_delta_refused_at_its_end_changes_no_body_it_read_before() {
    // Bodies are patched in place once a delta has been read whole: a delta cut short in
    // its particle section, after its body records were read, leaves every body as it was,
    // whether the delta only moves bodies or also adds and removes some.
    let mut enc = FrameEncoder::new(60);
    let mut dec = FrameDecoder::new();
    let mut cloud = Cloud::default();
    cloud.push(3, 10.0, 20.0);
    let bodies = [body(0, "a", [1.0, 2.0]), body(1, "b", [5.0, 5.0])];
    let f0 = enc.encode(
        0,
        0.0,
        DT,
        &FrameStats::default(),
        &[],
        &bodies,
        &cloud.view(),
    );
    dec.apply(&f0).unwrap();
    let moved = [body(0, "a", [1.5, 2.0]), body(1, "b", [5.0, 4.0])];
    let changed = [body(1, "b", [5.0, 4.0]), body(2, "new", [7.0, 7.0])];
    cloud.x[0] = 10.5;
    for (frame, now) in [(1, &moved[..]), (1, &changed[..])] {
        let mut enc = enc.clone();
        let delta = enc.encode(
            frame,
            0.1,
            DT,
            &FrameStats::default(),
            &[],
            now,
            &cloud.view(),
        );
        let before = (dec.bodies.clone(), dec.particles.clone(), dec.frame);
        assert!(dec.clone().apply(&delta).is_ok(), "the whole delta applies");
        assert!(dec.apply(&delta[..delta.len() - 1]).is_err());
        assert_eq!(
            (dec.bodies.clone(), dec.particles.clone(), dec.frame),
            before
        );
    }
}

/// A ball's truth at 60 frames a second: thrown up, falling, bouncing on a floor at 0
/// with restitution 0.5, then sliding to rest (symplectic Euler, as the engine steps).
fn thrown_ball(frames: u64) -> Vec<[f64; 2]> {
    let (mut p, mut v) = ([0.0f64, 10.0], [3.0f64, 4.0]);
    let mut out = vec![p];
    for _ in 1..frames {
        v[1] -= 9.8 * DT;
        if p[1] == 0.0 && v[1] < 0.0 {
            v[1] = 0.0;
            v[0] = (v[0] - 2.0 * DT).max(0.0);
        }
        p = [p[0] + v[0] * DT, p[1] + v[1] * DT];
        if p[1] < 0.0 {
            p[1] = 0.0;
            v[1] = if -v[1] * 0.5 < 0.5 { 0.0 } else { -v[1] * 0.5 };
        }
        out.push(p);
    }
    out
}

/// Frame `k` of a world of the one body `b` and no particles.
fn body_frame(enc: &mut FrameEncoder, k: usize, b: BodyIn) -> Vec<u8> {
    let cloud = Cloud::default();
    enc.encode(
        k as u64,
        k as f64 * DT,
        DT,
        &FrameStats::default(),
        &[],
        &[b],
        &cloud.view(),
    )
}

/// The bytes of a one-body delta frame's motion.
fn motion_bytes(f: &[u8]) -> usize {
    // Header, the emitters' count, the bodies' count, the motion's length, the particles'.
    f.len() - (HEADER_BYTES + 4)
}

#[test]
fn a_receiver_stays_within_the_stated_bound_and_rest_costs_next_to_nothing() {
    let truth = thrown_ball(600);
    let mut enc = FrameEncoder::new(10_000);
    let mut dec = FrameDecoder::new();
    let mut motion = Vec::new();
    for (k, p) in truth.iter().enumerate() {
        let mut b = body(0, "ball", *p);
        b.vel = [3.0, 4.0];
        let f = body_frame(&mut enc, k, b);
        dec.apply(&f).unwrap();
        if k > 0 {
            motion.push(motion_bytes(&f));
        }
        let got = dec.body("ball").unwrap();
        for i in 0..2 {
            let off = (got.pos()[i] - p[i]).abs();
            assert!(off <= POS_BOUND + FINE, "frame {k}: position off by {off}");
            if k > 0 {
                let disp = p[i] - truth[k - 1][i];
                let off = (got.vel()[i] * DT - disp).abs();
                assert!(
                    off <= 2.0 * POS_BOUND + 2.0 * FINE,
                    "frame {k}: displacement off by {off}"
                );
            }
        }
    }
    let still = (1..truth.len())
        .rfind(|&k| truth[k] != truth[k - 1])
        .unwrap()
        + 1;
    assert!(still < 560, "the ball rests from frame {still}");
    // At rest its motion is one byte a frame, or none.
    let resting = &motion[still + 1..];
    assert!(resting.iter().all(|&n| n <= 1), "at rest: {resting:?}");
    // In flight (before the first landing, near frame 114), at most 2 bytes a frame: the
    // residual of gravity, which the prediction leaves out, alone.
    let flying = &motion[3..110];
    assert!(flying.iter().all(|&n| n <= 2), "in flight: {flying:?}");
}

/// A key frame that is not the stream's (another encoder's, numbered far ahead or back)
/// applies, but the stream's next delta follows the state before it: that state comes
/// back, the key frame is dropped and counted, and the receiver stays in sync with the
/// stream, bit for bit with one that never saw it. The stream's own key frames are kept.
#[test]
fn a_key_frame_the_stream_does_not_follow_is_dropped_at_the_next_delta() {
    let cloud = Cloud::default();
    let stream = |frames: std::ops::Range<u64>, shift: f64| -> Vec<Vec<u8>> {
        let mut enc = FrameEncoder::new(5);
        frames
            .map(|k| {
                let x = k as f64 * 0.25 + shift;
                enc.encode(
                    k,
                    k as f64 * DT,
                    DT,
                    &FrameStats::default(),
                    &[],
                    &[body(0, "a", [x, 1.0]), body(1, "b", [x, 3.0])],
                    &cloud.view(),
                )
            })
            .collect()
    };
    let real = stream(0..20, 0.0);
    let ahead = stream(1 << 62..(1 << 62) + 1, 50.0).remove(0);
    let back = stream(2..3, -50.0).remove(0);
    let mut clean = FrameDecoder::new();
    let mut dec = FrameDecoder::new();
    for (k, frame) in real.iter().enumerate() {
        clean.apply(frame).unwrap();
        if k == 7 || k == 13 {
            // A forged key frame applies at once...
            let forged = if k == 7 { &ahead } else { &back };
            dec.apply(frame).unwrap();
            dec.apply(forged).unwrap();
            assert_ne!(dec.frame, clean.frame);
            continue;
        }
        dec.apply(frame).unwrap();
        // ...and is gone at the stream's next delta.
        assert_eq!(dec.frame, clean.frame, "frame {k}");
        assert_eq!(dec.bodies, clean.bodies, "frame {k}");
        assert!(dec.synced);
    }
    assert_eq!(dec.dropped_key_frames, 2);
    // The stream's own key frames (every fifth) were all kept.
    assert_eq!(clean.dropped_key_frames, 0);
}

/// The motion of bodies moving along x costs what the same motion along y costs: the
/// coder's contexts are the same on either axis.
#[test]
fn the_same_motion_costs_the_same_along_either_axis() {
    let heights: Vec<f64> = thrown_ball(300).iter().map(|p| p[1]).collect();
    let run = |along_y: bool| {
        let mut enc = FrameEncoder::new(10_000);
        let mut dec = FrameDecoder::new();
        let mut bytes = 0;
        for (k, &h) in heights.iter().enumerate() {
            let p = if along_y { [5.0, h] } else { [h, 5.0] };
            let f = body_frame(&mut enc, k, body(0, "ball", p));
            dec.apply(&f).unwrap();
            if k > 0 {
                bytes += motion_bytes(&f);
            }
            let got = dec.body("ball").unwrap().pos();
            for i in 0..2 {
                let off = (got[i] - p[i]).abs();
                assert!(off <= POS_BOUND + FINE, "frame {k}: position off by {off}");
            }
        }
        bytes
    };
    let (y, x) = (run(true), run(false));
    assert!(y > 100, "the fall and the bounces cost bytes: {y}");
    // The first decision of each frame (x's) sits at a different place in the range.
    assert!(x.abs_diff(y) <= y / 20, "along x {x} bytes, along y {y}");
}

#[test]
fn a_key_section_read_alone_refuses_what_a_key_frame_cannot_hold() {
    // One record, id 1, an update (POS): a key frame holds no particle to update.
    let update = [1u8, 1, POS, 2, 2];
    let err = read_key_particles(&update, false, 0).unwrap_err();
    assert!(
        err.to_string().contains("update of unknown particle 1"),
        "{err}"
    );
    // A NEW record cut short, and a count the bytes cannot back.
    assert!(read_key_particles(&[1, 1, NEW, 2], false, 0).is_err());
    assert!(read_key_particles(&[200, 1], false, 0).is_err());
    // Nothing, then bytes left over.
    assert!(read_key_particles(&[0], false, 0).unwrap().is_empty());
    let err = read_key_particles(&[0, 7], false, 0).unwrap_err();
    assert!(err.to_string().contains("1 bytes left over"), "{err}");
}

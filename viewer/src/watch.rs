//! One world's loop: its frames, snapshots and events from zenoh to its [`WorldSink`].
//! Each world watched runs one, on a thread of its own (Rerun keeps the time on the
//! timelines per thread, so worlds at different frames log side by side).
//!
//! Frames are delta-encoded, so every frame that arrives is decoded (cheap); drawing is
//! what costs, so each pass of the loop draws only the newest state (at most `--fps` times
//! a second) and logs the figures of every frame it decoded. When Rerun is slower than the
//! world, frames are skipped, never queued without bound, and the server is never held
//! back: it publishes real-time frames with zenoh's drop congestion control. A gap in the
//! frames (a frame lost on the way) is repaired by asking the server for a key frame of
//! its state now; a new server or a new scene, by fetching statics and state again.

use std::sync::mpsc::SyncSender;
use std::time::{Duration, Instant};

use anyhow::{anyhow, Result};
use ricochet_protocol::client::{parse_event, Client, FrameStream};
use ricochet_protocol::command::WorldInfo;
use ricochet_protocol::frame::{DecodeError, FrameDecoder};

use crate::between::Between;
use crate::drift::FrameSample;
use crate::sink::WorldSink;

/// How often the viewer checks that its statics are from the world's current server and
/// scene.
const SOURCE_CHECK: Duration = Duration::from_secs(2);

/// How every world's loop paces its drawing and when it stops.
#[derive(Clone, Copy, Debug)]
pub struct Pace {
    /// Stop after drawing this many frames.
    pub frames: Option<u64>,
    /// Draw at most once in this long (zero: every frame decoded).
    pub min_draw_interval: Duration,
    /// Stop when no frame has arrived for this long.
    pub idle_exit: Option<Duration>,
}

/// Where a world's loop sends the frames it decodes for the drift plots: its index among
/// the worlds watched, and the channel to the thread that compares them.
pub struct DriftFeed {
    pub world: usize,
    pub samples: SyncSender<(usize, FrameSample)>,
}

impl DriftFeed {
    /// The frame `decoder` holds, as logged by `sink` (a closed channel is ignored: the
    /// comparing thread only stops when the worlds do, or on an error reported there).
    fn send(&self, decoder: &FrameDecoder, sink: &WorldSink) {
        let at = sink.logged_at().unwrap_or((decoder.frame, decoder.time));
        let _ = self
            .samples
            .send((self.world, FrameSample::of(decoder, at)));
    }
}

/// The world's scene generation, if its server answers.
fn info_generation(client: &Client) -> Option<u64> {
    client
        .info(Duration::from_secs(1))
        .ok()
        .map(|i| i.generation)
}

/// What a world's loop did, for the log line at its end.
#[derive(Debug, Default)]
pub struct Tally {
    pub drawn: u64,
    pub skipped: u64,
    pub resyncs: u64,
    pub draw_time: Duration,
}

/// Watches the world of `client` (its first `info` already fetched) into `sink` until
/// `pace` says stop; with a `drift` feed, every frame decoded goes to the comparison too.
pub fn watch(
    client: Client,
    info: WorldInfo,
    mut sink: WorldSink,
    pace: Pace,
    drift: Option<DriftFeed>,
) -> Result<Tally> {
    let Pace {
        frames: frame_limit,
        min_draw_interval,
        idle_exit,
    } = pace;
    sink.set_info(info)?;

    let events = client.events()?;
    let snapshots = client.snapshots()?;
    let (frames, mut decoder) = client.join(Duration::from_secs(5))?;
    // Which server, and which of its scenes, the statics came from: checked every few
    // seconds, so a restarted server or a missed snapshot is caught up with.
    let mut source = (
        client.servers(Duration::from_secs(2))?,
        info_generation(&client),
    );
    let mut last_check = Instant::now();
    // A resync that failed (the server gone, say): retried at most once a second until a
    // key frame or a resync brings the decoder back.
    let mut lost_since: Option<Instant> = None;
    sink.log_statics(&decoder.statics)?;
    // On a reduced-rate stream the state comes with the stream's next key frame.
    if decoder.synced {
        sink.log_stats(decoder.frame, decoder.time, &decoder.stats, 0)?;
        if let Some(feed) = &drift {
            feed.send(&decoder, &sink);
        }
        sink.draw(&decoder)?;
    }

    let mut tally = Tally::default();
    let mut last_frame_at = Instant::now();
    let mut dropped_key_frames: u64 = 0;
    let mut reported_skips = Instant::now();
    // Frames decoded since the last drawing.
    let mut pending = 0u64;
    let mut last_draw = Instant::now();
    // On a reduced-rate stream: the steps between its last two frames, drawn as they come
    // due; and the newest frame, which the next one is interpolated from.
    let mut between: Option<Between> = None;
    let mut newest: Option<FrameDecoder> = None;
    while frame_limit.is_none_or(|n| sink.frames_drawn < n) {
        log_events(&events, &sink)?;
        // A snapshot comes when the statics change or a scene is (re)loaded.
        let mut new_statics = false;
        while let Ok(Some(sample)) = snapshots.try_recv() {
            match decoder.apply(&sample.payload().to_bytes()) {
                Ok(_) => new_statics = true,
                Err(e) => sink.log_note(&format!("unreadable snapshot: {e}"), "WARN")?,
            }
        }
        if last_check.elapsed() >= SOURCE_CHECK {
            last_check = Instant::now();
            let now = (
                client.servers(Duration::from_secs(1)).unwrap_or_default(),
                info_generation(&client),
            );
            if !now.0.is_empty() && now.1.is_some() && now != source {
                // A new server, or a new scene: the statics and state again, from scratch.
                match client.catch_up(Duration::from_secs(2)) {
                    Ok(fresh) => {
                        decoder = fresh;
                        (between, newest) = (None, None);
                        new_statics = true;
                        lost_since = None;
                        let what = if now.0 != source.0 {
                            "the world's server changed (restarted?)"
                        } else {
                            "the world's scene was reloaded"
                        };
                        sink.log_note(
                            &format!(
                                "{what}: statics and state fetched again at frame {}",
                                decoder.frame
                            ),
                            "WARN",
                        )?;
                        source = now;
                    }
                    Err(e) => sink.log_note(
                        &format!("catching up with the server failed, will retry: {e:#}"),
                        "WARN",
                    )?,
                }
            }
        }
        if new_statics {
            if let Ok(info) = client.info(Duration::from_secs(2)) {
                sink.set_info(info)?;
            }
            sink.log_statics(&decoder.statics)?;
        }

        // Between a reduced-rate stream's frames: draw each step as it comes due.
        if let Some(b) = between.as_mut() {
            let now = Instant::now();
            if let Some(step) = b
                .due(now, min_draw_interval.is_zero())
                .filter(|_| last_draw.elapsed() >= min_draw_interval)
            {
                last_draw = now;
                sink.draw_between(&b.draw(step))?;
                tally.draw_time += last_draw.elapsed();
            }
        }
        let wait = between
            .as_ref()
            .and_then(|b| b.wait(Instant::now()))
            .map_or(Duration::from_millis(200), |w| {
                w.max(min_draw_interval.saturating_sub(last_draw.elapsed()))
                    .clamp(Duration::from_millis(1), Duration::from_millis(200))
            });
        let Ok(Some(first)) = frames.recv_timeout(wait) else {
            if idle_exit.is_some_and(|limit| last_frame_at.elapsed() >= limit) {
                sink.log_note("the world stopped sending frames", "WARN")?;
                break;
            }
            continue;
        };
        last_frame_at = Instant::now();
        let mut batch = vec![first];
        while let Ok(Some(sample)) = frames.try_recv() {
            batch.push(sample);
        }
        let mut applied = 0u64;
        for sample in &batch {
            let bytes = sample.payload().to_bytes();
            match decoder.apply(&bytes) {
                Ok(h) => {
                    applied += 1;
                    sink.log_stats(h.frame, h.time, &h.stats, bytes.len())?;
                    if let Some(feed) = &drift {
                        feed.send(&decoder, &sink);
                    }
                    if decoder.dropped_key_frames > dropped_key_frames {
                        dropped_key_frames = decoder.dropped_key_frames;
                        sink.log_note(
                            &format!("a key frame the stream did not follow was dropped ({dropped_key_frames} so far)"),
                            "WARN",
                        )?;
                    }
                }
                Err(DecodeError::Stale { .. }) => {}
                Err(DecodeError::OutOfSync { held, follows }) => {
                    if lost_since.is_some_and(|t| t.elapsed() < Duration::from_secs(1)) {
                        continue;
                    }
                    // A reduced-rate stream is for a slow link: its next key frame
                    // resyncs, not the whole state at once.
                    if client.every() > 1 {
                        continue;
                    }
                    tally.resyncs += 1;
                    let resyncs = tally.resyncs;
                    let resynced = client.state(Duration::from_secs(2)).and_then(|state| {
                        decoder
                            .apply(&state)
                            .map_err(|e| anyhow!("the server's state is unreadable: {e}"))
                    });
                    match resynced {
                        Ok(_) => {
                            lost_since = None;
                            sink.log_note(
                                &format!("frames after {held} up to {follows} lost on the way; resynced at frame {} (resync {resyncs})", decoder.frame),
                                "WARN",
                            )?;
                        }
                        Err(e) => {
                            lost_since = Some(Instant::now());
                            sink.log_note(
                                &format!("frames after {held} up to {follows} lost and the resync failed ({e:#}); waiting for the next key frame"),
                                "WARN",
                            )?;
                        }
                    }
                }
                Err(e) => sink.log_note(&format!("unreadable frame: {e}"), "WARN")?,
            }
        }
        pending += applied;
        if client.every() > 1 && applied > 0 && decoder.synced {
            // A reduced-rate stream's frame: the steps since the last one are drawn as
            // they come due, this frame last (the frame before drawn whole first).
            // A recording (no drawing rate to keep) draws every step: those of the last
            // frame its process was too late for come first.
            if let Some(b) = between.as_mut().filter(|_| min_draw_interval.is_zero()) {
                for d in b.rest() {
                    sink.draw_between(&d)?;
                }
            }
            let before = between.take().map(Between::into_newest).or(newest.take());
            // One copy of the decoder a stream frame: the interpolation's end, or else
            // the next one's start.
            match before {
                Some(from) if Between::spans(&from, &decoder) => {
                    between = Some(Between::new(from, decoder.clone(), Instant::now()));
                    pending = 0;
                    continue;
                }
                _ => newest = Some(decoder.clone()),
            }
        }
        if pending == 0 || last_draw.elapsed() < min_draw_interval {
            continue;
        }
        tally.skipped += pending - 1;
        pending = 0;
        last_draw = Instant::now();
        sink.draw(&decoder)?;
        tally.draw_time += last_draw.elapsed();
        if tally.skipped > 0 && reported_skips.elapsed() >= Duration::from_secs(5) {
            tracing::debug!(
                world = %client.keys().world,
                skipped = tally.skipped,
                "frames decoded but not drawn (the --fps cap, or a slow sink)"
            );
            reported_skips = Instant::now();
        }
    }
    tally.drawn = sink.frames_drawn;
    Ok(tally)
}

/// The commands handled since the last pass, into the text log.
fn log_events(events: &FrameStream, sink: &WorldSink) -> Result<()> {
    while let Ok(Some(sample)) = events.try_recv() {
        match parse_event(&sample) {
            Ok(event) => sink.log_event(&event)?,
            Err(e) => sink.log_note(&format!("unreadable event: {e:#}"), "WARN")?,
        }
    }
    Ok(())
}

//! The authoritative server: hosts one world on zenoh and runs it in real time.
//!
//! The clock is an accumulator of whole steps: step k is due at `start + k dt`, computed
//! from integers of nanoseconds, so it does not drift over hours. Commands that arrived
//! since the last step are applied at the frame boundary, in arrival order per kind
//! (commands and requests taken in turn), each stamped with the frame it took effect in. A
//! step that starts more than one `dt` late is counted as an overrun; after more than
//! [`MAX_CATCH_UP`] late steps the clock is re-anchored (the lost steps are counted, never
//! silently dropped).
//!
//! Nothing a peer does can stall the step: zenoh's threads only queue what arrives
//! ([`inbox`]), replies and events leave from a thread of their own ([`outbox`]), frames
//! and snapshots from another ([`frames_out`]), with `Drop` congestion control, at most
//! [`MAX_COMMANDS_PER_FRAME`] commands, and commands for at most [`boundary_budget`] of
//! wall time, and [`MAX_QUERIES_PER_PASS`] queries are served per pass, and the steps a `step` command asks for run in slices of at most [`STEP_SLICE`],
//! with other clients served between slices.

pub mod answered;
mod apply;
pub mod budget;
mod clock;
pub mod frames_out;
pub mod hosted;
pub mod inbox;
pub mod journal;
pub mod outbox;
pub mod peers;
pub mod price;
pub mod streams;

use std::io::Write;
use std::path::PathBuf;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{anyhow, Context, Result};
use ricochet_engine::world::Limits;
use ricochet_protocol::command::{Event, Health};
use ricochet_protocol::keys::WorldKeys;
use ricochet_protocol::net::Network;
use ricochet_protocol::world as wire;
use zenoh::qos::{CongestionControl, Priority};
use zenoh::Wait;

use answered::Answered;
use apply::{apply_incoming, Deferred};
use budget::{BudgetLimits, Budgets};
use clock::{Clock, Tick};
use frames_out::FramesOut;
use hosted::Hosted;
use inbox::{Ask, Inbox, InboxLimits};
use journal::Journal;
use outbox::Outbox;

pub use hosted::{MAX_PENDING_STEPS, MAX_STEPS_PER_COMMAND};

/// Bytes of a key frame at most, by default: the frames of 160 000 particles or so (the
/// shipped particles-100k scene's take at most 5 MB); a world whose key frames pass it
/// would cost every viewer tens of MB a second and the server their encoding each frame.
pub const DEFAULT_MAX_FRAME_BYTES: u64 = 8 << 20;

/// Late steps run back to back before the clock gives up and re-anchors.
pub const MAX_CATCH_UP: u64 = 5;
/// Commands handled per frame boundary at most; the rest wait for the next one, so a
/// flood cannot stall the clock.
pub const MAX_COMMANDS_PER_FRAME: usize = 1000;
/// Wall time the commands of one frame boundary may take, at most: half the world's step
/// interval, from 2 to 50 ms. Past it the rest wait for the next boundary, so commands whose
/// cost is the whole world (`reset`, `load`, `clear`, `select`, `agitate` in a large world)
/// slow the world's clock by at most one such command a frame instead of stopping it.
pub fn boundary_budget(step_interval: Duration) -> Duration {
    (step_interval / 2).clamp(Duration::from_millis(2), Duration::from_millis(50))
}

/// Queries (state, snapshot, info) answered per pass of the loop at most.
pub const MAX_QUERIES_PER_PASS: usize = 64;
/// Wall time the steps of `step` commands may take before the host serves its other
/// clients again.
pub const STEP_SLICE: Duration = Duration::from_millis(10);
/// How often the host gives the heap's free pages back and logs what it turned away.
pub const TRIM_EVERY: Duration = Duration::from_secs(10);
/// How often, at most, the host publishes an event summing up the fire-and-forget
/// commands its inbox dropped (none when it dropped none).
pub const DROPS_EVERY: Duration = Duration::from_secs(1);
/// How long the server's session waits for a slow peer to take a blocking message (a
/// reply to a query asked with `Block`) before zenoh closes that peer's link: zenoh's
/// default is 5 s. Only the outbox thread ever waits so.
pub const BLOCK_WAIT_BEFORE_CLOSE: Duration = Duration::from_millis(1000);
/// The priority of frames and snapshots. zenoh keeps one queue, behind one lock, per
/// peer and priority: a reply the outbox thread is blocked on for a slow peer (up to
/// [`BLOCK_WAIT_BEFORE_CLOSE`]) holds that lock, and a frame at the replies' priority
/// would wait for it, and every frame queued behind it ([`frames_out`]). Replies and
/// events keep zenoh's default priority (`Data`), ahead of frames on a congested link.
pub const STEP_PRIORITY: Priority = Priority::DataLow;
/// How long a frame split in fragments (a key frame of many particles) may wait in all for
/// room in a peer's queue before zenoh drops it (zenoh's default is 50 ms). Frames leave
/// from a thread of their own ([`frames_out`]), so the wait holds up no step, only the
/// frames queued behind it, to every peer: a slow peer delays the others by at most this
/// much a key frame. With 20 ms the fire's key frames (2 MB) reached eight viewers on
/// loopback, where with 1 ms zenoh dropped those at the fire's peak, and each cost its
/// viewers the frames up to the next key frame (docs/network.md, "Fan-out"); at 1 Gbit/s
/// 2 MB take 16 ms (arithmetic, not measured).
pub const FRAGMENTS_WAIT_BEFORE_DROP: Duration = Duration::from_millis(20);

/// How to host a world.
#[derive(Clone, Debug)]
pub struct HostOptions {
    /// The scene to start from (none when resuming: the journal holds it).
    pub scene: Option<PathBuf>,
    pub world: String,
    pub network: Network,
    /// Start paused (step with commands).
    pub paused: bool,
    /// `NAME=VALUE` overrides of `[world]` fields.
    pub overrides: Vec<String>,
    /// A key frame every this many frames.
    pub keyframe_interval: u64,
    /// Stop after this many frames (for scripted runs); run until killed otherwise.
    pub max_frames: Option<u64>,
    /// Append every published frame to this file as a dump line (full precision, as
    /// `simulate --dump` writes them), flushed each frame.
    pub dump: Option<PathBuf>,
    /// Where `load` finds scenes by name; nothing outside it is read. None: `load` by
    /// name is refused (never the working directory by default).
    pub scenes_dir: Option<PathBuf>,
    /// The limits every world hosted here runs under at most (a scene's `[limits]` may
    /// lower them).
    pub limits: Limits,
    /// Steps per second of wall time at most: a world whose `dt` is shorter runs slower
    /// than real time rather than flooding its viewers.
    pub max_rate: f64,
    /// Bytes of a key frame at most, estimated before a scene or an action that adds
    /// bodies or particles is accepted ([`ricochet_protocol::world::key_frame_bytes`]).
    pub max_frame_bytes: u64,
    /// Per-sender rates and queue bounds (the command size bound is `limits`').
    pub inbox: InboxLimits,
    /// Every claimed sender id keeps buckets of its own, connected or not
    /// ([`peers::Peers::trusting`]; `--sender-ids claimed`).
    pub trust_claimed_senders: bool,
    /// How much of the stepping thread's time commands may take ([`budget`]).
    pub budget: BudgetLimits,
    /// Journal every accepted command and stepped frame to this file ([`journal`]).
    pub journal: Option<PathBuf>,
    /// Rebuild the world from this journal, then go on appending to it.
    pub resume: Option<PathBuf>,
    /// When the journal starts again from a checkpoint of the world ([`journal`]).
    pub checkpoints: journal::Checkpoints,
    /// Run the scene under the cheapest measured setting whose worst position error meets
    /// this (scene units); the scene's `[world] accuracy` if not given ([`crate::accuracy`]).
    pub accuracy: Option<f64>,
    /// Where measures for accuracy targets are cached (the default cache directory if
    /// not given).
    pub accuracy_cache: Option<PathBuf>,
}

impl HostOptions {
    /// A world named `world` with every default and nothing on disk (for tests).
    #[cfg(test)]
    pub(crate) fn for_tests(world: &str) -> HostOptions {
        HostOptions {
            scene: None,
            world: world.into(),
            network: Network::default(),
            paused: false,
            overrides: Vec::new(),
            keyframe_interval: 60,
            max_frames: None,
            dump: None,
            scenes_dir: None,
            limits: Limits::default(),
            max_rate: 1000.0,
            max_frame_bytes: DEFAULT_MAX_FRAME_BYTES,
            inbox: InboxLimits::default(),
            trust_claimed_senders: false,
            budget: BudgetLimits::default(),
            journal: None,
            resume: None,
            checkpoints: Default::default(),
            accuracy: None,
            accuracy_cache: None,
        }
    }
}

/// The server's zenoh configuration: the network's, with the receive size bounded to what
/// a command needs, a blocked send bounded in time and the frames' queues
/// ([`frame_queues`]), unless a configuration file was given: then its values hold, and
/// `assets/zenoh/server.json5` sets them all.
pub fn server_config(opts: &HostOptions) -> Result<zenoh::Config> {
    let mut config = opts.network.config()?;
    if opts.network.config.is_none() {
        let max_message = (opts.limits.command_bytes as usize).saturating_add(64 << 10);
        let own = [
            (
                "transport/link/rx/max_message_size",
                max_message.to_string(),
            ),
            (
                "transport/link/tx/queue/congestion_control/block/wait_before_close",
                BLOCK_WAIT_BEFORE_CLOSE.as_micros().to_string(),
            ),
        ];
        set(&mut config, own.into_iter().chain(frame_queues()))?;
    }
    Ok(config)
}

/// How the links that carry frames queue them, for the server and for a router between it
/// and viewers: room for a key frame of many particles (16 batches of 64 KiB, zenoh's
/// most; its default is 2), allocated only when needed, and the fragments' wait.
fn frame_queues() -> [(&'static str, String); 3] {
    [
        (
            "transport/link/tx/queue/congestion_control/drop/max_wait_before_drop_fragments",
            FRAGMENTS_WAIT_BEFORE_DROP.as_micros().to_string(),
        ),
        ("transport/link/tx/queue/size/data_low", "16".to_string()),
        (
            "transport/link/tx/queue/allocation/mode",
            "\"lazy\"".to_string(),
        ),
    ]
}

fn set(
    config: &mut zenoh::Config,
    values: impl IntoIterator<Item = (&'static str, String)>,
) -> Result<()> {
    for (key, value) in values {
        config
            .insert_json5(key, &value)
            .map_err(|e| anyhow!("zenoh configuration {key} = {value}: {e}"))?;
    }
    Ok(())
}

/// The server's counts now.
fn health(host: &Hosted, inbox: &Inbox, outbox: &Outbox) -> Health {
    let load = |a: &std::sync::atomic::AtomicU64| a.load(Ordering::Relaxed);
    Health {
        overruns: u64::from(host.overruns),
        rate_limited: load(&inbox.turned.rate_limited),
        queue_full: load(&inbox.turned.queue_full),
        refused: host.health.refused + load(&inbox.turned.too_large),
        unsent: load(&outbox.unsent) + load(&inbox.turned.queries_dropped),
        ..host.health.clone()
    }
}

/// The event telling subscribers that fire-and-forget commands were dropped since the
/// counts `before` (too large, over the rate, queue full), if any were: they had no reply
/// to carry the refusal.
fn drops_event(frame: u64, before: [u64; 3], now: [u64; 3]) -> Option<Event> {
    let [large, rate, full] = [0, 1, 2].map(|k| now[k].saturating_sub(before[k]));
    let total = large + rate + full;
    (total > 0).then(|| Event {
        frame,
        ok: false,
        command: None,
        ids: Vec::new(),
        error: Some(format!(
            "dropped {total} command(s) sent without a reply key since the last such event: \
             {large} over the size limit, {rate} over their sender's rate, {full} with the queue full"
        )),
    })
}

/// Publishes the statics snapshot if it is due ([`Hosted::snapshot_due`]).
fn publish_statics(h: &mut Hosted, out: &FramesOut, snapshots: usize) {
    if let Some(snapshot) = h.snapshot_due(Instant::now()) {
        if !out.send(snapshots, h.world.frame() as u32, snapshot) {
            tracing::warn!("the snapshot of frame {} was dropped", h.world.frame());
        }
    }
}

/// Hosts a world until killed (or `max_frames`).
pub fn run(opts: HostOptions) -> Result<()> {
    one_heap();
    let (mut host, mut answered, mut journal, opts) = match &opts.resume {
        Some(path) => {
            let resumed = journal::resume(path, &opts)?;
            tracing::info!(
                journal = %path.display(),
                world = %resumed.world,
                frame = resumed.host.world.frame(),
                remembered_ids = resumed.answered.len(),
                "resumed the world from its journal"
            );
            (
                resumed.host,
                resumed.answered,
                Some(resumed.journal),
                resumed.opts,
            )
        }
        None => {
            let scene = opts
                .scene
                .as_ref()
                .ok_or_else(|| anyhow!("a scene, or a journal to resume, is needed"))?;
            let text = std::fs::read_to_string(scene)
                .with_context(|| format!("cannot read scene {}", scene.display()))?;
            let mut opts = opts.clone();
            // The pick's overrides are journaled with the rest: a resume needs no measure.
            let picked = crate::accuracy::apply_to(
                scene,
                &text,
                &mut opts.overrides,
                opts.accuracy,
                opts.accuracy_cache.as_deref(),
            )?;
            if let Some(pick) = &picked {
                tracing::info!("{}", pick.reason());
            }
            let mut host = Hosted::load(text, scene.clone(), &opts)?;
            host.accuracy = picked.map(|p| p.reason());
            let journal = match &opts.journal {
                Some(path) => Some(Journal::create(path, &opts.world, &host, &opts)?),
                None => None,
            };
            (host, Answered::default(), journal, opts)
        }
    };
    let keys = WorldKeys::new(&opts.world).map_err(|e| anyhow!(e))?;
    host.paused |= opts.paused;

    let mut dump = match &opts.dump {
        Some(path) => Some(std::io::BufWriter::new(
            std::fs::File::create(path)
                .with_context(|| format!("cannot create dump {}", path.display()))?,
        )),
        None => None,
    };

    let session = zenoh::open(server_config(&opts)?)
        .wait()
        .map_err(|e| anyhow!("cannot open the server's zenoh session: {e}"))?;
    let z = |e: zenoh::Error| anyhow!("zenoh: {e}");
    // One publisher per frame stream (streams.rs), in the streams' order.
    let frames = host
        .streams
        .streams
        .iter()
        .map(|s| {
            session
                .declare_publisher(keys.frame_every(s.every))
                .congestion_control(CongestionControl::Drop)
                .priority(STEP_PRIORITY)
                .wait()
                .map_err(z)
        })
        .collect::<Result<Vec<_>>>()?;
    let snapshots = frames.len();
    let mut publishers = frames;
    publishers.push(
        session
            .declare_publisher(keys.snapshot.clone())
            .congestion_control(CongestionControl::Drop)
            .priority(STEP_PRIORITY)
            .wait()
            .map_err(z)?,
    );
    // The frame streams' publishers, in the streams' order, then the snapshot's.
    let out = FramesOut::start(publishers);
    let events = session
        .declare_publisher(keys.event.clone())
        .congestion_control(CongestionControl::Drop)
        .wait()
        .map_err(z)?;
    let outbox = Outbox::start(events);
    let (peers, _transports) = if opts.trust_claimed_senders {
        (peers::Peers::trusting(), None)
    } else {
        let (peers, listener) = peers::Peers::watch(&session).map_err(z)?;
        (peers, Some(listener))
    };
    let inbox = Arc::new(Inbox::new(
        InboxLimits {
            command_bytes: opts.limits.command_bytes as usize,
            ..opts.inbox
        },
        outbox.clone(),
        peers,
    ));
    let _commands = session
        .declare_subscriber(&keys.cmd)
        .callback({
            let inbox = Arc::clone(&inbox);
            move |sample| inbox.offer_command(sample)
        })
        .wait()
        .map_err(z)?;
    let _requests = session
        .declare_queryable(&keys.rpc)
        .callback({
            let inbox = Arc::clone(&inbox);
            move |query| inbox.offer_request(query)
        })
        .wait()
        .map_err(z)?;
    let mut queryables = Vec::new();
    let mut asks = vec![
        (keys.snapshot.clone(), Ask::Snapshot),
        (keys.info.clone(), Ask::Info),
    ];
    for s in &host.streams.streams {
        asks.push((keys.state_every(s.every), Ask::State(s.every)));
    }
    for (key, ask) in asks {
        let inbox = Arc::clone(&inbox);
        queryables.push(
            session
                .declare_queryable(key)
                .callback(move |query| inbox.offer_query(ask, query))
                .wait()
                .map_err(z)?,
        );
    }
    let _alive = session
        .liveliness()
        .declare_token(keys.alive_token(&session.zid().to_string()))
        .wait()
        .map_err(z)?;
    tracing::info!(
        world = %opts.world,
        scene = %host.scene_name.display(),
        mode = opts.network.mode_name(),
        listen = ?opts.network.listen,
        connect = ?opts.network.connect,
        paused = host.paused,
        "serving"
    );

    // Every frame leaves with `Drop` congestion control: a slow subscriber loses frames
    // (and resyncs from the next key frame or the state query), it never holds the clock.
    let mut last_drop_warning: Option<Instant> = None;
    let mut publish = |h: &mut Hosted| {
        h.fresh = false;
        publish_statics(h, &out, snapshots);
        // A stream is published only while someone subscribes to it (the frames thread
        // asks zenoh twice a second); a stream watched again starts with a key frame.
        for i in 0..h.streams.streams.len() {
            h.streams.set_watched(i, out.watched(i));
        }
        for (i, bytes) in h.encode_frames() {
            // The source names this session, which holds the world's token: clients take
            // frames from it only.
            if !out.send(i, h.world.frame() as u32, bytes)
                && last_drop_warning.is_none_or(|at| at.elapsed() >= Duration::from_secs(1))
            {
                last_drop_warning = Some(Instant::now());
                tracing::warn!(
                    frame = h.world.frame(),
                    dropped = out.dropped.load(Ordering::Relaxed),
                    "frames wait longer to leave than the queue holds: dropped"
                );
            }
        }
        if let Some(out) = dump.as_mut() {
            let written = wire::write_frame(out, &h.world).and_then(|()| out.flush());
            if let Err(e) = written {
                tracing::warn!("writing frame {} to the dump failed: {e}", h.world.frame());
            }
        }
    };
    // Frame 0: the state before the first step.
    publish(&mut host);

    // The wall time between steps: the world's dt, or longer where it would step faster
    // than `max_rate`.
    let min_interval_ns = (1e9 / opts.max_rate).round() as u64;
    let interval = |h: &Hosted| -> Duration {
        let dt_ns = (h.world.config.dt * 1e9).round() as u64;
        if dt_ns < min_interval_ns {
            tracing::warn!(
                dt = h.world.config.dt,
                max_rate = opts.max_rate,
                "dt is shorter than 1/max-rate: the world runs slower than real time"
            );
        }
        Duration::from_nanos(dt_ns.max(min_interval_ns))
    };
    let mut clock = Clock::new(interval(&host));
    let mut last_dt = host.world.config.dt;
    let mut deferred: Vec<Deferred> = Vec::new();
    let mut budgets = Budgets::new(opts.budget, Instant::now());
    // The state query's answer, kept for the frame it was made at.
    let mut state: Option<((u64, u64, u64), Vec<u8>)> = None;
    let mut last_report = (Instant::now(), Health::default());
    let mut last_drops = (Instant::now(), [0u64; 3]);
    loop {
        inbox.set_frame(host.world.frame());
        // A change of the statics held back by their rate goes out once it is due.
        publish_statics(&mut host, &out, snapshots);

        // Queries are answered from what the server has, a bounded number per pass.
        for _ in 0..MAX_QUERIES_PER_PASS {
            let Some((ask, query)) = inbox.next_query() else {
                break;
            };
            let body = match ask {
                Ask::Snapshot => {
                    host.refresh_snapshot();
                    host.snapshot.clone()
                }
                Ask::State(every) => {
                    let at = (host.generation, host.world.frame(), every);
                    match &state {
                        Some((made, bytes)) if *made == at => bytes.clone(),
                        _ => {
                            // Before a tier's first frame, the full stream's state: the
                            // tier's first frame is a key frame.
                            let bytes = host
                                .streams
                                .resync(every)
                                .or_else(|| host.streams.resync(1))
                                .expect("frame 0 was encoded");
                            state = Some((at, bytes.clone()));
                            bytes
                        }
                    }
                }
                Ask::Info => {
                    let mut info = host.info();
                    info.health = Some(health(&host, &inbox, &outbox));
                    serde_json::to_vec(&info).expect("world info serialises")
                }
            };
            host.health.queries += 1;
            outbox.reply(query, body);
        }

        // The frame boundary: commands and requests that arrived, up to a bound.
        let was_paused = host.paused;
        let (boundary, budget) = (Instant::now(), boundary_budget(clock.interval()));
        for _ in 0..MAX_COMMANDS_PER_FRAME {
            if boundary.elapsed() >= budget {
                break;
            }
            let Some(incoming) = inbox.next() else {
                break;
            };
            apply_incoming(
                &mut host,
                incoming,
                apply::Boundary {
                    answered: &mut answered,
                    budgets: &mut budgets,
                    deferred: &mut deferred,
                    journal: &mut journal,
                    outbox: &outbox,
                },
            );
            if host.fresh {
                // A new world's frame 0 goes out at once.
                publish(&mut host);
            }
        }

        // Steps asked for by `step` commands, in a slice; then the answers now due.
        if host.pending_steps > 0 {
            let began = Instant::now();
            while host.pending_steps > 0 && began.elapsed() < STEP_SLICE {
                advance(&mut host, &mut publish, &mut journal);
            }
        }
        if !deferred.is_empty() {
            let (ready, waiting): (Vec<_>, Vec<_>) = deferred
                .drain(..)
                .partition(|d| d.due_at_step <= host.steps_run);
            deferred = waiting;
            for d in ready {
                outbox.reply(d.query, d.reply.into_vec());
            }
        }

        answered.forget();
        if last_drops.0.elapsed() >= DROPS_EVERY {
            budgets.forget_full(Instant::now());
            let now = inbox.turned.unanswered.counts();
            if let Some(event) = drops_event(host.world.frame(), last_drops.1, now) {
                outbox.publish_event(&event);
            }
            last_drops = (Instant::now(), now);
        }
        if last_report.0.elapsed() >= TRIM_EVERY {
            give_back_memory();
            let now = health(&host, &inbox, &outbox);
            if now.refused + now.rate_limited + now.queue_full + now.unsent + now.over_budget
                > last_report.1.refused
                    + last_report.1.rate_limited
                    + last_report.1.queue_full
                    + last_report.1.unsent
                    + last_report.1.over_budget
            {
                tracing::warn!(
                    refused = now.refused - last_report.1.refused,
                    rate_limited = now.rate_limited - last_report.1.rate_limited,
                    queue_full = now.queue_full - last_report.1.queue_full,
                    unsent = now.unsent - last_report.1.unsent,
                    over_budget = now.over_budget - last_report.1.over_budget,
                    "turned away in the last 10 s"
                );
            }
            last_report = (Instant::now(), now);
        }

        let new_interval = if host.world.config.dt != last_dt {
            last_dt = host.world.config.dt;
            interval(&host)
        } else {
            clock.interval()
        };
        if new_interval != clock.interval() || (was_paused && !host.paused) {
            // The clock restarts from now at the new rate.
            clock.restart(new_interval);
        }

        if opts.max_frames.is_some_and(|m| host.world.frame() >= m) {
            tracing::info!(
                frame = host.world.frame(),
                overruns = host.overruns,
                "stopping after the last frame"
            );
            return Ok(());
        }
        if host.pending_steps > 0 {
            // More steps to run: serve the others, then the next slice, without sleeping.
            continue;
        }

        match clock.tick(Instant::now(), host.paused) {
            Tick::Wait(wait) => {
                std::thread::sleep(wait);
                continue;
            }
            Tick::Paused => continue,
            Tick::Step { late, dropped } => {
                if late >= 1 {
                    host.overruns = host.overruns.saturating_add(1);
                }
                if dropped > 0 {
                    tracing::warn!(
                        late_steps = dropped,
                        frame = host.world.frame(),
                        "the world cannot keep real time; the clock re-anchors"
                    );
                    host.overruns = host
                        .overruns
                        .saturating_add(dropped.min(u32::MAX as u64) as u32);
                }
            }
        }
        advance(&mut host, &mut publish, &mut journal);
        clock.stepped();
        // The journal's bound: a checkpoint, once no `step` command is in flight (a resume
        // finds its remaining steps in the journal's lines, never in a checkpoint).
        if let Some(j) = journal.as_mut() {
            j.poll(false);
            if j.checkpoint_due() && host.pending_steps == 0 && deferred.is_empty() {
                j.checkpoint(&host, &answered, &opts.world, &opts);
            }
        }
    }
}

/// One step of the world, as the clock or a `step` command takes it: stepped (counted
/// against pending `step`s), published, and journalled.
fn advance(
    host: &mut Hosted,
    publish: &mut impl FnMut(&mut Hosted),
    journal: &mut Option<Journal>,
) {
    host.advance();
    publish(host);
    if let Some(journal) = journal.as_mut() {
        journal.stepped(host.world.frame(), f64::from(host.last_step_ms));
    }
}

/// glibc's settings that keep no per-thread caches of freed blocks, and no cache of the
/// stacks of threads that ended.
pub const NO_THREAD_CACHES: &str = "glibc.malloc.tcache_count=0:glibc.pthread.stack_cache_size=0";

/// Starts this process again, same arguments, with glibc's per-thread caches of freed
/// blocks and its cache of ended threads' stacks turned off ([`NO_THREAD_CACHES`]), unless
/// `GLIBC_TUNABLES` already says how many blocks to keep (an operator's choice stands).
/// Those caches keep up to seven freed blocks of each small size per thread; after a burst
/// of traffic they pinned about half a MiB of heap pages that no trim could give back; the
/// stacks of the threads zenoh starts under load and ends later stayed resident (the
/// soak's figures, docs/reliability.md). glibc reads the setting
/// only at start, hence the new image; the process id stays. Returns only if the setting is
/// already in place or the new image could not start (then the server runs as it is).
pub fn without_thread_caches() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        use std::os::unix::process::CommandExt;
        let current = std::env::var("GLIBC_TUNABLES").unwrap_or_default();
        if current.contains("tcache_count") {
            return;
        }
        let tunables = if current.is_empty() {
            NO_THREAD_CACHES.to_string()
        } else {
            format!("{current}:{NO_THREAD_CACHES}")
        };
        let Ok(exe) = std::env::current_exe() else {
            return;
        };
        let e = std::process::Command::new(exe)
            .args(std::env::args_os().skip(1))
            .env("GLIBC_TUNABLES", tunables)
            .exec();
        tracing::warn!(
            "running with glibc's thread caches: could not start again without them: {e}"
        );
    }
}

/// Makes every thread allocate from one heap (glibc gives each thread that allocates its
/// own arena otherwise; zenoh's runtime threads each kept a few hundred KiB of pages after
/// a load). Called before the session opens; the step allocates little, so the shared
/// heap's lock costs nothing measurable (docs/reliability.md).
fn one_heap() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt sets an allocator parameter; M_ARENA_MAX takes any positive count.
    unsafe {
        libc::mallopt(libc::M_ARENA_MAX, 1);
    }
}

/// Returns the heap's free pages to the operating system (glibc keeps them resident
/// otherwise: a burst of traffic would hold its memory for good). Called every
/// [`TRIM_EVERY`]; cheap on a heap of a few MiB.
fn give_back_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: malloc_trim only releases free memory of the allocator's own heaps;
    // mallinfo2 only reads its counters.
    unsafe {
        libc::malloc_trim(0);
        let heap = libc::mallinfo2();
        tracing::debug!(
            in_use_kib = heap.uordblks / 1024,
            free_kib = heap.fordblks / 1024,
            mapped_kib = heap.hblkhd / 1024,
            "heap after a trim"
        );
    }
}

/// Runs a zenoh router: where servers and clients on several hosts meet. Without a
/// configuration file its links queue frames as the server's do ([`frame_queues`]).
pub fn run_router(network: &Network) -> Result<()> {
    let mut config = network.config()?;
    if network.config.is_none() {
        // Its links carry frames to viewers as the server's do.
        set(&mut config, frame_queues())?;
    }
    let _session = zenoh::open(config).wait().map_err(|e| {
        anyhow!(
            "cannot open the router's zenoh session (listen {:?}, connect {:?}): {e}",
            network.listen,
            network.connect
        )
    })?;
    tracing::info!(listen = ?network.listen, connect = ?network.connect, "router up");
    loop {
        std::thread::sleep(Duration::from_secs(3600));
    }
}

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
//! wall time, and [`MAX_QUERIES_PER_PASS`] queries are served per pass, and the steps a `step`
//! command asks for run in slices of at most [`STEP_SLICE`], with other clients served
//! between slices.
//!
//! The files follow a pass of the loop: [`start`] (the world resumed or loaded),
//! [`wiring`] (the zenoh keys), [`serve`] (the loop), [`queries`], [`boundary`] (commands
//! and asked steps), [`publish`] (frames out of the stepping thread), [`upkeep`],
//! [`clock`]; [`hosted`] is the world and what it was made from, [`journal`] its log.

pub mod answered;
mod apply;
mod boundary;
pub mod budget;
mod clock;
pub mod frames_out;
pub mod hosted;
pub mod inbox;
pub mod journal;
mod limiter;
mod memory;
pub mod outbox;
pub mod peers;
pub mod price;
mod publish;
mod queries;
mod router;
mod serve;
mod start;
pub mod streams;
pub mod travel;
mod upkeep;
mod wiring;
pub mod worlds;

use std::path::PathBuf;
use std::time::Duration;

use anyhow::{anyhow, Result};
use ricochet_engine::world::Limits;
use ricochet_protocol::keys::WorldKeys;
use ricochet_protocol::net::Network;
use zenoh::qos::Priority;
use zenoh::Wait;

use budget::BudgetLimits;
use inbox::InboxLimits;
use serve::Serving;
use wiring::Wiring;

pub use hosted::{MAX_PENDING_STEPS, MAX_STEPS_PER_COMMAND};
pub use memory::{without_thread_caches, NO_THREAD_CACHES};
pub use router::run_router;
pub use wiring::server_config;

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
    /// bodies or particles is accepted ([`crate::wire::key_frame_bytes`]).
    pub max_frame_bytes: u64,
    /// Per-sender rates and queue bounds (the command size bound is `limits`').
    pub inbox: InboxLimits,
    /// Which claimed sender ids keep buckets of their own ([`peers`]; `--sender-ids`).
    pub sender_ids: peers::SenderIds,
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
    /// How much time travel the host keeps: saves, history, frame hashes ([`travel`]).
    pub travel: travel::TravelLimits,
    /// Worlds served at most, this one and its forks ([`worlds`]).
    pub max_worlds: usize,
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
            sender_ids: peers::SenderIds::Signed,
            budget: BudgetLimits::default(),
            journal: None,
            resume: None,
            checkpoints: Default::default(),
            accuracy: None,
            accuracy_cache: None,
            travel: Default::default(),
            max_worlds: 4,
        }
    }
}

/// Hosts a world until killed (or `max_frames`): the world started ([`start`]), its keys
/// declared ([`wiring`]), then served ([`serve`]).
pub fn run(opts: HostOptions) -> Result<()> {
    memory::one_heap();
    let mut started = start::start(&opts)?;
    let opts = &started.opts;
    let keys = WorldKeys::new(&opts.world).map_err(|e| anyhow!(e))?;
    started.host.stepping.paused |= opts.paused;
    let session = zenoh::open(server_config(opts)?)
        .wait()
        .map_err(|e| anyhow!("cannot open the server's zenoh session: {e}"))?;
    let (wiring, publisher) = Wiring::declare(&session, &keys, &started.host, opts)?;
    tracing::info!(
        world = %opts.world,
        scene = %started.host.source.name.display(),
        mode = opts.network.mode_name(),
        listen = ?opts.network.listen,
        connect = ?opts.network.connect,
        paused = started.host.stepping.paused,
        "serving"
    );
    let stop = stop_on_signals()?;
    let (_worlds, slot) = worlds::Worlds::new(session.clone(), opts, stop.clone());
    Serving::new(started, wiring, publisher, stop)
        .in_slot(slot)
        .run()
}

/// A flag set to the number of the signal (SIGTERM or SIGINT) that asks the server to
/// stop, which the serving loop reads each pass. A second signal while the first is
/// being handled ends the process at once (exit status 1).
fn stop_on_signals() -> Result<std::sync::Arc<std::sync::atomic::AtomicUsize>> {
    use signal_hook::consts::{SIGINT, SIGTERM};
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicUsize::new(0));
    let stopping = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    for signal in [SIGTERM, SIGINT] {
        // Registered first, so it sees the flag as the first signal left it.
        signal_hook::flag::register_conditional_shutdown(signal, 1, stopping.clone())?;
        signal_hook::flag::register(signal, stopping.clone())?;
        signal_hook::flag::register_usize(signal, stop.clone(), signal as usize)?;
    }
    Ok(stop)
}

//! The command line of `ricochet-server`: its subcommands and their flags.

use std::path::{Path, PathBuf};

use anyhow::{bail, Result};
use clap::{Args, Parser, Subcommand};
use ricochet_engine::world::Limits;
use ricochet_protocol::keys::DEFAULT_WORLD;
use ricochet_protocol::net::{NetworkArgs, Verbosity};
use ricochet_server::host::budget::BudgetLimits;
use ricochet_server::host::inbox::InboxLimits;
use ricochet_server::host::journal::Checkpoints;
use ricochet_server::host::travel::TravelLimits;
use ricochet_server::host::{HostOptions, DEFAULT_MAX_FRAME_BYTES};

#[derive(Parser)]
#[command(
    name = "ricochet-server",
    version = ricochet_protocol::VERSION,
    about = "Ricochet: a 2D physics and particle server"
)]
pub struct Cli {
    #[command(flatten)]
    pub verbosity: Verbosity,
    #[command(subcommand)]
    pub command: Command,
}

/// How a world runs, for `run` and `simulate` alike: overrides of its `[world]`, its
/// limits, and an accuracy target that picks its setting.
#[derive(Args, Clone, Debug)]
#[command(next_help_heading = "World")]
pub struct WorldFlags {
    /// Override a `[world]` field, e.g. --set relaxation_iterations=30
    /// --set gravity=[0,-9.8] --set integrator=explicit. Repeatable.
    #[arg(long = "set", value_name = "NAME=VALUE")]
    pub set: Vec<String>,
    /// Lower or raise a limit of the world, e.g. --limit bodies=5000
    /// --limit step_work=1e7 (names and defaults: docs/security.md; `run` starts from a
    /// step's work of about a frame's time, step_work=1e6, `simulate` from 1e8). A
    /// scene's `[limits]` may lower these, never raise them. Repeatable.
    #[arg(long = "limit", value_name = "NAME=VALUE")]
    pub limit: Vec<String>,
    /// Run the scene under the cheapest setting whose worst position error meets TOL
    /// (scene units), measured on the scene at start-up against a converged reference
    /// (bounded: 120 steps, 20 s for the reference) or read from the cache; overrides the
    /// scene's `[world] accuracy`. The log says what was picked and why.
    #[arg(long, value_name = "TOL")]
    pub accuracy: Option<f64>,
    /// Where accuracy measures are cached, keyed by the scene's content
    /// (default: ~/.cache/ricochet/accuracy).
    #[arg(long, value_name = "DIR")]
    pub accuracy_cache: Option<PathBuf>,
}

impl WorldFlags {
    /// The limits `--limit` asks for, over `base`: [`Limits::real_time`] for a served
    /// world, [`Limits::default`] for a headless run.
    pub fn limits(&self, base: Limits) -> anyhow::Result<Limits> {
        Ok(base.with(&self.limit)?)
    }
}

#[derive(Args)]
pub struct RunArgs {
    /// The scene file (TOML).
    #[arg(help_heading = "World", long, required_unless_present = "resume")]
    pub scene: Option<PathBuf>,
    /// The world's name in key expressions.
    #[arg(help_heading = "World", long, default_value = DEFAULT_WORLD)]
    pub world: String,
    #[command(flatten)]
    pub network: NetworkArgs,
    /// Start paused; `resume` or `step` commands move the world.
    #[arg(help_heading = "World", long)]
    pub paused: bool,
    #[command(flatten)]
    pub how: WorldFlags,
    /// A key frame (all dynamic state) every this many frames.
    #[arg(help_heading = "Frames", long, default_value_t = 60)]
    pub keyframe_interval: u64,
    /// Stop after this many frames instead of running until killed.
    #[arg(help_heading = "Frames", long)]
    pub max_frames: Option<u64>,
    /// Append every frame the server publishes to this file as JSON Lines, in the
    /// form of `simulate --dump` (full precision), flushed each frame.
    #[arg(help_heading = "Frames", long, value_name = "FILE")]
    pub dump: Option<PathBuf>,
    /// The directory `load` commands may name scenes in (nothing outside it is read);
    /// the directory of --scene by default, unless that is the working directory (then
    /// none: `load` by name is refused).
    #[arg(help_heading = "World", long, value_name = "DIR")]
    pub scenes: Option<PathBuf>,
    /// Steps per second of wall time at most: a world with a shorter dt runs slower
    /// than real time instead of flooding its viewers.
    #[arg(
        help_heading = "Frames",
        long,
        default_value_t = 1000.0,
        value_name = "HZ"
    )]
    pub max_rate: f64,
    /// Bytes of a key frame at most: a scene, a spawn or an emitter whose particles and
    /// bodies would pass it (estimated at the largest size of each record) is refused.
    #[arg(help_heading = "Frames", long, default_value_t = DEFAULT_MAX_FRAME_BYTES, value_name = "BYTES")]
    pub max_frame_bytes: u64,
    /// Commands a second each sender may send over time (a sender is the zenoh id its
    /// session declares; Ricochet's clients declare theirs). Over it, commands are
    /// dropped and requests answered so.
    #[arg(
        help_heading = "Peers and their commands",
        long,
        default_value_t = 1000.0,
        value_name = "N"
    )]
    pub sender_rate: f64,
    /// Commands a sender may send at once above its rate.
    #[arg(
        help_heading = "Peers and their commands",
        long,
        default_value_t = 500.0,
        value_name = "N"
    )]
    pub sender_burst: f64,
    /// Which claimed sender ids keep rate buckets and budgets of their own: `signed`,
    /// only ids of sessions connected to the server, on messages signed by the key the id
    /// names and never seen before (any other claim is the anonymous sender's, so one
    /// process can neither claim many ids nor spend another client's); `connected`, ids of
    /// connected sessions, signed or not (a peer that sees a client's id can spend its
    /// rate); `claimed`, every id as claimed. Through a router the server dialled, a
    /// signed claim is taken whatever session it names.
    #[arg(help_heading = "Peers and their commands", long, value_enum, default_value_t = SenderIds::Signed, value_name = "WHICH")]
    pub sender_ids: SenderIds,
    /// Fraction of real time the commands of all senders may take of the stepping
    /// thread, over time: each command is priced by what it touches before it runs and
    /// charged what it took (docs/security.md, "The cost of a command").
    #[arg(help_heading = "Peers and their commands", long, default_value_t = BudgetLimits::default().share, value_name = "FRACTION")]
    pub command_share: f64,
    /// Fraction of real time one sender's commands may take, over time.
    #[arg(help_heading = "Peers and their commands", long, default_value_t = BudgetLimits::default().sender_share, value_name = "FRACTION")]
    pub sender_share: f64,
    /// Milliseconds of the stepping thread commands may take at once above their share;
    /// a command priced above it is refused.
    #[arg(help_heading = "Peers and their commands", long, default_value_t = BudgetLimits::default().burst.as_millis() as u64, value_name = "MS")]
    pub command_burst_ms: u64,
    /// Commands (and, apart, requests) waiting for the frame boundary at most; past it
    /// they are dropped and requests answered so.
    #[arg(
        help_heading = "Peers and their commands",
        long,
        default_value_t = 4096,
        value_name = "N"
    )]
    pub queue: usize,
    /// Write every accepted command, with the frame it took effect in, and every stepped
    /// frame to FILE (JSON Lines, each line flushed as written). When FILE exists (a
    /// server stopped or killed), the world it holds is resumed first, bit for bit, and
    /// the journal goes on: the same command line starts a service and restarts it. On
    /// SIGTERM or SIGINT the server checkpoints the world beside FILE and exits.
    #[arg(help_heading = "Journal", long, value_name = "FILE")]
    pub journal: Option<PathBuf>,
    /// Rebuild the world a journal holds, bit for bit, to its last frame, and go on
    /// (appending to the same journal); FILE must exist (--journal FILE resumes it when
    /// it exists and starts it otherwise; both may name the same FILE). The journal gives the scene, world name,
    /// overrides and limits; --scene, --world, --set and --limit are not needed.
    #[arg(help_heading = "Journal", long, value_name = "FILE")]
    pub resume: Option<PathBuf>,
    /// Bytes the journal may grow to before the host checkpoints the world beside it
    /// (FILE.<frame>.checkpoint) and starts the journal again from there.
    #[arg(help_heading = "Journal", long, default_value_t = Checkpoints::default().journal_bytes, value_name = "BYTES")]
    pub journal_bytes: u64,
    /// Milliseconds of stepping after which the host checkpoints the world: about what a
    /// resume replays, whatever the run's length.
    #[arg(help_heading = "Journal", long, default_value_t = Checkpoints::default().replay_ms, value_name = "MS")]
    pub checkpoint_after_ms: f64,
    /// Named states `save` may keep at most.
    #[arg(help_heading = "Time travel and forks", long, default_value_t = TravelLimits::default().saves, value_name = "N")]
    pub saves: usize,
    /// Bytes all saved states may take at most.
    #[arg(help_heading = "Time travel and forks", long, default_value_t = TravelLimits::default().save_bytes, value_name = "BYTES")]
    pub save_bytes: u64,
    /// Bytes the history `rewind` goes back through may take (a copy of the world every
    /// --history-every frames, by its estimated size; the oldest go first); 0 keeps none.
    #[arg(help_heading = "Time travel and forks", long, default_value_t = TravelLimits::default().history_bytes, value_name = "BYTES")]
    pub history_bytes: u64,
    /// Frames between two copies in the history: a rewind replays at most this many
    /// steps.
    #[arg(help_heading = "Time travel and forks", long, default_value_t = TravelLimits::default().history_every, value_name = "FRAMES")]
    pub history_every: u64,
    /// Worlds this server serves at most, its own and the forks `fork` starts.
    #[arg(
        help_heading = "Time travel and forks",
        long,
        default_value_t = 4,
        value_name = "N"
    )]
    pub max_worlds: usize,
}

#[derive(Subcommand)]
pub enum Command {
    /// Host a world on zenoh and run it in real time at the scene's fixed step.
    ///
    /// With no flags it listens on tcp/127.0.0.1:7447 and clients on the same machine
    /// connect there by default. Commands arrive on ricochet/<world>/cmd (fire and forget)
    /// and ricochet/<world>/rpc (request, reply); frames leave on ricochet/<world>/frame,
    /// the statics snapshot on ricochet/<world>/snapshot (also a queryable), the dynamic
    /// state for late joiners on the ricochet/<world>/state queryable, one event per
    /// handled command on ricochet/<world>/event; a liveliness token
    /// ricochet/<world>/alive/<zid> says the world is up and which peer serves it.
    #[command(after_help = "Examples:\n  \
ricochet-server run --scene assets/scenes/emitters.toml\n  \
ricochet-server run --scene table.toml --world table --paused -l tcp/0.0.0.0:7447\n  \
ricochet-server run --scene table.toml --journal /var/lib/ricochet/table.journal    # a service: resumes after a stop\n  \
ricochet-server run --scene pile.toml --accuracy 0.01 --limit bodies=20000")]
    Run(Box<RunArgs>),
    /// Make the TLS certificates of a secured deployment (assets/zenoh/).
    ///
    /// A certificate authority and the router's certificate signed by it, as PEM files in DIR
    /// (ca.pem, ca-key.pem, router.pem, router-key.pem; keys readable by their owner
    /// only). Clients trust ca.pem; keep ca-key.pem offline.
    Certs {
        /// Where to write them.
        #[arg(long, default_value = "certs", value_name = "DIR")]
        out: PathBuf,
        /// A host name or IP address clients reach the router by. Repeatable.
        #[arg(long = "host", value_name = "NAME", default_values_t = ["localhost".to_string(), "127.0.0.1".to_string()])]
        hosts: Vec<String>,
        /// Days the certificates are valid.
        #[arg(long, default_value_t = 365)]
        days: u32,
    },
    #[command(flatten)]
    Doc(ricochet_protocol::net::SelfDoc),
    /// Run a zenoh router where servers and clients on several hosts meet.
    ///
    /// They connect to it with `--mode client --connect tcp/<router>:7447`.
    Router {
        #[command(flatten)]
        network: NetworkArgs,
    },
    /// Run a scene headless for a number of steps, without any network.
    ///
    /// Line 0 of the dump is the state before the first step, line k the state after k
    /// steps: {"frame":k,"t":seconds,"bodies":[{"id","x","y","vx","vy","collided"}],
    /// "particles":[{"x","y","size","color":[r,g,b,a]}],"emitters":count}.
    ///
    /// The same scene, seed and inputs give the same frames, bit for bit.
    Simulate(SimulateArgs),
}

impl RunArgs {
    /// The host's options, each flag checked and named when refused.
    pub fn host_options(self) -> Result<HostOptions> {
        for (flag, value) in [
            ("--sender-rate", self.sender_rate),
            ("--sender-burst", self.sender_burst),
        ] {
            if !(value.is_finite() && value >= 1.0) {
                bail!("{flag} {value}: must be a number of commands of 1 or more");
            }
        }
        if self.queue == 0 {
            bail!("--queue 0: at least one command must be able to wait");
        }
        for (name, share) in [
            ("--command-share", self.command_share),
            ("--sender-share", self.sender_share),
        ] {
            if !(share > 0.0 && share <= 1.0) {
                bail!("{name} must be above 0 and at most 1, not {share}");
            }
        }
        if !(self.checkpoint_after_ms.is_finite() && self.checkpoint_after_ms > 0.0) {
            bail!(
                "--checkpoint-after-ms {}: must be a number of milliseconds above 0",
                self.checkpoint_after_ms
            );
        }
        if self.history_every == 0 {
            bail!("--history-every 0: must be a number of frames of 1 or more");
        }
        if self.max_worlds == 0 {
            bail!("--max-worlds 0: the server serves its own world at least");
        }
        if let (Some(journal), Some(resume)) = (&self.journal, &self.resume) {
            if journal != resume {
                bail!(
                    "--journal {} and --resume {} name different files: a resumed journal goes on in its own file (--journal FILE alone resumes FILE when it exists)",
                    journal.display(),
                    resume.display()
                );
            }
        }
        if self.journal_bytes < 4096 {
            bail!(
                "--journal-bytes {}: must be at least 4096",
                self.journal_bytes
            );
        }
        if !(self.max_rate.is_finite() && self.max_rate > 0.0) {
            bail!(
                "--max-rate {}: must be a number of steps per second above 0",
                self.max_rate
            );
        }
        Ok(HostOptions {
            scenes_dir: scenes_dir(self.scenes, self.scene.as_deref()),
            limits: self.how.limits(Limits::real_time())?,
            scene: self.scene,
            world: self.world,
            network: self.network.server(),
            paused: self.paused,
            overrides: self.how.set,
            keyframe_interval: self.keyframe_interval,
            max_frames: self.max_frames,
            dump: self.dump,
            max_rate: self.max_rate,
            max_frame_bytes: self.max_frame_bytes,
            sender_ids: match self.sender_ids {
                SenderIds::Signed => ricochet_server::host::peers::SenderIds::Signed,
                SenderIds::Connected => ricochet_server::host::peers::SenderIds::Connected,
                SenderIds::Claimed => ricochet_server::host::peers::SenderIds::Claimed,
            },
            budget: BudgetLimits {
                share: self.command_share,
                sender_share: self.sender_share,
                burst: std::time::Duration::from_millis(self.command_burst_ms),
            },
            inbox: InboxLimits {
                rate: self.sender_rate,
                burst: self.sender_burst,
                queue: self.queue,
                ..InboxLimits::default()
            },
            journal: self.journal,
            resume: self.resume,
            checkpoints: Checkpoints {
                journal_bytes: self.journal_bytes,
                replay_ms: self.checkpoint_after_ms,
            },
            accuracy: self.how.accuracy,
            accuracy_cache: self.how.accuracy_cache,
            travel: TravelLimits {
                saves: self.saves,
                save_bytes: self.save_bytes,
                history_bytes: self.history_bytes,
                history_every: self.history_every,
                ..TravelLimits::default()
            },
            max_worlds: self.max_worlds,
        })
    }
}

/// Where `load` may read scenes: `--scenes`, else the directory of `--scene` unless that
/// is the working directory: a scene named bare (or a resumed journal) must not open the
/// server's working directory to `load`.
fn scenes_dir(scenes: Option<PathBuf>, scene: Option<&Path>) -> Option<PathBuf> {
    match (scenes, scene) {
        (Some(dir), _) => Some(dir),
        (None, None) => None,
        (None, Some(scene)) => {
            let dir = scene.parent().unwrap_or(Path::new(""));
            let cwd = std::env::current_dir()
                .ok()
                .and_then(|d| d.canonicalize().ok());
            let here = dir.as_os_str().is_empty()
                || dir.canonicalize().ok().is_some_and(|d| Some(d) == cwd);
            (!here).then(|| dir.to_path_buf())
        }
    }
}

/// What `simulate` runs and writes.
#[derive(clap::Args)]
pub struct SimulateArgs {
    /// The scene file (TOML), e.g. assets/scenes/emitters.toml.
    #[arg(long)]
    pub scene: PathBuf,
    /// How many fixed steps to run.
    #[arg(long)]
    pub steps: u64,
    /// Seed of the world's random generator (overrides the scene's `[world] seed`).
    #[arg(long)]
    pub seed: Option<u64>,
    #[command(flatten)]
    pub how: WorldFlags,
    /// Write every frame as JSON Lines to this file ("-" for standard output).
    #[arg(long)]
    pub dump: Option<PathBuf>,
    /// Actions to apply, JSON Lines of {"frame": N, "action": {"do": ...}}: each is
    /// applied after N steps, before step N + 1, in file order.
    #[arg(long)]
    pub inputs: Option<PathBuf>,
    /// Write every step's figures as JSON Lines to this file (line k: step k): contacts,
    /// solver passes, deepest penetration, kinetic energy, particle contacts, sleeping
    /// bodies.
    #[arg(long, value_name = "FILE")]
    pub stats: Option<PathBuf>,
    /// Write every frame's state hash as JSON Lines to this file, `{"frame": F, "hash":
    /// "..."}` from frame 0: the hashes a server's `hashes` command gives for the same
    /// scene and commands, so a served run and its replay are compared frame by frame.
    #[arg(long, value_name = "FILE")]
    pub hashes: Option<PathBuf>,
    /// Encode every frame as the server would send it and report the bytes per frame,
    /// per dynamic body and per particle.
    #[arg(long)]
    pub wire_stats: bool,
    /// With --wire-stats or --frames: a key frame every this many frames, as `run`
    /// would send.
    #[arg(long, default_value_t = 60)]
    pub keyframe_interval: u64,
    /// Write the statics snapshot and every frame's bytes as `run` would publish them to
    /// this file, each as a u32 little-endian length then the payload (what
    /// `ricochet_client.py decode` and python/bench/decode.py read).
    #[arg(long, value_name = "FILE")]
    pub frames: Option<PathBuf>,
}

/// Which claimed sender ids keep buckets of their own (`--sender-ids`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum SenderIds {
    Signed,
    Connected,
    Claimed,
}

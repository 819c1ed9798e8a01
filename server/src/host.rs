//! The authoritative server: hosts one world on zenoh and runs it in real time.
//!
//! The clock is an accumulator of whole steps: step k is due at `start + k dt`, computed
//! from integers of nanoseconds, so it does not drift over hours. Commands that arrived
//! since the last step are applied at the frame boundary, in arrival order, each stamped
//! with the frame it took effect in. A step that starts more than one `dt` late is counted
//! as an overrun; after more than [`MAX_CATCH_UP`] late steps the clock is re-anchored
//! (the lost steps are counted, never silently dropped).

use std::io::Write;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{anyhow, Context, Result};
use ricochet_protocol::command::{Command, Event, Reply, ServerCommand, WorldInfo};
use ricochet_protocol::frame::FrameEncoder;
use ricochet_protocol::keys::WorldKeys;
use ricochet_protocol::net::Network;
use zenoh::qos::CongestionControl;
use zenoh::Wait;

use ricochet_engine::scene;
use ricochet_engine::world::{short, Limits, World};
use ricochet_protocol::command::MAX_ERROR_BYTES;
use ricochet_protocol::world as wire;

use crate::scenes::{read_scene, resolve_scene};

/// Late steps run back to back before the clock gives up and re-anchors.
pub const MAX_CATCH_UP: u64 = 5;
/// Commands handled per frame boundary at most; the rest wait for the next one, so a
/// flood cannot stall the clock.
pub const MAX_COMMANDS_PER_FRAME: usize = 1000;

/// Steps one `step` command may ask for: the server answers nothing else meanwhile.
pub const MAX_STEPS_PER_COMMAND: u32 = 10_000;

/// How to host a world.
#[derive(Clone, Debug)]
pub struct HostOptions {
    pub scene: PathBuf,
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
    /// Where `load` finds scenes by name; nothing outside it is read.
    pub scenes_dir: PathBuf,
    /// The limits every world hosted here runs under at most (a scene's `[limits]` may
    /// lower them).
    pub limits: Limits,
    /// Steps per second of wall time at most: a world whose `dt` is shorter runs slower
    /// than real time rather than flooding its viewers.
    pub max_rate: f64,
}

/// The world, its scene and what the wire remembers of it.
struct Hosted {
    world: World,
    scene_text: String,
    scene_name: PathBuf,
    overrides: Vec<String>,
    encoder: FrameEncoder,
    statics_revision: Option<u64>,
    snapshot: Vec<u8>,
    paused: bool,
    overruns: u32,
    last_step_ms: f32,
    /// Bumped by every (re)load, so viewers can tell a new scene.
    generation: u64,
    scenes_dir: PathBuf,
    limits: Limits,
}

impl Hosted {
    fn load(scene_text: String, scene_name: PathBuf, opts: &HostOptions) -> Result<Self> {
        let world = scene::parse_with(&scene_text, &scene_name, &opts.overrides, &opts.limits)?;
        let (overrides, keyframe_interval) = (opts.overrides.clone(), opts.keyframe_interval);
        Ok(Hosted {
            world,
            scene_text,
            scene_name,
            overrides,
            encoder: FrameEncoder::new(keyframe_interval),
            statics_revision: None,
            snapshot: Vec::new(),
            paused: false,
            overruns: 0,
            last_step_ms: 0.0,
            generation: 0,
            scenes_dir: opts.scenes_dir.clone(),
            limits: opts.limits.clone(),
        })
    }

    fn replace_world(&mut self, world: World) {
        self.world = world;
        self.generation += 1;
        self.encoder.force_key_frame();
        self.statics_revision = None;
    }

    fn info(&self) -> WorldInfo {
        let [lo, hi] = self.world.config.bounds;
        WorldInfo {
            scene: self
                .scene_name
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_else(|| self.scene_name.display().to_string()),
            bounds: [[lo.x, lo.y], [hi.x, hi.y]],
            dt: self.world.config.dt,
            groups: self.world.group_names().map(str::to_string).collect(),
            generation: self.generation,
        }
    }

    /// Re-encodes the statics snapshot if they changed; true when it did.
    fn refresh_snapshot(&mut self) -> bool {
        let rev = self.world.statics_revision();
        if self.statics_revision == Some(rev) {
            return false;
        }
        self.snapshot = wire::statics_snapshot(&self.world);
        self.statics_revision = Some(rev);
        true
    }

    fn encode_frame(&mut self) -> Vec<u8> {
        wire::encode_frame(
            &mut self.encoder,
            &self.world,
            self.last_step_ms,
            self.overruns,
        )
    }

    /// Applies one command; the reply says what it did.
    fn handle(&mut self, command: &Command, publish: &mut dyn FnMut(&mut Hosted)) -> Reply {
        let frame = self.world.frame();
        let result: Result<Vec<String>, String> = match command {
            Command::World(action) => self
                .world
                .apply(action)
                .map(|o| o.ids)
                .map_err(|e| e.to_string()),
            Command::Server(ServerCommand::Pause) => {
                self.paused = true;
                Ok(Vec::new())
            }
            Command::Server(ServerCommand::Resume) => {
                self.paused = false;
                Ok(Vec::new())
            }
            Command::Server(ServerCommand::Step { n }) if *n > MAX_STEPS_PER_COMMAND => Err(
                format!("`n` = {n} is more than {MAX_STEPS_PER_COMMAND} steps in one command"),
            ),
            Command::Server(ServerCommand::Step { n }) => {
                self.paused = true;
                for _ in 0..*n {
                    self.step();
                    publish(self);
                }
                Ok(Vec::new())
            }
            Command::Server(ServerCommand::Reset { paused }) => {
                match scene::parse_with(
                    &self.scene_text,
                    &self.scene_name,
                    &self.overrides,
                    &self.limits,
                ) {
                    Ok(world) => {
                        self.replace_world(world);
                        self.paused = *paused;
                        // Frame 0 of the new world goes out at once.
                        publish(self);
                        Ok(Vec::new())
                    }
                    Err(e) => Err(e.to_string()),
                }
            }
            Command::Server(ServerCommand::Load { path, text }) => {
                let loaded = self.load_scene(path.as_deref(), text.as_deref());
                if loaded.is_ok() {
                    publish(self);
                }
                loaded
            }
        };
        match result {
            Ok(ids) => Reply {
                ok: true,
                frame,
                ids,
                error: None,
            },
            Err(error) => Reply {
                ok: false,
                frame,
                ids: Vec::new(),
                error: Some(short(&error, MAX_ERROR_BYTES)),
            },
        }
    }

    fn load_scene(
        &mut self,
        path: Option<&str>,
        text: Option<&str>,
    ) -> Result<Vec<String>, String> {
        let (text, name) = match (path, text) {
            (Some(p), None) => {
                let file = resolve_scene(&self.scenes_dir, p)?;
                let text = read_scene(&file, &short(p, 64))?;
                // Errors name the scene as the client asked for it, not where it lives.
                (text, PathBuf::from(p))
            }
            (None, Some(t)) => (t.to_string(), PathBuf::from("<loaded scene>")),
            _ => return Err("`load` takes either `path` or `text`".into()),
        };
        let world = scene::parse_with(&text, &name, &self.overrides, &self.limits)
            .map_err(|e| e.to_string())?;
        self.scene_text = text;
        self.scene_name = name;
        self.replace_world(world);
        Ok(Vec::new())
    }

    fn step(&mut self) {
        let t = Instant::now();
        self.world.step();
        self.last_step_ms = t.elapsed().as_secs_f32() * 1e3;
    }
}

/// Hosts a world until killed (or `max_frames`).
pub fn run(opts: HostOptions) -> Result<()> {
    let keys = WorldKeys::new(&opts.world).map_err(|e| anyhow!(e))?;
    let text = std::fs::read_to_string(&opts.scene)
        .with_context(|| format!("cannot read scene {}", opts.scene.display()))?;
    let mut host = Hosted::load(text, opts.scene.clone(), &opts)?;
    host.paused = opts.paused;

    let mut dump = match &opts.dump {
        Some(path) => Some(std::io::BufWriter::new(
            std::fs::File::create(path)
                .with_context(|| format!("cannot create dump {}", path.display()))?,
        )),
        None => None,
    };

    let session = opts.network.open()?;
    let z = |e: zenoh::Error| anyhow!("zenoh: {e}");
    let frames = session
        .declare_publisher(&keys.frame)
        .congestion_control(CongestionControl::Drop)
        .wait()
        .map_err(z)?;
    let snapshots = session
        .declare_publisher(&keys.snapshot)
        .wait()
        .map_err(z)?;
    let events = session.declare_publisher(&keys.event).wait().map_err(z)?;
    let commands = session
        .declare_subscriber(&keys.cmd)
        .with(zenoh::handlers::FifoChannel::new(16 * 1024))
        .wait()
        .map_err(z)?;
    let requests = session
        .declare_queryable(&keys.rpc)
        .with(zenoh::handlers::FifoChannel::new(16 * 1024))
        .wait()
        .map_err(z)?;
    let snapshot_queries = session
        .declare_queryable(&keys.snapshot)
        .wait()
        .map_err(z)?;
    let state_queries = session.declare_queryable(&keys.state).wait().map_err(z)?;
    let info_queries = session.declare_queryable(&keys.info).wait().map_err(z)?;
    let _alive = session
        .liveliness()
        .declare_token(keys.alive_token(&session.zid().to_string()))
        .wait()
        .map_err(z)?;
    tracing::info!(
        world = %opts.world,
        scene = %opts.scene.display(),
        mode = opts.network.mode_name(),
        listen = ?opts.network.listen,
        connect = ?opts.network.connect,
        paused = host.paused,
        "serving"
    );

    // Real-time frames are dropped rather than queued when the network is congested, so a
    // slow subscriber never holds the clock back; frames stepped on request (paused, as in
    // a replay) wait for the network instead, so none is lost.
    let mut publish = |h: &mut Hosted| {
        if h.refresh_snapshot() {
            if let Err(e) = snapshots.put(h.snapshot.clone()).wait() {
                tracing::warn!("publishing the snapshot failed: {e}");
            }
        }
        let bytes = h.encode_frame();
        let sent = if h.paused {
            session
                .put(&keys.frame, bytes)
                .congestion_control(CongestionControl::Block)
                .wait()
        } else {
            frames.put(bytes).wait()
        };
        if let Err(e) = sent {
            tracing::warn!("publishing frame {} failed: {e}", h.world.frame());
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
    let interval = |h: &Hosted| {
        let dt_ns = (h.world.config.dt * 1e9).round() as u64;
        if dt_ns < min_interval_ns {
            tracing::warn!(
                dt = h.world.config.dt,
                max_rate = opts.max_rate,
                "dt is shorter than 1/max-rate: the world runs slower than real time"
            );
        }
        dt_ns.max(min_interval_ns)
    };
    let mut dt_ns = interval(&host);
    let mut last_dt = host.world.config.dt;
    let mut anchor = Instant::now();
    let mut due: u64 = 1; // steps since the anchor, the next one included
    loop {
        // Snapshot and state queries are answered at once.
        while let Ok(Some(query)) = snapshot_queries.try_recv() {
            host.refresh_snapshot();
            if let Err(e) = query
                .reply(query.key_expr().clone(), host.snapshot.clone())
                .wait()
            {
                tracing::debug!("snapshot reply failed: {e}");
            }
        }
        while let Ok(Some(query)) = state_queries.try_recv() {
            let state = host.encoder.resync_frame().expect("frame 0 was published");
            if let Err(e) = query.reply(query.key_expr().clone(), state).wait() {
                tracing::debug!("state reply failed: {e}");
            }
        }

        while let Ok(Some(query)) = info_queries.try_recv() {
            let info = serde_json::to_vec(&host.info()).expect("world info serialises");
            if let Err(e) = query.reply(query.key_expr().clone(), info).wait() {
                tracing::debug!("info reply failed: {e}");
            }
        }

        // The frame boundary: every command that arrived, in order, up to a bound.
        let was_paused = host.paused;
        let mut handled = 0;
        while handled < MAX_COMMANDS_PER_FRAME {
            let (payload, query) = if let Ok(Some(sample)) = commands.try_recv() {
                (sample.payload().to_bytes().into_owned(), None)
            } else if let Ok(Some(query)) = requests.try_recv() {
                (
                    query
                        .payload()
                        .map(|p| p.to_bytes().into_owned())
                        .unwrap_or_default(),
                    Some(query),
                )
            } else {
                break;
            };
            handled += 1;
            let parsed =
                Command::parse_limited(&payload, host.world.limits().command_bytes as usize);
            let reply = match &parsed {
                Ok(command) => host.handle(command, &mut publish),
                Err(error) => Reply {
                    ok: false,
                    frame: host.world.frame(),
                    ids: Vec::new(),
                    error: Some(error.clone()),
                },
            };
            if !reply.ok {
                tracing::warn!(
                    frame = reply.frame,
                    "command refused: {}",
                    reply.error.as_deref().unwrap_or("")
                );
            }
            let event = Event {
                frame: reply.frame,
                ok: reply.ok,
                command: parsed.ok(),
                ids: reply.ids.clone(),
                error: reply.error.clone(),
            };
            let _ = events
                .put(serde_json::to_vec(&event).expect("events serialise"))
                .wait();
            if let Some(query) = query {
                let body = serde_json::to_vec(&reply).expect("replies serialise");
                if let Err(e) = query.reply(query.key_expr().clone(), body).wait() {
                    tracing::debug!("reply failed: {e}");
                }
            }
        }
        let new_dt = if host.world.config.dt != last_dt {
            last_dt = host.world.config.dt;
            interval(&host)
        } else {
            dt_ns
        };
        if new_dt != dt_ns || (was_paused && !host.paused) {
            // The clock restarts from now at the new rate.
            dt_ns = new_dt;
            anchor = Instant::now();
            due = 1;
        }

        if opts.max_frames.is_some_and(|m| host.world.frame() >= m) {
            tracing::info!(
                frame = host.world.frame(),
                overruns = host.overruns,
                "stopping after the last frame"
            );
            return Ok(());
        }

        let deadline = anchor + Duration::from_nanos(due.saturating_mul(dt_ns));
        let now = Instant::now();
        if now < deadline {
            std::thread::sleep((deadline - now).min(Duration::from_millis(20)));
            continue;
        }
        if host.paused {
            anchor = Instant::now();
            due = 1;
            continue;
        }
        let late_steps = ((now - deadline).as_nanos() / dt_ns.max(1) as u128) as u64;
        if late_steps >= 1 {
            host.overruns = host.overruns.saturating_add(1);
        }
        if late_steps > MAX_CATCH_UP {
            tracing::warn!(
                late_steps,
                frame = host.world.frame(),
                "the world cannot keep real time; the clock re-anchors"
            );
            host.overruns = host
                .overruns
                .saturating_add(late_steps.min(u32::MAX as u64) as u32);
            anchor = now;
            due = 0;
        }
        host.step();
        publish(&mut host);
        due += 1;
    }
}

/// Runs a bare zenoh router: where servers and clients on several hosts meet.
pub fn run_router(network: &Network) -> Result<()> {
    let _session = network.open()?;
    tracing::info!(listen = ?network.listen, connect = ?network.connect, "router up");
    loop {
        std::thread::sleep(Duration::from_secs(3600));
    }
}
